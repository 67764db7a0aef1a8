"""The unit-invariant scale every solver works in.

Scaling the data by c is the same as changing the paper's μ to cμ and η₀ to η₀/c
(MODEL.md), so units would be a hidden hyper-parameter. The pipeline therefore centres
every row on its observed mean and divides the whole clip by the RMS of the centred
observed entries before solving, and undoes both afterwards. One scale for the whole clip
(not per row) keeps the relative size of the coordinates, which carries the geometry.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class UnitScale:
    """Affine map x → (x − centre) / scale, row-wise centre, one scale."""

    centre: np.ndarray   # (m, 1)
    scale: float

    @classmethod
    def fit(cls, matrix: np.ndarray, observed: np.ndarray) -> UnitScale:
        counts = observed.sum(axis=1, keepdims=True)
        # Sums and squares are taken in units of a power of two near the largest observed
        # value (exact: the same centre and scale to the last bit), so that coordinates
        # above 1e154 do not square to inf, which made every method's fill non-finite.
        largest = float(np.abs(matrix, where=observed, out=np.zeros(matrix.shape)).max(
            initial=0.0))
        unit = math.ldexp(1.0, math.frexp(largest)[1]) if 0.0 < largest < np.inf else 1.0
        # Observed entries only: a missing one may hold anything, which a small unit
        # would overflow (with a warning, though the value is then dropped).
        sums = np.divide(matrix, unit, out=np.zeros(matrix.shape), where=observed).sum(
            axis=1, keepdims=True)
        centre = np.divide(sums, counts, out=np.zeros_like(sums), where=counts > 0) * unit
        centred = np.subtract(matrix, centre, out=np.zeros(matrix.shape), where=observed)
        centred /= unit
        n_obs = int(observed.sum())
        rms = float(np.sqrt((centred ** 2).sum() / n_obs)) * unit if n_obs else 0.0
        return cls(centre=centre, scale=rms if rms > 0 else 1.0)

    def forward(self, matrix: np.ndarray) -> np.ndarray:
        return (matrix - self.centre) / self.scale

    def inverse(self, matrix: np.ndarray) -> np.ndarray:
        return matrix * self.scale + self.centre
