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

# The largest magnitude of a value mocapfill computes with (repair, rank, score; checked
# on each clip before, see motion.check_coordinates). Real coordinates lie far below it
# (a kilometre in micrometres is 1e9). Above 1.3e154 a square overflows float64 (largest
# 1.8e308) to inf: a score's sum of squared errors read "RMSE inf", the jump check's
# squared steps made its threshold infinite; above 2^1023 (9e307) the unit scale itself
# failed (OverflowError in fit). Within 1e100 the difference of two values (2e100), its
# square (4e200) and a sum of such squares over more samples than any memory holds stay
# finite. A larger value is a corrupt one, not a measurement.
MAX_MAGNITUDE = 1e100


def outsized(values: np.ndarray, columns: np.ndarray | None = None
             ) -> tuple[float, int, int] | None:
    """The value of largest magnitude above :data:`MAX_MAGNITUDE` in a (frames, columns)
    or (frames, columns, 3) array, among ``columns`` (bool, default all), with its frame
    and column: (value, frame, column); None where no value is that large. NaN (a
    missing value) is ignored. The columns' largest and smallest values are found
    without a copy of the array (20 ms for a 30-minute clip of 41 markers)."""
    if values.size == 0:
        return None
    axes = (0, *range(2, values.ndim))
    beyond = ((np.fmax.reduce(values, axis=axes) > MAX_MAGNITUDE)
              | (np.fmin.reduce(values, axis=axes) < -MAX_MAGNITUDE))
    if columns is not None:
        beyond &= columns
    if not beyond.any():
        return None
    found = np.flatnonzero(beyond)
    picked = np.abs(values[:, found])
    where = np.unravel_index(np.nanargmax(picked), picked.shape)
    value = float(values[:, found][where])
    return value, int(where[0]), int(found[where[1]])


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
