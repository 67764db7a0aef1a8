"""TSMC: the DCT temporal solve, and completion of smooth low-rank data."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers import _linalg, interp, tsmc

from ._synth import marker_gaps, masked, rel, smooth_low_rank


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
