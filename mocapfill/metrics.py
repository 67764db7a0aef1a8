"""Errors of a repair against the truth."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import MocapfillError
from .motion import Motion

# Length units as files spell them -> millimetres.
MM_PER_UNIT = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "cm": 10.0, "m": 1000.0,
               "meter": 1000.0, "metre": 1000.0, "mete": 1000.0, "in": 25.4, "inch": 25.4,
               "ft": 304.8}


def mm_per_unit(units: str) -> float | None:
    """Millimetres in one unit, or None when the unit is unknown.

    A unit divided by a number (``in/0.45``: CMU AMC lengths, inches over the ASF's
    ``:units length``) is that unit's millimetres over the number.
    """
    name, _, divisor = units.strip().lower().partition("/")
    mm = MM_PER_UNIT.get(name.strip())
    if mm is None or not divisor:
        return mm
    try:
        by = float(divisor)
    except ValueError:
        return None
    return mm / by if math.isfinite(by) and by > 0 else None


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
        """The fields, with None for an error that is undefined (no sample scored): JSON
        has no NaN."""
        def finite(value: float | None) -> float | None:
            return None if value is None or not np.isfinite(value) else value

        return {"rmse": finite(self.rmse), "rmse_3d": finite(self.rmse_3d),
                "rmse_mm": finite(self.rmse_mm), "rmse_3d_mm": finite(self.rmse_3d_mm),
                "missing_samples": self.missing_samples,
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
    for other, role in ((repaired, "repaired"), (gapped, "gapped")):
        if other is not None:
            _check_comparable(truth, other, role)
    if gapped is not None:
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


def _name(motion: Motion, role: str) -> str:
    return f"{role} file {motion.path}" if motion.path is not None else f"{role} clip"


def _check_comparable(truth: Motion, other: Motion, role: str) -> None:
    """The same frames, markers (by label, in order) and units as the truth, or an error
    naming both files: a silent mismatch would score the wrong samples."""
    if other.positions.shape != truth.positions.shape:
        raise MocapfillError(f"{_name(other, role)} has {other.n_frames} frames × "
                             f"{other.n_markers} markers, {_name(truth, 'truth')} "
                             f"{truth.n_frames} × {truth.n_markers}")
    if [x.strip() for x in other.labels] != [x.strip() for x in truth.labels]:
        first = next(i for i, (a, b) in enumerate(zip(truth.labels, other.labels))
                     if a.strip() != b.strip())
        raise MocapfillError(f"{_name(other, role)} names marker {first + 1} "
                             f"{other.labels[first]!r}, {_name(truth, 'truth')} "
                             f"{truth.labels[first]!r}")
    a, b = mm_per_unit(truth.units), mm_per_unit(other.units)
    if a is not None and b is not None and a != b:
        raise MocapfillError(f"{_name(other, role)} is in {other.units}, "
                             f"{_name(truth, 'truth')} in {truth.units}")

