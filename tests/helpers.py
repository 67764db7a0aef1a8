"""Synthetic clips for tests: smooth, low-rank-ish marker motion with known truth."""
from __future__ import annotations

import numpy as np

from mocapfill.motion import Motion


def smooth_clip(n_frames: int = 400, n_markers: int = 12, rate: float = 120.0,
                seed: int = 0, scale_mm: float = 100.0) -> Motion:
    """Markers driven by a few smooth latent signals plus fixed offsets (mm)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames) / rate
    freqs = np.array([0.4, 0.9, 1.3, 1.7, 2.3])
    latent = np.sin(2 * np.pi * freqs[:, None] * t + rng.uniform(0, 6, (5, 1)))
    mixing = rng.normal(size=(3 * n_markers, 5))
    data = scale_mm * (mixing @ latent) + rng.normal(scale=500, size=(3 * n_markers, 1))
    positions = data.reshape(n_markers, 3, n_frames).transpose(2, 0, 1)
    labels = tuple(f"MK{j:02d}" for j in range(n_markers))
    return Motion(positions, np.ones((n_frames, n_markers), bool), labels, rate, "mm")


def with_gap(motion: Motion, marker: int, start: int, stop: int) -> Motion:
    observed = motion.observed.copy()
    observed[start:stop, marker] = False
    return motion.with_positions(motion.positions, observed)
