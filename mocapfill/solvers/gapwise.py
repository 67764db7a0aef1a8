"""Per-gap blending of gap fillers, with weights learned from the clip itself.

No single completion method wins on every gap (``shared/docs/MODEL.md``, "What we
measured"): a cubic spline along time is very hard to beat on gaps of a few frames, the
low-rank TrNN fill carries long gaps on repetitive motion, and fills driven by the
markers that stay visible during the gap (a local regression, a rigid-body fit on the
most rigidly attached markers) win on long gaps in non-repetitive motion. This module
blends such candidate fills gap by gap, with weights chosen by *validation on the clip*:

1. **Pseudo-gaps.** For a sample of the clip's own interior gaps, hide an observed
   stretch of the same marker with the same length, near the real gap and not touching
   any other pseudo-gap (at most ``validation_fraction`` of the observed samples are
   hidden); on dense loss, where such stretches are rare, a stretch between observed
   frames that takes in real missing frames, scored on the frames it hides.
2. **Score.** Run every candidate on the clip with the pseudo-gaps hidden and compare
   with the hidden truth.
3. **Weights.** For every class of gap length (1, 2, 3–4, 5–8, …, doubling) fit convex
   weights w ≥ 0, Σw = 1 that minimise the squared error of the blend on that class's
   pseudo-gaps (an exact quadratic programme over the simplex,
   :func:`~mocapfill.solvers._linalg.simplex_least_squares`), kept where cross-validation
   shows they beat the best single candidate; this choice is averaged over bootstrap
   resamples of the pseudo-gaps (bagging).
4. **Fill.** Run every candidate on the real mask (or, for the costliest, TrNN, take the
   fill of its validation run: see :func:`blend`'s ``once``) and blend each real gap with
   the weights of its length class, leaving out on each gap of ``MIN_MODEL_GAP`` frames
   or more any candidate whose fill there is an outlier among the candidates' fills.

Every candidate joins the observed samples continuously at both ends of every gap
(interpolants by construction; model fills by adding the linear ramp between their
offsets from the observed samples just before and just after the gap), so the blend does
too.

A candidate is ``fn(matrix, observed) -> completed`` on the unit-RMS matrix; gaps are
runs of missing frames of one *group* of rows (the three coordinates of a marker, or a
single row when the mask is not organised in whole markers).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property, partial

import numpy as np

from ..gaps import gap_frames, missing_runs
from ._linalg import (
    distance_rows,
    linear_fill,
    nearest_markers,
    pair_distances,
    simplex_least_squares,
)
from ._threads import run_all

Candidate = Callable[[np.ndarray, np.ndarray], np.ndarray]

# Gaps shorter than this use only the cheap candidates (spline and the global fill): the
# per-gap models need a stretch of motion to be worth their per-gap cost.
MIN_MODEL_GAP = 5
# A real gap with at least this many stand-ins is weighted on its own evidence.
MIN_OWN_STANDINS = 6


@dataclass(frozen=True)
class GapSet:
    """Interior gaps of a clip as (group, start, stop) with stop exclusive."""

    groups: np.ndarray          # (g, k) row indices of each group (k = 3 for markers)
    gaps: list[tuple[int, int, int]]

    @cached_property
    def spans(self) -> np.ndarray:
        """The gaps as one (gaps, 3) array of (group, start, stop), made once for every
        step of the blend that reads them all (random loss: tens of thousands)."""
        return np.array(self.gaps, dtype=np.int64).reshape(-1, 3)

    @cached_property
    def lengths(self) -> np.ndarray:
        """(gaps,) the length of each gap in frames."""
        return self.spans[:, 2] - self.spans[:, 1]


def row_groups(observed: np.ndarray) -> np.ndarray:
    """Rows grouped as markers (3 rows with one mask) when the mask allows, else singly."""
    m = observed.shape[0]
    if m % 3 == 0 and (observed[0::3] == observed[1::3]).all() and \
            (observed[0::3] == observed[2::3]).all():
        return np.arange(m).reshape(-1, 3)
    return np.arange(m).reshape(-1, 1)


def interior_gaps(observed: np.ndarray, groups: np.ndarray) -> list[tuple[int, int, int]]:
    """Gaps with an observed sample on both sides (end gaps are not filled by default)."""
    n = observed.shape[1]
    return [(g, a, b) for g, rows in enumerate(groups)
            for a, b in missing_runs(observed[rows[0]]) if a > 0 and b < n]


def length_class(length: int) -> int:
    """0 for 1 frame, 1 for 2, 2 for 3–4, 3 for 5–8, … (⌈log₂ length⌉, in integers)."""
    return (max(int(length), 1) - 1).bit_length()


def length_classes(lengths: np.ndarray) -> np.ndarray:
    """:func:`length_class` of every length at once (the exponent of frexp is the bit
    length, exactly, for integers below 2⁵³)."""
    return np.frexp(np.maximum(lengths, 1) - 1)[1].astype(np.int64)


def ramp(values_before: np.ndarray, values_after: np.ndarray, length: int) -> np.ndarray:
    """(k, length) linear ramp from the offset just before a gap to the one just after."""
    s = np.arange(1, length + 1) / (length + 1)
    return np.outer(values_before, 1 - s) + np.outer(values_after, s)


def join_ends(fill: np.ndarray, matrix: np.ndarray, observed: np.ndarray,
              gapset: GapSet) -> np.ndarray:
    """Add to every interior gap the ramp that makes ``fill`` meet the observed samples.

    ``fill`` is a full-matrix estimate whose values on the observed samples next to a gap
    may differ from the data (a low-rank fit); the corrected fill equals the data at the
    samples just outside the gap, with the offset interpolated linearly in between
    (:func:`ramp`, here for all gaps at once: random loss gives tens of thousands).
    """
    out = np.where(observed, matrix, fill)
    if not gapset.gaps:
        return out
    g, a, b = gapset.spans.T
    rows = gapset.groups[g]                                          # (gaps, k)
    before = matrix[rows, (a - 1)[:, None]] - fill[rows, (a - 1)[:, None]]
    after = matrix[rows, b[:, None]] - fill[rows, b[:, None]]
    run, frames = gap_frames(a, b)
    s = (frames - a[run] + 1) / (b - a + 1)[run]
    for column in range(rows.shape[1]):
        r = rows[run, column]
        out[r, frames] = fill[r, frames] + (before[run, column] * (1 - s)
                                            + after[run, column] * s)
    return out


def held_short_runs(observed: np.ndarray, groups: np.ndarray, min_gap: int, *,
                    ends: bool = True) -> np.ndarray:
    """The mask with every missing run shorter than ``min_gap`` frames counted as observed
    (with ``ends=False`` only interior runs, those with an observed sample on both sides).

    One pass over the whole mask (random occlusion gives tens of thousands of runs).
    """
    k, n = groups.shape[0], observed.shape[1]
    edges = np.zeros((k, n + 2), dtype=np.int8)
    edges[:, 1:-1] = ~observed[groups[:, 0]]
    step = np.diff(edges, axis=1)                       # +1 where a run starts, −1 after it
    group, start = np.nonzero(step == 1)
    stop = np.nonzero(step == -1)[1]                    # same row-major order as the starts
    short = stop - start < min_gap
    if not ends:
        short &= (start > 0) & (stop < n)
    marks = np.zeros((k, n + 1), dtype=np.int32)
    np.add.at(marks, (group[short], start[short]), 1)
    np.add.at(marks, (group[short], stop[short]), -1)
    hold = np.cumsum(marks[:, :n], axis=1) > 0          # (groups, frames)
    held = observed.copy()
    for column in range(groups.shape[1]):
        held[groups[:, column]] |= hold
    return held


class ShortRunsFirst:
    """Candidates run with the short gaps filled first, as the long gaps' evidence.

    Calling an instance on a candidate wraps it: every interior missing run under
    ``min_gap`` frames is filled by the cubic spline and counted as observed; the
    candidate then sees only the longer gaps, and the short ones keep the spline's values
    (the Gaussian candidate treats short runs so itself). Flicker (markers lost for a
    frame or two, all through a clip) otherwise takes away what the per-gap models need
    over a long gap: a donor or predictor marker seen in every frame of it, complete
    frames for PCA. The candidates wrapped by one instance share the spline fill of each
    (matrix, mask) they are called on (0.04–0.05 s of a 1,100–3,700-frame real clip,
    three candidates, two passes).
    """

    def __init__(self, min_gap: int = MIN_MODEL_GAP) -> None:
        self.min_gap = min_gap
        self._last: tuple | None = None      # (matrix, observed, held, short, first)

    def prepared(self, matrix: np.ndarray, observed: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The mask with the short runs held, those runs, and the matrix with them filled
        (None where there is none); made once for the same two arrays in a row."""
        last = self._last           # one read: another thread may replace it meanwhile
        if last is not None and last[0] is matrix and last[1] is observed:
            return last[2:]
        from .interp import spline

        held = held_short_runs(observed, row_groups(observed), self.min_gap, ends=False)
        short = held & ~observed
        first = np.where(short, spline(matrix, observed), matrix) if short.any() else None
        self._last = (matrix, observed, held, short, first)
        return held, short, first

    def __call__(self, fill: Candidate) -> Candidate:
        def run(matrix: np.ndarray, observed: np.ndarray, **options) -> np.ndarray | None:
            held, short, first = self.prepared(matrix, observed)
            if first is None:
                return fill(matrix, observed, **options)
            out = fill(first, held, **options)
            return None if out is None else np.where(short, first, out)

        # (a candidate given its options by functools.partial is still the function)
        run.fills_gaps_alone = getattr(fill, "func", fill) in FILLS_GAPS_ALONE
        run.__wrapped__ = fill
        return run


# --------------------------------------------------------------------------- candidates

def odd_spline_fill(matrix: np.ndarray, observed: np.ndarray, *, degree: int = 5
                    ) -> np.ndarray:
    """Interpolating spline of odd ``degree`` along time through each row's samples.

    Degree 5 or 7 (:func:`mocapfill.solvers._splines.odd_spline`, the interpolant of
    ``scipy.interpolate.make_interp_spline``) is far more accurate than a
    cubic on smooth 120 Hz motion and far worse on noisy or abrupt motion; validation
    decides. End gaps are held (as the cubic spline does).

    Near the clip's ends a high-degree interpolant has too little data on one side and
    swings: a gap with fewer than (degree + 1)/2 observed samples before or after it in its
    row takes the cubic spline instead (so does a row with too few samples for the degree;
    under 4 samples, linear interpolation). Measured on 85_12 at mr = 0.2 (seed 0): one
    2-frame gap at frames 1–2 held 98 % of the quintic's squared error over all 2-frame
    gaps (squared error 1.0e−2 against the cubic's 1.3e−4); stand-ins almost never fall
    there, so the blend had trusted the quintic for that length class.
    """
    from ._splines import odd_spline
    from .interp import _interpolate, cubic_interpolant, local

    support = (degree + 1) // 2

    def make(t_obs: np.ndarray, y_obs: np.ndarray):
        if t_obs.size <= degree:             # every gap lacks support: the cubic's row
            return cubic_interpolant(t_obs, y_obs)
        high = odd_spline(t_obs, y_obs, degree)
        # Frames with fewer than ``support`` samples before them (t < t_obs[support − 1])
        # or after them (t > t_obs[−support]) take the cubic.
        first, last = t_obs[support - 1], t_obs[-support]

        def evaluate(t: np.ndarray) -> np.ndarray:
            values = high(t)
            edge = (t < first) | (t > last)
            if edge.any():
                values[edge] = cubic_interpolant(t_obs, y_obs)(t[edge])
            return values
        return evaluate

    return _interpolate(matrix, observed, local(make))


def _xyz(matrix: np.ndarray) -> np.ndarray:
    """(n, markers, 3) view of a 3·markers × n matrix."""
    return matrix.reshape(-1, 3, matrix.shape[1]).transpose(2, 0, 1)


def _kabsch(reference: np.ndarray, frames: np.ndarray, weights: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """Rigid motions taking each ``reference[l]`` (L, k, 3) onto ``frames[l]`` (L, k, 3):
    the least-squares fits over the k points, weighted by ``weights`` (L, k; rows summing
    to 1). Returns R (L, 3, 3) and t (L, 3)."""
    pc = np.einsum("lk,lka->la", weights, reference)
    qc = np.einsum("lk,lkb->lb", weights, frames)
    H = np.einsum("lk,lka,lkb->lab", weights, reference - pc[:, None], frames - qc[:, None])
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, 1, 2)
    sign = np.sign(np.linalg.det(V @ np.swapaxes(U, 1, 2)))
    V[:, :, 2] *= sign[:, None]
    R = V @ np.swapaxes(U, 1, 2)
    return R, qc - np.einsum("lab,lb->la", R, pc)


# Donor candidates of :func:`rigid_fill` per gapped marker, on clips with more markers
# than this and one: the nearest ones (RMS distance), as for the regression's predictors.
# Every clip of the accuracy tables (41 markers at most) measures every pair as before.
RIGID_CANDIDATES = 40


def distance_spread(P: np.ndarray, seen: np.ndarray, *, rows: Sequence[int] | None = None,
                    candidates: int = RIGID_CANDIDATES) -> np.ndarray:
    """(markers, markers) standard deviation over time of the distance between markers.

    Small for markers on the same rigid segment; ∞ on the diagonal and for pairs that
    share fewer than 10 observed frames. Only the rows ``rows`` (default: all) are
    measured, the others ∞ (the gapped markers': on 85_12 with ten of 41 markers gapped,
    410 pairs instead of 861). With more than ``candidates`` + 1 markers, each row only to
    its ``candidates`` nearest markers (:func:`~mocapfill.solvers._linalg.nearest_markers`),
    the rest ∞: every pair of 300 markers over 10,000 frames took 8.5–12.5 s of each rigid
    fill.
    """
    k = P.shape[1]
    rows = range(k) if rows is None else rows
    spread = np.full((k, k), np.inf)
    if k - 1 <= candidates:
        measured = distance_rows(P, seen, [(j, slice(None)) for j in rows], True)
        for j, (count, _, std) in zip(rows, measured):
            spread[j] = np.where(count >= 10, std, np.inf)
            spread[j, j] = np.inf
        return spread
    near = nearest_markers(P, seen, candidates)
    measured = distance_rows(P, seen, [(j, near[j]) for j in rows], True)
    for j, (count, _, std) in zip(rows, measured):
        spread[j, near[j]] = np.where(count >= 10, std, np.inf)
    return spread


def rigid_fill(matrix: np.ndarray, observed: np.ndarray, *, donors: int = 3,
               min_gap: int = MIN_MODEL_GAP, only: frozenset | None = None,
               centre: np.ndarray | None = None, weighted: bool = False,
               ends: bool | tuple[bool, bool] = True) -> np.ndarray | None:
    """Rigid-body fill: move the marker with its most rigidly attached visible markers.

    For a gap [a, b) of marker j, the ``donors`` markers observed on [a−1, b] whose
    distance to j varies least (at least three of them) are taken as one rigid body; the
    rigid motion (Kabsch) from their positions at frame a−1 to those at every gap frame
    carries j's position at a−1 into the gap, likewise from frame b, and the two are
    blended linearly so the fill meets both ends exactly. Interior gaps shorter than
    ``min_gap`` and gaps without three donors get a linear fill (held at an end).

    With ``ends``, a gap at the clip's start or end (filled where ``--ends extrapolate``
    asks), of any length, is carried from its one seen side alone, with donors seen there
    and all through it. It held the last sample before, as the splines do, and a moving
    limb ran off it. Measured (``scripts/end_gaps.py sums``, thirty-seventh session;
    summed end-gap errors in mm, session start → end gaps of 5 frames or more → every end
    gap): 5 markers hidden over a clip's first or last 10–240 frames and random loss,
    seeds 1–2 77.7 → 61.3 → 45.6, held-out seeds 6–8 110.2 → 87.5 → 76.6; the paper's
    random loss alone (12 cells, seeds 1–3) 94.5 → 91.7 → 50.0, most of it from 1–4-frame
    end gaps, where a held sample lags the marker by the frames it missed. Without
    ``ends`` (where the end fills are not used) end gaps are held: the windows of a long
    clip fill their inner edges' gaps from their most weighted candidate, and those fills
    are blended into the clip's interior. ``ends`` may name one end, as a (start, end)
    pair (:func:`end_sides`): a window holding one of the clip's ends carries the gaps
    there and holds those at its inner edge.

    None when the rows are not markers. With ``only`` (a set of (marker, start, stop)),
    other gaps keep the linear fill (:data:`FILLS_GAPS_ALONE`).

    ``weighted``: each donor counts in the fit in inverse proportion to the variance of
    its distance to j (``1 / spread²``: the weighted least squares of donors whose
    departures from one rigid body are independent, of those sizes), so that more donors
    can be taken without the looser ones bending the motion. The default's blend runs
    both forms (:func:`mocapfill.solvers.trnn.complete`): three donors, and six weighted.

    ``centre`` (rows,): where each row's zero lies in true coordinates, for a matrix whose
    rows were centred one by one (the pipeline's unit scale). Centring each coordinate
    on its own mean moves every marker by its own mean position and bends the rigid
    bodies, so the donors are chosen and the rigid motion fitted on ``matrix + centre``.
    Measured (the default's blend, ``bench accuracy``): CMU mean 3.605 → 3.174 mm (85_02
    ml = 60 23.49 → 16.20, 85_12 ml = 40 6.74 → 5.28), walkl 1.9904 → 1.9887 mm.
    """
    groups = row_groups(observed)
    if groups.shape[1] != 3:
        return None
    out = linear_fill(matrix, observed)
    gaps = [(j, a, b) for j, a, b in interior_gaps(observed, groups) if b - a >= min_gap]
    gaps += end_gaps(observed, groups, ends)
    spans = np.array([gap for gap in gaps if only is None or gap in only],
                     dtype=np.int64).reshape(-1, 3)
    if not spans.size:
        return out
    P, shift, _, chosen, spread = _rigid_donors(matrix, observed, spans, donors, centre)
    for part, gap, frames, fill in _rigid_motions(P, spans, chosen,
                                                  spread if weighted else None):
        rows = 3 * spans[part][gap, 0][:, None] + np.arange(3)
        out[rows, frames[:, None]] = fill - shift[rows]
    return out


def _rigid_donors(matrix: np.ndarray, observed: np.ndarray, spans: np.ndarray, donors: int,
                  centre: np.ndarray | None):
    """What :func:`rigid_fill` moves the gaps ``spans`` (gaps, 3) with: the true positions
    P (n, markers, 3; NaN where unseen), the rows' ``shift`` (centre), the clip's
    :func:`_seen_before`, and each gap's donors (gaps, donors; −1 past the last) with
    their distance spreads to the gapped marker (gaps, donors)."""
    shift = np.zeros(len(matrix)) if centre is None else np.asarray(centre, dtype=np.float64)
    P = _xyz(np.where(observed, matrix + shift[:, None], np.nan))
    j, a, b = spans.T
    spread_all = distance_spread(P, observed[0::3].T, rows=np.unique(j).tolist())
    before = _seen_before(observed)
    # Seen on [a − 1, b], the gap and the frames beside it (only the one seen at an end).
    lo, hi = np.maximum(a - 1, 0), np.minimum(b + 1, P.shape[0])
    usable = (before[:, hi] - before[:, lo] == hi - lo).T
    spread = np.where(usable, spread_all[j], np.inf)                 # (gaps, markers)
    reference = np.where(a > 0, a - 1, b)
    chosen = _distinct_donors_of_gaps(                               # (gaps, donors)
        spread, donors, lambda g, columns: P[reference[g, None], columns])
    return P, shift, before, chosen, np.take_along_axis(spread, np.maximum(chosen, 0), axis=1)


def _rigid_motions(P: np.ndarray, spans: np.ndarray, chosen: np.ndarray,
                   spread: np.ndarray | None):
    """(indices of the gaps, then :func:`_rigid_batch` of them) of :func:`rigid_fill` for
    the gaps with three donors or more, batch by batch: the gaps with the same number of donors in
    batches of at most _RIGID_BATCH gap frames, each one stack of 3 × 3 Kabsch problems,
    two per frame."""
    count = (chosen >= 0).sum(axis=1)
    lengths = spans[:, 2] - spans[:, 1]
    for size in range(3, chosen.shape[1] + 1):
        which = np.flatnonzero(count == size)
        if not which.size:
            continue
        ends = np.cumsum(lengths[which])
        cuts = np.searchsorted(ends, np.arange(_RIGID_BATCH, ends[-1], _RIGID_BATCH))
        for part in np.split(which, np.unique(cuts)):
            if part.size:
                yield (part, *_rigid_batch(P, spans[part], chosen[part, :size],
                                           None if spread is None else spread[part, :size]))


# Gap frames per batch of :func:`rigid_fill` (its arrays: about 0.5 KB per frame).
_RIGID_BATCH = 1 << 15


def _rigid_batch(P: np.ndarray, spans: np.ndarray, chosen: np.ndarray,
                 spread: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`rigid_fill` of the gaps ``spans`` (gaps, 3), each moved with its donors
    ``chosen`` (gaps, d), weighted by 1 / spread² where ``spread`` (gaps, d) is given:
    every gap frame's gap (an index into ``spans``) and frame, in gap order
    (:func:`~mocapfill.gaps.gap_frames`), and its fill (frames, 3) in true positions."""
    j, a, b = spans.T
    gap, frames = gap_frames(a, b)
    s = ((frames - a[gap] + 1) / (b - a + 1)[gap])[:, None]
    # An end gap is carried from its one seen side alone.
    s = np.where((a == 0)[gap, None], 1.0, np.where((b == len(P))[gap, None], 0.0, s))
    if spread is None:
        weights = np.full(chosen.shape, 1.0 / chosen.shape[1])
    else:                       # (a donor at exactly constant distance: a small floor)
        variance = spread ** 2
        weights = 1.0 / (variance + 1e-6 * np.maximum(variance.max(axis=1, keepdims=True),
                                                      1e-300))
        weights /= weights.sum(axis=1, keepdims=True)
    donors, w = chosen[gap], weights[gap]                            # (frames, d)
    moved = P[frames[:, None], donors]                               # (frames, d, 3)
    fill = np.zeros((gap.size, 3))
    for ref, weight in ((a - 1, 1 - s), (b, s)):
        side = weight[:, 0] > 0
        if not side.any():
            continue
        R, t = _kabsch(P[ref[gap[side]][:, None], donors[side]], moved[side], w[side])
        fill[side] += weight[side] * (np.einsum("lab,lb->la", R,
                                                P[ref[gap[side]], j[gap[side]]]) + t)
    return gap, frames, fill


# Windows beside a gap on which :func:`rigid_local_errors` tries the gap's rigid body: at
# offsets 0 and 1 (in window lengths plus a frame) before and after it.
LOCAL_WINDOWS = 2
# The most by which the rigid fills' weight on a long gap is multiplied or divided, as their
# error tried beside the gap compares with that on the stand-ins (:func:`_locally_checked`).
# Their weight comes from stand-ins of their length class, placed among all the clip's
# markers; a real gap often loses its rigid neighbours with it (one occlusion), and the
# fill then moves the marker with looser ones. Tried beside the gap with the gap's own
# donors, the error follows the fill's error on the gap: Spearman 0.90 on the 1,476
# hidden gaps with three donors of ``scripts/replay_gaps.py``. Measured (thirty-third
# session, docs/results.md), the replay's catastrophic fills and mean error over its 1,557
# gaps, and the sum of the CMU ml = 20/40/60 cells (3 seeds): without 10, 3.924 mm,
# 59.75 mm; factor t/e within [1/2, 2]: 7, 3.888, 58.95; within [1/4, 4]: 8, 3.898,
# 58.58; (t/e)² within [1/4, 4]: 6, 3.968 (worse on 9 of 18 clips); cutting only (t/e
# capped at 1), squared: 7, 4.020. The walking set stayed at 1.9827 mm.
LOCAL_CLIP = 2.0
# Errors below this (RMS per sample, in the blend's unit-RMS scale: 1e−6 of the data's
# spread) are rounding: added to both errors the check compares, it leaves their ratio
# near 1 where both are that small (a rigid body of exact data), and no lower.
LOCAL_RESOLUTION = 1e-6


def rigid_local_errors(matrix: np.ndarray, observed: np.ndarray, spans: np.ndarray, *,
                       donors: int = 3, weighted: bool = False,
                       centre: np.ndarray | None = None) -> np.ndarray:
    """(gaps,) RMS error per coordinate of :func:`rigid_fill` beside each gap of ``spans``
    (gaps, 3): the gap's own donors (those seen all through it) carry the marker over
    windows of the gap's length where all of them and the marker are seen, up to
    LOCAL_WINDOWS on each side of the gap (a frame apart from it and from each other), and
    the fill is compared with the marker's samples there. NaN for a gap with no such
    window or fewer than three donors. The rigid fill's error on the gap itself follows
    it closely, because the donors are the gap's: where the neighbours occluded with the
    marker were its rigid ones, the loose ones left carry it badly beside the gap too.
    """
    n = matrix.shape[1]
    P, _, before, chosen, spread = _rigid_donors(matrix, observed, spans, donors, centre)
    j, a, b = spans.T
    length = b - a
    starts = [a - (length + 1) * (i + 1) for i in range(LOCAL_WINDOWS)] + \
        [b + 1 + (length + 1) * i for i in range(LOCAL_WINDOWS)]
    sums, counts = np.zeros(len(spans)), np.zeros(len(spans))
    # The marker and its donors (−1: the marker again), all seen on [start − 1, start + L].
    markers = np.column_stack([j, np.where(chosen >= 0, chosen, j[:, None])])
    for start in starts:
        ok = (start >= 1) & (start + length + 1 <= n) & ((chosen >= 0).sum(axis=1) >= 3)
        lo, hi = np.clip(start - 1, 0, n), np.clip(start + length + 1, 0, n)
        seen = before[markers, hi[:, None]] - before[markers, lo[:, None]]
        which = np.flatnonzero(ok & (seen == (hi - lo)[:, None]).all(axis=1))
        if not which.size:
            continue
        windows = np.stack([j[which], start[which], start[which] + length[which]], axis=1)
        for part, gap, frames, fill in _rigid_motions(P, windows, chosen[which],
                                                      spread[which] if weighted else None):
            error = ((fill - P[frames, windows[part][gap, 0]]) ** 2).sum(axis=1)
            np.add.at(sums, which[part][gap], error)
            np.add.at(counts, which[part][gap], 3.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(sums / counts)


def _distinct_donors_of_gaps(spread: np.ndarray, count: int,
                             at: Callable[[np.ndarray, np.ndarray], np.ndarray]
                             ) -> np.ndarray:
    """(gaps, count) :func:`_distinct_donors` of every gap at once, −1 past the last: of
    gap g, the columns in order of ``spread[g]`` (gaps, columns), distinct in their
    positions ``at(gs, columns)`` ((len(gs), c, 3) for the gaps gs and their columns
    (len(gs), c)) at the frame before the gap. Where the first ``count`` finite ones hold
    no copy of each other (all but files with a trajectory under several labels), they
    are the answer; the other gaps are taken one by one."""
    gaps = np.arange(len(spread))
    order = np.argsort(spread, axis=1, kind="stable")[:, :count]
    finite = np.isfinite(np.take_along_axis(spread, order, axis=1))
    where = at(gaps, order)                                          # (gaps, c, 3)
    apart = np.abs(where[:, :, None] - where[:, None]).max(axis=3)   # (gaps, c, c)
    tolerance = 1e-12 * (1.0 + np.abs(where).max(axis=2))            # of the later one
    earlier = np.triu(np.ones((order.shape[1],) * 2, dtype=bool), 1)
    copies = ((apart <= tolerance[:, None, :]) & earlier
              & finite[:, :, None] & finite[:, None, :])
    chosen = np.full((len(spread), count), -1, dtype=np.int64)
    chosen[:, :order.shape[1]] = np.where(finite, order, -1)
    columns = np.arange(spread.shape[1])[None]
    for g in np.flatnonzero(copies.any(axis=(1, 2))).tolist():
        taken = _distinct_donors(at(gaps[g:g + 1], columns)[0],
                                 np.argsort(spread[g], kind="stable"), spread[g], count)
        chosen[g] = -1
        chosen[g, :taken.size] = taken
    return chosen


def _distinct_donors(at: np.ndarray, order: np.ndarray, spread: np.ndarray, count: int
                     ) -> np.ndarray:
    """The first ``count`` markers of ``order`` with a finite ``spread``, passing over any
    whose position ``at`` (markers, 3; one frame) is that of a marker already taken.

    Some files hold one trajectory under several labels (a Qualisys file with each marker
    also as ``NAME_2`` and ``NAME_3``: c3d.org's Sample26 Walking_Hybrid_2). Their
    distances to the gapped marker vary alike, so the copies come out as its most rigid
    donors together; copies of one point leave the rotation of the rigid body undefined,
    and its fill was then whatever rounding made of it.
    """
    taken: list[int] = []
    for d in order.tolist():
        if len(taken) == count or not np.isfinite(spread[d]):
            break
        if taken and (np.abs(at[taken] - at[d]).max(axis=1)
                      <= 1e-12 * (1.0 + np.abs(at[d]).max())).any():
            continue
        taken.append(d)
    return np.array(taken, dtype=int)


def _nearest_frames(a: int, b: int, n: int, count: int) -> np.ndarray:
    """The ``count`` frames outside [a, b) nearest it, in order: as many on each side as
    the other side allows, the earlier frame first among equally near ones (one-sided
    near the clip ends). The same frames as sorting all n − (b − a) of them by distance
    (which cost a sort of the clip's frames for every gap)."""
    half = (count + 1) // 2                     # the left side's share (it wins ties)
    before, after = a, n - b                                 # frames available each side
    if before >= half and after >= count - half:
        left = half
    elif before < half:
        left = before
    else:
        left = min(before, count - after)
    right = min(after, count - left)
    return np.r_[a - left:a, b:b + right]


# Predictors (marker groups) of :func:`regression_fill` per gap: the nearest ones. Clips of
# up to 41 markers (the CMU and walking clips of the accuracy tables) keep them all. With
# every visible marker as a predictor, clips with many markers fitted hundreds of
# coefficients on at most 800 frames. Measured with the default method on clips of virtual
# markers rigidly attached to CMU markers (20–80 mm offsets, 0.2 mm noise; 5 % of samples
# in 20–120-frame gaps), all predictors → the nearest 40: 100 markers on 85_12 15.18 →
# 15.07 mm, 300 on 85_12 11.70 → 11.28 mm (39.6 → 36.4 s), 200 on 02_05 8.72 → 6.68 mm.
REGRESSION_PREDICTORS = 40


def regression_fill(matrix: np.ndarray, observed: np.ndarray, *, window: int = 400,
                    ridge: float = 1e-3, min_gap: int = MIN_MODEL_GAP,
                    max_predictors: int = REGRESSION_PREDICTORS,
                    only: frozenset | None = None) -> np.ndarray:
    """Local ridge regression on the groups that stay visible during each gap.

    For a gap [a, b) of group g, the predictors are the other groups observed on [a−1, b],
    at most ``max_predictors`` of them where the groups are markers (three rows): those
    nearest to g at a−1 and b (the sum of the two distances; see
    :data:`REGRESSION_PREDICTORS`). Rows grouped singly (a channel matrix of angles,
    where nearness means nothing) keep every predictor. The training frames are those
    within ``window`` frames of the gap where g and all predictors are observed. The
    prediction is corrected by the ramp of its offsets at a−1 and b. Shorter gaps
    (< ``min_gap``) and gaps with fewer than 10 training frames get a linear fill; with
    ``only`` (a set of (group, start, stop)), so do the gaps not in it
    (:data:`FILLS_GAPS_ALONE`).
    """
    groups = row_groups(observed)
    gaps = interior_gaps(observed, groups)
    out = linear_fill(matrix, observed)
    seen = observed[groups[:, 0]]                                    # (groups, n)
    n = matrix.shape[1]
    for g, a, b in gaps:
        if b - a < min_gap or (only is not None and (g, a, b) not in only):
            continue
        predictors = np.flatnonzero(seen[:, a - 1:b + 1].all(axis=1))
        predictors = predictors[predictors != g]
        if predictors.size == 0:
            continue
        if predictors.size > max_predictors and groups.shape[1] == 3:
            ends = matrix[:, [a - 1, b]]                             # (rows, 2)
            apart = np.linalg.norm(ends[groups[predictors]] - ends[groups[g]], axis=1)
            nearest = np.argsort(apart.sum(axis=1), kind="stable")[:max_predictors]
            predictors = np.sort(predictors[nearest])
        frames = _nearest_frames(a, b, n, 2 * window)
        frames = frames[seen[g, frames] & seen[np.ix_(predictors, frames)].all(axis=0)]
        if frames.size < 10:
            continue
        rows_x = groups[predictors].ravel()
        rows_y = groups[g]
        A = matrix[np.ix_(rows_x, frames)].T
        y = matrix[np.ix_(rows_y, frames)].T
        a_mean, y_mean = A.mean(axis=0), y.mean(axis=0)
        A0 = A - a_mean
        gram = A0.T @ A0
        gram.flat[::gram.shape[0] + 1] += ridge * frames.size
        coef = np.linalg.solve(gram, A0.T @ (y - y_mean))
        span = np.arange(a - 1, b + 1)
        pred = ((matrix[np.ix_(rows_x, span)].T - a_mean) @ coef + y_mean).T   # (k, L+2)
        before = matrix[rows_y, a - 1] - pred[:, 0]
        after = matrix[rows_y, b] - pred[:, -1]
        out[np.ix_(rows_y, np.arange(a, b))] = pred[:, 1:-1] + ramp(before, after, b - a)
    return out


# Candidates whose fill of a gap depends on the observed samples alone, never on other
# gaps' fills: they take ``only=`` (the gaps wanted), and a validation run, which is scored
# on the stand-ins alone, asks them for those (the real gaps were a third of the per-gap
# work of a 12,000-frame window's validation run).
FILLS_GAPS_ALONE = (rigid_fill, regression_fill)


# --------------------------------------------------------------------------- validation

def pseudo_gaps(observed: np.ndarray, gapset: GapSet, rng: np.random.Generator, *,
                fraction: float = 0.1, repeats: int = 10, repeats_long: int = 2,
                tries: int = 8
                ) -> list[tuple[tuple[int, int, int], int]]:
    """Observed stretches to hide, up to ``repeats`` per real gap (``repeats_long`` for gaps
    of ``MIN_MODEL_GAP`` frames or more): same group, same length.

    A stretch [s, s+L) of group g is accepted when g is observed on [s−1, s+L] (so it is
    an interior gap of exactly length L) and it keeps one observed frame between itself
    and every other pseudo-gap. Other real gaps may lie close by, as they do around the
    real gap: a stand-in placed only in clean stretches would flatter the interpolants,
    which degrade where knots are sparse. It is sought near the real gap first (within
    4L + 8 frames), then anywhere. At most ``fraction`` of the observed samples are hidden.
    Long gaps get few stand-ins: many long stand-ins at once make the validation clip far
    harder than the real one (on WalkL_0003, 10 per gap put TrNN's validation error at
    17.7 mm against 2.1 mm on the real gaps, and reversed its ranking against PCA; 2 per
    gap gave 2.7 mm and the right ranking).

    When ``tries`` placements find no such stretch, ``tries`` more accept a stretch
    [s, s+L) that takes in real missing frames, as long as g is observed at s−1 and s+L
    and at least one frame inside is observed: in the validation clip it is one gap of
    length L, like the real gap, and only the frames it hid are scored (and count against
    the budget). On dense random loss (60 % of frames) a run of 7 observed frames is rare,
    so without these the 5–8 and 9–16 frame classes had 2 and 0 stand-ins among 725 and
    95 real gaps (10_01, mr = 0.6) and borrowed the weights of the 3–4 frame class, which
    favour the local fills; with them, 10_01 mr = 0.6 went from 1.31 to 1.16 mm (seeds
    0–2; tsmc 1.20).
    Returns ((group, start, stop), index of the real gap it stands in for) pairs.
    """
    n = observed.shape[1]
    seen = observed[gapset.groups[:, 0]]
    budget = fraction * seen.sum()
    # The placement loop reads single samples and short stretches tens of thousands of
    # times on random loss (85_12 at mr = 0.6: 57,000 tries), where a numpy call on a
    # slice cost more than the work. So the mask of each group with a gap (stand-ins lie
    # in the real gap's group) is read as Python lists, with the count of observed
    # samples before each frame (what a stretch hides), and the frames taken as one
    # bytearray per group, searched without a copy.
    gapped = sorted({g for g, _, _ in gapset.gaps})
    observed_before = np.zeros((len(gapped), n + 1), dtype=np.int64)
    np.cumsum(seen[gapped], axis=1, out=observed_before[:, 1:])
    observed_before = dict(zip(gapped, observed_before.tolist()))
    seen_rows = dict(zip(gapped, seen[gapped].tolist()))
    taken = {g: bytearray(n) for g in gapped}   # inside or next to a chosen pseudo-gap
    chosen = []
    # Every real gap gets up to ``repeats`` stand-ins, round by round; within a round the
    # gaps of rare length classes go first so the budget does not all go to short gaps.
    lengths = gapset.lengths
    classes = length_classes(lengths)
    frequency = np.bincount(classes)[classes] if classes.size else classes
    rounds = []
    for _ in range(repeats):
        shuffled = rng.permutation(len(gapset.gaps))
        rounds.append(shuffled[np.argsort(frequency[shuffled], kind="stable")])
    order = np.concatenate(rounds).tolist() if rounds else []
    used = 0
    stand_ins = np.zeros(len(gapset.gaps), int)
    # Once the budget cannot take the shortest gap that fits the clip, no later gap can
    # place a stand-in (and only placements draw random numbers): on random loss the
    # budget runs out in the first of the ``repeats`` rounds over tens of thousands of gaps.
    fitting = lengths[lengths + 2 <= n]
    shortest = int(fitting.min()) if fitting.size else None
    for index in order:
        g, a, b = gapset.gaps[index]
        length = b - a
        if shortest is None or used + shortest > budget:
            break
        if used + length > budget or length + 2 > n:
            continue
        if length >= MIN_MODEL_GAP and stand_ins[index] >= repeats_long:
            continue
        reach = 4 * length + 8
        for attempt in range(2 * tries):
            lo, hi = ((max(1, a - reach), min(n - length - 1, b + reach))
                      if attempt % tries < tries // 2 else (1, n - length - 1))
            if hi <= lo:
                continue
            s = int(rng.integers(lo, hi))
            if taken[g].find(1, s - 1, s + length + 1) >= 0:
                continue
            # First tries: an observed stretch. Then, where none was found (on dense loss,
            # long observed stretches are rare), a stretch that absorbs real missing
            # frames between observed ends: the gap it makes has the real gap's length,
            # and only the frames it hides are scored.
            hides = observed_before[g][s + length] - observed_before[g][s]
            if seen_rows[g][s - 1] and seen_rows[g][s + length] and (
                    hides == length if attempt < tries else 0 < hides):
                taken[g][s - 1:s + length + 1] = b"\x01" * (length + 2)
                chosen.append(((g, s, s + length), int(index)))
                stand_ins[index] += 1
                used += hides
                break
    return chosen


def end_gaps(observed: np.ndarray, groups: np.ndarray,
             ends: bool | tuple[bool, bool] = True) -> list[tuple[int, int, int]]:
    """Gaps touching the clip's first or last frame (not a group missing throughout), at
    the ends ``ends`` names (:func:`end_sides`)."""
    n = observed.shape[1]
    sides = end_sides(ends)
    return [(g, a, b) for g, rows in enumerate(groups)
            for a, b in missing_runs(observed[rows[0]])
            if (a == 0) != (b == n) and sides[a != 0]]


def end_sides(ends: bool | tuple[bool, bool]) -> tuple[bool, bool]:
    """Which of the clip's ends, (start, end), ``ends`` names: one flag for both, or a
    pair (a window of a long clip holds one of the clip's ends or neither; its other
    edges' gaps are not the clip's)."""
    return (ends, ends) if isinstance(ends, bool) else (bool(ends[0]), bool(ends[1]))


END_STAND_INS = 2
END_FRACTION = 0.025


def end_stand_ins(train: np.ndarray, groups: np.ndarray, ends: list[tuple[int, int, int]],
                  rng: np.random.Generator, *, repeats: int = END_STAND_INS,
                  fraction: float = END_FRACTION) -> list[tuple[int, int, int]]:
    """Stand-ins for the end gaps ``ends``, at most ``fraction`` of the observed samples
    (in ``train``, the mask with the interior stand-ins hidden), one per group at each end.
    For each end gap of MIN_MODEL_GAP frames or more, first its own group over the
    ``length`` frames beside the gap, where observed over them and the frame after (its end
    gap, twice as long in the validation run, is scored there only: at the same distances
    from the first frame seen as the real gap's samples); then, for every end gap, up to
    ``repeats`` other groups observed over the gap's frames and the frame beside them,
    hidden there, so that each is an end gap of the real one's length. (The own group's
    stand-in on shorter end gaps too, the random loss of the paper's protocol: the end
    samples' error summed over its 12 cells and seeds 1–3 went 101.8 → 104.0 mm.)

    The default's fill of an end gap was its TrNN candidate's alone, unvalidated and with
    nothing to join at the open end (``scripts/end_gaps.py``: 48–91 mm on 10–60-frame end
    gaps of CMU clips where PCA's fill erred 1.5–13 mm; on random loss 2–25 mm where
    TSMC's erred 1.4–4.8): the stand-ins let validation weigh the candidates there.
    Other groups alone (thirty-fifth session) brought 13–91 mm down to 3.5–29 mm; the own
    group's stand-in first, with the outlier rule on end gaps (:func:`_blend_end_gaps`),
    took the sum over seven cases and two seeds from 118 to 78 mm, over held-out seeds
    6–8 from 142 to 110 mm (docs/results.md, thirty-sixth session).
    """
    n = train.shape[1]
    seen = train[groups[:, 0]]                  # (a copy: what is left seen as we go)
    budget = fraction * seen.sum()
    # The frame beside each stand-in stays seen: a marker with end gaps at both ends (or
    # one taken at both ends) was hidden twice over the same frames, or over all it shows.
    kept_seen = np.zeros_like(seen)
    used = 0
    taken = {0: set(), n: set()}
    chosen = []

    def place(h: int, s: int, t: int, at: int) -> None:
        seen[h, s:t] = False
        kept_seen[h, at] = True
        chosen.append((h, s, t))

    for index in rng.permutation(len(ends)).tolist():
        g, a, b = ends[index]
        length = b - a
        at_start = a == 0
        if length + 1 >= n:
            continue
        side = taken[0 if at_start else n]
        own = (length, 2 * length, 2 * length) if at_start else (n - 2 * length,
                                                                  n - length,
                                                                  n - 2 * length - 1)
        if (length >= MIN_MODEL_GAP and 2 * length + 1 < n and g not in side
                and seen[g, own[0]:own[1]].all() and seen[g, own[2]]
                and not kept_seen[g, own[0]:own[1]].any()):
            if used + length > budget:
                return chosen
            side.add(g)
            used += length
            place(g, *own)
        span = (0, length, length) if at_start else (n - length, n, n - length - 1)
        fitting = np.flatnonzero(seen[:, span[0]:span[1]].all(axis=1) & seen[:, span[2]]
                                 & ~kept_seen[:, span[0]:span[1]].any(axis=1))
        fitting = [h for h in fitting.tolist() if h != g and h not in side]
        for h in rng.permutation(fitting)[:repeats].tolist() if fitting else []:
            if used + length > budget:
                return chosen
            side.add(h)
            used += length
            place(h, *span)
    return chosen


# The source of an end gap's stand-in in :func:`blend`'s list (interior ones name their
# real gap's index), and the error given to a candidate's non-finite fill of one.
END_SOURCE = -1
UNFILLED_ERROR = 1e6


def _blend_end_gaps(out: np.ndarray, fills: list[np.ndarray | None],
                    ends: list[tuple[int, int, int]], groups: np.ndarray,
                    weights: dict[int, np.ndarray]) -> None:
    """Fill each end gap of ``out`` (in place) with the candidates' fills in the weights of
    its length class (the nearest with evidence), over the candidates run whose fill there
    is finite and, on gaps of MIN_MODEL_GAP frames or more, is not an outlier.

    The outlier rule is the interior gaps' (:func:`_without_outliers`), over the distinct
    fills: at an open end several candidates give one fill (the splines and the
    regression fill hold the last sample there), and with them counted apart the
    typical distance from the median fill was 0, which turned the rule off. A TrNN fill
    0.65 (unit RMS) off where the others erred 0.001–0.06 kept a fifth of the weight so
    (10_01, 10 frames, seed 5: 14 mm). On shorter end gaps, where fills agree closely, the
    rule dropped good ones (02_05, random loss, seed 3: 2.3 → 5.7 mm).
    """
    for g, a, b in ends:
        w = _weights_for(length_class(b - a), weights, None).copy()
        rows = groups[g][:, None]
        segments = {k: fills[k][rows, a:b] for k in range(w.size) if fills[k] is not None}
        segments = {k: segment for k, segment in segments.items()
                    if np.isfinite(segment).all()}
        w[[k for k in range(w.size) if k not in segments]] = 0.0
        if b - a >= MIN_MODEL_GAP and w.sum() > 0:
            w = _end_gap_inliers(w, segments, b - a)
        if w.sum() > 0:
            out[rows, a:b] = sum(w[k] / w.sum() * segments[k] for k in np.flatnonzero(w > 0))


def _end_gap_inliers(w: np.ndarray, segments: dict[int, np.ndarray], length: int
                     ) -> np.ndarray:
    """``w`` without the candidates whose fill of an end gap (``segments``: candidate →
    its fill there) is an outlier among the distinct fills (see :func:`_blend_end_gaps`),
    where there are four or more: of three, two that agree on a wrong fill made the right
    one the outlier (02_05, random loss, seed 3: the held fill, weight 0.99 and 0.015 off,
    dropped for TrNN's 0.29 off; the end samples' error 2.35 → 7.94 mm)."""
    ran = list(segments)
    stack = np.stack([segments[k].reshape(-1) for k in ran])
    _, first, which = np.unique(stack, axis=0, return_index=True, return_inverse=True)
    if first.size < 4:
        return w
    which = which.ravel()
    distinct_w = np.bincount(which, w[ran], minlength=first.size)
    kept = _without_outliers(distinct_w[None], stack[first][None, :, None, :],
                             factor=outlier_factor(length))[0]
    out = w.copy()
    out[[k for j, k in enumerate(ran) if kept[which[j]] == 0]] = 0.0
    return out


# A stand-in's evidence is kept as (EᵀE, number of samples) for its error matrix E
# (samples × candidates): the squared error of any blend w is wᵀ EᵀE w, so sums of these
# small Gram matrices serve every fit below without stacking the samples again. A list of
# stand-ins is held as Stack: grams (stand-ins, k, k) and sizes (stand-ins,).
Evidence = tuple[np.ndarray, int]
Stack = tuple[np.ndarray, np.ndarray]


def evidence(E: np.ndarray) -> Evidence:
    """The (Gram matrix, sample count) of one stand-in's errors E (samples × candidates)."""
    return E.T @ E, E.shape[0]


def _stack(blocks: list[Evidence]) -> Stack:
    return np.stack([gram for gram, _ in blocks]), np.array([size for _, size in blocks])


def _best_single(grams: np.ndarray) -> np.ndarray:
    """The one-hot weights of each Gram matrix's best single candidate (…, k, k) → (…, k)."""
    k = grams.shape[-1]
    return np.eye(k)[np.diagonal(grams, axis1=-2, axis2=-1).argmin(axis=-1)]


def _cross_validated(stack: Stack, order: np.ndarray | None = None) -> np.ndarray:
    """The convex blend, or the best single candidate when the blend does not generalise.

    Two-fold cross-validation over pseudo-gaps (alternate stand-ins of ``order``, default
    all in turn, in each fold): the blend is kept only when its held-out error beats that
    of picking the best single candidate.
    """
    grams, sizes = stack
    if order is None:
        order = np.arange(len(sizes))
    return _cross_validated_stacks([stack], [np.asarray(order)[None]])[0][0]


def _cross_validated_stacks(stacks: list[Stack], orders: list[np.ndarray]
                            ) -> list[np.ndarray]:
    """:func:`_cross_validated` for each stack and each row of its ``orders`` (resamples ×
    stand-ins): weights (resamples × k) per stack. The convex fits of all resamples of all
    stacks are solved side by side (a clip's gaps weighted on their own stand-ins: 75 of
    them, 64 resamples each, on the nimble squat; one at a time that was 0.4 s of Python
    overhead); each resample's sums are those of its own stack, as when it is solved alone.
    """
    grams = [_resampled_sums(stack[0], order) for stack, order in zip(stacks, orders)]
    chosen = [_best_single(gram) for gram in grams]                 # (R, k) each
    split = [i for i, order in enumerate(orders) if order.shape[1] >= 4]
    if not split:
        return chosen
    first = [_resampled_sums(stacks[i][0], orders[i][:, 0::2]) for i in split]
    second = [_resampled_sums(stacks[i][0], orders[i][:, 1::2]) for i in split]
    fits = np.concatenate(first + second)
    tests = np.concatenate(second + first)
    blend_w, single_w = simplex_least_squares(fits), _best_single(fits)
    held_out = np.einsum("pi,pij,pj->p", blend_w, tests, blend_w)
    held_out_single = np.einsum("pi,pij,pj->p", single_w, tests, single_w)
    half = held_out.size // 2           # the first folds' fits, then the second folds'
    wins = (held_out[:half] + held_out[half:]) < (held_out_single[:half]
                                                  + held_out_single[half:])
    gram = np.concatenate([grams[i] for i in split])
    solved = simplex_least_squares(gram[wins]) if wins.any() else None
    offsets = np.cumsum([0] + [len(orders[i]) for i in split])
    done = 0
    for position, i in enumerate(split):
        won = wins[offsets[position]:offsets[position + 1]]
        count = int(won.sum())
        if count:
            chosen[i][won] = solved[done:done + count]
            done += count
    return chosen


def _resampled_sums(grams: np.ndarray, orders: np.ndarray) -> np.ndarray:
    """Σ grams[i] over each row of ``orders`` (R, length) → (R, k, k), as one product of
    the rows' counts with the stacked matrices (no R × length stack of them: 130 MB for
    64 resamples of the 4,000 stand-ins of a random-loss class)."""
    count, blocks = len(orders), len(grams)
    keys = (orders + blocks * np.arange(count)[:, None]).ravel()
    counts = np.bincount(keys, minlength=count * blocks).reshape(count, blocks)
    k = grams.shape[1]
    return (counts.astype(np.float64) @ grams.reshape(blocks, k * k)).reshape(count, k, k)


# Bootstrap resamples whose choices are averaged (see ``_bagged``).
BAG_ROUNDS = 64


def _bagged(blocks: list[Evidence], rng: np.random.Generator,
            rounds: int = BAG_ROUNDS) -> np.ndarray:
    """:func:`_cross_validated` averaged over bootstrap resamples of the stand-ins.

    Bagging the choice (Breiman 1996, "Bagging predictors"; as model averaging, Buckland,
    Burnham & Augustin 1997): where the stand-ins clearly favour one candidate every
    resample picks it and the weights stay one-hot; where the evidence is close, the
    choice flips between resamples and the average hedges between the contenders
    instead of staking the whole gap on which of them a few stand-ins happened to
    favour. The hard choice also flipped on rounding: WalkL_0001 gave 1.694 or 1.726 mm
    with two BLAS threads or one, the bagged weights 1.717 with either. Measured on the
    walking set (one BLAS thread, interior gap samples): mean 2.003 → 1.995 mm; full
    tables in docs/results.md. The resamples are solved side by side
    (:func:`_cross_validated_stacks`).
    """
    return _bagged_many([blocks], rng, rounds)[0]


def _bagged_many(block_lists: list[list[Evidence]], rng: np.random.Generator,
                 rounds: int = BAG_ROUNDS) -> list[np.ndarray]:
    """:func:`_bagged` of each list of stand-ins in turn (the same draws from ``rng`` as
    one call after the other), their fits solved side by side."""
    # One draw of all the rounds per list: the same numbers as one draw per round (the
    # generator's stream does not depend on how it is split into calls), in a 64th of
    # the calls (75 gaps on their own stand-ins on the nimble squat: 4,800 calls, 0.07 s).
    orders = [rng.integers(0, len(blocks), (rounds, len(blocks))) for blocks in block_lists]
    chosen = _cross_validated_stacks([_stack(blocks) for blocks in block_lists], orders)
    return [weights.mean(axis=0) for weights in chosen]


def blend_weights(errors: dict[int, list[Evidence]], rng: np.random.Generator, *,
                  min_gaps: int = 30) -> dict[int, np.ndarray]:
    """Convex weights per length class from the stand-ins' evidence (bagged choices).

    A class with fewer than ``min_gaps`` pseudo-gaps borrows those of its nearest classes
    (shorter first) until it has enough.
    """
    classes = sorted(errors)
    block_lists = []
    for cls in classes:
        blocks = list(errors[cls])
        for step in range(1, 64):
            if len(blocks) >= min_gaps:
                break
            for other in (cls - step, cls + step):
                blocks.extend(errors.get(other, []))
        block_lists.append(blocks)
    return dict(zip(classes, _bagged_many(block_lists, rng)))


def _weights_for(cls: int, weights: dict[int, np.ndarray], default: np.ndarray) -> np.ndarray:
    if cls in weights:
        return weights[cls]
    if not weights:
        return default
    nearest = min(weights, key=lambda c: (abs(c - cls), -c))
    return weights[nearest]


# A candidate whose fill of a gap lies farther than this many times the typical distance
# from the candidates' median fill is left out of that gap's blend (see ``_without_outliers``):
# OUTLIER_FACTOR on gaps under LONG_GAP frames, LONG_OUTLIER_FACTOR on longer ones. Long
# gaps are where candidates go wild (a catastrophic-fill audit, 1,801 hidden gaps of 20–200
# frames on 21 real clips: 58 fills more than twice the best simple method's error, most
# with a candidate far off the truth kept in the blend; factor 2, replayed: 47), while on
# short gaps the candidates agree closely and a factor of 2 dropped good fills (85_12 at
# mr = 0.4, 0.126 → 0.145 mm). Measured with the PCA candidate joined to the gap ends, the
# default over the accuracy benchmark (docs/results.md, twenty-eighth session): factor 3
# everywhere walkl 1.9887 mm, CMU mean 4.114; 2 everywhere 1.9885, 3.834 with the
# random-loss cells up to 16 % worse; 2 from 20 frames on 1.9885, 3.830 with them within 2 %.
OUTLIER_FACTOR = 3.0
LONG_OUTLIER_FACTOR = 2.0
LONG_GAP = 20


def outlier_factor(length: int) -> float:
    """The outlier rule's factor for gaps of ``length`` frames."""
    return LONG_OUTLIER_FACTOR if length >= LONG_GAP else OUTLIER_FACTOR


def _without_outliers(w: np.ndarray, segments: np.ndarray, rounds: int = 3,
                      factor: float = OUTLIER_FACTOR) -> np.ndarray:
    """The weights ``w`` (gaps, k) of gaps of one length without the candidates whose fill
    is an outlier on that gap; ``segments`` (gaps, k, rows, length) holds the fills.

    A convex blend with a small weight on a fill that went wild on this gap inherits that
    fraction of its error: a 3 % weight on a spline 270 mm off (10_01, 40-frame gaps, seed
    1) put 8 mm into the blend. The candidates' fills of the gap are compared with their
    pointwise median; a candidate whose RMS distance from it exceeds ``factor`` (see
    :func:`outlier_factor`) times the median of these distances (the Hampel identifier,
    median and median absolute deviation, here of whole fills; Davies & Gather 1993, "The
    identification of multiple outliers", JASA 88:782) is an outlier. The median and the
    typical distance are then taken again over the others, up to ``rounds`` times, since a
    cluster of wild fills drags the first median. Outliers lose their weight on this gap and
    the others are rescaled; nothing changes where the typical distance is 0 or where only
    outliers had weight. Measured offline on the fills and weights of the sixth session's
    runs (one round → three): walking set 1.9894 → 1.9866 → 1.9835 mm; CMU continuous gaps
    e.g. 85_12 ml = 20 6.06 → 3.39 → 3.36, 10_01 ml = 40 7.49 → 5.55 → 5.34 mm (tables in
    docs/results.md).

    The gaps are judged side by side (a Python loop over a thousand gaps on random loss
    took 0.5 s); each gap's medians are those of ``np.median`` over its inliers.
    """
    inlier = np.ones(w.shape, dtype=bool)
    judging = np.arange(len(w))
    for _ in range(rounds):
        if judging.size == 0:
            break
        stack, mask = segments[judging], inlier[judging]
        centre = _median_of(stack, mask)                             # (gaps, rows, length)
        distance = np.sqrt(((stack - centre[:, None]) ** 2).mean(axis=(2, 3)))
        typical = _median_of(distance, mask)
        judged = distance <= factor * typical[:, None]
        settled = (typical <= 0) | (judged == mask).all(axis=1)
        moved = judging[~settled]
        inlier[moved] = judged[~settled]
        judging = moved
    kept = np.where(inlier, w, 0.0)
    total = kept.sum(axis=1, keepdims=True)
    return np.where(total > 0, kept / np.where(total > 0, total, 1.0), w)


# The rigid-partner check (see ``_rigid_partner_violations``): partners per gap, the band's
# margin and the violation that clearly leaves it, both in standard deviations of the
# partner's distance, and how many partners' bands must be left. Measured (one BLAS
# thread) against the session start: a replay of 1,557 hidden gaps of 5–120 frames
# (often 2–3 neighbouring markers together) on 18 real clips counted 38 catastrophic
# fills (error above max(2 × the best of linear, spline and pca, that + 10 mm)) before,
# 27 after (CMU 14 → 10, btk golf/dance 5 → 3, other vendor files 19 → 14, walking 0);
# the accuracy benchmark walkl 1.9904 → 1.9904 mm, below pca on every file, CMU mean
# 3.7955 → 3.6052 mm, 24 of 24 cells won (85_02 ml = 20/40/60 3.99 → 3.40, 16.27 →
# 14.86, 26.41 → 23.49; 10_01 ml = 60 9.49 → 9.79; random loss unchanged). Margin and
# tolerance of 1 std: 25 catastrophic, walkl 1.9906, CMU 3.655; 1 std with one
# partner's band enough: 20, 1.9909, 3.830 (85_12 ml = 60 7.75 → 9.45 mm).
RIGID_PARTNERS = 3
PARTNER_MARGIN = 2.0
PARTNER_TOLERANCE = 2.0
PARTNER_VOTES = 2


def _partner_bands(matrix: np.ndarray, observed: np.ndarray, gapset: GapSet,
                   centre: np.ndarray | None
                   ) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
    """For each marker j with an interior gap of ``MIN_MODEL_GAP`` frames or more: (spread,
    lo, hi, others) of its distances to the markers ``others`` (all, or its
    RIGID_CANDIDATES nearest on clips with more markers), over the frames seeing both:
    standard deviation (∞ where fewer than 10 such frames), least and largest value. In
    true distances: ``matrix`` plus the rows' ``centre`` (see :func:`blend`). Empty where
    the rows are not markers. Made beside the candidates' runs (it needs none of them).
    """
    if gapset.groups.shape[1] != 3:
        return {}
    spans, lengths = gapset.spans, gapset.lengths
    rows = sorted(set(spans[lengths >= MIN_MODEL_GAP, 0].tolist()))
    if not rows:
        return {}
    P = _xyz(matrix if centre is None else matrix + centre[:, None])
    seen = observed[0::3].T
    k = P.shape[1]
    near = nearest_markers(P, seen, RIGID_CANDIDATES) if k - 1 > RIGID_CANDIDATES else None
    others = {j: np.delete(np.arange(k), j) if near is None else near[j] for j in rows}
    if near is None and 2 * len(rows) > k:
        # Most markers gapped (the windows of long clips): every pair once, not twice.
        tables = pair_distances(P, seen, extent=True)
        measured = ([table[j, others[j]] for table in tables] for j in rows)
    else:
        measured = distance_rows(P, seen, [(j, others[j]) for j in rows], True, extent=True)
    return {j: (np.where(count >= 10, std, np.inf), lo, hi, others[j])
            for j, (count, _, std, lo, hi) in zip(rows, measured)}


def _seen_before(observed: np.ndarray) -> np.ndarray:
    """(markers, n + 1): how many frames before each frame see each marker (a marker is
    seen on [a, b) when the difference of its counts at b and a is b − a)."""
    seen = observed[0::3]
    before = np.zeros((seen.shape[0], seen.shape[1] + 1), dtype=np.int32)
    np.cumsum(seen, axis=1, out=before[:, 1:])
    return before


def _rigid_partner_violations(matrix: np.ndarray, centre: np.ndarray | None,
                              before: np.ndarray, groups: np.ndarray, spans: np.ndarray,
                              segments: np.ndarray, bands: dict) -> np.ndarray:
    """(gaps, k) True where a candidate's fill of a gap clearly leaves the distance band to
    the gapped marker's rigid partners; ``spans`` (gaps, 3) are gaps of one length,
    ``segments`` (gaps, k, 3, length) the candidates' fills of them, ``before`` the clip's
    :func:`_seen_before` (made once for all lengths).

    The partners of a gap [a, b) of marker j are, as :func:`rigid_fill` chooses its
    donors, the RIGID_PARTNERS markers observed on [a−1, b] whose distance to j varies
    least over the clip, a trajectory held under several labels once
    (:func:`_distinct_donors`); a partner's band is the range of that distance over the frames
    seeing both, widened by PARTNER_MARGIN standard deviations. A fill violates a partner's
    band when the RMS over the gap of its distance outside the band exceeds
    PARTNER_TOLERANCE standard deviations, and the gap's band when it violates those of
    PARTNER_VOTES partners (all of them where there are fewer).
    """
    gaps, k, _, length = segments.shape
    j, a, b = spans.T
    markers, row = np.unique(j, return_inverse=True)
    spread, lo, hi, others = (np.stack(table)[row] for table in       # (gaps, candidates)
                              zip(*(bands[m] for m in markers.tolist())))
    if not others.shape[1]:                                 # a clip of one marker
        return np.zeros((gaps, k), dtype=bool)
    usable = (before[others, (b + 1)[:, None]] - before[others, (a - 1)[:, None]]
              == (b - a + 2)[:, None])
    ranked = np.where(usable, spread, np.inf)
    shift = np.zeros(len(matrix)) if centre is None else centre

    def at(g: np.ndarray, columns: np.ndarray) -> np.ndarray:
        rows = groups[np.take_along_axis(others[g], columns, axis=1)]   # (g, c, 3)
        return matrix[rows, (a[g] - 1)[:, None, None]] + shift[rows]

    chosen = _distinct_donors_of_gaps(ranked, RIGID_PARTNERS, at)   # (gaps, p), −1: none
    taken = chosen >= 0
    column = np.where(taken, chosen, 0)
    rows = groups[np.take_along_axis(others, column, axis=1)]       # (gaps, p, 3)
    where = (matrix[rows[..., None], (a[:, None] + np.arange(length))[:, None, None]]
             + shift[rows][..., None])                               # (gaps, p, 3, length)
    dist = np.sqrt(((segments[:, :, None] - where[:, None]) ** 2).sum(axis=3))
    # (gaps, 1, p, 1); 0 in the columns of partners not taken (their band may be ∞, and
    # ∞ − ∞ would warn: those columns are left out below)
    spread, lo, hi = (np.where(taken, np.take_along_axis(table, column, axis=1),
                               0.0)[:, None, :, None] for table in (spread, lo, hi))
    margin = PARTNER_MARGIN * spread
    excess = np.maximum(np.maximum(dist - (hi + margin), 0.0), (lo - margin) - dist)
    rms = np.sqrt((excess ** 2).mean(axis=3))                        # (gaps, k, p)
    outside = (rms > PARTNER_TOLERANCE * spread[..., 0] + 1e-12) & taken[:, None]
    votes = np.minimum(PARTNER_VOTES, taken.sum(axis=1))[:, None]
    return (outside.sum(axis=2) >= votes) & (votes > 0)


def _median_of(values: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``np.median(values[g][mask[g]], axis=0)`` for every g at once (mask: (g, k), each
    row with a True): the masked-out values sort last, and the middle one or the mean of
    the middle two is taken as ``np.median`` does."""
    shape = mask.shape + (1,) * (values.ndim - 2)
    ordered = np.sort(np.where(mask.reshape(shape), values, np.inf), axis=1)
    count = mask.sum(axis=1).reshape((-1,) + (1,) * (values.ndim - 1))
    low = np.take_along_axis(ordered, (count - 1) // 2, axis=1)[:, 0]
    high = np.take_along_axis(ordered, count // 2, axis=1)[:, 0]
    return np.where(((count - 1) // 2 == count // 2)[:, 0], low, (low + high) / 2)


@dataclass(frozen=True)
class Validation:
    """What the stand-ins showed: their evidence by length class, and by the real gap each
    stood in for (indices into that clip's interior gaps, so meaningful for it alone)."""

    names: tuple[str, ...]
    by_class: dict[int, list[Evidence]]
    by_gap: dict[int, list[Evidence]]

    @staticmethod
    def pooled(validations: list[Validation]) -> Validation:
        """The length-class evidence of several clips (windows of one clip) together.

        Evidence is additive (Gram matrices of the errors), so the pooled stand-ins weigh
        as if one validation had hidden them all. The per-gap evidence is left out: it
        names gaps of the clip it came from.
        """
        names = validations[0].names
        if any(v.names != names for v in validations):
            raise ValueError("validations of different candidates cannot be pooled")
        by_class: dict[int, list[Evidence]] = {}
        for validation in validations:
            for cls, blocks in validation.by_class.items():
                by_class.setdefault(cls, []).extend(blocks)
        return Validation(names, by_class, {})


@dataclass(frozen=True)
class BlendReport:
    """What the validation learned: weights per length class, candidate names, sizes, and
    the validation itself (to be lent to a neighbouring window, see :func:`blend`)."""

    names: tuple[str, ...]
    weights: dict[int, np.ndarray]
    pseudo_gaps: int
    validation: Validation


def _gap_weights(gapset: GapSet, weights: dict[int, np.ndarray],
                 own: dict[int, list[Evidence]], names: tuple[str, ...], default: str,
                 rng: np.random.Generator, prior: dict[str, float] | None,
                 prior_share: float) -> list[np.ndarray]:
    """Each interior gap's weights, before the outlier rule.

    A gap with enough stand-ins of its own (long gaps, which are few) is judged on that
    local evidence; the others share the weights of their length class. On gaps of
    ``MIN_MODEL_GAP`` frames or more the ``prior`` is mixed in with share ``prior_share``.
    """
    fallback = np.eye(len(names))[names.index(default)]
    prior_w = np.array([(prior or {}).get(name, 0.0) for name in names])
    if prior_w.sum() > 0:
        prior_w = prior_w / prior_w.sum()
    gap_weights = []
    # Random loss gives tens of thousands of gaps in a handful of length classes: each
    # class's weights are looked up once and shared by its gaps (the same array).
    lengths = gapset.lengths
    of_class: dict[int, np.ndarray] = {}
    # The gaps judged on their own stand-ins are bagged side by side, in gap order.
    judged = [index for index in range(len(gapset.gaps))
              if len(own.get(index, ())) >= MIN_OWN_STANDINS]
    on_own = dict(zip(judged, _bagged_many([own[index] for index in judged], rng)))
    for index, (length, cls) in enumerate(zip(lengths.tolist(),
                                              length_classes(lengths).tolist())):
        if index in on_own:
            w = on_own[index]
        else:
            w = of_class.get(cls)
            if w is None:
                w = of_class[cls] = _weights_for(cls, weights, fallback)
        if length >= MIN_MODEL_GAP and prior:
            w = (1 - prior_share) * w + prior_share * prior_w
        gap_weights.append(w)
    return gap_weights


def _blind_gaps_temporal(gap_weights: list[np.ndarray], gapset: GapSet, observed: np.ndarray,
                         columns: list[int]) -> list[np.ndarray]:
    """The gaps' weights, those of a gap whose every frame has no observed sample at all
    (a dropped frame) given to the candidates ``columns`` alone (in their proportions, or
    equally where the weights gave them none).

    Every other candidate reads the gap's frames across markers, and there is nothing
    there: TrNN left such a frame near its start (its temporal term moves it slowly, and
    on data without noise it stops first), and the stand-ins, one marker at a time, never
    show it. On a smooth clip rounded to 0.001 mm with one frame of 41 markers dropped, the
    default filled 13 of them 30 mm off and refused 28 as jumps, where a spline is exact
    to 0.001 mm (an audit's case, thirty-fourth session).
    """
    nothing = ~observed.any(axis=0)
    if not columns or not nothing.any() or not gapset.gaps:
        return gap_weights
    before = np.concatenate([[0], np.cumsum(nothing)])
    _, a, b = gapset.spans.T
    blind = np.flatnonzero(before[b] - before[a] == b - a)
    if not blind.size:
        return gap_weights
    keep = np.zeros(len(gap_weights[0]))
    keep[columns] = 1.0
    out = list(gap_weights)
    for index in blind.tolist():
        w = gap_weights[index] * keep
        out[index] = w / w.sum() if w.sum() > 0 else keep / keep.sum()
    return out


def _local_errors(checks: dict[int, Callable[[np.ndarray], np.ndarray]], gapset: GapSet
                  ) -> dict[int, np.ndarray]:
    """Candidate index → (long gaps,) its ``check``'s errors beside the gaps of
    MIN_MODEL_GAP frames or more (see :func:`_locally_checked`)."""
    long = gapset.spans[gapset.lengths >= MIN_MODEL_GAP]
    return {column: check(long) for column, check in checks.items()} if long.size else {}


def _locally_checked(gap_weights: list[np.ndarray], gapset: GapSet,
                     errors: dict[int, list[Evidence]], tried: dict[int, np.ndarray],
                     own: dict[int, list[Evidence]] | None = None) -> list[np.ndarray]:
    """The gaps' weights scaled gap by gap by how each candidate fared near the gap (gaps of
    MIN_MODEL_GAP frames or more), then normalised again.

    With t a candidate's typical error on the stand-ins of the gap's length class (the
    median over them of its RMS error per sample) and e its error near the gap, its weight
    on the gap is multiplied by t / e, within [1 / LOCAL_CLIP, LOCAL_CLIP]. Two sources
    of e, whose factors multiply where both exist:

    ``tried``: candidate index → (long gaps,) the RMS error of its fill of each long gap
    tried beside it on the real mask (NaN: not tried; see :func:`rigid_local_errors`).
    ``own``: real gap index → the evidence of the stand-ins hidden for that gap (same
    marker, same length, sought near it first: :func:`pseudo_gaps`); e is every
    candidate's RMS error over them. A long gap has at most two, too few to weigh the
    candidates alone (:data:`MIN_OWN_STANDINS`), but they tell which candidates the gap's
    marker suits better or worse than the clip's markers as a whole (a fast limb where
    the class's weights come mostly from the trunk). It is the marker that counts, not
    the place: on the 1,557 gaps of ``scripts/replay_gaps.py`` the mean error went
    3.888 → 3.862 mm with all of them, 3.864 with those within 4 gap lengths, and
    3.889 with those within one (thirty-fourth session, docs/results.md).
    """
    lengths = gapset.lengths
    long = np.flatnonzero(lengths >= MIN_MODEL_GAP)
    near = [position for position, index in enumerate(long.tolist()) if (own or {}).get(index)]
    if not long.size or not (tried or near) or not errors:
        return gap_weights
    classes = length_classes(lengths[long])
    typical = {}
    for cls in np.unique(classes).tolist():
        blocks = errors.get(cls) or errors[min(errors, key=lambda c: (abs(c - cls), -c))]
        grams, sizes = _stack(blocks)
        rms = np.sqrt(np.diagonal(grams, axis1=1, axis2=2) / sizes[:, None])
        typical[cls] = np.median(rms, axis=0)                       # (k,)
    t = np.stack([typical[c] for c in classes.tolist()])            # (long gaps, k)
    factor = np.ones_like(t)
    for column, e in tried.items():
        factor[:, column] = _local_factor(t[:, column], e)
    if near:
        e = np.empty((len(near), t.shape[1]))
        for row, position in enumerate(near):
            grams, sizes = _stack(own[int(long[position])])
            e[row] = np.sqrt(np.diagonal(grams, axis1=1, axis2=2).sum(axis=0) / sizes.sum())
        factor[near] *= _local_factor(t[near], e)
    out = list(gap_weights)
    for position in np.flatnonzero((factor != 1).any(axis=1)).tolist():
        w = gap_weights[long[position]] * factor[position]
        if w.sum() > 0:
            out[long[position]] = w / w.sum()
    return out


def _local_factor(typical: np.ndarray, error: np.ndarray) -> np.ndarray:
    """typical / error within [1 / LOCAL_CLIP, LOCAL_CLIP]; 1 where ``error`` is NaN.
    (Errors at rounding's level, on exact data, compare as equal.)"""
    ratio = (typical + LOCAL_RESOLUTION) / (error + LOCAL_RESOLUTION)
    return np.where(np.isfinite(error), np.clip(ratio, 1 / LOCAL_CLIP, LOCAL_CLIP), 1.0)


def _stand_in_errors(fill_fn: Candidate, blinded: np.ndarray, train: np.ndarray,
                     matrix: np.ndarray, rows: np.ndarray, frames: np.ndarray,
                     spans: frozenset) -> np.ndarray:
    """A candidate's errors (fill − data) on the hidden samples of the stand-ins, from its
    validation run: (samples, k) for the rows ``rows`` (samples, k) at ``frames``. A
    candidate of :data:`FILLS_GAPS_ALONE` fills the stand-ins' ``spans`` alone."""
    alone = fill_fn in FILLS_GAPS_ALONE or getattr(fill_fn, "fills_gaps_alone", False)
    fill = fill_fn(blinded, train, only=spans) if alone else fill_fn(blinded, train)
    return fill[rows, frames[:, None]] - matrix[rows, frames[:, None]]


def _stand_in_errors_and_fill(fill_fn: Candidate, blinded: np.ndarray, train: np.ndarray,
                              matrix: np.ndarray, observed: np.ndarray, gapset: GapSet,
                              rows: np.ndarray, frames: np.ndarray
                              ) -> tuple[np.ndarray, np.ndarray]:
    """A candidate run once (:func:`blend`'s ``once``): its errors on the stand-ins' hidden
    samples, as :func:`_stand_in_errors`, and the values its validation run fills the real
    missing samples with, joined to the real gaps' ends (a 1-D array in the order of
    ``matrix[~observed]``: small enough to come back from a child process)."""
    fill = fill_fn(blinded, train)
    errors = fill[rows, frames[:, None]] - matrix[rows, frames[:, None]]
    return errors, join_ends(fill, matrix, observed, gapset)[~observed]


def _gap_holding(train: np.ndarray, groups: np.ndarray, span: tuple[int, int, int]
                 ) -> tuple[int, int, int]:
    """The gap of ``train`` that holds the hidden ``span`` (g, s, t): an end gap's own
    stand-in joins the real end gap beside it."""
    g, s, t = span
    seen = train[groups[g][0]]
    before = np.flatnonzero(seen[:s])
    after = np.flatnonzero(seen[t:])
    return (g, int(before[-1]) + 1 if before.size else 0,
            t + int(after[0]) if after.size else seen.size)


def _hidden_samples(hidden: list, groups: np.ndarray, observed: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows (samples, k) and frames (samples,) of what the stand-ins hid, and the bounds
    of each stand-in's samples: the frames it hid (it may have absorbed real missing
    frames), stand-in after stand-in, in time order."""
    g, a, b = np.array([span for span, _ in hidden]).T
    run, frames = gap_frames(a, b)
    rows = groups[g][run]
    kept = observed[rows[:, 0], frames]
    run = run[kept]
    return rows[kept], frames[kept], np.searchsorted(run, np.arange(len(hidden) + 1))


def blend(matrix: np.ndarray, observed: np.ndarray, candidates: dict[str, Candidate], *,
          default: str, seed: int = 0, validation_fraction: float = 0.1,
          prior: dict[str, float] | None = None, prior_share: float = 0.5,
          validation: Validation | None = None, costly: tuple[str, ...] = (),
          optional: tuple[str, ...] = (), validators: dict[str, Candidate] | None = None,
          once: tuple[str, ...] = (), centre: np.ndarray | None = None,
          local_checks: dict[str, Callable[[np.ndarray], np.ndarray]] | None = None,
          temporal: tuple[str, ...] = (),
          validate_ends: bool | tuple[bool, bool] = True
          ) -> tuple[np.ndarray, BlendReport]:
    """Fill every interior gap with a validated convex blend of the candidate fills.

    Parameters
    ----------
    matrix, observed
        The unit-RMS matrix and its mask (solver convention).
    candidates
        name → fill function; each returns a full matrix, read on the gaps only. The
        fills should meet the observed samples continuously at the gap ends (the blend
        adds no ramp of its own); the default's TSMC candidate on scattered loss is the
        one that does not (see :func:`mocapfill.solvers.tsmc.gap_fill`).
    default
        Candidate used alone for length classes with no validation evidence at all.
    prior, prior_share
        Weights (name → weight) mixed in with share ``prior_share`` on gaps of at least
        ``MIN_MODEL_GAP`` frames. Validation hides extra data, which handicaps the global
        candidates (their evidence is the whole clip) more than the local ones; on long
        real gaps the validated weights alone were measured to over-trust local fills.
    seed
        Seed of the pseudo-gap placement (the fill is deterministic for a given seed).
    validation_fraction
        Largest share of the observed samples hidden for validation.
    validation
        Evidence gathered on another clip with the same candidates (usually the
        neighbouring windows of a long clip, :meth:`Validation.pooled`): no stand-ins are
        hidden and the candidates run once, on the real mask. Without it the clip
        validates itself, which runs every candidate twice (but those run ``once``).
    costly
        Names of the slowest candidates, whose runs start first, in this order, before
        the others (scheduling only: the fill does not depend on it).
    optional
        Names of candidates not run on the real mask when the weights give them no weight
        on any gap (on a clip validating itself, their runs there wait for the
        validation). Such a candidate also drops out of the panel of the outlier rule,
        and if it is the ``default``, the end gaps take the fill of the candidate run with
        the most weight over the gaps. For the windows of long clips, where the costly
        candidates often get no weight at all.
    validators
        name → a cheaper form of that candidate, run in its place on the validation mask
        only (the windows of long clips: TrNN to a looser tolerance).
    once
        Names of candidates run once, on the validation mask, where the clip validates
        itself: that run is scored on the stand-ins, and its fill, joined to the real
        gaps' ends (:func:`join_ends`: where a stand-in took in a real gap's neighbour),
        is the candidate's fill of the real gaps too. The fill then comes from a clip with
        the stand-ins' samples hidden as well (at most ``validation_fraction``); for a
        global model such as TrNN that is a small share of its evidence, and its second
        run was the costliest of the blend's (see :func:`mocapfill.solvers.trnn.complete`).
        An end gap's own-marker stand-in (:func:`end_stand_ins`) lengthens the end gap in
        that run, so the fill of the real end gap comes from twice its length: running
        TrNN on the real mask as well did not help (the end-gap cases of
        docs/results.md, thirty-sixth session, with an own-marker stand-in on every end
        gap: 77.9 → 76.8 mm on seeds 1–2, 105.5 → 110.5 on seeds 6–8). Not with
        ``validators`` or ``optional`` for the same name.
    centre
        (rows,) where each row's zero lies in the clip's units over the scale (the
        pipeline's row-wise centring, :class:`mocapfill.scaling.UnitScale`): the
        rigid-partner check adds it back to measure true distances between markers
        (without it, those of ``matrix`` as it is).
    local_checks
        name → a function of gaps' spans (gaps, 3) giving that candidate's RMS error per
        sample when its fill of each gap is tried beside the gap, on the real mask
        (:func:`rigid_local_errors`): its weight on each long gap is scaled by how that
        compares with its error on the stand-ins (:func:`_locally_checked`). Run beside
        the candidates (it needs none of them).
    temporal
        Names of candidates that fill a row from its own samples along time: a gap in
        frames where nothing at all is observed (a dropped frame) is theirs alone
        (:func:`_blind_gaps_temporal`). The default gives the cubic spline, what Vicon's
        and QTM's polynomial fills do there: on that smooth clip with 0.3 mm of noise the
        spline erred 0.89 mm (3-D) on the dropped frames, the three splines in their
        class weights' proportions 1.20 mm (TrNN, which had 0.73 there, is the one that
        failed without noise).

    validate_ends
        Whether the gaps touching the clip's ends get stand-ins of their own
        (:func:`end_stand_ins`, where the clip validates itself and no candidate is
        ``optional``): their fills then blend the candidates in the weights those earn.
        False where the end gaps' fills will not be used (the pipeline's ``--ends leave``
        and ``hold``): the stand-ins hide data the interior gaps' fills use (walkl,
        repaired so: 1.9819 → 1.9891 mm). A pair (start, end) says which of the matrix's
        two ends are the clip's (a window of a long clip holds one or neither): only
        the gaps touching those get stand-ins.

    Returns
    -------
    completed, BlendReport
        Gaps touching the clip ends take the ``default`` candidate's fill, or with
        ``validate_ends`` the blend their stand-ins weigh (the default's where there are
        none).
    """
    names = tuple(candidates)
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    rng = np.random.default_rng(seed)
    if validation is not None and validation.names != names:
        raise ValueError(f"validation of candidates {validation.names}, not {names}")
    if set(once) & (set(validators or ()) | set(optional)):
        raise ValueError("a candidate run once has no validator and is not optional")
    hidden = ([] if validation is not None else
              pseudo_gaps(observed, gapset, rng, fraction=validation_fraction))
    # End gaps get stand-ins of their own where the clip validates itself and every
    # candidate is run (not in the light windows of long clips; the pipeline solves the
    # windows holding the clip's ends in full where their fills are used, and says which
    # ends are the clip's: ``validate_ends``), drawn from their own generator
    # so that the interior stand-ins are those drawn without them.
    ends = (end_gaps(observed, groups, validate_ends)
            if any(end_sides(validate_ends)) and validation is None and not optional else [])

    errors: dict[int, list[Evidence]] = {}
    own: dict[int, list[Evidence]] = {}        # real gap index -> its stand-ins' evidence
    end_errors: dict[int, list[Evidence]] = {}
    if validation is not None:
        errors, own = validation.by_class, validation.by_gap
    if hidden or ends:
        train = observed.copy()
        # The global candidate leans on the complete frames (its warm start is their
        # subspace): a validation mask that destroys them would misjudge it, so stand-ins
        # that would leave fewer than half of the clip's complete frames are dropped.
        # (The complete frames are counted as stand-ins are taken, not recounted over a
        # copy of the mask for each: 0.21 s of a 12,000-frame window's 622 stand-ins.)
        complete = observed.all(axis=0)
        complete_count = int(complete.sum())
        complete_floor = max(complete_count // 2, 60)
        kept = []

        def take(span: tuple[int, int, int], source: int) -> None:
            nonlocal complete_count
            g, s, t = span
            lost = int(complete[s:t].sum())
            if complete_floor > 60 and complete_count - lost < complete_floor:
                return
            train[groups[g], s:t] = False
            complete[s:t] = False
            complete_count -= lost
            kept.append((span, source))

        for span, source in hidden:
            take(span, source)
        for span in (end_stand_ins(train, groups, ends, np.random.default_rng([seed, 1]))
                     if ends else []):
            take(span, END_SOURCE)
        hidden = kept
    first = [names.index(name) for name in costly if name in candidates]
    order = first + [i for i in range(len(names)) if i not in first]
    fills: list[np.ndarray | None] = [None] * len(names)

    def fill_job(i: int):
        return partial(candidates[names[i]], matrix, observed)

    if hidden:
        blinded = np.where(train, matrix, 0.0)
        sample_rows, sample_frames, bounds = _hidden_samples(hidden, groups, observed)
        # (an end stand-in may lengthen a real end gap: the rigid and regression fills
        # are asked for the gap that holds it)
        spans = frozenset(_gap_holding(train, groups, span) if source == END_SOURCE else span
                          for span, source in hidden)
        ran_once = {i for i in order if names[i] in once}
        trials = {i: partial(_stand_in_errors_and_fill, candidates[names[i]], blinded, train,
                             matrix, observed, gapset, sample_rows, sample_frames)
                  if i in ran_once else
                  partial(_stand_in_errors, (validators or {}).get(names[i],
                                                                  candidates[names[i]]),
                          blinded, train, matrix, sample_rows, sample_frames, spans)
                  for i in order}

    def gather(trial_errors: list[np.ndarray]) -> None:
        stacked = np.stack(trial_errors, axis=2)          # (samples, rows, candidates)
        for index, ((_, a, b), source) in enumerate(hidden):
            lo, hi = bounds[index], bounds[index + 1]
            # Samples row by row, as the (rows × frames) block of the stand-in.
            block = stacked[lo:hi].transpose(1, 0, 2).reshape(-1, len(names))
            if source == END_SOURCE:
                # (a candidate that leaves an end gap open there gets no weight)
                block = np.where(np.isfinite(block), block, UNFILLED_ERROR)
                end_errors.setdefault(length_class(b - a), []).append(evidence(block))
                continue
            block = evidence(block)
            errors.setdefault(length_class(b - a), []).append(block)
            own.setdefault(source, []).append(block)

    # Every candidate but those run ``once`` runs twice, on the validation mask and on the
    # real one; the runs are independent, so they share the cores: each candidate's two
    # runs side by side, the ``costly`` candidates first, so that no core is left alone
    # with a long run at the end. A validation run keeps only its errors on the stand-ins
    # (and, run once, its fill's values on the real missing samples), not its full fill,
    # so the validation runs may go to a process of their own (``apart``, where the
    # process may fork: no thread waits for the interpreter's lock on the other's behalf).
    # The ``optional`` candidates' fills wait for the weights, which need the validation.
    # The rigid-partner check's distance bands need no candidate: made beside them.
    centre = None if centre is None else np.asarray(centre, dtype=np.float64)
    # So are the local checks' errors beside the long gaps.
    checks = {names.index(name): check for name, check in (local_checks or {}).items()
              if name in names}
    context = {"bands": partial(_partner_bands, matrix, observed, gapset, centre)}
    if checks:
        context["checks"] = partial(_local_errors, checks, gapset)
    made: dict = {}
    if hidden:
        keys = [(kind, i) for i in order for kind in ("trial", "fill")
                if kind == "trial" or (names[i] not in optional and i not in ran_once)]
        keys += [(kind, -1) for kind in context]
        done = dict(zip(keys, run_all([trials[i] if kind == "trial" else
                                       fill_job(i) if kind == "fill" else context[kind]
                                       for kind, i in keys],
                                      apart=[k for k, (kind, _) in enumerate(keys)
                                             if kind == "trial"])))
        made = {kind: done.pop((kind, -1)) for kind in context}
        for i in range(len(names)):
            fills[i] = done.get(("fill", i))
            if i in ran_once:
                done[("trial", i)], missing_values = done[("trial", i)]
                fills[i] = matrix.copy()
                fills[i][~observed] = missing_values
        gather([done[("trial", i)] for i in range(len(names))])
    weights = blend_weights(errors, rng)
    gap_weights = _gap_weights(gapset, weights, own, names, default, rng, prior, prior_share)
    gap_weights = _blind_gaps_temporal(gap_weights, gapset, observed,
                                       [names.index(name) for name in temporal if name in names])
    # Over the distinct weight vectors (gaps of one length class share one array).
    distinct = {id(w): w for w in gap_weights}.values()
    used = np.any([w > 0 for w in distinct], axis=0) if gap_weights else \
        np.zeros(len(names), dtype=bool)
    later = [i for i in order if fills[i] is None and (names[i] not in optional or used[i])]
    if all(fill is None for fill in fills) and not later:
        later = [names.index(default)]
    missing = [kind for kind in context if kind not in made]
    late = run_all([fill_job(i) for i in later] + [context[kind] for kind in missing])
    made.update(zip(missing, late[len(later):]))
    for i, fill in zip(later, late):
        fills[i] = fill
    bands = made["bands"]
    # (It scales weights, and leaves those at zero there: ``used``.)
    gap_weights = _locally_checked(gap_weights, gapset, errors, made.get("checks", {}), own)
    ran = [i for i in range(len(names)) if fills[i] is not None]

    # The default's fill takes the end gaps; where it was not run (``optional``), that of
    # the candidate with the most weight over the gaps.
    base = names.index(default)
    if fills[base] is None:
        total = np.sum(gap_weights, axis=0) if gap_weights else np.zeros(len(names))
        base = max(ran, key=lambda i: total[i])
    out = np.where(observed, matrix, fills[base])
    if end_errors:
        _blend_end_gaps(out, fills, ends, groups,
                        blend_weights(end_errors, np.random.default_rng([seed, 2])))
    # The gaps as one (gaps, 3) array and their weights as one (gaps, k) array, not a
    # Python loop over them: random loss gives tens of thousands of gaps (85_12 at
    # mr = 0.6: 44,000).
    spans, lengths = gapset.spans, gapset.lengths
    weight_rows = np.array(gap_weights, dtype=np.float64).reshape(-1, len(names))
    present = np.bincount(lengths, minlength=MIN_MODEL_GAP)[MIN_MODEL_GAP:]
    seen_before = _seen_before(observed) if bands else None
    for length in (np.flatnonzero(present) + MIN_MODEL_GAP).tolist():
        indices = np.flatnonzero(lengths == length)
        g, a = spans[indices, 0], spans[indices, 1]
        rows = groups[g][:, :, None]                                 # (gaps, rows, 1)
        frames = (a[:, None] + np.arange(length))[:, None, :]        # (gaps, 1, length)
        segments = np.stack([fills[i][rows, frames] for i in ran], axis=1)
        kept = _without_outliers(weight_rows[np.ix_(indices, ran)], segments,
                                 factor=outlier_factor(length))
        if bands:
            off = _rigid_partner_violations(matrix, centre, seen_before, groups,
                                            spans[indices],
                                            segments if centre is None else
                                            segments + centre[rows][:, None], bands)
            inside = np.where(off, 0.0, kept)
            total = inside.sum(axis=1, keepdims=True)
            kept = np.where(total > 0, inside / np.where(total > 0, total, 1.0), kept)
        weight_rows[indices] = 0.0
        weight_rows[np.ix_(indices, ran)] = kept
    # Gaps sharing one weight vector are blended together (random loss gives tens of
    # thousands of gaps, most of them sharing their length class's weights): the rows
    # sorted, and each run of equal rows taken at once.
    order = np.lexsort(weight_rows.T)
    ordered = weight_rows[order]
    starts = np.flatnonzero(np.r_[order.size > 0, (ordered[1:] != ordered[:-1]).any(axis=1)])
    for lo, hi in zip(starts.tolist(), np.r_[starts[1:], order.size].tolist()):
        g, a, b = spans[np.sort(order[lo:hi])].T
        run, frames = gap_frames(a, b)
        rows, frames = groups[g][run], frames[:, None]
        out[rows, frames] = sum(wk * f[rows, frames]
                                for wk, f in zip(ordered[lo], fills) if wk > 0)
    return out, BlendReport(names, weights, len(hidden),
                            validation or Validation(names, errors, own))
