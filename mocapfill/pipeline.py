"""The repair pipeline (`mocapfill.repair` is its entry point): choose markers, normalise,
solve, restore observed, apply the gap policy, report.

Observed samples are sacred: whatever a solver returns, every sample observed in the input
comes back bit-identical, and only samples the policy allows are filled.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from functools import cache
from numbers import Real

import numpy as np

from ._blas import single_threaded
from ._memory import release_memory
from .errors import NothingToRepair, ParameterError, SolverError, named
from .gaps import Gap, find_gaps, gap_frames, missing_runs
from .motion import (
    Motion,
    check_coordinates,
    finite_samples,
    label_matches,
    matches_nothing,
    require_motion,
    too_large,
    whole_number,
)
from .scaling import UnitScale, outsized
from .solvers import get_method, option_parameters
from .solvers._threads import in_order, thread_count

ENDS = ("leave", "hold", "extrapolate")
SPACES = ("positions", "channels")

# Gap statuses as reported (one per gap).
FILLED = "filled"
LEFT_TOO_LONG = "left: too long"
LEFT_END = "left: end"
LEFT_WHOLE = "left: whole-clip missing"
LEFT_NOT_SELECTED = "left: not selected"
LEFT_NOT_MARKER = "left: not a marker"
REJECTED_JUMP = "rejected: jump"
LEFT_CHANNELS = "left: channels missing"
LEFT_CUT = "left: cut short"
LEFT_NO_WINDOW = "left: missing through a window"

# Default jump threshold: the larger of this floor (mm; MoCapTools rejects spline fills
# missing a linear forward prediction by > 40 mm) and JUMP_FACTOR times the marker's
# largest observed second difference (its own worst acceleration × dt²). Where a gap end
# has a single observed sample the prediction is to stand still, and the marker's largest
# observed frame-to-frame step is added (its own worst speed × dt).
JUMP_FLOOR_MM = 40.0
JUMP_FACTOR = 5.0


@dataclass(frozen=True)
class RepairOptions:
    """What to fill and how.

    Attributes
    ----------
    method
        Completion method name (see ``mocapfill.solvers.METHODS``).
    solver_options
        Keyword arguments for the method (rank, lam, mu, rho, eta0, tol, max_iter, ...).
        None for any of them is the method's default.
    max_gap_frames
        Gaps longer than this many frames (a whole number ≥ 0) are left missing; None
        fills every length.
    ends
        Gaps touching the first or last frame: "leave" them missing (default), "hold" the
        nearest observed value, or "extrapolate" with the method's fill clamped to the
        marker's observed range widened by ``END_MARGIN`` of that range on each side (and
        to what the source file can store: an integer C3D's int16 range).
    markers, exclude
        Names or shell globs (one pattern may be given as a string), matched with or
        without a label's ``Subject:`` prefix: only
        markers matching ``markers`` (all when empty) and not matching ``exclude`` are
        filled. Every marker still serves as evidence. ``markers``, or ``exclude``, that
        match no marker of the clip (their patterns together) is a ParameterError.
    max_jump_mm
        Jump check. At each end of a gap that has observed samples, the fill's first
        sample is compared with the constant-velocity prediction from the last two observed
        samples (the last sample itself where only one is observed there); a deviation
        above the threshold rejects the whole gap's fill (it stays missing, reported as
        "rejected: jump"). None = the larger of 40 mm and 5 × the marker's largest
        observed second difference, plus its largest observed frame-to-frame step where
        the prediction had only one sample; 0 or inf disables the check. In file units
        when the units are unknown. A channel-space repair is checked on the points its
        filled channels move (see :func:`repair_channels`).
    space
        ``"positions"`` (default): fill the marker (or joint) positions. ``"channels"``: a
        clip read from BVH or AMC filled in joint-channel space, the angles themselves
        (:func:`repair_channels`), as ``mocapfill repair`` does when OUT has the input's
        format: the only repair a BVH or AMC can be written back from (positions cannot
        be turned into joint angles; ``write`` refuses filled positions). A clip from
        another format is a ParameterError.
    """

    method: str = "trnn"
    solver_options: dict = field(default_factory=dict)
    max_gap_frames: int | None = None
    ends: str = "leave"
    markers: tuple[str, ...] = ()
    exclude: tuple[str, ...] = ()
    max_jump_mm: float | None = None
    space: str = "positions"

    def __post_init__(self) -> None:
        for name in ("markers", "exclude"):
            # One pattern given as a string, not its letters as patterns ("L*": L and *).
            if isinstance(getattr(self, name), str):
                object.__setattr__(self, name, (getattr(self, name),))
        if self.ends not in ENDS:
            raise ParameterError(f"ends must be one of {', '.join(ENDS)}, got {self.ends!r}")
        if self.max_gap_frames is not None:
            # A count, as --rank and --max-iter are: 2.5 acted as 2 (a gap's length in
            # frames is whole), nan and inf as no limit, a string as a TypeError.
            gap_frames = self.max_gap_frames
            if not whole_number(gap_frames):
                raise ParameterError(f"max gap must be a whole number of frames, got "
                                     f"{gap_frames!r}")
            if gap_frames < 0:
                raise ParameterError(f"max gap must be ≥ 0 frames, got {gap_frames}")
            object.__setattr__(self, "max_gap_frames", int(gap_frames))
        if self.max_jump_mm is not None and not self.max_jump_mm >= 0:
            raise ParameterError(f"max jump must be ≥ 0 mm, got {self.max_jump_mm}")
        if self.space not in SPACES:
            raise ParameterError(f"space must be one of {', '.join(SPACES)}, got {self.space!r}")
        # Fail early on an unknown method, or an option the method does not take (batches
        # would otherwise fail file after file). The rate is the clip's, which the repair
        # passes the method itself (given here too, it was a TypeError inside the repair).
        if self.solver_options.get("rate") is not None:     # (None: the default, as for all)
            raise ParameterError("rate is not a solver option: the repair gives the method "
                                 "the clip's own (mocapfill.read(path, rate=...) sets it)")
        object.__setattr__(self, "solver_options",
                           checked_solver_options(self.method, self.solver_options))


def checked_solver_options(method: str, options: dict) -> dict:
    """``options`` for ``method`` as the solver takes them, or a ParameterError for an
    unknown method, an option it does not take, a value not of the option's kind or out
    of its range (RepairOptions, complete_matrix)."""
    parameters = option_parameters(get_method(method))
    unknown = sorted(set(options) - set(parameters))
    if unknown:
        given = ", ".join(f"--{name.replace('_', '-')}" for name in unknown)
        raise ParameterError(f"{given} does not apply to method {method!r}")
    _check_kinds(options, parameters)
    check_solver_options(options)
    # None for any option is the method's default, as on the command line: a solver
    # that takes None for a value has None as its default (tau_factor=None was a
    # TypeError in the solver); a count given as a whole float (10.0: from JSON,
    # numpy) is that count (range(10.0) is a TypeError).
    return {name: int(value) if name in _COUNTS else value
            for name, value in options.items() if value is not None}


# The ranges of the options the command line offers (--rank ... --max-iter), whatever the
# method: checked for callers from Python as for the command line.
_COUNTS = ("rank", "max_iter")
_POSITIVE = ("lam", "eta0", "tol", "max_iter", "rank")


# The kinds of value a solver option may take, by the first type its annotation names
# ("float | None": a number) or else by its default's type.
_KINDS = {"int": "a number", "float": "a number", "bool": "True or False", "str": "a name"}


def _check_kinds(options: dict, parameters: dict) -> None:
    """A ParameterError for a solver option from Python whose value is not of its kind:
    a number (not a string, not True), a flag or a name; None passes (the default).
    Such values reached the solvers and ended in bare TypeErrors."""
    for name, value in options.items():
        if value is None:
            continue
        parameter = parameters[name]
        annotation = parameter.annotation
        if not isinstance(annotation, str):
            annotation = getattr(annotation, "__name__", "")
        kind = _KINDS.get(annotation.split("|")[0].strip())
        if kind is None and parameter.default is not None:
            kind = _KINDS.get(type(parameter.default).__name__)
        if kind is None:
            continue
        flag = isinstance(value, (bool, np.bool_))
        ok = {"a number": isinstance(value, Real) and not flag,
              "True or False": flag, "a name": isinstance(value, str)}[kind]
        if not ok:
            raise ParameterError(f"--{name.replace('_', '-')} must be {kind}, got {value!r}")


def check_solver_options(options: dict) -> None:
    """A ParameterError for an option that is not finite, or a value of rank, lam, mu,
    rho, eta0, tol or max_iter out of its range (the other options, and None, pass)."""
    def refuse(name: str, rule: str) -> None:
        raise ParameterError(f"--{name.replace('_', '-')} must be {rule}, got {options[name]}")

    for name, value in options.items():
        if isinstance(value, (int, float)) and not math.isfinite(value):
            refuse(name, "finite")

    for name in _COUNTS:
        value = options.get(name)
        if value is not None and not whole_number(value):
            refuse(name, "a whole number")
    for name in _POSITIVE:
        if options.get(name) is not None and not options[name] > 0:
            refuse(name, "> 0")
    if options.get("mu") is not None and not options["mu"] >= 0:
        refuse("mu", "≥ 0")
    if options.get("rho") is not None and not options["rho"] > 1:
        refuse("rho", "> 1")


END_MARGIN = 0.1


@dataclass(frozen=True)
class GapOutcome:
    """What happened to one gap."""

    gap: Gap
    status: str
    method: str


@dataclass(frozen=True)
class RepairResult:
    """The repaired clip and a record of every gap of the input."""

    motion: Motion
    gaps: list[GapOutcome]
    seconds: float

    @property
    def filled(self) -> int:
        return sum(o.status == FILLED for o in self.gaps)

    @property
    def left(self) -> int:
        return len(self.gaps) - self.filled


def frames_in_seconds(seconds: float, rate: float, path, given: str) -> float:
    """``seconds`` at the clip's ``rate`` as frames; a ParameterError naming ``path`` when
    the clip states no rate (an option in seconds, ``given`` as the user wrote it, would
    otherwise silently mean 0 frames)."""
    if not rate > 0:
        raise ParameterError(f"{named(path)}the file states no frame rate, so --max-gap "
                             f"{given} has no length in frames; give it in frames (40)")
    return seconds * rate


def whole_frames_within(frames: float) -> int:
    """The most whole frames that last no longer than ``frames`` (a --max-gap in seconds
    times the rate, finite and ≥ 0): a gap of one frame more is longer than the seconds
    given. Rounded to 1e-6 frame first, so that float error does not lose a frame (0.29 s
    at 100 Hz is 28.999999999999996 frames: 29). Rounding to the nearest frame filled a
    gap of 18 frames (0.072 s) at 250 Hz under --max-gap 0.07s (17.5 frames, taken as 18).
    """
    return math.floor(round(frames, 6))


def _selected(label: str, options: RepairOptions) -> bool:
    """Whether ``--markers`` / ``--exclude`` leave the marker ``label`` to be filled."""
    return not ((options.markers and not label_matches(label, options.markers))
                or label_matches(label, options.exclude))


def _gap_statuses(gaps: list[Gap], motion: Motion, options: RepairOptions) -> list[str]:
    """:func:`_gap_status` of each gap, each marker's selection worked out once (a clip
    with scattered loss has tens of thousands of gaps: 85_12 at mr = 0.6, 43,941)."""
    selected: dict[int, bool] = {}
    statuses = []
    for gap in gaps:
        if gap.marker not in selected:
            selected[gap.marker] = _selected(gap.label, options)
        statuses.append(_gap_status(gap, motion, options, selected[gap.marker]))
    return statuses


def _gap_status(gap: Gap, motion: Motion, options: RepairOptions,
                selected: bool | None = None) -> str:
    """What the repair does with ``gap``: FILLED or the reason it is left
    (``selected``: the marker's :func:`_selected`, worked out here when not given)."""
    if not motion.fillable[gap.marker]:
        return LEFT_NOT_MARKER
    if gap.whole_clip:
        return LEFT_WHOLE
    if not (_selected(gap.label, options) if selected is None else selected):
        return LEFT_NOT_SELECTED
    if options.max_gap_frames is not None and gap.length > options.max_gap_frames:
        return LEFT_TOO_LONG
    if (gap.at_start or gap.at_end) and options.ends == "leave":
        return LEFT_END
    return FILLED


# Long clips are solved in overlapping windows: time stays linear in the clip length and
# the solvers' working set (a dozen candidate fills and TrNN buffers per window) bounded.
# 12000 frames (100 s at 120 Hz) kept a 30-minute clip's peak memory under 1.5 GB.
WINDOW_FRAMES = 12000
WINDOW_OVERLAP = 2000
# A method that can lend its validation between windows (``fn.windowed``, the default
# ``trnn``) validates itself on one window in VALIDATE_EVERY (and on the last); the windows
# between borrow the evidence of the validated windows on either side, so their candidates
# run once instead of twice. Measured on a 44,046-frame real clip (CMU 85_12, 02_05, 85_02
# forward and reversed, cross-faded; 5 % of samples in 20–120-frame gaps; seeds 0, 1): every
# window validated 6.590 / 6.153 mm, one in two 6.593 / 6.144, one in three 6.579 / 6.146
# (the whole clip in one solve: 9.239 / 8.846), seed 1 in 81, 72 and 65 s.
VALIDATE_EVERY = 3

# Windows are solved side by side where there are cores to spare (their candidate fills
# share one queue of threads, so one window's serial steps and the end of its batch of
# fills overlap another's fills), up to WINDOWS_MEMORY bytes of windows in progress at
# once, counting WINDOW_BYTES_PER_CELL bytes per cell of a window (its candidates' fills
# and solver buffers). Measured on 2 cores: a 120-marker, 30,000-frame synthetic clip
# (three windows) peaked at 0.43 GB with ``--method linear``, 0.85 GB with the default one
# job at a time, 1.05 GB two jobs at a time and 1.42 GB with two windows side by side:
# 115–145 bytes per cell and window. The bench's 30-minute clip (41 markers) peaked at
# 0.91–0.95 GB before and 0.98 GB after, its repair 60–69 s (median 67) → 55–60 s
# (median 57), alternated, with the same output.
WINDOW_BYTES_PER_CELL = 120
WINDOWS_MEMORY = 1 << 30


def windows_at_once(rows: int, window_frames: int) -> int:
    """How many windows of ``rows`` × ``window_frames`` may be solved side by side."""
    return max(1, WINDOWS_MEMORY // max(1, rows * window_frames * WINDOW_BYTES_PER_CELL))


def _solve_scaled(matrix: np.ndarray, observed: np.ndarray, method: str,
                  solver_options: dict, borrowed: list | None = None, *,
                  fill_ends: bool = True, clip_ends: tuple[bool, bool] = (True, True)):
    """The method's fill of ``matrix`` in the unit scale, back in the clip's units.

    With ``borrowed`` (a list, possibly empty) the method's ``windowed`` form is called
    with those validations and (fill, validation) is returned. ``clip_ends``: which ends
    of ``matrix`` are the clip's (a window of a long clip holds one or neither). Where
    the end fills are used (``fill_ends``) and the method validates them
    (``validates_ends``), only the gaps touching those get stand-ins, and a window that
    holds one is solved as a whole clip is (every candidate run, not the windows'
    lighter form, whose candidates run only where weighted): its end gaps are then
    validated, not given one candidate's fill.
    """
    scale = UnitScale.fit(matrix, observed)
    scaled = scale.forward(np.where(observed, matrix, 0.0))
    fn = get_method(method)
    if getattr(fn, "takes_centre", False):
        # Where each row's zero lies in the unit scale: distances between markers and
        # rigid bodies are true ones only with it (the row-wise centring moves each
        # marker by its own mean position). The default's rigid candidate and
        # rigid-partner check, and the PCA method's distance weights, add it back.
        solver_options = {**solver_options, "centre": scale.centre[:, 0] / scale.scale}
    light = True
    if getattr(fn, "validates_ends", False):
        sides = clip_ends if fill_ends else (False, False)
        if sides != (True, True):       # (the method's default: both ends validated)
            solver_options = {**solver_options,
                              "validate_ends": sides if any(sides) else False}
        light = not any(sides)
    validation = None
    try:
        if borrowed is not None:
            solved, validation = fn.windowed(scaled, observed, borrowed=borrowed,
                                             skip_unweighted=light, **solver_options)
        else:
            solved = fn(scaled, observed, **solver_options)
    except (np.linalg.LinAlgError, FloatingPointError) as exc:
        # A numerical breakdown (found by fuzzing: coordinates near the float32 limit in a
        # corrupt C3D made an SVD fail) is a clean failure of this clip, not a traceback.
        given = ", ".join(f"--{k.replace('_', '-')} {v:g}" for k, v in solver_options.items()
                          if isinstance(v, (int, float)) and k != "rate")
        suspects = (f"the options given ({given}) or " if given else "") + \
            "the file's coordinates (corrupt or absurd values)"
        raise SolverError(f"method {method!r} broke down numerically on this clip ({exc}); "
                          f"check {suspects}") from None
    solved = scale.inverse(solved)
    # Checked here, so that the only non-finite fills after a long clip's windows are
    # assembled are the samples no window could fill (complete_matrix).
    if not np.isfinite(solved).all(where=~observed):
        raise SolverError(f"method {method!r} returned non-finite values")
    return solved if borrowed is None else (solved, validation)


def window_bounds(n_frames: int, window: int, overlap: int,
                  observed: np.ndarray | None = None) -> list[tuple[int, int]]:
    """[start, stop) of overlapping windows covering ``n_frames``; the last one is full.

    Windows start ``window − overlap`` frames apart. With ``observed`` (rows × frames), a
    window starts earlier where a gap runs out of the window before it, so that one window
    holds that gap whole with GAP_CONTEXT frames before it where it can
    (:func:`_start_holding`): a gap no window holds whole is extrapolated from each side.
    """
    if n_frames <= window:
        return [(0, n_frames)]
    step = window - overlap
    starts = [0]
    while True:
        start = starts[-1]
        following = start + step
        if observed is not None:
            following = min(following, _start_holding(observed, start, window))
        if following >= n_frames - window:
            break
        starts.append(following)
    starts.append(n_frames - window)
    return [(a, a + window) for a in starts]


# Frames of observed samples that a window started early for a gap keeps before the gap.
GAP_CONTEXT = 500


def _start_holding(observed: np.ndarray, start: int, window: int) -> int:
    """The latest start of a window that holds whole (with an observed sample on either
    side) each gap that runs out of the window [start, start + window), keeping up to
    GAP_CONTEXT frames before it, and at least half a window after ``start`` where that
    holds the gap; the clip's length where no gap needs one (gaps longer than a window, or
    reaching an end of the clip or of this window, are held by none).

    Only a gap that begins in the window's first half and is over half a window long
    needs an earlier start. Refused before, such a gap (7,000 frames in 12,000-frame
    windows) was held by no window, and each side's extrapolation, cross-faded, filled it
    with two held values 1 m off (an audit's case, thirty-fourth session). Each window
    started that early holds the gap that made it start so: there are no more such
    windows than such gaps."""
    n = observed.shape[1]
    last = start + window - 1
    half = start + window // 2
    best = n
    for row in np.flatnonzero(~observed[:, last]).tolist():
        before = observed[row, start:last]
        after = observed[row, last + 1:last + window]
        if not before.any() or not after.any():
            continue
        gap_start = last - int(before[::-1].argmax())           # its first missing frame
        gap_stop = last + 1 + int(after.argmax())               # its first observed frame after
        lowest = gap_stop - window + 1                  # the earliest start holding its end
        if lowest > gap_start - 1:                      # longer than a window
            continue
        floor = max(lowest, half) if max(lowest, half) <= gap_start - 1 else lowest
        best = min(best, max(floor, gap_start - 1 - GAP_CONTEXT))
    return best


# Called as progress(windows done, windows in all) after each window of a long clip (the
# command line's progress bar; see :func:`reporting_windows`).
_WINDOW_PROGRESS: ContextVar[Callable[[int, int], None] | None] = ContextVar(
    "mocapfill_window_progress", default=None)


@contextmanager
def reporting_windows(progress: Callable[[int, int], None]):
    """Within the block, long clips report ``progress(done, total)`` after each window."""
    token = _WINDOW_PROGRESS.set(progress)
    try:
        yield
    finally:
        _WINDOW_PROGRESS.reset(token)


def _window_fills(matrix: np.ndarray, observed: np.ndarray, bounds: list[tuple[int, int]],
                  method: str, solver_options: dict, fill_ends: bool = True):
    """Each window's fill, window after window.

    For a method with a ``windowed`` form the windows 0, VALIDATE_EVERY, 2·VALIDATE_EVERY,
    … and the last validate themselves, and each window between borrows the validations
    of the nearest validated windows on both sides; the validated window after it is
    solved first and its fill held (one window's array) until its turn.

    Where the machine has the cores and the windows are small (:func:`windows_at_once`),
    several windows are solved side by side (:func:`~mocapfill.solvers._threads.in_order`),
    their candidate fills in one queue for the cores.
    """
    def solve(k: int, borrowed: list | None = None):
        start, stop = bounds[k]
        return _solve_scaled(matrix[:, start:stop], observed[:, start:stop], method,
                             solver_options, borrowed, fill_ends=fill_ends,
                             clip_ends=(start == 0, stop == matrix.shape[1]))

    lends = getattr(get_method(method), "windowed", None) is not None and len(bounds) >= 3
    needs: dict[int, tuple[int, ...]] = {}
    if lends:
        validated = sorted(set(range(0, len(bounds), VALIDATE_EVERY)) | {len(bounds) - 1})
        needs = {k: (max(j for j in validated if j < k), min(j for j in validated if j > k))
                 for k in range(len(bounds)) if k not in validated}
    threads = thread_count()
    at_once = min(threads, windows_at_once(matrix.shape[0], bounds[0][1] - bounds[0][0]))
    if at_once > 1:
        def job(k: int, lent: dict):
            if not lends:
                return solve(k), None
            fill, validation = solve(k, [lent[j] for j in needs.get(k, ())])
            return fill, (validation if k not in needs else None)

        yield from in_order(len(bounds), needs, job, at_once=at_once,
                            ahead=2 * VALIDATE_EVERY + at_once, threads=threads, apart=True)
        return
    if not lends:
        for k in range(len(bounds)):
            yield solve(k)
        return
    held: dict[int, np.ndarray] = {}
    validations: dict[int, object] = {}
    for k in range(len(bounds)):
        if k in held:
            yield held.pop(k)
            continue
        if k not in needs:
            fill, validations[k] = solve(k, [])
            yield fill
            continue
        before, after = needs[k]
        if after not in validations:
            held[after], validations[after] = solve(after, [])
        fill, _ = solve(k, [validations[before], validations[after]])
        yield fill


# Weight of a window's fill of a gap that runs into the window's edge inside the clip
# (an extrapolation from one side), against 1 for a gap the window holds whole: where a
# neighbouring window holds the gap whole, its fill decides.
EDGE_GAP_WEIGHT = 1e-3


def _window_trust(observed: np.ndarray, at_start: bool, at_end: bool) -> np.ndarray:
    """(rows, frames) weight of one window's fill: 1, EDGE_GAP_WEIGHT on the missing runs
    that touch an edge of the window which is not the clip's (``at_start``/``at_end``:
    the window begins or ends the clip), and 0 on every frame of a row the window never
    observes (it knows nothing of that marker: its fill there was the scale's centre)."""
    trust = np.ones(observed.shape)
    seen = observed.any(axis=1)
    trust[~seen] = 0.0
    rows = np.flatnonzero(seen)
    # Row by row, in place: no window-sized temporaries (a 300-marker window is 86 MB).
    if not at_start:
        for row, first in zip(rows.tolist(), observed[rows].argmax(axis=1).tolist()):
            trust[row, :first] = EDGE_GAP_WEIGHT
    if not at_end:
        for row, last in zip(rows.tolist(), observed[rows, ::-1].argmax(axis=1).tolist()):
            if last:
                trust[row, -last:] = EDGE_GAP_WEIGHT
    return trust


def complete_matrix(matrix: np.ndarray, observed: np.ndarray, method: str = "trnn", *,
                    window_frames: int = WINDOW_FRAMES, window_overlap: int = WINDOW_OVERLAP,
                    overwrite: bool = False, fill_ends: bool = True,
                    **solver_options) -> np.ndarray:
    """Complete a (3·markers × frames) matrix in the unit-invariant scale.

    Clips longer than ``window_frames`` are solved in windows overlapping by
    ``window_overlap`` frames, blended with linear cross-fades, so memory stays bounded and
    time linear in the clip length (0 disables windowing); a window starts early where that
    lets it hold whole a gap that runs out of the window before (:func:`window_bounds`).
    Row by row, a window that never
    observes a row gives no fill for it, and a gap running into a window's inner edge gets
    little weight from that window (:func:`_window_trust`); a missing sample no window can
    fill (a marker missing through a whole window and the overlaps around it) stays NaN.
    Observed entries of the result equal ``matrix`` exactly. With ``overwrite`` the fills
    are written into ``matrix`` itself (its missing entries), which is returned: no second
    clip-sized array. ``solver_options`` are the method's, refused (ParameterError) as
    :class:`RepairOptions` refuses them: unknown to the method, or out of range. Gaps at the
    clip's ends are filled either way; ``fill_ends`` False says their fills will not be
    used (``repair`` without ``--ends extrapolate``), so that a method that validates its
    end-gap fills (the default, whose end stand-ins hide data it would otherwise use for
    the interior gaps) does not.
    """
    if "centre" in solver_options:
        raise ParameterError("'centre' is not an option: the rows' centres are the unit "
                             "scale's, set here")
    # Checked as RepairOptions checks them: a misspelt option (rnak=3) gave the default's
    # fill, a negative tol or lam was taken. ``rate`` is the clip's, which the repair
    # hands every method (those with no use for it take it in ``**options``), not one of
    # the method's own.
    own = {name: value for name, value in solver_options.items() if name != "rate"}
    solver_options = {**{name: value for name, value in solver_options.items()
                         if name == "rate"}, **checked_solver_options(method, own)}
    n = matrix.shape[1]
    out = matrix if overwrite else np.array(matrix, dtype=np.float64)
    if not window_frames or n <= window_frames:
        np.copyto(out, _solve_scaled(matrix, observed, method, solver_options, fill_ends=fill_ends),
                  where=~observed)
        return out
    if not 0 < window_overlap < window_frames // 2:
        raise ParameterError("window overlap must be positive and under half the window")
    ramp = np.linspace(0.0, 1.0, window_overlap + 2)[1:-1]
    bounds = window_bounds(n, window_frames, window_overlap, observed)
    # Each window's weighted fill plus what earlier windows left pending on its first
    # frames; the frames before the next window's start are then final and written out
    # (a window only reads frames no earlier window has written). The sums are those of
    # accumulating every window into one clip-sized array, in the same order.
    rows = matrix.shape[0]
    pending, pending_weight = np.zeros((rows, 0)), np.zeros((rows, 0))
    progress = _WINDOW_PROGRESS.get()
    if progress is not None:
        progress(0, len(bounds))
    fills = _window_fills(matrix, observed, bounds, method, solver_options, fill_ends)
    for index, ((start, stop), fill) in enumerate(zip(bounds, fills)):
        w = np.ones(stop - start)
        if start > 0:
            w[:window_overlap] = ramp
        if stop < n:
            w[-window_overlap:] = ramp[::-1]
        weight = _window_trust(observed[:, start:stop], start == 0, stop == n)
        weight *= w
        total = weight * fill
        del fill
        carried = pending.shape[1]
        total[:, :carried] += pending
        weight[:, :carried] += pending_weight
        final = (bounds[index + 1][0] if index + 1 < len(bounds) else stop) - start
        done = total[:, :final]
        np.divide(done, weight[:, :final], out=done, where=weight[:, :final] > 0)
        done[weight[:, :final] == 0] = np.nan        # no window could fill these
        np.copyto(out[:, start:start + final], done,
                  where=~observed[:, start:start + final])
        pending, pending_weight = total[:, final:].copy(), weight[:, final:].copy()
        del total
        release_memory()            # the window's freed arrays, back to the system
        if progress is not None:
            progress(index + 1, len(bounds))
    return out


def _complete_clip(motion: Motion, matrix: np.ndarray, observed: np.ndarray,
                   options: RepairOptions, rows: str = "3 × markers with data") -> np.ndarray:
    """:func:`complete_matrix` with the options; a solver failure names the clip's file.

    ``rows`` says what the matrix's rows are, for the message refusing a --rank above them.
    """
    rank = options.solver_options.get("rank")
    limit = min(matrix.shape[0], matrix.shape[1], WINDOW_FRAMES)   # rows, frames per solve
    if rank is not None and rank > limit:
        raise ParameterError(f"{named(motion.path)}--rank {rank} is larger than this clip allows "
                             f"({limit}: the smaller of {rows} and frames)")
    try:
        return complete_matrix(matrix, observed, options.method, rate=motion.rate,
                               overwrite=True, fill_ends=options.ends == "extrapolate",
                               **options.solver_options)
    except SolverError as exc:
        raise SolverError(f"{named(motion.path)}{exc}") from None


def _fill_ends(values: np.ndarray, observed: np.ndarray, gap: Gap, ends: str) -> None:
    """Rewrite an end gap of one marker (frames × 3, in place) for the end policy (what
    the source file can store is kept to after, for every fill: :func:`repair`)."""
    seen = values[observed]
    if ends == "hold":
        anchor = values[gap.stop] if gap.at_start else values[gap.start - 1]
        values[gap.start:gap.stop] = anchor
    else:  # extrapolate: keep the method's fill, never beyond the observed range + margin
        low, high = seen.min(axis=0), seen.max(axis=0)
        margin = END_MARGIN * (high - low)
        np.clip(values[gap.start:gap.stop], low - margin, high + margin,
                out=values[gap.start:gap.stop])


def _jump_thresholds(values: np.ndarray, observed: np.ndarray, markers: list[int],
                     options: RepairOptions, mm_per_unit: float
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Largest allowed boundary deviation for each of ``markers``, in file units: from a
    constant-velocity prediction (two observed samples beside the gap) and from a
    standing-still one (a single observed sample beside it).

    Without the second, fills of fast markers were rejected wherever random loss left a
    single sample beside a gap: on 85_12 with 20 % of the samples removed (seed 0), 90 of
    28,870 gaps, all correct to within 0.64 mm (median 0.03), for steps of 43–57 mm.

    ``values`` (frames, all markers, 3) and ``observed`` (frames, all markers), read by
    blocks of consecutive frames (each block's rows contiguous in memory; by columns of a
    few markers over the whole clip, a 216,000-frame clip of 41 markers took 0.9–1.0 s).
    """
    count = len(markers)
    if options.max_jump_mm is not None:
        limit = options.max_jump_mm / mm_per_unit if options.max_jump_mm > 0 else np.inf
        return np.full(count, limit), np.full(count, limit)
    worst_step, worst_accel = np.zeros(count), np.zeros(count)
    n = values.shape[0]
    chosen = np.asarray(markers, dtype=np.int64)
    every = np.array_equal(chosen, np.arange(values.shape[1]))
    block = max(16, _THRESHOLD_VALUES // max(1, 3 * count))
    for lo in range(0, n, block):
        # Frames lo−2 … hi−1: the steps ending at frames ≥ max(lo, 1) and the second
        # differences ending at frames ≥ max(lo, 2), each computed once over the clip.
        first, hi = max(lo - 2, 0), min(lo + block, n)
        v = values[first:hi] if every else values[first:hi, chosen]
        seen = observed[first:hi] if every else observed[first:hi, chosen]
        # Differences over consecutive observed frames only (norms as np.linalg.norm's:
        # x² + y² + z² summed in that order), in place.
        a = max(lo, 1) - first
        step = np.subtract(v[a:], v[a - 1:-1])
        step *= step
        norms = np.sqrt(step[..., 0] + step[..., 1] + step[..., 2])
        np.maximum(worst_step, np.max(norms, axis=0, initial=0.0,
                                      where=seen[a:] & seen[a - 1:-1]), out=worst_step)
        c = max(lo, 2) - first
        if c >= len(v):
            continue
        accel = np.multiply(v[c - 1:-1], 2)
        np.subtract(v[c:], accel, out=accel)
        accel += v[c - 2:-2]
        accel *= accel
        norms = np.sqrt(accel[..., 0] + accel[..., 1] + accel[..., 2])
        np.maximum(worst_accel, np.max(norms, axis=0, initial=0.0,
                                       where=seen[c:] & seen[c - 1:-1] & seen[c - 2:-2]),
                   out=worst_accel)
    floor = JUMP_FLOOR_MM / mm_per_unit
    unseen = ~observed[:, markers].any(axis=0)
    moving = np.where(unseen, np.inf, np.maximum(floor, JUMP_FACTOR * worst_accel))
    still = np.where(unseen, np.inf,
                     np.maximum(floor, worst_step + JUMP_FACTOR * worst_accel))
    return moving, still


# Values (frames × markers × 3) per block of the jump thresholds' differences: 8 MB per
# temporary (8,525 frames of 41 markers).
_THRESHOLD_VALUES = 1 << 20


def _boundary_jumps(positions: np.ndarray, observed: np.ndarray, gaps: list[Gap]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Worst deviation of each gap's fill from the prediction at its ends, for all gaps
    at once: (at ends with two observed samples, at ends with one), 0 where there is none.

    ``positions`` (frames, markers, 3) holds the fills. With two observed samples beside
    the gap the prediction is the last one plus the step between them (constant
    velocity); with one, the sample itself.
    """
    worst = np.zeros((2, len(gaps)))
    if not gaps:
        return worst[0], worst[1]
    n = positions.shape[0]
    marker = np.array([g.marker for g in gaps])
    start = np.array([g.start for g in gaps])
    stop = np.array([g.stop for g in gaps])
    for edge, inside, step in ((start - 1, start, -1), (stop, stop - 1, 1)):
        valid = (edge >= 0) & (edge < n)
        valid[valid] = observed[edge[valid], marker[valid]]
        e, i, k = edge[valid], inside[valid], marker[valid]
        before = e + step
        has_before = (before >= 0) & (before < n)
        has_before[has_before] = observed[before[has_before], k[has_before]]
        before = np.where(has_before, before, e)
        velocity = np.where(has_before[:, None],
                            positions[e, k] - positions[before, k], 0.0)
        deviation = np.linalg.norm(positions[i, k] - (positions[e, k] + velocity), axis=1)
        which = np.flatnonzero(valid)
        for kind, chosen in ((0, has_before), (1, ~has_before)):
            rows = which[chosen]
            worst[kind, rows] = np.maximum(worst[kind, rows], deviation[chosen])
    return worst[0], worst[1]


def _jumping(positions: np.ndarray, motion: Motion, gaps: list[Gap],
             options: RepairOptions) -> list[bool]:
    """For each filled gap, whether its fill jumps at an end (see ``RepairOptions``):
    ``positions`` (frames, markers, 3) hold the fills, ``motion`` the input they join."""
    from .metrics import mm_per_unit

    unit_mm = mm_per_unit(motion.units) or 1.0
    moving, still = _boundary_jumps(positions, motion.observed, gaps)
    markers = sorted({gap.marker for gap in gaps})
    limits = dict(zip(markers, zip(*_jump_thresholds(motion.positions, motion.observed,
                                                     markers, options, unit_mm))))
    return [bool(jump_moving > limits[gap.marker][0] or jump_still > limits[gap.marker][1])
            for gap, jump_moving, jump_still in zip(gaps, moving, still)]


@single_threaded()
def repair(motion: Motion, options: RepairOptions | None = None) -> RepairResult:
    """Fill the gaps of a clip (BLAS on one thread meanwhile, see :mod:`mocapfill._blas`).

    Parameters
    ----------
    motion
        The clip; its observed samples are never changed.
    options
        Method, solver settings and gap policy.

    Returns
    -------
    RepairResult
        The repaired Motion (same source handle, so writers can patch the input file) and
        one outcome per gap of the input.

    Raises
    ------
    TypeError
        ``motion`` is not a Motion (a file name: read it first with ``mocapfill.read``),
        or ``options`` not a RepairOptions.
    FormatError
        Naming the clip's file: a coordinate of a marker (or, in channel space, a channel
        value) too large to process (``motion.check_coordinates``).
    """
    require_motion(motion, "repair")
    if options is not None and not isinstance(options, RepairOptions):
        raise TypeError(f"repair() takes a RepairOptions as options, got "
                        f"{type(options).__name__} (RepairOptions(method=...) sets the method)")
    options = options or RepairOptions()
    if motion.n_frames < 2:     # in either space: nothing to interpolate or fit from
        raise NothingToRepair(f"{named(motion.path)}a clip of {motion.n_frames} frame(s) cannot be "
                              "repaired")
    if options.markers and not any(label_matches(label, options.markers)
                                   for label in motion.labels):
        # A typo would otherwise end in "0 gaps filled, N left (N not selected)".
        raise ParameterError(matches_nothing(motion, "--markers", options.markers))
    if options.exclude and not any(label_matches(label, options.exclude)
                                   for label in motion.labels):
        # A typo (--exclude LKNEE for LKNE) would fill the marker meant to stay open. The
        # patterns together, as for --markers: a batch of several subjects may exclude
        # 'Male:*' and 'Female:*', each file matching one of them.
        raise ParameterError(matches_nothing(motion, "--exclude", options.exclude))
    # In either space: the jump check squares the positions' steps.
    check_coordinates(motion, motion.fillable)
    if options.space == "channels":
        return repair_channels(motion, options)
    started = time.perf_counter()
    if not (motion.observed[:, motion.fillable]).any():
        raise NothingToRepair(f"{named(motion.path)}no marker has a single observed sample; "
                              "nothing to fill from")
    gaps = find_gaps(motion)
    outcomes = [GapOutcome(g, status, options.method)
                for g, status in zip(gaps, _gap_statuses(gaps, motion, options))]
    if not any(o.status == FILLED for o in outcomes):
        return RepairResult(motion, outcomes, time.perf_counter() - started)

    evidence = np.flatnonzero(motion.fillable & motion.observed.any(axis=0))
    matrix, observed = motion.matrix(evidence)
    solved = _complete_clip(motion, matrix, observed, options)
    del matrix                      # long clips: free each full-size copy once it is used
    # The solved markers' rows back into (frames, markers, 3), the others as read, without
    # building and checking a Motion (two passes over the clip fewer).
    filled = motion.positions_from_matrix(solved, evidence)
    del solved, observed

    # ``filled`` becomes the result: accepted fills stay, everything else is put back from
    # the input below (no extra full-size copy of the clip).
    positions = filled
    accepted = np.zeros(motion.observed.shape, dtype=bool)
    new_observed = motion.observed.copy()
    to_check = [index for index, o in enumerate(outcomes) if o.status == FILLED]
    for index in to_check:
        gap = outcomes[index].gap
        if gap.at_start or gap.at_end:
            _fill_ends(filled[:, gap.marker, :], motion.observed[:, gap.marker], gap,
                       options.ends)
    storable = getattr(motion.source, "value_range", None)
    if storable is not None:
        # Every fill within what the source file can store (an integer C3D's int16 words
        # at its scale), as a measured sample is: a marker seen near the limit gave fills
        # past it, and the patch writer refused the whole clip (an end fill of 2646 beside
        # a limit of 2637.6 in btk-sample04__sub_labels.c3d with --ends extrapolate; 3283
        # mm beside 3276.7 inside a gap). (NaN stays NaN; observed samples are put back
        # from the input below.)
        np.clip(filled, storable[0], storable[1], out=filled,
                where=~motion.observed[:, :, None])
    # A long clip's windows leave NaN where none of them observes the marker (missing
    # through a whole window and the overlaps around it): such a gap is left, whole.
    unfilled = ~finite_samples(filled) & ~motion.observed
    if unfilled.any():
        for index in to_check:
            gap = outcomes[index].gap
            if unfilled[gap.start:gap.stop, gap.marker].any():
                outcomes[index] = GapOutcome(gap, LEFT_NO_WINDOW, options.method)
        to_check = [index for index in to_check if outcomes[index].status == FILLED]
    jumping = _jumping(filled, motion, [outcomes[i].gap for i in to_check], options)
    kept = []
    for index, jumps in zip(to_check, jumping):
        if jumps:
            outcomes[index] = GapOutcome(outcomes[index].gap, REJECTED_JUMP, options.method)
        else:
            kept.append(outcomes[index].gap)
    # Every accepted gap's samples at once (scattered loss: tens of thousands of gaps,
    # a slice assignment each took 0.1 s).
    if kept:
        marker, start, stop = np.array([(g.marker, g.start, g.stop) for g in kept]).T
        run, frames = gap_frames(start, stop)
        accepted[frames, marker[run]] = True
        new_observed |= accepted
    # Sacred: observed samples come from the input, bit for bit; samples not filled keep
    # the input's values too.
    np.copyto(positions, motion.positions, where=~accepted[:, :, None])
    # Every observed sample finite, checked without gathering them (a 216,000-frame clip:
    # 0.86 s for the gather, 0.1 s this way).
    if (new_observed & ~finite_samples(positions)).any():
        raise SolverError(f"{named(motion.path)}method {options.method!r} returned non-finite "
                          "values")
    return RepairResult(motion.with_positions(positions, new_observed), outcomes,
                        time.perf_counter() - started)


def _fill_channel_ends(column: np.ndarray, observed: np.ndarray, start: int, stop: int,
                       ends: str) -> None:
    """End-gap policy for one channel column (in place), like :func:`_fill_ends`."""
    if ends == "hold":
        column[start:stop] = column[stop] if start == 0 else column[start - 1]
    else:
        seen = column[observed]
        margin = END_MARGIN * (seen.max() - seen.min())
        np.clip(column[start:stop], seen.min() - margin, seen.max() + margin,
                out=column[start:stop])


def repair_channels(motion: Motion, options: RepairOptions) -> RepairResult:
    """Fill a skeleton clip (BVH, AMC) in channel space: the joint angles themselves.

    Positions cannot be turned back into joint angles without inverse kinematics (twist is
    unobservable), so a repair written back into a BVH/AMC completes the channel matrix,
    rotation channels unwrapped along time, and re-wraps only the filled cells. Each
    channel's runs of missing frames follow the gap policy of the joint that owns the
    channel. The returned outcomes describe the position gaps of the input: a gap is
    filled when every channel that moves the point was filled. The jump check runs on
    those points' positions: a point whose fill jumps has the fills of every channel
    moving it put back over its gap, and every gap that loses fills so is "rejected: jump".
    A gap some of whose channels were left missing is "left: channels missing", or "left:
    cut short" where the format kept a fill out (an AMC's value the file may have been cut
    short inside: ``acclaim.with_channels``), so the counts say what the output holds.
    No gap is left partly filled: where the runs filled would fill only part of a point's
    gap (one the policy leaves, or with a channel left missing), the fills of every channel
    moving the point are put back over that gap, as for a jump.
    """
    from . import formats
    from .skeleton import Skeleton, moving_channels

    started = time.perf_counter()
    rejected: set[tuple[int, int]] = set()
    module = formats.format_module(motion.path) if motion.path is not None else None
    if module is None or not hasattr(module, "channels"):
        raise ParameterError("channel-space repair needs a clip read from a BVH or AMC file")
    values, observed = module.channels(motion)
    if observed.size and not observed.any():
        # As in position space: no value to fill from is a failure, not an unchanged copy.
        raise NothingToRepair(f"{named(motion.path)}no joint channel has a single observed "
                              "value; nothing to fill from")
    skeleton: Skeleton = motion.source.state.skeleton
    owner = np.full(values.shape[1], -1)
    for joint, columns in enumerate(skeleton.rotation_columns):
        owner[list(columns)] = joint
    for joint, columns in enumerate(skeleton.translation_columns):
        owner[list(columns)] = joint
    # The channels are what the method solves for (an angle is a value like any other).
    found = outsized(values)
    if found is not None:
        value, frame, column = found
        raise too_large(motion.path, "channel value", value,
                        f"joint {motion.labels[owner[column]]}, frame {motion.first_frame + frame}")

    fill = np.zeros_like(observed)
    for column in range(values.shape[1]):
        for start, stop in missing_runs(observed[:, column]):
            gap = Gap(int(owner[column]), motion.labels[owner[column]], start, stop,
                      motion.n_frames)
            if _gap_status(gap, motion, options) == FILLED:
                fill[start:stop, column] = True
    before = find_gaps(motion)
    # moves(j): the channels that move joint j, found once for each joint with a gap
    moves = cache(lambda joint: moving_channels(skeleton, joint))
    refused = np.zeros_like(fill)       # fills the format kept out (with_channels)
    windowless = np.zeros_like(fill)    # runs no window of a long clip could fill
    if fill.any():
        rows = values.shape[1]
        pad = (-rows) % 3  # methods read rows in x/y/z triples; constant rows carry nothing
        matrix = np.vstack([values.T, np.zeros((pad, values.shape[0]))])
        mask = np.vstack([observed.T, np.ones((pad, values.shape[0]), bool)])
        # A channel-space matrix's rows are channels, not 3 × markers: say so if --rank
        # is refused (the padding rows count towards the limit, so name them too).
        described = f"the {rows} channels" + (f" (padded to {rows + pad})" if pad else "")
        solved = _complete_clip(motion, matrix, mask, options, described)[:rows].T
        for column in np.flatnonzero(fill.any(axis=0)):
            for start, stop in missing_runs(observed[:, column]):
                if fill[start, column] and (start == 0 or stop == values.shape[0]):
                    _fill_channel_ends(solved[:, column], observed[:, column], start, stop,
                                       options.ends)
        # A long clip's windows leave NaN where none observes the channel: its run is left.
        for column in np.flatnonzero((fill & ~np.isfinite(solved)).any(axis=0)):
            for start, stop in missing_runs(observed[:, column]):
                if not np.isfinite(solved[start:stop, column]).all():
                    fill[start:stop, column] = False
                    windowless[start:stop, column] = True
        repaired = module.with_channels(motion, np.where(fill, solved, values),
                                        observed | fill)
        # The jump check, on the points the filled channels move: a point whose fill
        # jumps has the fills of every channel moving it put back over its gap (points
        # sharing those channels lose those frames' fills too).
        done = [g for g in before if repaired.observed[g.start:g.stop, g.marker].all()]
        jumping = [g for g, jumps in zip(done, _jumping(repaired.positions, motion, done,
                                                        options)) if jumps]
        if jumping:
            for gap in jumping:
                fill[gap.start:gap.stop, moves(gap.marker)] = False
            repaired = module.with_channels(motion, np.where(fill, solved, values),
                                            observed | fill)
            rejected = {(g.marker, g.start) for g in done
                        if not repaired.observed[g.start:g.stop, g.marker].all()}
        refused = fill & ~repaired.source.state.observed
        # A gap reported left holds no fill. Channel runs follow the policy one by one,
        # so a point's gap the policy leaves could be filled in part: an end gap with a
        # run that starts inside it, a clip-long gap made of several channels' runs, a
        # gap longer than --max-gap made of shorter runs. Such a gap (or one a rejected
        # neighbour cut into) gets the fills of every channel moving its point put back,
        # until no gap is partly filled (points sharing those channels lose them too).
        while partial := [g for g in before
                          if repaired.observed[g.start:g.stop, g.marker].any()
                          and not repaired.observed[g.start:g.stop, g.marker].all()]:
            for gap in partial:
                fill[gap.start:gap.stop, moves(gap.marker)] = False
            repaired = module.with_channels(motion, np.where(fill, solved, values),
                                            observed | fill)
    else:
        repaired = motion
    outcomes = []
    for gap in before:
        done = repaired.observed[gap.start:gap.stop, gap.marker].all()
        status = FILLED if done else _gap_status(gap, motion, options)
        if status == FILLED and not done:
            status = (REJECTED_JUMP if (gap.marker, gap.start) in rejected
                      else LEFT_CUT if refused[gap.start:gap.stop, moves(gap.marker)].any()
                      else LEFT_NO_WINDOW
                      if windowless[gap.start:gap.stop, moves(gap.marker)].any()
                      else LEFT_CHANNELS)
        outcomes.append(GapOutcome(gap, status, options.method))
    return RepairResult(repaired, outcomes, time.perf_counter() - started)
