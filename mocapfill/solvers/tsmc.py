"""TSMC: low-rank completion with a temporal-stability term and sparse noise.

Feng, Ji, Liang & Xu (2014), "Exploiting temporal stability and low-rank structure for
motion capture data refinement", Information Sciences 277:777–793. The model::

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

from ._linalg import as_problem, linear_fill, soft_threshold, svt, temporal_solve

__all__ = ["complete"]


def complete(matrix: np.ndarray, observed: np.ndarray, *, lam: float | None = None,
             mu: float = 100.0, rho: float = 1.2, eta0: float = 1e-2,
             eta_max: float = 1e10, tol: float = 1e-5, max_iter: int = 500,
             rate: float | None = None, seed: int | None = None) -> np.ndarray:
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
    rate, seed
        Shared pipeline options, ignored.
    """
    matrix, observed = as_problem(matrix, observed)
    if mu < 0 or rho < 1 or eta0 <= 0:
        raise ValueError("need mu >= 0, rho >= 1, eta0 > 0")
    m, n = matrix.shape
    lam = 100.0 / np.sqrt(max(m, n)) if lam is None else float(lam)
    PD = np.where(observed, matrix, 0.0)
    norm_PD = float(np.linalg.norm(PD))
    if norm_PD == 0.0:
        return np.zeros((m, n))

    X = linear_fill(matrix, observed)
    M = X.copy()
    S = np.zeros((m, n))
    Y1 = np.zeros((m, n))
    Y2 = np.zeros((m, n))
    eta = float(eta0)
    for _ in range(max_iter):
        X_prev = X
        W = 0.5 * (M + Y1 / eta + PD - S + Y2 / eta)
        X, _rank = svt(W, 1.0 / (2.0 * eta))
        TS = PD - X + Y2 / eta
        S = np.where(observed, soft_threshold(TS, lam / eta), TS)
        M = temporal_solve(eta * X - Y1, eta, mu) if mu > 0 else X - Y1 / eta
        r1 = M - X
        r2 = PD - X - S
        Y1 += eta * r1
        Y2 += eta * r2
        eta = min(rho * eta, eta_max)
        change = np.linalg.norm(X - X_prev) / (np.linalg.norm(X) or 1.0)
        if max(np.linalg.norm(r1), np.linalg.norm(r2)) / norm_PD <= tol and change <= tol:
            break
    return X
