"""Properties every comparison method shares: observed entries of exactly low-rank
complete data come back, output finite, inputs untouched, unknown options rejected."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers import get_method

from ._synth import smooth_low_rank

# max |out − D| on observed entries of complete rank-4 data. TSMC's Neumann temporal term
# flattens the first/last frames (its sparse term absorbs ~1e-2 there), so its bound is
# looser and the interior is checked separately.
METHODS = {
    "linear": 0.0, "spline": 0.0, "pchip": 0.0, "pca": 0.0, "gaussian": 0.0,
    "svt": 1e-2, "tsmc": 5e-2, "ialm": 1e-5, "psvt": 1e-5,
}


@pytest.mark.parametrize("name", sorted(METHODS))
def test_common_contract(name):
    method = get_method(name)
    M = smooth_low_rank(7, m=24, n=150, r=4)
    observed = np.ones(M.shape, dtype=bool)
    M_in, obs_in = M.copy(), observed.copy()
    out = method(M, observed, rate=100.0, seed=0)
    assert out.shape == M.shape and out.dtype == np.float64
    assert np.isfinite(out).all()
    assert out is not M
    np.testing.assert_array_equal(M, M_in)
    np.testing.assert_array_equal(observed, obs_in)
    assert np.abs(out - M).max() <= METHODS[name] + 1e-12
    if name == "tsmc":
        assert np.abs(out - M)[:, 5:-5].max() < 1e-3


@pytest.mark.parametrize("name", sorted(METHODS))
def test_gapped_input_untouched_and_output_finite(name):
    method = get_method(name)
    M = smooth_low_rank(8, m=24, n=150, r=4)
    observed = np.ones(M.shape, dtype=bool)
    observed[3:6, 40:70] = False
    observed[9:12, 100:130] = False
    data = np.where(observed, M, np.nan)
    data_in = data.copy()
    out = method(data, observed)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(np.isnan(data), np.isnan(data_in))
    np.testing.assert_array_equal(data[observed], data_in[observed])


@pytest.mark.parametrize("name", sorted(METHODS))
def test_unknown_option_rejected(name):
    M = smooth_low_rank(9, m=6, n=20, r=2)
    with pytest.raises(TypeError):
        get_method(name)(M, np.ones(M.shape, dtype=bool), no_such_option=1)
