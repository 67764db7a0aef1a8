"""TSMC: the DCT temporal solve, and completion of smooth low-rank data."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers import _linalg, interp, tsmc

from ._synth import marker_gaps, masked, rel, scattered, smooth_low_rank


# 134 = 2·67 and 409 (prime) take the banded-Cholesky path, the others the DCT.
@pytest.mark.parametrize("n", [1, 2, 5, 16, 33, 128, 134, 409])
def test_temporal_solve_matches_dense_solve(n):
    rng = np.random.default_rng(n)
    B = rng.standard_normal((4, n))
    eta, mu = 0.37, 12.5
    T = _linalg.second_difference_matrix(n)
    dense = np.linalg.solve((eta * np.eye(n) + mu * T.T @ T).T, B.T).T
    np.testing.assert_allclose(_linalg.temporal_solve(B, eta, mu), dense, rtol=0, atol=1e-10)


def test_second_difference_eigenvalues_are_those_of_gram():
    for n in (2, 7, 20):
        T = _linalg.second_difference_matrix(n)
        np.testing.assert_allclose(np.sort(_linalg.second_difference_eigenvalues(n)),
                                   np.linalg.eigvalsh(T.T @ T), atol=1e-12)


def test_linear_fill_holds_ends():
    M = np.array([[np.nan, 1.0, np.nan, 3.0, np.nan], [np.nan] * 5])
    out = _linalg.linear_fill(M, np.isfinite(M))
    np.testing.assert_array_equal(out, [[1.0, 1.0, 2.0, 3.0, 3.0], [0.0] * 5])


def test_beats_linear_interpolation_on_smooth_low_rank():
    M = smooth_low_rank(1)
    observed = marker_gaps(1, *M.shape, length=40)
    data = masked(M, observed)
    out = tsmc.complete(data, observed)
    err, err_lin = rel(out, M, ~observed), rel(interp.linear(data, observed), M, ~observed)
    assert err < 1e-3 and err < 0.01 * err_lin


def test_offered_to_the_default_on_scattered_loss_only(monkeypatch):
    m, n = 30, 300
    assert tsmc.offered(scattered(0, m, n, 0.2))
    assert not tsmc.offered(marker_gaps(0, m, n, length=40))       # long gaps: 13 % lost
    assert not tsmc.offered(scattered(0, m, n, 0.01))              # under 2 % in short runs
    monkeypatch.setattr(tsmc, "MAX_GRAM_COST", m * m * n - 1)
    assert not tsmc.offered(scattered(0, m, n, 0.2))


def test_candidate_on_a_padded_length_fills_as_the_model_does():
    # 409 frames (prime) are solved on 432 = 2⁴·3³, the next fast DCT length: the padding
    # only frees the temporal term past the last frame.
    M = smooth_low_rank(2, n=409)
    observed = scattered(2, *M.shape, 0.3)
    data = masked(M, observed)
    fill = tsmc.gap_fill(data, observed)
    assert fill.shape == M.shape
    np.testing.assert_array_equal(fill[observed], data[observed])
    assert rel(fill, M, ~observed) < 1e-3
    assert rel(fill, tsmc.complete(data, observed), ~observed) < 1e-3


def _textbook_tsmc(D, observed, *, lam, mu, rho, eta0, iterations):
    """The module docstring's updates written out plainly (X, S, M, Y₁, Y₂ as named)."""
    PD = np.where(observed, D, 0.0)
    X = _linalg.linear_fill(D, observed)
    M, S, Y1, Y2 = X.copy(), np.zeros_like(X), np.zeros_like(X), np.zeros_like(X)
    eta = eta0
    for _ in range(iterations):
        X, _ = _linalg.svt((M + Y1 / eta + PD - S + Y2 / eta) / 2, 1 / (2 * eta))
        TS = PD - X + Y2 / eta
        S = np.where(observed, _linalg.soft_threshold(TS, lam / eta), TS)
        M = _linalg.temporal_solve(eta * X - Y1, eta, mu)
        Y1 += eta * (M - X)
        Y2 += eta * (PD - X - S)
        eta *= rho
    return X


def test_iteration_equals_the_textbook_updates():
    M = smooth_low_rank(4, n=200)
    rng = np.random.default_rng(4)
    D = M + 0.05 * rng.standard_normal(M.shape)
    D[rng.random(M.shape) < 0.02] += 3.0                 # gross outliers: S is not zero
    observed = scattered(4, *M.shape, 0.3)
    options = dict(lam=0.1, mu=20.0, rho=1.3, eta0=0.05)
    for iterations in (1, 2, 7, 25):
        ours = tsmc.complete(D, observed, tol=0.0, max_iter=iterations, **options)
        plain = _textbook_tsmc(D, observed, iterations=iterations, **options)
        np.testing.assert_allclose(ours, plain, rtol=0, atol=1e-9 * np.abs(plain).max())


def test_float32_iteration_fills_as_float64_does():
    # The default's candidate iterates in float32 (half the memory traffic): its fill of
    # the missing entries must agree with float64's to within the stopping tolerance's
    # reach (the two stop on different iterations), be as accurate, and come back as
    # float64.
    M = smooth_low_rank(5, n=300)
    observed = scattered(5, *M.shape, 0.3)
    data = masked(M, observed)
    single = tsmc.complete(data, observed, dtype=np.float32, tol=1e-4)
    double = tsmc.complete(data, observed, tol=1e-4)
    assert single.dtype == np.float64
    assert rel(single, double, ~observed) < 1e-3
    assert rel(single, M, ~observed) <= 1.1 * rel(double, M, ~observed)
    with pytest.raises(ValueError, match="dtype"):
        tsmc.complete(data, observed, dtype=np.int32)


def test_a_penalty_cap_that_is_not_positive_is_a_parameter_error():
    # eta_max = 0 was a bare ZeroDivisionError (1 / eta) from inside the loop.
    from mocapfill.errors import ParameterError

    with pytest.raises(ParameterError, match="eta_max > 0"):
        tsmc.complete(np.eye(3), np.ones((3, 3), dtype=bool), eta_max=0.0)
