"""Robust PCA by the inexact augmented Lagrange multiplier method, with a partial mask.

- :func:`ialm` — Lin, Chen & Ma, "The augmented Lagrange multiplier method for exact
  recovery of corrupted low-rank matrices", UIUC tech. report UILU-ENG-09-2215, 2010
  (arXiv:1009.5055), Algorithm 5 (inexact ALM):
  ``min ‖A‖_* + λ‖E‖₁  s.t.  D = A + E``.
- :func:`psvt` — Oh, Tai, Bazin, Kim & Kweon, "Partial sum minimization of singular values
  in robust PCA: algorithm and applications", IEEE TPAMI 38(4):744–758, 2016: the nuclear
  norm is replaced by the partial sum ``Σ_{i>N} σ_i`` (the N largest singular values are
  free), whose proximal map is the partial singular value thresholding (PSVT) operator —
  keep the top N singular values, shrink the rest. Same inexact-ALM loop, with the
  penalty growth ρ = 1.1 of the authors' released code (``TNN_RPCA.m``, which Hu et al.
  ran for their Fig. 2–3).

Missing data: with Ω the observed set, the constraint is imposed on Ω only, i.e. E is free
off Ω (``E = D − A + Y/μ`` there, no shrinkage), D is taken as 0 off Ω — the usual
extension of RPCA to partial observations (with Ω everything, it is the papers' method).

Defaults are the papers': λ = 1/√max(m, n), μ₀ = 1.25/‖P_Ω D‖₂, ρ = 1.5 (PSVT: 1.1),
μ̄ = 1e7·μ₀, Y₀ = P_Ω D / J(P_Ω D) with J(D) = max(‖D‖₂, λ⁻¹‖D‖_∞), stop when
‖P_Ω(D − A − E)‖_F/‖P_Ω D‖_F < 1e−7. The methods return the low-rank part A (outliers and
gaps are in E).
"""
from __future__ import annotations

import numpy as np

from ..errors import ParameterError
from ._linalg import as_problem, soft_threshold, svt

__all__ = ["ialm", "partial_svt", "psvt"]


def partial_svt(x: np.ndarray, tau: float, keep: int) -> np.ndarray:
    """PSVT operator: ``U (diag(σ₁..σ_N) ⊕ max(σ_{N+1..} − τ, 0)) Vᵀ``, N = ``keep``."""
    u, s, vt = np.linalg.svd(np.asarray(x, dtype=np.float64), full_matrices=False)
    s = s.copy()
    s[keep:] = np.maximum(s[keep:] - tau, 0.0)
    rank = int(np.count_nonzero(s > 0))
    return (u[:, :rank] * s[:rank]) @ vt[:rank]


def _alm(matrix, observed, prox, lam, mu0, rho, mu_max_factor, tol, max_iter):
    for name, value in (("mu0", mu0), ("mu_max_factor", mu_max_factor)):
        if value is not None and not value > 0:     # 1/μ in every step
            raise ParameterError(f"{name} must be > 0, got {value}")
    matrix, observed = as_problem(matrix, observed)
    m, n = matrix.shape
    D = np.where(observed, matrix, 0.0)
    norm_fro = float(np.linalg.norm(D))
    if norm_fro == 0.0:
        return np.zeros((m, n))
    lam = 1.0 / np.sqrt(max(m, n)) if lam is None else float(lam)
    norm_two = float(np.linalg.norm(D, 2))
    norm_inf = float(np.abs(D).max()) / lam
    Y = D / max(norm_two, norm_inf)
    mu = 1.25 / norm_two if mu0 is None else float(mu0)
    mu_max = mu * mu_max_factor
    E = np.zeros((m, n))
    A = np.zeros((m, n))
    for _ in range(max_iter):
        A = prox(D - E + Y / mu, 1.0 / mu)
        T = D - A + Y / mu
        E = np.where(observed, soft_threshold(T, lam / mu), T)
        Z = D - A - E
        Y += mu * Z
        mu = min(mu * rho, mu_max)
        if np.linalg.norm(Z) / norm_fro < tol:
            break
    return A


def ialm(matrix: np.ndarray, observed: np.ndarray, *, lam: float | None = None,
         mu0: float | None = None, rho: float = 1.5, mu_max_factor: float = 1e7,
         tol: float = 1e-7, max_iter: int = 1000, rate: float | None = None,
         seed: int | None = None) -> np.ndarray:
    """RPCA by inexact ALM (Lin, Chen & Ma 2010, Alg. 5); returns the low-rank part A.

    Parameters
    ----------
    lam
        λ, weight of ‖E‖₁ on Ω; default 1/√max(m, n).
    mu0
        Initial penalty μ₀; default 1.25/‖P_Ω D‖₂.
    rho
        Penalty growth μ ← min(ρμ, μ̄); paper 1.5.
    mu_max_factor
        μ̄ = mu_max_factor · μ₀ (the authors' code: 1e7).
    tol
        Stop when ‖P_Ω(D − A − E)‖_F / ‖P_Ω D‖_F < tol (paper 1e−7).
    max_iter
        Iteration cap (authors' code: 1000).
    rate, seed
        Shared pipeline options, ignored.
    """
    return _alm(matrix, observed, lambda x, t: svt(x, t)[0], lam, mu0, rho, mu_max_factor,
                tol, max_iter)


def psvt(matrix: np.ndarray, observed: np.ndarray, *, rank: int = 10,
         lam: float | None = None, mu0: float | None = None, rho: float = 1.1,
         mu_max_factor: float = 1e7, tol: float = 1e-7, max_iter: int = 1000,
         rate: float | None = None, seed: int | None = None) -> np.ndarray:
    """RPCA with the partial sum of singular values (Oh et al. 2016); returns A.

    Parameters
    ----------
    rank
        N, the target rank: the N largest singular values are not penalised. Oh et al.
        assume N known from the application; our default 10 (clipped to min(m, n)) is a
        typical rank of body-marker data at unit-RMS scale, override it when known.
    lam, mu0, mu_max_factor, tol, max_iter
        As in :func:`ialm`.
    rho
        Penalty growth μ ← min(ρμ, μ̄): 1.1 in the authors' code. IALM's 1.5 stopped
        earlier, with errors up to 3e4 times larger on the bench's Fig. 2 matrices (NRE
        3.0e−3 against 1.4e−7 at r₀ = 80, cr = 0.1; m = 1000, n = 200). Their code also
        starts from Y₀ = 0 and updates E before A; kept as IALM here (A first from
        Y₀ = P_Ω D / J): from Y₀ = 0 the first E takes every entry above λ/μ₀ for an
        outlier, and with N above the data's rank A is free to keep D − E, so exactly
        low-rank data came back 0.27 off (rank 4, N = 10).
    rate, seed
        Shared pipeline options, ignored.
    """
    rank = int(rank)
    if rank < 0:
        raise ValueError(f"rank must be non-negative, got {rank}")
    keep = min(rank, min(np.shape(matrix)))
    return _alm(matrix, observed, lambda x, t: partial_svt(x, t, keep), lam, mu0, rho,
                mu_max_factor, tol, max_iter)
