"""Gaussian conditional fill: the clip's frames as draws of one normal law, fitted by EM.

Every frame x ∈ Rᵐ (m = 3·markers) is taken as a draw from N(μ, Σ). A missing set M of a
frame is filled with its conditional expectation given the observed set O,

    E[x_M | x_O] = μ_M + Σ_MO Σ_OO⁻¹ (x_O − μ_O) = μ_M − Λ_MM⁻¹ Λ_MO (x_O − μ_O),  Λ = Σ⁻¹,

and μ, Σ are estimated from the incomplete clip by the EM algorithm for the multivariate
normal with data missing at random (Dempster, Laird & Rubin 1977; Little & Rubin,
*Statistical Analysis with Missing Data*, 2nd ed. 2002, §11.2): the E-step fills every
frame with its conditional expectation and adds the conditional covariance Λ_MM⁻¹ to the
scatter, the M-step takes the mean and covariance of the filled frames. A ridge δ·I on Σ
(δ relative to Σ's mean variance) keeps Σ invertible when markers move together, as in
Schneider's regularised EM (J. Climate 14:853, 2001).

EM converges linearly, slowly where a marker is missing over long stretches; its steps are
extrapolated with SQUAREM (Varadhan & Roland, Scand. J. Statist. 35:335, 2008), which
reaches the same fixed point in a fraction of the E-steps (:func:`_squarem`).

The precision form needs one m × m factorisation per iteration and, per frame, a solve
with only its missing block: with z = x − μ holding any value on M,
z_M − Λ_MM⁻¹ (Λ z)_M = −Λ_MM⁻¹ Λ_MO z_O. Frames are batched by the size of their
missing set, so random occlusions (one pattern per frame) cost no Python loop per frame.

This is the model behind the PCA fills of biomechanics (Gløersen & Federolf 2016 regress
on a truncated eigenbasis of Σ) with the full covariance instead, fitted on every frame
rather than on the complete ones only. Measured (``docs/results.md``, fourth session): on
the Gløersen–Federolf walking set it fills long gaps better than TrNN (mean 3-D error 2.11
against 2.31 mm; 2.00 smoothed as in :func:`gap_fill`), on the CMU clips' 10-marker gaps
worse (85_02 ml = 40: 60 against 59 mm, 10_01 ml = 40: 17 against 7.9), so the default
blends both.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ._linalg import spd_inverse

# The Gaussian candidate is offered when one EM iteration stays within both budgets
# (multiply-adds). The missing sets: random occlusions of many markers give nearly every
# frame its own large set (85_12 at mr = 0.6 with runs under 5 frames held: 4264 sets,
# 1.1e8, 0.2 s per iteration), and there the splines win anyway. The dense part: the
# covariance and the precision products (2·m²·n), 3e7 on an 810-frame clip of 41 markers,
# 1.4e8 on 4500 frames, 300 markers over a 12000-frame window 1.6e10; and the precision,
# the covariance's inverse (m³), 1.9e6 for 41 markers but 2.7e10 for 1,000 markers, whose
# clips of 30 frames passed the products' budget (5.4e8) and spent most of their repair
# inverting 3,000 × 3,000 matrices.
MAX_SET_COST = 2e7
MAX_DENSE_COST = 1e9

# Frames whose missing blocks are gathered into one batched solve at a time (memory:
# chunk · s² floats for missing sets of size s).
_CHUNK = 1024


@dataclass(frozen=True)
class _Patterns:
    """Incomplete frames whose missing sets have one size s, grouped by missing set."""

    frames: np.ndarray      # (f,) frame indices
    which: np.ndarray       # (f,) index of each frame's missing set in ``rows``
    rows: np.ndarray        # (k, s) row indices of each distinct missing set
    counts: np.ndarray      # (k,) frames per missing set
    width: int              # m, the rows of the mask

    @cached_property
    def blocks(self) -> np.ndarray:
        """(k, s, s) flat indices i·m + j of each missing set's block in an m × m matrix,
        made at the first E-step and kept for the others: gathering the blocks and
        scattering their inverses through them took a third of the time of the inverses
        themselves (a real clip with 465 missing sets of 11 sizes)."""
        return self.rows[:, :, None] * self.width + self.rows[:, None, :]

    @cached_property
    def union(self) -> tuple[np.ndarray | None, np.ndarray]:
        """The rows missing in some of these frames (None when that is most rows) and each
        set's rows as positions in it: the E-step forms (Λz)_M from those rows of Λ only.
        Real occlusions leave a few markers missing in many combinations (11 sizes of
        missing set, each within 27–39 of 159 rows, on a squat clip); dense random
        loss misses nearly every row in some frame, where the gather would cost more than
        the rows it leaves out."""
        union = np.flatnonzero(np.bincount(self.rows.ravel(), minlength=self.width))
        if union.size > 3 * self.width // 4:
            return None, self.rows
        return union, np.searchsorted(union, self.rows)


def _missing_sets(missing: np.ndarray) -> list[_Patterns]:
    """Incomplete frames grouped by the size of their missing set, then by the set.

    Real occlusions give few distinct sets (one inverse each, shared by their frames);
    random ones give up to one per frame.
    """
    sizes = missing.sum(axis=0)
    groups = []
    # The sizes present, ascending, from a count (a plain ``np.unique`` imports numpy.ma,
    # 12–15 ms of every command's start).
    for size in np.flatnonzero(np.bincount(sizes)[1:]) + 1:
        frames = np.flatnonzero(sizes == size)
        keys = np.packbits(missing[:, frames], axis=0).T            # (f, ⌈m/8⌉)
        _, first, which, counts = np.unique(keys, axis=0, return_index=True,
                                            return_inverse=True, return_counts=True)
        rows = np.nonzero(missing[:, frames[first]].T)[1].reshape(first.size, size)
        groups.append(_Patterns(frames, which.ravel(), rows, counts, missing.shape[0]))
    return groups


def conditional_step(Z: np.ndarray, precision: np.ndarray, sets: list[_Patterns]
                     ) -> np.ndarray:
    """Replace the missing entries of the centred frames ``Z`` (in place) by their
    conditional expectation under ``precision``; returns Σ_t Λ_MM⁻¹ scattered (m × m)."""
    m = Z.shape[0]
    scatter = np.zeros((m, m))
    for group in sets:
        union, local = group.union
        rows_of_precision = precision if union is None else precision[union]
        # Λ_MM⁻¹ of every missing set: the solve and the conditional covariance at once.
        inverse = np.linalg.inv(precision.take(group.blocks))               # (k, s, s)
        scatter += np.bincount(group.blocks.ravel(),
                               (group.counts[:, None, None] * inverse).ravel(),
                               minlength=m * m).reshape(m, m)
        for lo in range(0, group.frames.size, _CHUNK):
            f = group.frames[lo:lo + _CHUNK]
            which = group.which[lo:lo + _CHUNK]
            product = rows_of_precision @ Z[:, f]
            g = np.take_along_axis(product.T, local[which], axis=1)        # (f, s) of Λz
            Z[group.rows[which].T, f] -= np.einsum("fij,fj->if", inverse[which], g)
    return scatter


@dataclass(frozen=True)
class NormalFit:
    """An EM fit: the completed frames and the normal law N(mean, precision⁻¹)."""

    filled: np.ndarray          # (m, n), the data on the observed entries
    mean: np.ndarray            # (m, 1)
    precision: np.ndarray       # (m, m)
    iterations: int


def fit_normal(matrix: np.ndarray, observed: np.ndarray, *, start: np.ndarray,
               ridge: float = 3e-6, max_iter: int = 60, tol: float = 1e-4,
               accelerate: bool = True) -> NormalFit:
    """EM fit of N(μ, Σ) to the frames, filling the missing entries with E[x_M | x_O].

    Parameters
    ----------
    matrix, observed
        The unit-RMS matrix and its mask (solver convention).
    start
        A full matrix whose values on the missing entries start the iteration (a low-rank
        fill: EM converges linearly; from a linear interpolation it needs ~100 iterations
        for what 30 give from a rank-15 start on the walking set).
    ridge
        δ: Σ + δ·mean(diag Σ)·I. Walking set, unsmoothed: 1e−4 2.29 mm (it blurs long-gap
        fills), 3e−5 2.16, 1e−5 2.12, 3e−6–1e−7 2.12–2.14.
    max_iter, tol
        At most ``max_iter`` E-steps; stop earlier when no filled entry moves by more than
        ``tol`` (unit-RMS scale) from one E-step to the next.
    accelerate
        Extrapolate the EM steps with SQUAREM (see :func:`_squarem`); False runs plain EM.
    """
    F = np.where(observed, matrix, start).astype(np.float64)
    m, n = F.shape
    # Only the incomplete frames change: the complete ones enter every M-step through
    # their sum and scatter, accumulated once (about a shift c, the start's mean, so the
    # raw moments lose no precision). On 85_12 with ten 40-frame gaps (4500 frames, 400
    # incomplete) an iteration costs a tenth of the whole-clip update.
    incomplete = np.flatnonzero(~observed.all(axis=0))
    shift = F.mean(axis=1, keepdims=True)
    fixed = np.delete(F, incomplete, axis=1) - shift
    fixed_sum = fixed.sum(axis=1, keepdims=True)
    fixed_scatter = fixed @ fixed.T
    del fixed
    missing = ~observed[:, incomplete]
    sets = _missing_sets(missing)
    # The missing entries' flat indices and rows: the E-step reads and writes those
    # entries only (boolean masks over every incomplete frame took 0.9 ms of an E-step's
    # 8–10 on a real clip).
    gone = np.flatnonzero(missing)
    gone_rows = gone // missing.shape[1]

    def m_step(FI: np.ndarray, scatter: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mean and ridged covariance of the filled frames (conditional scatter added)."""
        ZI = FI - shift
        offset = (fixed_sum + ZI.sum(axis=1, keepdims=True)) / n       # μ − c
        cov = (fixed_scatter + ZI @ ZI.T + scatter) / n - offset @ offset.T
        cov[np.diag_indices(m)] += ridge * max(float(np.trace(cov)) / m, 1e-12)
        return shift + offset, cov

    def e_step(FI: np.ndarray, mean: np.ndarray, cov: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, float]:
        """The frames filled under N(mean, cov), their conditional scatter, and how far
        the filled entries moved from ``FI``."""
        ZI = FI - mean
        before = ZI.take(gone)
        scatter = conditional_step(ZI, spd_inverse(cov), sets)
        after = ZI.take(gone)
        filled = FI.copy()              # the data exactly where seen, not x − μ + μ
        filled.flat[gone] = after + mean[gone_rows, 0]
        return filled, scatter, float(np.abs(after - before).max())

    FI = F[:, incomplete]
    mean, cov = m_step(FI, np.zeros((m, m)))
    iterations = 0
    if sets:
        run = _squarem if accelerate else _plain_em
        FI, mean, cov, iterations = run(FI, mean, cov, m_step, e_step, max_iter, tol)
    F[:, incomplete] = FI
    return NormalFit(F, mean, spd_inverse(cov), iterations)


def _plain_em(FI, mean, cov, m_step, e_step, max_iter: int, tol: float):
    """EM steps until the fills settle (or ``max_iter``): (fills, mean, cov, E-steps)."""
    for iteration in range(1, max_iter + 1):
        FI, scatter, change = e_step(FI, mean, cov)
        mean, cov = m_step(FI, scatter)
        if change <= tol:
            return FI, mean, cov, iteration
    return FI, mean, cov, max_iter


def _squarem(FI, mean, cov, m_step, e_step, max_iter: int, tol: float):
    """EM accelerated by SQUAREM (Varadhan & Roland, "Simple and globally convergent
    methods for accelerating the convergence of any EM algorithm", Scand. J. Statist.
    35:335, 2008, scheme S3): from θ₀ = (μ, Σ), two EM steps give θ₁, θ₂; with
    r = θ₁ − θ₀, v = θ₂ − θ₁ − r and α = −‖r‖/‖v‖ (at most −1), the next point is
    θ₀ − 2αr + α²v, whose EM step starts the next cycle. α is moved halfway towards −1
    (the plain second step) until the extrapolated Σ is positive definite.

    EM converges linearly, and slowly where much of a marker is missing: on 02_05 with
    60-frame gaps it needed 127–235 E-steps to settle to 1e−4, and the 60 it was allowed
    before left one elbow gap 25 mm off (the lost benchmark cell of docs/results.md,
    "Twentieth session"); SQUAREM settles there in 47–111. Returns (fills, mean, cov,
    E-steps).
    """
    evaluations = 0
    while True:
        FI, scatter, change = e_step(FI, mean, cov)
        evaluations += 1
        first = m_step(FI, scatter)
        if change <= tol or evaluations >= max_iter:
            return FI, *first, evaluations
        FI, scatter, _ = e_step(FI, *first)
        evaluations += 1
        second = m_step(FI, scatter)
        if evaluations >= max_iter:
            return FI, *second, evaluations
        r = [a - b for a, b in zip(first, (mean, cov))]
        v = [c - a - d for c, a, d in zip(second, first, r)]
        rr = sum(float(np.vdot(x, x)) for x in r)
        vv = sum(float(np.vdot(x, x)) for x in v)
        alpha = min(-np.sqrt(rr / vv), -1.0) if vv > 0 else -1.0
        if not np.isfinite(alpha):
            alpha = -1.0
        while alpha < -1.0:
            candidate = [t - 2 * alpha * a + alpha * alpha * b
                         for t, a, b in zip((mean, cov), r, v)]
            if _positive_definite(candidate[1]):
                break
            alpha = max((alpha - 1.0) / 2, -1.0) if alpha < -1.01 else -1.0
        mean, cov = candidate if alpha < -1.0 else second


def _positive_definite(cov: np.ndarray) -> bool:
    if not np.isfinite(cov).all():
        return False
    try:
        np.linalg.cholesky(cov)
    except np.linalg.LinAlgError:
        return False
    return True


def complete(matrix: np.ndarray, observed: np.ndarray, *, rank: int | None = None,
             ridge: float = 3e-6, max_iter: int = 60, tol: float = 1e-4,
             rate: float | None = None, seed: int | None = None) -> np.ndarray:
    """``--method gaussian``: the EM conditional fill from the rank-r low-rank start.

    r defaults to TrNN's, min(15, r̃) with r̃ the clip's rank estimate. No smoothing and
    no joining at the gap ends: this is the plain model (the default ``trnn`` uses the
    smoothed, joined :func:`gap_fill` as one of its candidates). ``rate`` and ``seed``
    are accepted for the common signature and unused.
    """
    from .lowrank import low_rank_start
    from .trnn import paper_rank

    matrix = np.where(observed, matrix, 0.0)
    start = low_rank_start(matrix, observed, rank=paper_rank(matrix, observed, rank))
    return fit_normal(matrix, observed, start=start, ridge=ridge, max_iter=max_iter,
                      tol=tol).filled


def _smooth(rows: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian smoothing of each row along time, edges held (``sigma`` in frames)."""
    if sigma <= 0:
        return rows
    radius = int(np.ceil(4 * sigma))
    x = np.arange(-radius, radius + 1)
    kernel = np.exp(-0.5 * (x / sigma) ** 2)
    kernel /= kernel.sum()
    padded = np.pad(rows, ((0, 0), (radius, radius)), mode="edge")
    return np.stack([np.convolve(row, kernel, mode="valid") for row in padded])


def iteration_cost(observed: np.ndarray, *, min_gap: int = 5) -> tuple[float, float]:
    """Multiply-adds of one EM iteration of :func:`gap_fill`: (missing sets, dense part:
    the m × m products and the precision's inverse)."""
    from .gapwise import held_short_runs, row_groups

    held = held_short_runs(observed, row_groups(observed), min_gap)
    m, n = observed.shape
    sets = sum(p.counts.size * p.rows.shape[1] ** 3 + p.frames.size * p.rows.shape[1] * m
               for p in _missing_sets(~held))
    return float(sets), 2.0 * m * m * n + float(m) ** 3


def affordable(observed: np.ndarray, *, min_gap: int = 5) -> bool:
    """Whether :func:`gap_fill` stays within the iteration budgets on this mask."""
    sets, dense = iteration_cost(observed, min_gap=min_gap)
    return sets <= MAX_SET_COST and dense <= MAX_DENSE_COST


def gap_fill(matrix: np.ndarray, observed: np.ndarray, *, min_gap: int = 5,
             sigma: float = 1.25, rank: int | None = None, **fit_options) -> np.ndarray:
    """The Gaussian fill as a candidate of the per-gap blend (:mod:`.gapwise`).

    - Runs shorter than ``min_gap`` frames take the cubic spline and count as observed:
      the blend fills them with splines anyway, and random occlusions would otherwise
      give every frame its own large missing set (a solve of that size per frame).
    - The conditional expectation carries the noise of every marker it is read from, and
      at the gap ends it steps from the data to a prediction. The fill is therefore
      smoothed along time (Gaussian, ``sigma`` frames), across each gap's ends into the
      observed frames beside it, and every interior gap is joined exactly to the samples
      just outside it by the linear ramp of what is left of the offsets there
      (:func:`~mocapfill.solvers.gapwise.join_ends`). Measured on the walking set (mean
      3-D error, WalkL_0001–0010): the raw fill 2.12 mm, σ = 1 2.02, σ = 1.25–1.5 2.02,
      σ = 2 2.04, σ = 4 2.63; ramping the offset between the data and the marker's
      prediction at the gap ends instead (as if it were hidden there) 2.30 — those
      offsets do not persist into the gap.
    """
    from .gapwise import GapSet, held_short_runs, interior_gaps, join_ends, row_groups
    from .interp import spline
    from .lowrank import low_rank_start
    from .trnn import paper_rank

    groups = row_groups(observed)
    held = held_short_runs(observed, groups, min_gap)
    # The spline's values are read on the held short runs only (where there are none, as
    # in clips of long gaps only, the spline is not run: 30 runs on a 30-minute clip).
    base = np.where(observed, matrix,
                    spline(matrix, observed) if (held > observed).any() else 0.0)
    if held.all():
        return base
    start = low_rank_start(base, held, rank=paper_rank(base, held, rank))
    filled = fit_normal(base, held, start=start, **fit_options).filled
    # Only the rows with gaps are read from the smoothed fill (the others are the data).
    gapped = np.flatnonzero(~held.all(axis=1))
    filled[gapped] = _smooth(filled[gapped], sigma)
    return join_ends(filled, base, held,
                     GapSet(groups, interior_gaps(held, groups)))
