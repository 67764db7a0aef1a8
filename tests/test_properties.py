"""Property tests: any mask, any finite data -> finite output, observed samples untouched,
the same result twice."""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mocapfill.errors import NothingToRepair
from mocapfill.motion import Motion
from mocapfill.pipeline import RepairOptions, repair

METHODS = ["trnn", "trnn-paper", "linear", "spline", "pchip", "pca", "svt", "tsmc"]


@st.composite
def clips(draw):
    frames = draw(st.integers(2, 40))
    markers = draw(st.integers(1, 6))
    finite = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False, width=64)
    positions = draw(arrays(np.float64, (frames, markers, 3), elements=finite))
    observed = draw(arrays(np.bool_, (frames, markers)))
    return Motion(positions, observed, tuple(f"M{j}" for j in range(markers)), 120.0)


@pytest.mark.parametrize("method", METHODS)
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(clip=clips())
def test_repair_is_finite_keeps_observed_and_is_deterministic(method, clip):
    options = RepairOptions(method=method, max_jump_mm=0, ends="hold")
    try:
        first = repair(clip, options).motion
    except NothingToRepair:
        # The one refusal a clip of finite data may get: nothing observed to fill from.
        # Any other error (a SolverError for a non-finite fill, ...) fails the test.
        assert not clip.observed.any()
        return
    assert np.isfinite(first.positions[first.observed]).all()
    np.testing.assert_array_equal(first.positions[clip.observed], clip.positions[clip.observed])
    assert (first.observed >= clip.observed).all()
    # Markers with no observed sample stay missing.
    empty = ~clip.observed.any(axis=0)
    assert not first.observed[:, empty].any()
    second = repair(clip, options).motion
    np.testing.assert_array_equal(np.nan_to_num(first.positions, nan=7.0),
                                  np.nan_to_num(second.positions, nan=7.0))
