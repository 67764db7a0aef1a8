"""RPCA by inexact ALM and by partial singular value thresholding (PSVT)."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers import rpca

from ._synth import rel


def rpca_problem(seed: int, m: int = 400, n: int = 200, r0: int = 10, cr: float = 0.1):
    """Lin et al.'s synthetic set-up: rank-r0 Gaussian product plus cr·mn sparse errors
    uniform in [-10, 10]."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((m, r0)) @ rng.standard_normal((r0, n))
    E = np.zeros((m, n))
    k = int(cr * m * n)
    E.flat[rng.choice(m * n, k, replace=False)] = rng.uniform(-10, 10, k)
    return A, E


def test_ialm_recovers_low_rank_part():
    A, E = rpca_problem(0, m=300, n=150)
    out = rpca.ialm(A + E, np.ones(A.shape, dtype=bool))
    assert rel(out, A) < 1e-5


def test_psvt_recovers_low_rank_part():
    A, E = rpca_problem(1, m=300, n=150)
    out = rpca.psvt(A + E, np.ones(A.shape, dtype=bool), rank=10)
    assert rel(out, A) < 1e-4


def test_psvt_grows_its_penalty_as_its_authors_code_does():
    # Oh et al.'s released code grows μ by ρ = 1.1; IALM's 1.5 stops earlier, 2e4 times
    # further from the low-rank part on this matrix (rank 20, 20 % of the entries corrupted).
    A, E = rpca_problem(4, m=300, n=100, r0=20, cr=0.2)
    everything = np.ones(A.shape, dtype=bool)
    assert rel(rpca.psvt(A + E, everything, rank=20), A) < 1e-6
    assert rel(rpca.psvt(A + E, everything, rank=20, rho=1.5), A) > 1e-4


def test_partial_svt_keeps_top_values():
    rng = np.random.default_rng(2)
    U, _ = np.linalg.qr(rng.standard_normal((9, 4)))
    V, _ = np.linalg.qr(rng.standard_normal((7, 4)))
    X = (U * [8.0, 4.0, 2.0, 0.5]) @ V.T
    out = rpca.partial_svt(X, 1.0, keep=2)
    np.testing.assert_allclose(out, (U[:, :3] * [8.0, 4.0, 1.0]) @ V[:, :3].T, atol=1e-12)


def test_ialm_with_missing_entries():
    A, E = rpca_problem(3, m=150, n=100, r0=5, cr=0.05)
    observed = np.random.default_rng(3).random(A.shape) > 0.2
    out = rpca.ialm(np.where(observed, A + E, np.nan), observed)
    assert rel(out, A) < 1e-3


def test_psvt_rejects_negative_rank():
    with pytest.raises(ValueError):
        rpca.psvt(np.eye(3), np.ones((3, 3), dtype=bool), rank=-1)


@pytest.mark.parametrize("method", [rpca.ialm, rpca.psvt])
@pytest.mark.parametrize("option", [{"mu0": 0.0}, {"mu0": -1.0}, {"mu_max_factor": 0.0},
                                    {"mu_max_factor": -2.0}])
def test_a_penalty_that_is_not_positive_is_a_parameter_error(method, option):
    # mu0 = 0 was a bare ZeroDivisionError (1 / mu) from inside the loop.
    from mocapfill.errors import ParameterError

    with pytest.raises(ParameterError, match="must be > 0"):
        method(np.eye(3), np.ones((3, 3), dtype=bool), **option)
