"""Gaussian conditional fill by EM: the E-step formula, the fit, and the blend candidate."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers import gaussian, interp
from mocapfill.solvers.gapwise import interior_gaps, row_groups

from ._synth import masked, rel, smooth_low_rank


def random_spd(seed: int, m: int) -> np.ndarray:
    A = np.random.default_rng(seed).standard_normal((m, m))
    return A @ A.T + 0.5 * np.eye(m)


@pytest.mark.parametrize("can_miss", [range(9), [1, 2, 6, 7]], ids=["any row", "four rows"])
def test_conditional_step_is_the_textbook_conditional_expectation(can_miss):
    # Where few rows are ever missing, (Λz)_M is formed from those rows of Λ alone.
    m, n = 9, 40
    rng = np.random.default_rng(0)
    cov = random_spd(1, m)
    Z = rng.standard_normal((m, n))
    missing = rng.random((m, n)) < 0.3
    missing[np.setdiff1d(np.arange(m), can_miss)] = False
    missing[:, 5:12] = missing[:, [4]]       # a missing set shared by several frames
    missing[:, 0] = False                    # a complete frame
    expected = Z.copy()
    scatter = np.zeros((m, m))
    for t in range(n):
        hid, seen = missing[:, t], ~missing[:, t]
        if not hid.any():
            continue
        gain = cov[np.ix_(hid, seen)] @ np.linalg.inv(cov[np.ix_(seen, seen)])
        expected[hid, t] = gain @ Z[seen, t]
        scatter[np.ix_(hid, hid)] += cov[np.ix_(hid, hid)] - gain @ cov[np.ix_(seen, hid)]
    got = np.where(missing, 123.0, Z)        # the values on M must not matter
    sets = gaussian._missing_sets(missing)
    unions = [group.union[0] for group in sets]
    if len(can_miss) < m:
        assert all(union is not None for union in unions)
    else:                                    # and both kinds of group where any row can
        assert {union is None for union in unions} == {True, False}
    out = gaussian.conditional_step(got, np.linalg.inv(cov), sets)
    np.testing.assert_allclose(got, expected, atol=1e-10)
    np.testing.assert_allclose(out, scatter, atol=1e-10)


def test_em_recovers_the_normal_law_from_incomplete_frames():
    m, n = 6, 4000
    rng = np.random.default_rng(2)
    cov = random_spd(3, m)
    mean = rng.standard_normal((m, 1))
    X = mean + np.linalg.cholesky(cov) @ rng.standard_normal((m, n))
    observed = rng.random((m, n)) > 0.3
    observed[:, 0] = True
    fit = gaussian.fit_normal(np.where(observed, X, 0.0), observed, start=np.zeros((m, n)),
                              ridge=0.0, max_iter=200, tol=1e-10)
    full_cov = np.cov(X, bias=True)
    assert np.abs(fit.mean - X.mean(axis=1, keepdims=True)).max() < 0.05
    assert np.abs(np.linalg.inv(fit.precision) - full_cov).max() < 0.1 * np.abs(full_cov).max()
    # Without the conditional covariance in the M-step the variances of the hidden
    # coordinates would shrink; EM keeps them.
    ratio = np.diag(np.linalg.inv(fit.precision)) / np.diag(full_cov)
    assert np.all(np.abs(ratio - 1) < 0.1)


def _textbook_em(matrix, observed, start, ridge, iterations):
    """EM on every frame as written in the module docstring (no frame left out)."""
    m, n = matrix.shape
    F = np.where(observed, matrix, start)
    scatter = np.zeros((m, m))
    for _ in range(iterations):
        mean = F.mean(axis=1, keepdims=True)
        Z = F - mean
        cov = (Z @ Z.T + scatter) / n
        cov += ridge * np.trace(cov) / m * np.eye(m)
        scatter = np.zeros((m, m))
        for t in range(n):
            hid, seen = ~observed[:, t], observed[:, t]
            if not hid.any():
                continue
            gain = cov[np.ix_(hid, seen)] @ np.linalg.inv(cov[np.ix_(seen, seen)])
            Z[hid, t] = gain @ Z[seen, t]
            scatter[np.ix_(hid, hid)] += cov[np.ix_(hid, hid)] - gain @ cov[np.ix_(seen, hid)]
        F = np.where(observed, matrix, Z + mean)
    return F


def test_em_on_the_incomplete_frames_alone_is_em_on_every_frame():
    # fit_normal accumulates the complete frames once and iterates on the others only;
    # that must be the same EM, iterate for iterate, with the clip's mean far from 0.
    m, n = 6, 300
    rng = np.random.default_rng(4)
    X = 5.0 + np.linalg.cholesky(random_spd(5, m)) @ rng.standard_normal((m, n))
    observed = rng.random((m, n)) > 0.1
    start = X + rng.standard_normal((m, n))
    for iterations in (1, 4):
        fit = gaussian.fit_normal(np.where(observed, X, 0.0), observed, start=start,
                                  ridge=1e-3, max_iter=iterations, tol=0.0, accelerate=False)
        assert fit.iterations == iterations
        expected = _textbook_em(X, observed, start, 1e-3, iterations)
        np.testing.assert_allclose(fit.filled, expected, atol=1e-9)
        np.testing.assert_allclose(fit.filled[observed], X[observed], rtol=0, atol=0)


def test_squarem_reaches_the_em_fixed_point_in_fewer_e_steps():
    # A marker that follows another, missing for most of the clip: much of its
    # information is missing, the slow case of plain EM (178 E-steps here).
    m, n = 12, 600
    rng = np.random.default_rng(9)
    X = np.linalg.cholesky(random_spd(11, m)) @ rng.standard_normal((m, n))
    X[6:9] = X[0:3] + 0.2 * rng.standard_normal((3, n))
    observed = np.ones((m, n), dtype=bool)
    observed[6:9, 50:550] = False
    observed[0:3, 300:330] = False
    observed[3:6, 400:480] = False
    start = np.zeros((m, n))
    kwargs = dict(start=start, ridge=1e-4, max_iter=5000, tol=1e-9)
    plain = gaussian.fit_normal(np.where(observed, X, 0.0), observed, accelerate=False,
                                **kwargs)
    fast = gaussian.fit_normal(np.where(observed, X, 0.0), observed, accelerate=True,
                               **kwargs)
    assert fast.iterations < plain.iterations / 3 < 5000 / 3
    np.testing.assert_allclose(fast.filled, plain.filled, rtol=0, atol=1e-7)
    np.testing.assert_allclose(fast.precision, plain.precision, rtol=1e-5)
    assert np.array_equal(fast.filled[observed], X[observed])


def test_an_extrapolated_covariance_must_be_finite_and_positive_definite():
    assert gaussian._positive_definite(np.eye(3))
    assert not gaussian._positive_definite(np.diag([1.0, -1.0, 1.0]))
    assert not gaussian._positive_definite(np.diag([1.0, np.nan, 1.0]))
    assert not gaussian._positive_definite(np.diag([1.0, np.inf, 1.0]))


def test_squarem_stops_at_its_e_step_budget():
    m, n = 6, 200
    rng = np.random.default_rng(3)
    X = np.linalg.cholesky(random_spd(2, m)) @ rng.standard_normal((m, n))
    observed = rng.random((m, n)) > 0.3
    for budget in (1, 2, 5):
        fit = gaussian.fit_normal(np.where(observed, X, 0.0), observed, start=np.zeros((m, n)),
                                  max_iter=budget, tol=0.0)
        assert fit.iterations == budget


def affine_markers(seed: int, markers: int = 10, n: int = 500) -> np.ndarray:
    """Random smooth motion; the last marker is an affine combination of three others."""
    rng = np.random.default_rng(seed)
    base = smooth_low_rank(seed, m=3 * (markers - 1), n=n, r=8).reshape(markers - 1, 3, n)
    c = rng.standard_normal(3)
    c /= c.sum()
    last = np.tensordot(c, base[:3], axes=1)
    return np.concatenate([base, last[None]]).reshape(3 * markers, n)


@pytest.mark.parametrize("seed", [0, 1])
def test_fills_a_marker_that_is_a_linear_combination_of_others(seed):
    M = affine_markers(seed)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 100:400] = False           # most of the clip
    out = gaussian.complete(masked(M, observed), observed)
    assert rel(out, M, ~observed) < 1e-3
    np.testing.assert_array_equal(out[observed], M[observed])


def test_gap_fill_joins_the_data_and_leaves_short_runs_to_the_spline():
    M = affine_markers(4, n=600)
    rng = np.random.default_rng(5)
    M = M + 0.002 * rng.standard_normal(M.shape)      # noise: the raw fill would step
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 200:320] = False
    observed[3:6, 50:53] = False             # a 3-frame run: spline territory
    data = masked(M, observed)
    data_in = data.copy()
    out = gaussian.gap_fill(np.where(observed, M, 0.0), observed)
    np.testing.assert_array_equal(data_in[observed], data[observed])
    np.testing.assert_array_equal(out[observed], M[observed])
    np.testing.assert_allclose(out[3:6, 50:53], interp.spline(data, observed)[3:6, 50:53])
    assert rel(out, M, ~observed) < 0.01
    # No jump at the gap ends: the first and last filled steps are of the size of the
    # data's own frame-to-frame steps.
    typical = np.abs(np.diff(M[-3:], axis=1)).max()
    assert np.abs(out[-3:, 200] - M[-3:, 199]).max() <= 1.5 * typical
    assert np.abs(M[-3:, 320] - out[-3:, 319]).max() <= 1.5 * typical


def test_random_occlusion_and_wide_clips_are_over_budget_and_marker_gaps_are_not():
    m, n = 3 * 41, 2000
    rng = np.random.default_rng(6)
    gaps = np.ones((m, n), dtype=bool)
    for j in range(10):
        start = int(rng.integers(1, n - 60))
        gaps[3 * j:3 * j + 3, start:start + 60] = False
    assert gaussian.affordable(gaps)
    # 60 % of the markers hidden at random in every frame: runs of every length.
    hit = rng.random((41, n)).argsort(axis=0) < 25
    random = ~np.repeat(hit, 3, axis=0)
    assert gaussian.iteration_cost(random)[0] > gaussian.MAX_SET_COST
    assert not gaussian.affordable(random)
    assert len(interior_gaps(random, row_groups(random))) > 1000
    # 300 markers over a 12000-frame window: the m × m products alone are too dear.
    wide = np.ones((900, 12000), dtype=bool)
    wide[:3, 100:200] = False
    assert not gaussian.affordable(wide)
    # 1,000 markers over 30 frames: the products are within budget (5.4e8), but each
    # iteration inverts a 3,000 × 3,000 covariance (2.7e10).
    few = np.ones((3000, 30), dtype=bool)
    few[:3, 10:20] = False
    assert 2.0 * 3000 * 3000 * 30 <= gaussian.MAX_DENSE_COST
    assert not gaussian.affordable(few)
