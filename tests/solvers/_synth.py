"""Synthetic matrices shared by the solver tests (not a test module)."""
from __future__ import annotations

import numpy as np


def unit_rms(M: np.ndarray) -> np.ndarray:
    M = M - M.mean(axis=1, keepdims=True)
    return M / np.sqrt((M ** 2).mean(axis=1, keepdims=True))


def smooth_low_rank(seed: int, m: int = 30, n: int = 300, r: int = 4) -> np.ndarray:
    """(m, n) unit-RMS rows, rank r, smooth along time (a few sinusoids)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    F = np.array([np.sin(2 * np.pi * (q + 1) * t + rng.uniform(0, 6)) for q in range(r)])
    return unit_rms(rng.standard_normal((m, r)) @ F)


def marker_gaps(seed: int, m: int, n: int, length: int, every: int = 1) -> np.ndarray:
    """Observed mask with one gap of ``length`` frames in every ``every``-th marker."""
    rng = np.random.default_rng(seed)
    observed = np.ones((m, n), dtype=bool)
    for j in range(0, m // 3, every):
        start = int(rng.integers(5, n - length - 5))
        observed[3 * j:3 * j + 3, start:start + length] = False
    return observed


def scattered(seed: int, m: int, n: int, rate: float) -> np.ndarray:
    """Observed mask with each marker's samples missing at random (runs of 1-4 frames),
    never at the first or last frame."""
    rng = np.random.default_rng(seed)
    lost = rng.random((m // 3, n)) < rate
    lost[:, [0, -1]] = False
    return np.repeat(~lost, 3, axis=0)


def masked(M: np.ndarray, observed: np.ndarray) -> np.ndarray:
    return np.where(observed, M, np.nan)


def rel(a: np.ndarray, b: np.ndarray, where: np.ndarray | None = None) -> float:
    if where is not None:
        a, b = a[where], b[where]
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))
