"""Errors of a repair against the truth."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import MocapfillError
from .motion import Motion, check_coordinates, require_motion

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

    Raises
    ------
    TypeError
        A Motion for an array (:func:`score` takes clips), or a mask that is not bool.
    ValueError
        Arrays that are not (frames, markers, 3) of one shape, or a mask of another shape.
    """
    for array, role in ((truth, "truth"), (estimate, "estimate")):
        if isinstance(array, Motion):
            raise TypeError(f"rmse() takes arrays, got a Motion as {role}: score() takes "
                            "clips, or pass their .positions")
    truth, estimate, mask = np.asarray(truth), np.asarray(estimate), np.asarray(mask)
    if truth.ndim != 3 or truth.shape[2] != 3 or estimate.shape != truth.shape:
        raise ValueError(f"rmse() takes truth and estimate of one (frames, markers, 3) "
                         f"shape, got {truth.shape} and {estimate.shape}")
    # Checked, not converted: a 0/1 mask indexed frames 0 and 1 (a wrong RMSE), and a
    # (frames, markers, 3) one such as np.isnan(positions) picked coordinates, not
    # samples (the 3-D error then equal to the RMSE).
    if mask.dtype != bool:
        raise TypeError(f"rmse() takes a bool mask, got {mask.dtype}")
    if mask.shape != truth.shape[:2]:
        raise ValueError(f"rmse() takes a (frames, markers) mask, {truth.shape[:2]}, got "
                         f"{mask.shape}: one entry per sample")
    diff = (estimate - truth)[mask]
    if diff.size == 0:
        return float("nan"), float("nan")
    sq = float((diff ** 2).sum())
    return float(np.sqrt(sq / diff.size)), float(np.sqrt(sq / len(diff)))


def score(truth: Motion, repaired: Motion, gapped: Motion | None = None) -> Score:
    """Score a repair on the samples missing in ``gapped`` and present in ``truth``.

    Without ``gapped``, the scored samples are those that differ between the two files:
    present in one and missing in the other, or present in both with values further apart
    than the two files can store them (see :func:`storage_step`): the same clip read from
    a CSV with 3 decimals and from a float32 C3D differs in every sample by rounding alone.
    A sample still missing in ``repaired`` counts as unfilled and is left out of the RMSE.

    ``rmse`` and ``rmse_3d`` are in the truth's units, ``rmse_mm`` and ``rmse_3d_mm`` in
    mm (None when the truth's unit is not a known length). Clips in different units that
    are both known lengths (a CMU AMC in ``in/0.45`` and the C3D ``convert`` wrote from it
    in mm) are compared in mm; a unit that is not a known length (a BVH's ``unknown``)
    must be the same in both, or the clips are refused.

    Raises
    ------
    MocapfillError
        Naming both files: different frames, markers or marker names, or units that
        cannot be compared.
    FormatError
        Naming the file: a coordinate too large to process (``motion.check_coordinates``).
    """
    for clip, role in ((truth, "truth"), (repaired, "repaired"), (gapped, "gapped")):
        if clip is not None or role != "gapped":
            require_motion(clip, "score", role)
    for other, role in ((repaired, "repaired"), (gapped, "gapped")):
        if other is not None:
            _check_comparable(truth, other, role)
    for clip in (truth, repaired):      # their differences are squared and summed
        check_coordinates(clip)
    truth_mm, repaired_mm = _common_scale(truth, repaired)
    if gapped is not None:
        target = truth.observed & ~gapped.observed
    else:
        both = truth.observed & repaired.observed
        target = (truth.observed != repaired.observed) | (
            both & _differ(truth, repaired, truth_mm, repaired_mm))
        target &= truth.observed
    scored = target & repaired.observed
    value, value_3d = rmse(truth.positions * truth_mm, repaired.positions * repaired_mm,
                           scored)
    if truth_mm != 1.0:         # computed in mm: back to the truth's units
        value_mm, value_3d_mm = value, value_3d
        value, value_3d = value / truth_mm, value_3d / truth_mm
    else:
        factor = mm_per_unit(truth.units)
        value_mm = None if factor is None else value * factor
        value_3d_mm = None if factor is None else value_3d * factor
    return Score(value, value_3d, value_mm, value_3d_mm, int(scored.sum()),
                 int((target & ~repaired.observed).sum()))


def _common_scale(truth: Motion, repaired: Motion) -> tuple[float, float]:
    """Factors that bring both clips' positions to one unit: (1, 1) when their units are
    the same length, the millimetres of each unit where they differ (both known lengths,
    see :func:`_check_comparable`)."""
    a, b = mm_per_unit(truth.units), mm_per_unit(repaired.units)
    if a is None or b is None or a == b:
        return 1.0, 1.0
    return a, b


# Relative rounding of float32 storage (C3D float words, float32 NPZ arrays): half a unit
# in the last place is at most 2^-24 of the value. The tolerance allows 2^-22, room for
# two such roundings on the way from the truth to the repair and one more.
_FLOAT32_SLACK = 2.0 ** -22
# Text files print at most this many decimals for the step search (more is float64 text).
_MAX_DECIMALS = 9


def storage_step(motion: Motion) -> np.ndarray:
    """(markers, 3) the step between the values each coordinate column of a file can hold.

    For a text file it is 10^-d, d the fewest decimals that print every observed value of
    the column (found from the values, so it holds for CSV, TRC and anything converted from
    them); values that went through float32 storage on the way still count as printed
    with d decimals when float32's rounding explains the rest. An integer C3D adds its
    POINT:SCALE. 0 where no decimal count up to 9 fits (float64 values, or float32 ones
    not from text: their rounding is relative, see ``_FLOAT32_SLACK``).
    """
    values = motion.positions
    step = np.zeros(values.shape[1:])
    undecided = np.ones(values.shape[1:], bool)
    with np.errstate(invalid="ignore", over="ignore"):
        for decimals in range(_MAX_DECIMALS + 1):
            scaled = values * 10.0 ** decimals
            off = np.abs(scaled - np.rint(scaled))
            # NaN (missing) samples pass: only observed values say how a column is stored.
            fits = ~(off > np.abs(scaled) * 2.0 ** -23).any(axis=0)
            step[undecided & fits] = 10.0 ** -decimals
            undecided &= ~fits
            if not undecided.any():
                break
    scale = _integer_c3d_scale(motion)
    return step if scale is None else np.maximum(step, scale)


def _integer_c3d_scale(motion: Motion) -> float | None:
    # Imported here: the metrics load without the format readers.
    from .formats.c3d import C3DSource

    source = motion.source
    return source.scale if isinstance(source, C3DSource) and not source.is_float else None


def _differ(truth: Motion, repaired: Motion, truth_scale: float = 1.0,
            repaired_scale: float = 1.0) -> np.ndarray:
    """(frames, markers) True where a sample of the two clips differs by more than their
    storage can explain: a step of each file (twice its rounding) plus float32's relative
    rounding. Exact comparison took every sample of a CSV truth against a C3D repair for
    a filled one (24,599 samples scored on the walk sample instead of its 1,617 gaps).
    Each clip's positions and storage step are taken times its scale (to one unit; the
    float64 rounding of that is far inside float32's slack)."""
    truth_values = truth.positions * truth_scale
    tolerance = (storage_step(truth) * truth_scale
                 + storage_step(repaired) * repaired_scale)[None] \
        + _FLOAT32_SLACK * np.abs(truth_values)
    with np.errstate(invalid="ignore"):
        return (np.abs(truth_values - repaired.positions * repaired_scale) > tolerance
                ).any(axis=2)


def _name(motion: Motion, role: str) -> str:
    return f"{role} file {motion.path}" if motion.path is not None else f"{role} clip"


def _check_comparable(truth: Motion, other: Motion, role: str) -> None:
    """The same frames and markers (by label, in order) as the truth, and units that can be
    compared with its units (both known lengths, or the same unit), or an error naming both
    files: a silent mismatch would score the wrong samples."""
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
    if (a is None or b is None) and other.units.strip().lower() != truth.units.strip().lower():
        unknown = truth.units if a is None else other.units
        raise MocapfillError(f"{_name(other, role)} is in {other.units}, "
                             f"{_name(truth, 'truth')} in {truth.units}: {unknown!r} is not "
                             "a known length, so the two cannot be compared")

