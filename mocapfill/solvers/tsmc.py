"""TSMC: low-rank completion with a temporal-stability term and sparse noise.

Feng, Xiao, Zhuang, Yang, Zhang & Song (2014), "Exploiting temporal stability and low-rank
structure for motion capture data refinement", Information Sciences 277:777–793. The model::

    min_{X,S} ‖X‖_* + (μ/2)‖X Tᵀ‖_F² + λ‖P_Ω(S)‖₁   s.t.  P_Ω(D) = P_Ω(X + S)

with T the second-difference operator along time (Neumann ends, see ``_linalg``): the
nuclear norm captures the low rank of marker trajectories, the temporal term their
smoothness, and S the sparse noise/outliers on observed entries.

Solver (ours, the same augmented-Lagrangian split TrNN uses, with r = 0): an auxiliary
M = X carries the temporal term, so every step has a closed form::

    min ‖X‖_* + (μ/2)‖M Tᵀ‖² + λ‖P_Ω S‖₁  s.t.  M = X,  P_Ω D = X + S  (S free off Ω)

    X ← SVT_{1/(2η)}((M + Y₁/η + P_Ω D − S + Y₂/η) / 2)
    S ← soft_{λ/η}(P_Ω D − X + Y₂/η) on Ω,  P_Ω D − X + Y₂/η off Ω
    M ← (ηX − Y₁)(ηI + μTᵀT)⁻¹                         (DCT-II diagonalises TᵀT)
    Y₁ += η(M − X),  Y₂ += η(P_Ω D − X − S),  η ← min(ρη, η_max)

stopping when both constraint residuals and the relative change of X are ≤ tol.

Defaults (unit-RMS rows, the TrNN mocap settings of Hu et al. 2018 which extend this
model): λ = 100/√max(m, n) (in effect: observed entries are kept, S ≈ 0 unless an entry is
a gross outlier), μ = 100, ρ = 1.2, η₀ = 1e−2, tol = 1e−5. The penalty schedule is the one
our TrNN uses by default rather than the paper's ρ = 1.4, η₀ = 1e−5: the latter stops at
ε = 1e−4 far from converged (η still small), which is a property of the stopping rule,
not of the model; pass ``rho=1.4, eta0=1e-5, tol=1e-4`` to reproduce it. The iteration
starts from linear interpolation of each row (X₀), as the TrNN prototype does.
"""
from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ._linalg import (
    as_problem,
    iteration_dtype,
    linear_fill,
    padded_to_fast_length,
    svt,
    temporal_solve,
)

__all__ = ["complete"]


def complete(matrix: np.ndarray, observed: np.ndarray, *, lam: float | None = None,
             mu: float = 100.0, rho: float = 1.2, eta0: float = 1e-2,
             eta_max: float = 1e10, tol: float = 1e-5, max_iter: int = 500,
             dtype: type = np.float64, rate: float | None = None,
             seed: int | None = None) -> np.ndarray:
    """Complete ``matrix`` with the TSMC model (Feng et al. 2014); returns X.

    Parameters
    ----------
    lam
        λ, weight of ‖P_Ω S‖₁; default 100/√max(m, n).
    mu
        μ, weight of the temporal term (μ/2)‖X Tᵀ‖²; 0 gives plain nuclear-norm completion
        with sparse noise.
    rho, eta0, eta_max
        Penalty schedule η ← min(ρη, η_max) from η₀.
    tol
        Stop when ‖P_Ω D − X − S‖/‖P_Ω D‖, ‖M − X‖/‖P_Ω D‖ and ‖ΔX‖/‖X‖ are all ≤ tol.
    max_iter
        Iteration cap.
    dtype
        Floating type of the iteration, float64 or float32 (the default's candidate,
        :func:`gap_fill`); X comes back float64 either way.
    rate, seed
        Shared pipeline options, ignored.
    """
    matrix, observed = as_problem(matrix, observed)
    if mu < 0 or rho < 1 or eta0 <= 0 or not eta_max > 0:     # 1/η in every step
        raise ParameterError(f"need mu >= 0, rho >= 1, eta0 > 0, eta_max > 0; got mu={mu}, "
                             f"rho={rho}, eta0={eta0}, eta_max={eta_max}")
    dtype = iteration_dtype(dtype)
    m, n = matrix.shape
    lam = 100.0 / np.sqrt(max(m, n)) if lam is None else float(lam)
    PD = np.where(observed, matrix, 0.0)
    norm_PD = float(np.linalg.norm(PD))
    if norm_PD == 0.0:
        return np.zeros((m, n))
    # The arrays below are all of ``dtype``: numpy keeps an array's type in arithmetic
    # with Python floats.
    PD = PD.astype(dtype, copy=False)
    X = linear_fill(matrix, observed).astype(dtype, copy=False)
    M = X.copy()
    Y1 = np.zeros((m, n), dtype)
    # The state in fewer passes over the m × n arrays (as in TrNN's loop): P = PD − S, and
    # Y₂ as η_C·C, C being the clipped P_Ω(...) of the S step made with η_C. With
    # T = PD − X + Y₂/η and C' = P_Ω(clip(T, ±λ/η)): S = T − C' (soft threshold on Ω,
    # T off it), the residual PD − X − S = C' − Y₂/η, and Y₂ + η(PD − X − S) = η·C'.
    # S and Y₂ start at 0.
    P = PD.copy()
    C = np.zeros((m, n), dtype)
    eta_C = 1.0
    W, T = np.empty((m, n), dtype), np.empty((m, n), dtype)
    eta = float(eta0)
    for _ in range(max_iter):
        X_prev = X
        np.add(M, P, out=W)                 # W = (M + Y₁/η + PD − S + Y₂/η) / 2
        W += Y1 / eta
        W += (eta_C / eta) * C
        W *= 0.5
        X, _rank = svt(W, 1.0 / (2.0 * eta))
        np.subtract(PD, X, out=T)
        T += (eta_C / eta) * C
        C_new = np.clip(T, -lam / eta, lam / eta)
        C_new *= observed
        np.subtract(PD, T, out=P)           # PD − S = PD − T + C'
        P += C_new
        # r₂ = C' − Y₂/η, before Y₂ becomes η·C'.
        np.multiply(C, eta_C / eta, out=W)
        np.subtract(C_new, W, out=W)
        norm_r2 = np.linalg.norm(W)
        C, eta_C = C_new, eta
        np.multiply(X, eta, out=W)
        W -= Y1
        M = temporal_solve(W, eta, mu) if mu > 0 else W / eta
        np.subtract(M, X, out=T)            # r₁
        norm_r1 = np.linalg.norm(T)
        T *= eta
        Y1 += T
        eta = min(rho * eta, eta_max)
        np.subtract(X, X_prev, out=T)
        change = np.linalg.norm(T) / (np.linalg.norm(X) or 1.0)
        if max(norm_r1, norm_r2) / norm_PD <= tol and change <= tol:
            break
    return X.astype(np.float64, copy=False)


# The default ``trnn`` blends a TSMC fill among its candidates where the loss is scattered:
# where at least this share of all samples lies in missing runs shorter than the blend's
# ``MIN_MODEL_GAP`` (the paper's random-loss protocol; real occlusions of whole stretches
# leave it out and pay nothing).
SCATTERED_SHARE = 0.02
# ... and where one Gram product of its shrinkage (m² · n multiply-adds) stays within this:
# 6.8e7 on 85_12 (123 rows, 4500 frames: 1.2 s per run), so a clip of 41 markers up to
# about 6,600 frames. A 12,000-frame window of a long clip (1.8e8, some 4 s per run, and
# two runs in every window that validates) is left to the other candidates.
MAX_GRAM_COST = 1e8


def offered(observed: np.ndarray) -> bool:
    """Whether the default's blend runs :func:`gap_fill` on this mask."""
    from .gapwise import MIN_MODEL_GAP, held_short_runs, row_groups

    m, n = observed.shape
    if m * m * n > MAX_GRAM_COST:
        return False
    scattered = held_short_runs(observed, row_groups(observed), MIN_MODEL_GAP) & ~observed
    return np.count_nonzero(scattered) >= SCATTERED_SHARE * observed.size


def gap_fill(matrix: np.ndarray, observed: np.ndarray, *, tol: float = 1e-4,
             **options) -> np.ndarray:
    """TSMC as a candidate of the default's per-gap blend, to ε = 1e−4.

    In the blend, on the random-loss cells of ``bench accuracy`` (mean RMSE of seeds 0–2),
    ε = 1e−4 against 1e−5: 02_05 mr = 0.4 0.4260 against 0.4245 mm (the blend without it
    0.4312, TSMC alone 0.4289), 10_01 mr = 0.2 0.7623 against 0.7525; the candidate's run
    on 02_05 takes 0.6–0.7 against 0.9 s.

    It iterates in float32, as the TrNN candidate does: the iteration is a dozen passes
    over the m × n arrays, and in float64 two candidates side by side on a 2-core
    machine left the second core waiting on memory. The shrinkage's small Gram matrix is
    still formed in float64 (:func:`~mocapfill.solvers._linalg.svt`), so the fills are
    float64's to about 1e−6 of the unit scale, with the same iterations and ranks (10_01
    mr = 0.2: 60 iterations, rank 93, either way). Measured, one run in process: 85_12
    mr = 0.6 1.5–1.9 → 1.1 s, 02_05 mr = 0.4 0.72 → 0.53–0.57 s.

    Returns the data on the observed samples. Solved, as the TrNN candidate is, on the
    clip padded with wholly unobserved frames to the next length the DCT handles fast
    (1854 frames of 02_05 → 1875: the temporal step by DCT instead of the banded solve,
    2 against 5.5 ms for 123 rows), then cropped. Its fill is not joined to the gap ends:
    on scattered loss of a noisy clip the smooth low-rank estimate is the better fill of a
    short gap than one pulled through the noisy samples beside it (joined, the blend's
    02_05 mr = 0.4 figure went back to 0.4314 mm).
    """
    matrix, observed = as_problem(matrix, observed)
    n = matrix.shape[1]
    big, seen = padded_to_fast_length(matrix, observed)
    options.setdefault("dtype", np.float32)
    return np.where(observed, matrix, complete(big, seen, tol=tol, **options)[:, :n])
