"""Interpolation baselines: exactness on polynomials, PCHIP shape preservation, end holds."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers import interp

from ._synth import masked


def _rows(*rows):
    return np.vstack(rows).astype(np.float64)


T = np.arange(80, dtype=np.float64)


def test_spline_exact_on_cubic_with_interior_gap():
    M = _rows(1e-3 * T ** 3 - 0.05 * T ** 2 + 0.7 * T - 3.0, -2e-4 * (T - 40) ** 3 + T)
    observed = np.ones(M.shape, dtype=bool)
    observed[:, 20:45] = False
    observed[1, 60:63] = False
    out = interp.spline(masked(M, observed), observed)
    np.testing.assert_allclose(out, M, rtol=0, atol=1e-9)


def test_linear_exact_on_line_but_not_on_curve():
    M = _rows(2.5 * T - 7.0, 0.01 * T ** 2)
    observed = np.ones(M.shape, dtype=bool)
    observed[:, 10:50] = False
    out = interp.linear(masked(M, observed), observed)
    np.testing.assert_allclose(out[0], M[0], rtol=0, atol=1e-12)
    assert np.abs(out[1] - M[1]).max() > 1.0  # the chord, not the parabola


def test_pchip_monotone_without_overshoot_on_step():
    y = np.where(T < 40, 0.0, 1.0)
    observed = np.ones((1, T.size), dtype=bool)
    observed[0, 30:38] = False
    observed[0, 41:52] = False
    out = interp.pchip(masked(y[None], observed), observed)[0]
    assert np.all(np.diff(out) >= -1e-15)
    assert out.min() >= 0.0 and out.max() <= 1.0
    # the cubic spline does overshoot on the same data (why PCHIP is offered)
    spl = interp.spline(masked(y[None], observed), observed)[0]
    assert spl.max() > 1.0 or spl.min() < 0.0


@pytest.mark.parametrize("method", [interp.linear, interp.spline, interp.pchip])
def test_end_gaps_held_and_empty_rows_zero(method):
    M = _rows(np.sin(T / 9.0), np.cos(T / 7.0), T)
    observed = np.ones(M.shape, dtype=bool)
    observed[0, :12] = False
    observed[0, 70:] = False
    observed[1, 30:40] = False
    observed[2] = False
    before = M.copy(), observed.copy()
    data = masked(M, observed)
    out = method(data, observed)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out[0, :12], M[0, 12])
    np.testing.assert_array_equal(out[0, 70:], M[0, 69])
    np.testing.assert_array_equal(out[observed], M[observed])
    np.testing.assert_array_equal(out[2], 0.0)
    np.testing.assert_array_equal(observed, before[1])
    assert np.isnan(data[2]).all()


def test_few_samples_fall_back():
    observed = np.zeros((2, 10), dtype=bool)
    observed[0, 4] = True
    observed[1, [2, 7]] = True
    M = np.arange(20.0).reshape(2, 10)
    out = interp.spline(masked(M, observed), observed)
    np.testing.assert_array_equal(out[0], 4.0)
    np.testing.assert_allclose(out[1, 2:8], M[1, 2:8])


@pytest.mark.parametrize("degree", [5, 7])
def test_local_fits_match_the_whole_row_and_follow_the_gaps(degree):
    """Piecewise fits around far-apart gaps give the whole-row spline's values, and the
    pieces are separate fits (a row of 6,000 samples is never solved whole)."""
    from mocapfill.solvers._splines import odd_spline

    rng = np.random.default_rng(3)
    n = 6000
    t = np.arange(n, dtype=np.float64)
    y = np.cumsum(rng.normal(size=(n, 3)), axis=0) + 50 * np.sin(t / 40)[:, None]
    seen = np.ones(n, dtype=bool)
    for start in (300, 1700, 1760, 4000, 5900):      # 1700 and 1760 share a fit
        seen[start:start + rng.integers(3, 60)] = False
    seen[3000:4500:2] = False                        # a scattered stretch: one fit
    asked = t[~seen]
    sizes = []

    def spy(t_obs, y_obs):
        sizes.append(t_obs.size)
        return odd_spline(t_obs, y_obs, degree)

    pieces = interp.local(spy)(t[seen], y[seen])(asked)
    whole = odd_spline(t[seen], y[seen], degree)(asked)
    np.testing.assert_allclose(pieces, whole, rtol=0, atol=1e-12 * np.abs(y).max())
    assert len(sizes) == 4 and max(sizes) < seen.sum() / 2
    assert interp.local(spy)(t[seen], y[seen])(np.empty(0)).shape == (0, 3)
