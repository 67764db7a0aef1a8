"""Errors of a repair against the truth."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import MocapfillError
from .motion import Motion

# Length units as files spell them -> millimetres.
MM_PER_UNIT = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "cm": 10.0, "m": 1000.0,
               "meter": 1000.0, "metre": 1000.0, "mete": 1000.0, "in": 25.4, "inch": 25.4,
               "ft": 304.8}


def mm_per_unit(units: str) -> float | None:
    """Millimetres in one unit, or None when the unit is unknown."""
    return MM_PER_UNIT.get(units.strip().lower())


@dataclass(frozen=True)
class Score:
    """RMSE over missing coordinates (the paper's) and 3-D RMS marker error."""

    rmse: float
    rmse_3d: float
    rmse_mm: float | None
    rmse_3d_mm: float | None
    missing_samples: int
    unfilled_samples: int

    def as_dict(self) -> dict:
        return {"rmse": self.rmse, "rmse_3d": self.rmse_3d, "rmse_mm": self.rmse_mm,
                "rmse_3d_mm": self.rmse_3d_mm, "missing_samples": self.missing_samples,
                "unfilled_samples": self.unfilled_samples}


def rmse(truth: np.ndarray, estimate: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """(paper RMSE over coordinates, 3-D RMS error) on the (frames, markers) samples in mask.

    Arrays are (frames, markers, 3). The paper's RMSE is ‖(X − X̂)_{Ω^c}‖_F/√|Ω^c| over
    coordinates; the 3-D error is the RMS of the Euclidean marker error, √3 times larger.
    """
    diff = (estimate - truth)[mask]
    if diff.size == 0:
        return float("nan"), float("nan")
    sq = float((diff ** 2).sum())
    return float(np.sqrt(sq / diff.size)), float(np.sqrt(sq / len(diff)))


def score(truth: Motion, repaired: Motion, gapped: Motion | None = None) -> Score:
    """Score a repair on the samples missing in ``gapped`` and present in ``truth``.

    Without ``gapped``, the scored samples are those that differ between the two files:
    present in one and missing in the other, or present in both with different values.
    A sample still missing in ``repaired`` counts as unfilled and is left out of the RMSE.
    """
    if truth.positions.shape != repaired.positions.shape:
        raise MocapfillError(f"truth has {truth.n_frames} frames × {truth.n_markers} markers, "
                             f"repaired has {repaired.n_frames} × {repaired.n_markers}")
    if gapped is not None:
        if gapped.positions.shape != truth.positions.shape:
            raise MocapfillError("gapped file does not match the truth in frames × markers")
        target = truth.observed & ~gapped.observed
    else:
        both = truth.observed & repaired.observed
        changed = both & ~np.isclose(truth.positions, repaired.positions, rtol=1e-9,
                                     atol=0).all(axis=2)
        target = (truth.observed != repaired.observed) | changed
        target &= truth.observed
    scored = target & repaired.observed
    value, value_3d = rmse(truth.positions, repaired.positions, scored)
    factor = mm_per_unit(truth.units)
    return Score(value, value_3d, None if factor is None else value * factor,
                 None if factor is None else value_3d * factor, int(scored.sum()),
                 int((target & ~repaired.observed).sum()))
