"""Singular value thresholding: the shrinkage operator and completion of a low-rank matrix."""
from __future__ import annotations

import numpy as np

from mocapfill.solvers import _linalg, svt

from ._synth import masked, rel


def test_shrinkage_operator_subtracts_tau_and_zeroes_small_values():
    rng = np.random.default_rng(0)
    U, _ = np.linalg.qr(rng.standard_normal((8, 5)))
    V, _ = np.linalg.qr(rng.standard_normal((12, 5)))
    sigma = np.array([9.0, 5.0, 3.0, 1.5, 0.5])
    X = (U * sigma) @ V.T
    Y, rank = _linalg.svt(X, 2.0)
    assert rank == 3
    np.testing.assert_allclose(np.linalg.svd(Y, compute_uv=False)[:5],
                               [7.0, 3.0, 1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(Y, (U[:, :3] * [7.0, 3.0, 1.0]) @ V[:, :3].T, atol=1e-12)
    Z, rank0 = _linalg.svt(X, 10.0)
    assert rank0 == 0 and not Z.any()


def test_wide_and_tall_matrices_shrink_through_the_gram_matrix_as_the_svd_does():
    rng = np.random.default_rng(3)
    sigma = np.array([40.0, 12.0, 3.0, 0.8, 0.05])
    for shape in [(6, 120), (120, 6)]:        # aspect ≥ _GRAM_ASPECT: the Gram route
        U, _ = np.linalg.qr(rng.standard_normal((shape[0], 5)))
        V, _ = np.linalg.qr(rng.standard_normal((shape[1], 5)))
        X = (U * sigma) @ V.T + 1e-3 * rng.standard_normal(shape)
        for tau in (0.5, 2.0, 50.0):
            u, s, vt = np.linalg.svd(X, full_matrices=False)
            kept = s > tau
            expected = (u[:, kept] * (s[kept] - tau)) @ vt[kept]
            Y, rank = _linalg.svt(X, tau)
            assert Y.shape == shape and rank == kept.sum()
            np.testing.assert_allclose(Y, expected, atol=1e-10)


def test_soft_threshold():
    np.testing.assert_array_equal(_linalg.soft_threshold(np.array([-3.0, -0.5, 0.0, 2.0]), 1.0),
                                  [-2.0, 0.0, 0.0, 1.0])


def test_completes_rank3_with_30_percent_missing():
    rng = np.random.default_rng(1)
    M = rng.standard_normal((60, 3)) @ rng.standard_normal((3, 200))
    M /= np.sqrt((M ** 2).mean())
    observed = rng.random(M.shape) > 0.3
    data = masked(M, observed)
    out = svt.complete(data, observed)
    assert rel(out, M, ~observed) < 1e-3
    assert np.isnan(data[~observed]).all()


def test_divergent_step_on_a_very_sparse_mask_stops_with_a_finite_iterate():
    # δ = 1.2/p is huge when 2 % of the entries are seen: the iteration diverges, and an
    # SVD of overflowing values may never return. The solver must stop and stay finite.
    rng = np.random.default_rng(3)
    matrix = rng.normal(size=(30, 40)) * 1e3
    observed = rng.random((30, 40)) < 0.02
    completed = svt.complete(matrix, observed, max_iter=5000)
    assert np.isfinite(completed).all()


def test_a_float32_matrix_is_shrunk_in_float32_as_float64_is():
    # Down to a singular value 1e−4 of the largest: a Gram matrix formed in float32 holds
    # σ² only to about 1e−7·σ₁² and would lose it (and the rank with it).
    rng = np.random.default_rng(6)
    U, _ = np.linalg.qr(rng.standard_normal((9, 5)))
    V, _ = np.linalg.qr(rng.standard_normal((400, 5)))
    X = (U * [300.0, 80.0, 20.0, 4.0, 0.03]) @ V.T
    for tau in (0.01, 1.0, 250.0):
        single, rank32 = _linalg.svt(X.astype(np.float32), tau)
        double, rank64 = _linalg.svt(X, tau)
        assert single.dtype == np.float32 and rank32 == rank64
        np.testing.assert_allclose(single, double, rtol=0, atol=1e-5 * np.abs(double).max())
