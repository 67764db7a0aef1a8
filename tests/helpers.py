"""Synthetic clips for tests: smooth, low-rank-ish marker motion with known truth; and the
check of a patched text file against the file it patched."""
from __future__ import annotations

import math
import re
import tracemalloc

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


def assert_only_nan_tokens_replaced(gapped: str, patched: str) -> int:
    """Assert ``patched`` is ``gapped`` with only its ``nan`` tokens replaced by numbers.

    Both are whole texts (BVH frame lines, AMC bone lines: whitespace-separated tokens).
    Every other token, every separator and every line ending must be the same text, so a
    writer that rewrites an observed value beside a filled one (even to the same number
    printed differently) is caught. Returns how many tokens were replaced.
    """
    before, after = gapped.splitlines(keepends=True), patched.splitlines(keepends=True)
    assert len(after) == len(before), f"{len(after)} lines written, {len(before)} read"
    replaced = 0
    for number, (old, new) in enumerate(zip(before, after), start=1):
        if new == old:
            continue
        old_parts, new_parts = re.split(r"(\s+)", old), re.split(r"(\s+)", new)
        assert len(new_parts) == len(old_parts), f"line {number}: {old!r} became {new!r}"
        for old_part, new_part in zip(old_parts, new_parts):
            if old_part.lower() == "nan":
                assert math.isfinite(float(new_part)), f"line {number}: {new_part!r} filled"
                replaced += 1
            else:
                assert new_part == old_part, (f"line {number}: {old_part!r} became "
                                              f"{new_part!r} (not a gap)")
    return replaced


def peak_bytes(function) -> int:
    """The most memory allocated while ``function`` runs (numpy's arrays are traced)."""
    tracemalloc.start()
    try:
        function()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
