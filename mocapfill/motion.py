"""The one data model: a motion clip of marker trajectories and its occlusion mask.

``observed`` is True where a sample is present. That is the only meaning of the mask in
mocapfill. A marker sample is observed or missing as a whole (all three coordinates).
"""
from __future__ import annotations

import fnmatch
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from numbers import Integral, Real
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np

from .errors import FormatError, named
from .scaling import MAX_MAGNITUDE, outsized


def finite_samples(positions: np.ndarray) -> np.ndarray:
    """(frames, markers) True where all three coordinates of a sample are finite.

    The coordinates are combined one by one: ``np.isfinite(positions).all(axis=2)``,
    reducing over the length-3 axis, took 0.32 s of a 216,000-frame clip of 41 markers
    (a Motion's whole check and copy 0.75 s, 0.30 s this way).
    """
    finite = np.isfinite(positions)
    return finite[..., 0] & finite[..., 1] & finite[..., 2]


def whole_number(value: object) -> bool:
    """Whether a count given from Python is a whole number: 40, numpy's int64(40) or
    40.0, not 2.5, nan, inf, True or "40"."""
    if isinstance(value, (bool, np.bool_)):
        return False
    return isinstance(value, Integral) or (isinstance(value, Real)
                                           and float(value).is_integer())


# Frame numbers lie in [-FRAME_NUMBER_LIMIT, FRAME_NUMBER_LIMIT): what 64 bits hold.
FRAME_NUMBER_LIMIT = 2**63


def _number_text(value: int) -> str:
    """A whole number for a message: its digits, or their count where they are many
    (Python refuses to print more than 4300)."""
    if abs(value) < 10**30:
        return str(value)
    return f"a number of about {int(abs(value).bit_length() * math.log10(2)) + 1} digits"


@dataclass(frozen=True, eq=False)
class Motion:
    """Marker trajectories of one clip.

    Attributes
    ----------
    positions
        (frames, markers, 3) float64 coordinates in ``units``. Missing samples hold NaN.
    observed
        (frames, markers) bool, True where the sample is present.
    labels
        Marker names, one per marker.
    rate
        Frame rate in Hz: a finite number ≥ 0, 0 when not known.
    units
        Length unit of ``positions`` as the file states it ("mm", "m", ...).
    fillable
        (markers,) bool; False for points that are not markers (C3D model outputs such as
        angles, forces, moments, powers). They are never filled, never used as evidence for
        other markers, and left out of a new TRC or CSV. (Markers the user excludes with
        ``--exclude`` stay fillable: they are evidence, only their gaps are left.)
    source
        Format-specific handle that a writer of the same format uses to patch the original
        file instead of regenerating it (None for data built in memory).
    path
        The file the clip was read from, if any.
    first_frame
        Frame number of the first frame as the file counts it (1 in most formats): a whole
        number (numpy's integers and whole floats such as 3.0 are taken as the int), the
        clip's frames numbered within 64 bits (from -2**63; the last at most 2**63 - 1).

    ``positions``, ``observed`` and ``fillable`` are read-only arrays the Motion owns (a
    change is a new Motion: :meth:`replace`, :meth:`with_positions`; copy them to edit).

    Raises
    ------
    ValueError
        Arrays of the wrong shapes, labels not one per marker, a rate or first frame that
        is not one.
    """

    positions: np.ndarray
    observed: np.ndarray
    labels: tuple[str, ...]
    rate: float
    units: str = "mm"
    fillable: np.ndarray | None = None
    source: Any = field(default=None, repr=False)
    path: Path | None = None
    first_frame: int = 1

    def __post_init__(self) -> None:
        positions = np.asarray(self.positions, dtype=np.float64)
        if positions.ndim != 3 or positions.shape[2] != 3:
            raise ValueError(f"positions must be (frames, markers, 3), got {positions.shape}")
        observed = np.asarray(self.observed, dtype=bool)
        if observed.shape != positions.shape[:2]:
            raise ValueError(f"observed must be {positions.shape[:2]}, got {observed.shape}")
        if len(self.labels) != positions.shape[1]:
            raise ValueError(f"{len(self.labels)} labels for {positions.shape[1]} markers")
        # A sample with a non-finite coordinate is missing, whatever the file said.
        observed = observed & finite_samples(positions)
        positions = np.where(observed[:, :, None], positions, np.nan)
        fillable = (np.ones(positions.shape[1], bool) if self.fillable is None
                    else np.array(self.fillable, dtype=bool))
        if fillable.shape != (positions.shape[1],):
            raise ValueError("fillable must have one entry per marker")
        # Read-only, as the clip is frozen: positions set to NaN in place kept their
        # samples observed (a repair then failed with a SolverError), and observed set
        # False in place left the values. The three arrays are the Motion's own (made
        # above), so no caller's array is locked.
        for array in (positions, observed, fillable):
            array.flags.writeable = False
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "observed", observed)
        object.__setattr__(self, "labels", tuple(str(label) for label in self.labels))
        object.__setattr__(self, "fillable", fillable)
        # Checked here, not by each writer: a rate of -5, nan or inf was written to an NPZ
        # that read then refused, and a first frame of 2.5 crashed the C3D writer.
        rate = float(self.rate)
        if not (math.isfinite(rate) and rate >= 0):
            raise ValueError(f"rate must be a frame rate (a positive, finite number of Hz, "
                             f"or 0 when not known), got {self.rate!r}")
        if not whole_number(self.first_frame):
            raise ValueError(f"first_frame must be a whole number, got {self.first_frame!r}")
        first_frame = int(self.first_frame)
        # Frame numbers of 64 bits at most, as an NPZ stores them (a C3D's 32 bits are the
        # C3D writer's, which numbers from 1 what does not fit): a first frame of 1e20 read
        # from a TRC (or 1e300 from an NPZ) crashed the NPZ writer with an OverflowError.
        last = FRAME_NUMBER_LIMIT - max(positions.shape[0], 1)
        if not -FRAME_NUMBER_LIMIT <= first_frame <= last:
            raise ValueError(f"first_frame must fit in 64 bits with the clip's frames "
                             f"(-2**63 to {last}), got {_number_text(first_frame)}")
        object.__setattr__(self, "rate", rate)
        object.__setattr__(self, "first_frame", first_frame)

    @property
    def n_frames(self) -> int:
        return self.positions.shape[0]

    @property
    def n_markers(self) -> int:
        return self.positions.shape[1]

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.rate if self.rate > 0 else float("nan")

    def replace(self, **changes: Any) -> Motion:
        """A copy with some fields changed (the source handle and path are kept)."""
        return replace(self, **changes)

    def with_positions(self, positions: np.ndarray, observed: np.ndarray) -> Motion:
        """A copy holding new positions and mask, same labels, rate, units and source."""
        return replace(self, positions=positions, observed=observed)

    def matrix(self, markers: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The (3·markers × frames) matrix of the paper and its observed mask.

        Rows 3j, 3j+1, 3j+2 hold x, y, z of the j-th selected marker; columns are frames.
        Missing entries are NaN.
        """
        idx = np.arange(self.n_markers) if markers is None else np.asarray(markers)
        frames, rows = self.n_frames, 3 * len(idx)
        every = np.array_equal(idx, np.arange(self.n_markers))
        flat = (self.positions if every else self.positions[:, idx, :]).reshape(frames, rows)
        data = np.empty((rows, frames))
        # Transposed a block of frames at a time: the whole (frames × rows) transpose in one
        # copy strode through memory and took 0.55–1.2 s on a 216,000-frame clip of 41
        # markers, by blocks 0.09 s.
        for start in range(0, frames, _TRANSPOSE_FRAMES):
            block = slice(start, start + _TRANSPOSE_FRAMES)
            data[:, block] = flat[block].T
        mask = np.repeat(self.observed[:, idx].T, 3, axis=0)
        return data, mask

    def with_matrix(self, data: np.ndarray, mask: np.ndarray,
                    markers: np.ndarray | None = None) -> Motion:
        """A copy whose selected markers take the values of a (3·k × frames) matrix.

        ``mask`` (3·k × frames) must hold whole samples; a sample is observed when its
        x row is True.
        """
        idx = np.arange(self.n_markers) if markers is None else np.asarray(markers)
        observed = self.observed.copy()
        observed[:, idx] = mask[0::3].T
        return self.with_positions(self.positions_from_matrix(data, idx), observed)

    def positions_from_matrix(self, data: np.ndarray, markers: np.ndarray | None = None
                              ) -> np.ndarray:
        """A copy of the positions (frames, markers, 3) whose selected markers take the
        values of a (3·k × frames) matrix; no Motion is built (nor its mask checked)."""
        idx = np.arange(self.n_markers) if markers is None else np.asarray(markers)
        positions = self.positions.copy()
        for start in range(0, self.n_frames, _TRANSPOSE_FRAMES):   # by blocks, as matrix()
            block = slice(start, start + _TRANSPOSE_FRAMES)
            positions[block, idx, :] = data[:, block].T.reshape(-1, len(idx), 3)
        return positions


# Frames per block of the transposes between (frames, markers, 3) and the (3·markers ×
# frames) matrix (4096 frames of 41 markers: 4 MB, within a core's caches).
_TRANSPOSE_FRAMES = 4096


def from_matrix(data: np.ndarray, observed: np.ndarray | None = None, *, rate: float = 120.0,
                units: str = "mm", labels: list[str] | None = None) -> Motion:
    """Build a Motion from a (3·markers × frames) matrix (the paper's layout)."""
    data = np.asarray(data, dtype=np.float64)
    if data.ndim != 2 or data.shape[0] % 3:
        raise ValueError("matrix must be (3*markers, frames)")
    n_markers = data.shape[0] // 3
    if observed is None:
        observed = np.isfinite(data)
    observed = np.asarray(observed, bool).reshape(n_markers, 3, -1).all(axis=1).T
    positions = data.reshape(n_markers, 3, -1).transpose(2, 0, 1)
    labels = labels or [f"M{j + 1:03d}" for j in range(n_markers)]
    return Motion(positions, observed, tuple(labels), rate, units)


def require_motion(value: object, function: str, argument: str = "motion") -> None:
    """A TypeError unless ``value`` is a Motion: a file name handed to ``repair`` and the
    other functions taking a clip failed deep inside ("'str' object has no attribute
    'n_frames'")."""
    if isinstance(value, Motion):
        return
    hint = ""
    if isinstance(value, (str, PathLike)):
        hint = f": read the file first, mocapfill.read({str(value)!r}) gives its Motion"
    raise TypeError(f"{function}() takes a Motion as {argument}, got "
                    f"{type(value).__name__}{hint}")


def check_coordinates(motion: Motion, markers: np.ndarray | None = None) -> None:
    """Before a clip is computed with (repaired, its rank estimated, scored): a
    FormatError naming its file where an observed coordinate of ``markers`` (bool, one per
    marker; default all) is larger in magnitude than ``scaling.MAX_MAGNITUDE`` (1e100):
    sums of squares of such values overflow to inf (a repair failed with a traceback, a
    score read "RMSE inf"). The error names the largest, its marker and its frame."""
    found = outsized(motion.positions, markers)
    if found is not None:
        value, frame, marker = found
        raise too_large(motion.path, "coordinate", value,
                        f"marker {motion.labels[marker]}, frame {motion.first_frame + frame}")


def too_large(path, what: str, value: float, where: str) -> FormatError:
    """The error of a ``what`` (a coordinate, a channel value) found at ``where`` in the
    clip of ``path`` beyond ``scaling.MAX_MAGNITUDE`` (see :func:`check_coordinates`)."""
    return FormatError(path, f"a {what} ({value:.6g}: {where}) is too large to process "
                             f"(more than {MAX_MAGNITUDE:g} in magnitude: a corrupt value)")


def label_matches(label: str, patterns: Sequence[str]) -> bool:
    """Whether a marker label matches any of the names or shell globs, with or without
    its Vicon ``Subject:`` prefix (``LKNE`` and ``L*`` select ``Male:LKNE``). A name is
    matched as written first: ``L[1]`` is that label, not the glob of ``L1``."""
    bare = label.rsplit(":", 1)[-1]
    return any(p in (label, bare) or fnmatch.fnmatchcase(label, p)
               or fnmatch.fnmatchcase(bare, p) for p in patterns)


def matches_nothing(motion: Motion, option: str, patterns: Sequence[str]) -> str:
    """The error for ``--markers`` or ``--exclude`` patterns that select no marker of the
    clip, naming its file (repair, plot)."""
    shown = ", ".join(motion.labels[:8]) + (", ..." if motion.n_markers > 8 else "")
    return (f"{named(motion.path)}{option} {' '.join(patterns)} matches no marker "
            f"(the clip has {shown})")


def unique_labels(names: Sequence[str]) -> list[str]:
    """``names`` with repeats renamed LASI, LASI_2, LASI_3 ..., skipping any name already
    in the list (readers and writers whose formats need unique marker names)."""
    seen: set[str] = set(names)
    unique: list[str] = []
    counts: dict[str, int] = {}
    for name in names:
        if name in counts:
            while True:
                counts[name] += 1
                candidate = f"{name}_{counts[name]}"
                if candidate not in seen:
                    break
            seen.add(candidate)
            unique.append(candidate)
        else:
            counts[name] = 1
            unique.append(name)
    return unique

