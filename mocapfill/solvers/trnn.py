"""Truncated-nuclear-norm completion (TrNN) of motion-capture matrices.

Hu, Wang, Liu, Yang, Yu & Zhang, "Motion Capture Data Completion via Truncated Nuclear Norm
Regularization", IEEE Signal Processing Letters 25(2), 2018. The model and every update
step follow ``shared/docs/MODEL.md`` (the reconstruction of the paper's Section II):

    min ‖X‖_r + λ‖P_Ω(S)‖₁ + (μ/2)‖X Tᵀ‖_F²   s.t.  P_Ω(D) = X + S

solved by an augmented-Lagrangian iteration on the split form with X = L Rᵀ, an auxiliary
M = L Rᵀ that carries the temporal term (solved in the DCT-II basis that diagonalises TᵀT),
and U, V whose rows span the top-r singular subspaces (Lemma 3).

Two entry points behind the common solver signature:

- :func:`complete_paper` (``--method trnn-paper``): the algorithm with the paper's mocap
  settings (λ = 100/√max(m,n), μ = 100, ρ = 1.4, η₀ = 1e−5, ε = 1e−4, r = min(15, r̃)),
  started from linear interpolation as the prototype did.
- :func:`complete` (``--method trnn``, the default): the same iteration with the changes
  our measurements called for (see ``docs/results.md``): a low-rank warm start, slower
  penalty growth and a tighter tolerance so it stops converged, fills that join the
  observed samples at both ends of every gap, and a per-gap blend with local fillers
  whose weights are validated on the clip itself (:mod:`mocapfill.solvers.gapwise`).
- :func:`complete_lowrank`: the TrNN part of the default alone.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ._linalg import (
    iteration_dtype,
    linear_fill,
    padded_to_fast_length,
    temporal_solve,
    times_spd_inverse,
)

if TYPE_CHECKING:
    from .gapwise import Validation


@dataclass
class TrnnResult:
    """Outcome of :func:`trnn`.

    Attributes
    ----------
    X
        The low-rank estimate L Rᵀ (m × n).
    S
        The sparse part (outliers on Ω, the residual off Ω).
    iterations
        Iterations run.
    converged
        Whether both stopping criteria were met before ``max_iter``.
    """

    X: np.ndarray
    S: np.ndarray
    iterations: int
    converged: bool


def _orthonormal_maximiser(G: np.ndarray) -> np.ndarray:
    """argmax tr(U G) over U with U Uᵀ = I (Lemma 3): U = Q Pᵀ from G = P Σ Qᵀ.

    G is tall (m × r or n × r, r the truncation rank), and Q Pᵀ = Q Σ⁻¹ Qᵀ Gᵀ is the
    transposed polar factor of G, computed here from the eigendecomposition of the r × r
    Gram matrix GᵀG = Q Σ² Qᵀ in float64: for the n × r argument of the V step on
    123 × 4500 this costs about 0.1 ms where LAPACK's SVD of G took 2–3 ms, an eighth
    of an iteration. Where G is too ill-conditioned for the squared singular values
    (σ_min² below 1e−10 σ_max²) the SVD is used as before.
    """
    G64 = G.astype(np.float64)
    values, Q = np.linalg.eigh(G64.T @ G64)
    if values[0] > 1e-10 * values[-1] > 0:
        return ((Q / np.sqrt(values)) @ (Q.T @ G64.T)).astype(G.dtype)
    P, _, Qt = np.linalg.svd(G, full_matrices=False)
    return Qt.T @ P.T


def _wide_svd(X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The thin SVD of a wide X (m ≤ n) from the eigendecomposition of the m × m X Xᵀ.

    About 10× cheaper than LAPACK's SVD for mocap shapes (123 × 4500). Right vectors
    beyond the truncation rank are only used scaled by √σ (the factor R), which stays
    accurate even where σ is too small for the vector itself to be; the float32 fast path
    uses it.
    """
    values, vectors = np.linalg.eigh(X @ X.T)
    order = np.argsort(values)[::-1]
    values = np.clip(values[order], 0.0, None)
    U = vectors[:, order]
    sv = np.sqrt(values)
    projections = U.T @ X                                      # rows: σᵢ vᵢᵀ
    safe = np.where(sv > 0, sv, 1.0)
    Vt = projections / safe[:, None]
    return U, sv, Vt


def trnn(D: np.ndarray, observed: np.ndarray, *, rank: int, d: int | None = None,
         lam: float | None = None, mu: float = 100.0, rho: float = 1.4, eta0: float = 1e-5,
         eta_max: float = 1e10, tol: float = 1e-4, max_iter: int = 500,
         X0: np.ndarray | None = None, dtype: type = np.float64) -> TrnnResult:
    """Run Algorithm 1 of the paper on a matrix with missing entries.

    Parameters
    ----------
    D
        (m, n) data; entries off ``observed`` are ignored.
    observed
        (m, n) bool, the set Ω. All True with ``mu=0`` gives TrNN-RPCA.
    rank
        r, the number of singular values left out of the truncated nuclear norm.
    d
        Width of the factors L (m × d) and R (n × d); default min(m, n), so the
        factorisation imposes no rank bound of its own (the identity behind the split
        form needs d ≥ rank X).
    lam
        λ, weight of the ℓ₁ term on Ω; default 1/√max(m, n).
    mu
        μ, weight of the temporal second-difference term; 0 disables it.
    rho, eta0, eta_max
        Penalty schedule η ← min(ρη, η_max) starting from η₀.
    tol
        ε of both stopping criteria (relative constraint violation, relative change of X).
    max_iter
        Iteration cap.
    X0
        Starting estimate; default linear interpolation of each row along time.
    dtype
        Floating type of the iteration: float64 (MODEL.md) or float32, which halves the
        memory traffic and the cost of the products and DCTs (the default ``trnn`` method
        uses it; its fills were measured as accurate as float64's). X and S come back
        float64 either way.

    Returns
    -------
    TrnnResult
    """
    D = np.asarray(D, dtype=np.float64)
    observed = np.asarray(observed, dtype=bool)
    m, n = D.shape
    if not 0 < rank <= min(m, n):
        raise ValueError(f"rank must be in 1..{min(m, n)}, got {rank}")
    d = min(m, n) if d is None else int(d)
    if not rank <= d <= min(m, n):
        raise ValueError(f"d must be in {rank}..{min(m, n)}, got {d}")
    lam = 1.0 / np.sqrt(max(m, n)) if lam is None else float(lam)

    dtype = iteration_dtype(dtype)
    PD = np.where(observed, D, 0.0)
    norm_PD = np.linalg.norm(PD) or 1.0
    X = linear_fill(D, observed) if X0 is None else np.asarray(X0, dtype=np.float64)
    del X0          # read, never written: a caller that hands it over may see it freed

    # Initialisation chosen by the prototype (MODEL.md): factors from the SVD of X₀.
    if dtype == np.float32 and m <= n:
        Us, sv, Vts = _wide_svd(X)
    else:
        Us, sv, Vts = np.linalg.svd(X, full_matrices=False)
    root = np.sqrt(sv[:d])
    L = (Us[:, :d] * root).astype(dtype)
    R = (Vts[:d].T * root).astype(dtype)
    U = Us[:, :rank].T.astype(dtype)        # r × m
    PD = PD.astype(dtype)
    omega = observed.astype(dtype)
    # V (r × n) lives below X in one (m + r) × n array and is copied below W in another,
    # so that X with V, and W R with V R, and Wᵀ(ηK) + Vᵀ(U K) are one matrix product
    # each instead of a large and a skinny one (the skinny ones ran at a third of the
    # large ones' rate). XV alternates with a spare: X_prev stays readable.
    XV, XV_spare, WV = (np.empty((m + rank, n), dtype=dtype) for _ in range(3))
    XV[:m] = X
    XV[m:] = Vts[:rank]
    X, V, W = XV[:m], XV[m:], WV[:m]
    del Us, sv, Vts         # the start's float64 SVD (Vts: min(m, n) × n), not needed now
    # The state is kept in a form that needs fewer passes over the m × n arrays than the
    # textbook variables (every numpy operation is a pass, and the passes were a third of
    # an iteration): P = PD − S in place of S, and Y₂ as η_C·C, where C is the clipped
    # P_Ω(...) of the S step and η_C the η it was made with. S starts at PD − X₀, Y₁ and
    # Y₂ at 0.
    P = X.copy()
    M = X.copy()
    C = np.zeros_like(X)
    eta_C = 1.0
    Y1 = np.zeros_like(X)
    eta = float(eta0)
    # y ← a·x + y in one pass (BLAS axpy on the flat views of contiguous arrays).
    from ._compiled import blas

    axpy = blas("axpy", X)
    T, C_spare = np.empty_like(X), np.empty_like(X)
    stacked = np.empty((m + rank, d), dtype=dtype)
    RtR = R.T @ R

    def penalised(gram: np.ndarray, e: np.floating) -> np.ndarray:     # I + 2η·gram
        A = gram * (2 * e)
        A.flat[::d + 1] += 1
        return A

    converged = False
    iterations = 0
    for iteration in range(1, max_iter + 1):
        iterations = iteration              # (ruff B007: the loop variable is read after)
        X_prev = X
        e = dtype.type(eta)                 # keeps float32 products float32
        # W = M + PD − S + (Y₁ + Y₂)/η = M + P + Y₁/η + (η_C/η)·C
        np.add(M, P, out=W)
        axpy(Y1.ravel(), W.ravel(), a=1.0 / eta)
        axpy(C.ravel(), W.ravel(), a=eta_C / eta)
        WV[m:] = V
        # (10) L then R, each a d×d SPD system; Uᵀ(V R) avoids forming the m×n UᵀV. The
        # R step is (ηWᵀL + Vᵀ(U L))A⁻¹ = Wᵀ(ηK) + Vᵀ(U K) with K = L A⁻¹ (m × d): the
        # n × d × d product with A⁻¹ becomes an m × d × d one.
        WVR = WV @ R                                            # [W R; V R]
        L = times_spd_inverse(e * WVR[:m] + U.T @ WVR[m:], penalised(RtR, e))
        LtL = L.T @ L
        K = times_spd_inverse(L, penalised(LtL, e))
        np.multiply(K, e, out=stacked[:m])
        np.matmul(U, K, out=stacked[m:])
        R = WV.T @ stacked                                      # Wᵀ(ηK) + Vᵀ(U K)
        RtR = R.T @ R
        # (13) U, V by Lemma 3, from the new L and R (the S and M steps below do not use
        # them), V using the new U. V's argument G = R (U L)ᵀ is n × r, but its Gram
        # matrix is (U L) RᵀR (U L)ᵀ and the maximiser Q Σ⁻¹ Qᵀ Gᵀ = [Q Σ⁻¹ Qᵀ (U L)] Rᵀ,
        # an r × d matrix times Rᵀ: computed with X = L Rᵀ as one product.
        U = _orthonormal_maximiser(L @ (V @ R).T)
        UL = (U @ L).astype(np.float64)
        values, Q = np.linalg.eigh(UL @ RtR.astype(np.float64) @ UL.T)
        XV, XV_spare = XV_spare, XV
        # RᵀR is float32 here: its rounding (1e−7 of the largest σ²) must stay far below
        # the smallest σ² (measured: σ²_r/σ²_1 ≥ 8e−4 on the CMU clips).
        if values[0] > 1e-6 * values[-1] > 0:
            stacked_V = ((Q / np.sqrt(values)) @ Q.T @ UL).astype(dtype)
            np.matmul(np.concatenate([L, stacked_V]), R.T, out=XV)
        else:
            np.matmul(L, R.T, out=XV[:m])
            XV[m:] = _orthonormal_maximiser(R @ UL.T.astype(dtype))
        X, V = XV[:m], XV[m:]
        np.subtract(X, X_prev, out=T)
        # ‖X‖² = tr(LᵀL RᵀR), from the two d × d Gram matrices instead of a pass over X.
        norm_X = np.sqrt(max(float(np.vdot(LtL, RtR)), 0.0))
        change = np.linalg.norm(T) / (norm_X or 1.0)
        # (11a) S: soft threshold on Ω, free off Ω. With T = PD − X + Y₂/η and
        # C' = P_Ω(clip(T, ±λ/η)), S = T − C', the residual PD − X − S is C' − Y₂/η and
        # the multiplier update Y₂ + η(PD − X − S) is η·C'.
        np.subtract(PD, X, out=T)
        axpy(C.ravel(), T.ravel(), a=eta_C / eta)
        C_new = np.clip(T, -lam / eta, lam / eta, out=C_spare)
        C_new *= omega
        residual_norm = np.inf
        if change <= tol:                   # the other criterion, only when it can matter
            np.multiply(C, eta_C / eta, out=W)
            np.subtract(C_new, W, out=W)
            residual_norm = np.linalg.norm(W)
        np.subtract(PD, T, out=P)           # PD − S = PD − T + C'
        P += C_new
        C_spare, C, eta_C = C, C_new, eta
        # (11b) M: (ηX − Y₁)(ηI + μTᵀT)⁻¹ through the DCT.
        np.multiply(X, e, out=W)
        W -= Y1
        if mu > 0:
            M = temporal_solve(W, eta, mu)
        else:
            np.divide(W, e, out=M)
        # Y₁ ← Y₁ + η(M − X) with the η of this iteration, then the schedule.
        np.subtract(M, X, out=T)
        axpy(T.ravel(), Y1.ravel(), a=eta)
        eta = min(rho * eta, eta_max)
        if residual_norm / norm_PD <= tol and change <= tol:
            converged = True
            break
    S = np.subtract(PD, P, out=P)
    return TrnnResult(X=X.astype(np.float64), S=S.astype(np.float64), iterations=iterations,
                      converged=converged)


def paper_rank(matrix: np.ndarray, observed: np.ndarray, rank: int | None) -> int:
    """r = min(15, r̃) with r̃ the unit-invariant rank estimate, unless given."""
    if rank is not None:
        return int(rank)
    from ..rank import estimate_rank

    return max(1, min(15, estimate_rank(matrix, observed, exact=False).rank))


def complete_paper(matrix: np.ndarray, observed: np.ndarray, *, rank: int | None = None,
                   d: int | None = None, lam: float | None = None, mu: float = 100.0,
                   rho: float = 1.4, eta0: float = 1e-5, eta_max: float = 1e10,
                   tol: float = 1e-4, max_iter: int = 500, **_shared) -> np.ndarray:
    """TrNN exactly as published, with the paper's mocap settings as defaults.

    λ defaults to 100/√max(m, n) (Sec. III-B); see :func:`trnn` for the others.
    """
    m, n = matrix.shape
    lam = 100.0 / np.sqrt(max(m, n)) if lam is None else lam
    result = trnn(matrix, observed, rank=paper_rank(matrix, observed, rank), d=d, lam=lam,
                  mu=mu, rho=rho, eta0=eta0, eta_max=eta_max, tol=tol, max_iter=max_iter)
    return result.X


# ε of :func:`complete_lowrank` (see its notes).
LOWRANK_TOL = 1e-4

# PCA models per gapped marker in the default's PCA candidate (``pca.complete``'s
# ``max_models``), on a clip repaired whole and in the windows of a long clip. In the
# windows of the bench's 30-minute synthetic clip (every marker gapped, the gaps
# overlapping in many combinations) PCA spent the whole budget on every marker and took
# over a quarter of a validating window's time; with 4 models instead of 8 its runs there take
# 1.1–1.3 s instead of 1.8–2.5 s, and the repairs' errors stay the same: the synthetic
# clip 2.7351 mm either way, the real 41,958-frame clip 12.1717 / 11.6758 → 12.1723 /
# 11.6752 mm (seeds 0 / 1), a real 111,788-frame one 12.0187 → 12.0162 mm. Clips
# repaired whole keep 8 (the accuracy tables' setting).
PCA_MODELS = 8
WINDOW_PCA_MODELS = 4

# The PCA candidate is offered on clips with 60 complete frames or more (counted with the
# short gaps filled), and on the others where its models are few: at most this many
# distinct sets of visible markers over the missing frames of the gapped markers (its
# predictor searches and models are per such set; 0.1–0.35 ms each, measured). Offered so
# on the replay of 1,557 hidden gaps on 18 real clips (docs/results.md, thirtieth
# session): JA1Gait35 (324 frames, 53 markers, 94 sets, 0.06 s per run) 8.92 → 5.46 mm
# mean error, its catastrophic fills 5 → 0; the OptiTrack racing clip (574 sets)
# 2.85 → 2.46 mm; nothing else moved. Left out: random loss (the bench's mr = 0.6 cells,
# 4,966–16,019 sets, 0.7–3.9 s per run, their fills moved by 0.002 mm at most), a
# 48-marker clip whose markers all come and go (ktk-duplicate_labels, 2,730 sets: its
# repair 0.61 → 1.04 s), the bench's 300-marker clip.
PCA_PATTERNS_WITHOUT_COMPLETE = 1000


def pca_offered(observed: np.ndarray, groups: np.ndarray) -> bool:
    """Whether the default's blend runs the PCA candidate on this mask of markers
    (``groups``: :func:`~mocapfill.solvers.gapwise.row_groups`, three rows each): with 60
    complete frames or more, counted with the gaps under ``MIN_MODEL_GAP`` frames filled
    (flicker leaves none otherwise), where it is cheap; otherwise where it has at most
    :data:`PCA_PATTERNS_WITHOUT_COMPLETE` sets of visible markers to model."""
    from .gapwise import MIN_MODEL_GAP, held_short_runs
    from .pca import _patterns

    held = held_short_runs(observed, groups, MIN_MODEL_GAP, ends=False)
    if held.all(axis=0).sum() >= 60:
        return True
    seen = held[groups[:, 0]]                                   # (markers, frames)
    patterns = 0
    for i in np.flatnonzero(seen.any(axis=1) & ~seen.all(axis=1)):
        # (marker i's own row, unseen on those frames, adds no set)
        patterns += len(_patterns(seen[:, ~seen[i]])[0])
        if patterns > PCA_PATTERNS_WITHOUT_COMPLETE:
            return False
    return True


# The order in which the blend starts its candidates' runs (``blend``'s ``costly``): the
# longest first, as measured on the benchmark's and the shared data's clips, so that
# neither core is left alone with a long run at the end. The Gaussian EM costs most where
# occlusions overlap in many patterns: on real clips with hundreds of gaps its validation
# run (0.3–0.9 s, twice its fill's) came last and ran alone for 0.2–0.55 s.
RUN_ORDER = ("trnn", "gaussian", "tsmc", "pca", "regression", "rigid", "rigid6")


def complete_lowrank(matrix: np.ndarray, observed: np.ndarray, *, rank: int | None = None,
                     d: int | None = None, lam: float | None = None, mu: float = 100.0,
                     rho: float = 1.2, eta0: float = 0.05, eta_max: float = 1e10,
                     tol: float = LOWRANK_TOL, max_iter: int = 500, dtype: type = np.float32,
                     **_shared) -> np.ndarray:
    """TrNN converged from a low-rank warm start, its fill joined to the gap ends.

    The global low-rank candidate of :func:`complete`: the warm start of
    :func:`~mocapfill.solvers.lowrank.low_rank_start` (subspace of the complete frames and
    per-frame least squares, or alternating least squares), then Algorithm 1 with d = m,
    ρ = 1.2, η₀ = 0.05, ε = 1e−4 in float32, then the linear ramp that makes the fill
    meet the observed samples on both sides of every interior gap.

    η₀ (3-D error of this fill alone, mean over WalkL_0001–0010): 1e−2 2.67 mm, 0.03 2.34,
    0.05 2.31, 0.1 2.54 (WalkL_0005 alone: 2.90, 2.46, 2.53, 4.50), 1 6.43; larger η₀ also
    takes fewer iterations. float32 gives the same fills as float64 to within the spread
    of the iteration (η₀ = 0.1: WalkL_0005 4.498 vs 4.483 mm; 85_12 ml=40 9.6 vs 11.2 mm)
    at about 60 % of the time per iteration.

    ε: MODEL.md's ρ = 1.2 came with ε = 1e−5. From this warm start, at ρ = 1.2, ε = 1e−4
    stops with the same fills (this candidate alone, mean over WalkL_0001–0010: 2.3117
    against 2.3116 mm; seed 1 of the CMU ml = 20/40/60 cells within 0.04 mm, either way)
    in 13–29 % fewer iterations (85_12: 48 → 34); 3e−4 began to move the random-loss
    cells of the default (02_05 mr = 0.2: 0.347 → 0.351 mm).
    """
    from .gapwise import GapSet, interior_gaps, join_ends, row_groups
    from .lowrank import low_rank_start

    m, n = matrix.shape
    matrix = np.where(observed, matrix, 0.0)
    lam = 100.0 / np.sqrt(max(m, n)) if lam is None else lam
    r = paper_rank(matrix, observed, rank)
    # Solved on a few extra, wholly unobserved frames up to the DCT's next fast length.
    big, seen = padded_to_fast_length(matrix, observed)
    # The warm start is handed over unnamed, so that trnn can let it go once its float32
    # state is made (a full float64 matrix, 72 MB on 300 markers × 10,000 frames, held
    # through every iteration before; CPython 3.11 and later pass a Python function its
    # arguments' references, older ones keep them to the end of the call).
    result = trnn(big, seen, rank=r, d=d, lam=lam, mu=mu, rho=rho, eta0=eta0,
                  eta_max=eta_max, tol=tol, max_iter=max_iter,
                  X0=low_rank_start(big, seen, rank=r), dtype=dtype)
    groups = row_groups(observed)
    return join_ends(result.X[:, :n], matrix, observed,
                     GapSet(groups, interior_gaps(observed, groups)))


def complete(matrix: np.ndarray, observed: np.ndarray, *, seed: int = 0,
             validation_fraction: float = 0.1, **trnn_options) -> np.ndarray:
    """Our TrNN: the converged low-rank fill, blended gap by gap with other fillers.

    Design (full tables in ``docs/results.md``). Candidate fills, each continuous with the
    observed samples at both ends of every gap (all but ``tsmc``, see below):

    - ``trnn``: :func:`complete_lowrank` — warm start from the subspace of the complete
      frames (ALS without them), Algorithm 1 converged (d = m, ρ = 1.2, η₀ = 0.05,
      ε = 1e−4, float32), plus the end ramp. Alone: 1.7–3.7 mm on WalkL_0001–0010, mean
      2.3 (pca 2.1–6.1, mean 3.5).
    - ``spline``, ``quintic``, ``septic``: interpolating splines of degree 3, 5, 7 along
      time. Measured on 85_02 (smooth, 120 Hz): degree 5 halves the cubic's error at
      mr = 0.4 (0.077 vs 0.156 mm) and degree 7 cuts it 5× at ml = 20; on 02_05 both
      are worse than the cubic. Only validation can tell which clip is which.
    - ``regression``: local ridge regression on the markers visible during the gap.
    - ``rigid``: rigid-body motion of the three most rigidly attached visible markers
      (24 mm on 85_02 at ml = 40, where TrNN gives 60 and pca 22), fitted on the true
      positions (the pipeline's row centres added back: ``centre``).
    - ``rigid6``: the same with the six most rigidly attached, each weighted by the
      inverse variance of its distance to the marker. Alone in place of ``rigid``, four
      to twelve donors helped the long gaps of 85_02 and hurt those of 85_12 and 10_01;
      both forms side by side (thirty-second session, docs/results.md): CMU mean 3.19 →
      2.73 mm (85_02 ml = 40 15.2 → 10.2), walkl 1.9833 → 1.9827 mm, the replay's
      catastrophic fills 15 → 10 of 1,557.
    - On each gap of 5 frames or more, the two rigid fills' weights are scaled by how the
      fill fares beside the gap with the gap's own donors (:data:`~.gapwise.LOCAL_CLIP`,
      :func:`~.gapwise.rigid_local_errors`): the stand-ins cannot show that a real gap
      lost its rigid neighbours with it (thirty-third session: the replay's catastrophic
      fills 10 → 7 of 1,557, mean 3.924 → 3.888 mm; CMU ml cells' sum 59.75 → 58.95 mm).
      Every candidate's weight there is also scaled by how it fared on the stand-ins of
      that gap (same marker, same length; :func:`~.gapwise._locally_checked`): the class's
      weights come from all the markers, and a fast limb suits other fills than the trunk
      (thirty-fourth session: the replay's mean 3.888 → 3.862 mm, better on 15 of 18
      clips; CMU ml cells' sum 58.95 → 58.59 mm; walkl 1.9828 → 1.9819 mm).
    - ``pca``: Gløersen & Federolf (2016), where the clip has ≥ 60 complete frames (it is
      then cheap) or few models to make (:func:`pca_offered`); joined to the gap ends by
      the ramp of its offsets beside each gap (:func:`mocapfill.solvers.pca.gap_fill`).
    - ``regression``, ``rigid``, ``rigid6`` and ``pca`` see the gaps under 5 frames filled first by
      the cubic spline (:class:`~mocapfill.solvers.gapwise.ShortRunsFirst`; complete
      frames are counted so too): flicker otherwise leaves a long gap without a donor or
      predictor seen all through it, and a clip without complete frames. Long gaps
      among flickering markers (``scripts/mixed_loss.py``, CMU ml = 40 with mr = 0.05 /
      0.2): 15 of 16 better, 85_02 88 → 59 mm, 10_01 20 → 11 mm.
    - ``gaussian``: :func:`mocapfill.solvers.gaussian.gap_fill` — the conditional
      expectation under a normal law of the frames fitted by EM (60 E-steps, extrapolated
      by SQUAREM: plain EM stopped there short of its fixed point, which cost the 02_05
      ml = 60 cell), smoothed over 1.25 frames and joined to the data; the best single
      fill of the walking set's long gaps (2.00 mm against TrNN's 2.31), offered where
      one EM iteration is cheap enough.
    - Gaps touching the clip's ends (filled where ``--ends extrapolate`` asks) get stand-ins
      of their own: the gap's marker over the frames beside it, and other markers hidden at
      the same end over the same frames (:func:`~.gapwise.end_stand_ins`), whose errors
      weigh the candidates there as the interior stand-ins do theirs; an outlier fill is
      dropped (:func:`~.gapwise._blend_end_gaps`). They took the TrNN candidate's fill alone
      before, which has nothing to join at the open end (``scripts/end_gaps.py``: CMU clips
      with 5 markers hidden over their first or last 10–240 frames 13–91 mm, other markers'
      stand-ins 3.5–29 mm (thirty-fifth session), with the marker's own and the outlier
      rule 1.9–16 mm (thirty-sixth); random loss at mr = 0.6 2.1–28 → 1.9–16 → 1.9–9.0
      mm). The rigid fills carry end gaps with their donors from the one side seen
      (:func:`~.gapwise.rigid_fill`; thirty-seventh session: 1.9–9.0 → 1.2–3.6 mm on the
      random loss of 10_01, 02_05 and 85_02 at mr = 0.6, seeds 1–2). Where the end
      fills are not
      used (the pipeline's ``--ends leave`` and ``hold``: ``validate_ends=False``) nothing
      is hidden there: the stand-ins cost the interior fills data (walkl 1.9819 → 1.9891
      mm with them).
    - ``tsmc``: :func:`mocapfill.solvers.tsmc.gap_fill` — Feng et al.'s nuclear norm with
      the temporal term, to ε = 1e−4, its smooth estimate not joined to the gap ends;
      offered on scattered loss only (≥ 2 % of the samples in runs under 5 frames; real
      occlusions of whole stretches do not pay for it). On the random-loss cells of
      02_05 (mr = 0.2 / 0.4 / 0.6) it took the blend from 0.3475 / 0.4312 / 0.5690 to
      0.3402 / 0.4260 / 0.5622 mm, where TSMC alone gives 0.35 / 0.4289 / 0.58.

    The weights come from :func:`mocapfill.solvers.gapwise.blend`: observed stretches of
    the same markers with the same lengths are hidden (≤ 10 % of the samples), every
    candidate is scored there, and convex weights per gap-length class are kept when
    two-fold cross-validation shows they beat the best single candidate, that choice
    averaged over 64 bootstrap resamples of the stand-ins (on dense loss, stand-ins may
    take in real missing frames and are scored on the frames they hide); on each gap of 5
    frames or more, a candidate whose fill is an outlier among the candidates' fills
    there loses its weight (Hampel's rule on the distances from their median fill), and so
    does one that moves the marker off its most rigidly attached neighbours (the
    rigid-partner check of :mod:`.gapwise`, in true distances: the pipeline hands over
    its rows' centres as ``centre``).
    The TrNN candidate runs once, on the validation mask (``blend``'s ``once``): its fill
    of the real gaps comes from that run, which hides at most ``validation_fraction`` of
    the samples from it, and its second run was the longest job of the blend. Measured
    (``bench accuracy --methods trnn``, against two runs): walkl 1.9885 → 1.9904 mm, below
    ``pca`` on every file; CMU mean 3.8297 → 3.7955 mm, every cell still won; the
    benchmark's repairs 156 → 115 s; ``mocapfill repair`` of 85_12 ml = 40 1.41 → 1.10 s,
    85_02 0.77 → 0.63 s (medians of 7, alternated). The Gaussian and PCA candidates
    rely on the data more: run once as well, walkl 2.1954 and 1.9947 mm, CMU mean 3.853
    and 3.953 mm; they run twice.
    Things measured and rejected: validating many long stand-ins at once (the validation
    clip becomes much harder than the real one and reverses rankings), placing stand-ins
    only in clean stretches (flatters high-degree splines), per-gap weights from 2 stand-ins
    (too noisy), a pose k-NN fill (15–200 mm), a leave-marker-out low-rank prediction
    plus spline of its residual (13–75 mm on random gaps).

    Parameters
    ----------
    seed
        Seed of the validation pseudo-gaps (fixed: the repair is deterministic).
    validation_fraction
        Largest share of the observed samples hidden for validation.
    **trnn_options
        Passed to :func:`complete_lowrank` (rank, d, lam, mu, rho, eta0, tol, max_iter).
    """
    return complete_window(matrix, observed, seed=seed,
                           validation_fraction=validation_fraction, **trnn_options)[0]


def complete_window(matrix: np.ndarray, observed: np.ndarray, *,
                    borrowed: Sequence[Validation | None] = (), seed: int = 0,
                    validation_fraction: float = 0.1, skip_unweighted: bool = False,
                    **trnn_options
                    ) -> tuple[np.ndarray, Validation | None]:
    """:func:`complete` for one window of a long clip, lending or borrowing validation.

    With ``borrowed`` validations (those of neighbouring windows) whose candidates are this
    window's, their pooled evidence sets the weights and the candidates run once; with
    none that fit, the window validates itself as :func:`complete` does. With
    ``skip_unweighted`` (the pipeline's windows) no candidate but the cubic spline is run
    on the real mask where the weights give it nothing
    (:func:`~mocapfill.solvers.gapwise.blend`'s ``optional``): the spline, cheap, stays
    in the outlier rule's panel. Returns the completed window and the validation used
    (None where the window has no gap).

    Skipping only TrNN and PCA (the fourteenth session) left the quintic, septic and rigid
    fills running in every window of the bench's synthetic 216,000-frame clip, where no
    gap gives them weight. Skipping them too, measured on that clip: error against the
    generator's truth 2.7444 → 2.7351 mm (the outlier rule then judges its 16–32-frame
    gaps, the only ones blended, among Gaussian, regression and spline fills); on the
    42,000-frame real clip of CMU 85_12, 02_05 and 85_02 (every candidate weighted in
    every window) the same 12.1750 / 11.6672 mm for seeds 0 / 1.

    In those windows the validation run of TrNN also stops at ε ten times looser than the
    fill's (1e−3: about 30 instead of 51 iterations on a 12,000-frame window). Measured:
    the synthetic clip's error the same 2.7351 mm, the real clip's 12.1717 / 11.6758 mm;
    the 30-minute clip's repair 70.1–78.0 s (median 72.8) → 62.2–73.5 s (median 64.4),
    alternated, user CPU 97–103 → 81–96 s. On a clip repaired whole (the CMU and walking
    cells) nothing changes: it measured as a wobble in the random-loss cells there
    (thirteenth session, docs/results.md).
    """
    from functools import partial

    from .gapwise import (
        ShortRunsFirst,
        Validation,
        blend,
        odd_spline_fill,
        regression_fill,
        rigid_fill,
        row_groups,
    )
    from .gaussian import affordable as gaussian_affordable
    from .gaussian import gap_fill as gaussian_fill
    from .interp import spline
    from .tsmc import gap_fill as tsmc_fill
    from .tsmc import offered as tsmc_offered

    trnn_options.pop("rate", None)
    centre = trnn_options.pop("centre", None)
    validate_ends = trnn_options.pop("validate_ends", True)
    if observed.all():
        return np.array(matrix, dtype=np.float64), None
    # The per-gap models and PCA see the short gaps filled first (one spline fill for
    # the three per mask: see gapwise.ShortRunsFirst).
    short_runs_first = ShortRunsFirst()
    # In the windows of long clips (``skip_unweighted``), the validation run's TrNN stops
    # at a tolerance ten times looser than the fill's.
    loose = {**trnn_options, "tol": 10 * trnn_options.get("tol", LOWRANK_TOL)}
    candidates = {
        "trnn": lambda a, o: complete_lowrank(a, o, **trnn_options),
        "spline": spline,
        "quintic": partial(odd_spline_fill, degree=5),
        "septic": partial(odd_spline_fill, degree=7),
        "regression": short_runs_first(regression_fill),
    }
    if gaussian_affordable(observed):
        candidates["gaussian"] = gaussian_fill
    # The rigid-body and PCA fills need rows that are x, y, z of markers (one mask per
    # marker); a channel matrix or a mask split within a marker gets the other fillers.
    groups = row_groups(observed)
    markers = groups.shape[1] == 3
    # Six donors weighted by their rigidity, beside the three most rigid unweighted:
    # validation weighs them gap class by gap class (see ``complete``), and each long gap
    # by how the fill fares beside it with the gap's own donors (blend's local_checks).
    rigid_forms = {"rigid": {}, "rigid6": {"donors": 6, "weighted": True}} if markers else {}
    for name, options in rigid_forms.items():
        # (end gaps carried only where their fills are used: see rigid_fill's ``ends``)
        candidates[name] = short_runs_first(partial(rigid_fill, centre=centre,
                                                    ends=validate_ends, **options))
    if tsmc_offered(observed):
        candidates["tsmc"] = tsmc_fill
    if markers and pca_offered(observed, groups):
        # Gløersen & Federolf's PCA fill: its errors are partly independent of TrNN's.
        from .pca import gap_fill as pca

        # A budget of PCA models per marker keeps clips with gaps overlapping in many
        # combinations from costing one PCA each (validation judges what is left); the
        # windows of long clips get a smaller one (see WINDOW_PCA_MODELS).
        candidates["pca"] = short_runs_first(
            partial(pca, max_models=WINDOW_PCA_MODELS if skip_unweighted else PCA_MODELS,
                    centre=centre, ends=validate_ends))
    names = tuple(candidates)
    checks = {name: partial(_rigid_tried_beside, short_runs_first, matrix, observed,
                            centre=centre, **options)
              for name, options in rigid_forms.items()}
    # A lender with no evidence (a window without gaps, or too few for a stand-in) would
    # leave every gap to the default candidate: the window then validates itself.
    fitting = [v for v in borrowed if v is not None and v.names == names and v.by_class]
    completed, report = blend(matrix, observed, candidates, default="trnn", seed=seed,
                              validation_fraction=validation_fraction,
                              validation=Validation.pooled(fitting) if fitting else None,
                              costly=RUN_ORDER,
                              optional=tuple(n for n in names if n != "spline")
                              if skip_unweighted else (),
                              validators={"trnn": lambda a, o: complete_lowrank(a, o, **loose)}
                              if skip_unweighted else None,
                              once=() if skip_unweighted else ("trnn",), centre=centre,
                              temporal=("spline",), validate_ends=validate_ends,
                              # (not in the windows of long clips: the bench's 30-minute
                              # clip took 21.4 → 27.2 s with them, and long_clips.py 12001:0
                              # and 22001:0 moved by 0.003 mm at most)
                              local_checks=None if skip_unweighted else checks or None)
    return completed, report.validation


def _rigid_tried_beside(short_runs_first, matrix: np.ndarray, observed: np.ndarray,
                        spans: np.ndarray, **options) -> np.ndarray:
    """:func:`~mocapfill.solvers.gapwise.rigid_local_errors` of the gaps ``spans`` on the
    clip as the rigid candidates see it (its short runs filled first)."""
    from .gapwise import rigid_local_errors

    held, _, first = short_runs_first.prepared(matrix, observed)
    return rigid_local_errors(matrix if first is None else first, held, spans, **options)


complete.forwards_to = complete_lowrank     # its **trnn_options (see solvers.option_names)
complete.windowed = complete_window         # lends validation between windows (pipeline)
complete.takes_centre = True                # the pipeline passes its rows' centres (blend)
complete.validates_ends = True              # ...and validate_ends=False where ends are left
