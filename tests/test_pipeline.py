import json
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest

from mocapfill.errors import FormatError, NothingToRepair, ParameterError, SolverError
from mocapfill.gaps import missing_runs
from mocapfill.motion import Motion
from mocapfill.pipeline import RepairOptions, repair
from mocapfill.solvers import METHODS

from .helpers import smooth_clip, with_gap


def gapped_clip() -> tuple[Motion, Motion]:
    truth = smooth_clip(400, 12)
    gapped = with_gap(with_gap(with_gap(truth, 2, 100, 160), 5, 200, 230), 7, 40, 45)
    return truth, gapped


def test_repair_fills_interior_gaps_closer_than_linear_interpolation():
    truth, gapped = gapped_clip()
    missing = ~gapped.observed
    errors = {}
    for method in ("trnn", "linear"):
        filled = repair(gapped, RepairOptions(method=method)).motion
        assert filled.observed.all()
        errors[method] = np.sqrt(np.mean((filled.positions - truth.positions)[missing] ** 2))
    assert errors["trnn"] < errors["linear"] / 2


@pytest.mark.parametrize("method", ["trnn", "trnn-paper"])
def test_observed_samples_are_returned_bit_identical(method):
    _, gapped = gapped_clip()
    filled = repair(gapped, RepairOptions(method=method)).motion
    np.testing.assert_array_equal(filled.positions[gapped.observed],
                                  gapped.positions[gapped.observed])


def test_complete_clip_comes_back_unchanged():
    truth = smooth_clip(100, 5)
    result = repair(truth)
    assert result.gaps == []
    np.testing.assert_array_equal(result.motion.positions, truth.positions)


def test_repair_is_unit_invariant():
    truth, gapped = gapped_clip()
    in_m = gapped.replace(positions=gapped.positions / 1000.0, units="m")
    mm = repair(gapped).motion.positions
    m = repair(in_m).motion.positions * 1000.0
    np.testing.assert_allclose(m, mm, rtol=1e-6, atol=1e-6 * np.abs(mm).max())


@pytest.mark.parametrize("method", ["trnn", "linear", "gaussian"])
def test_coordinates_up_to_the_largest_processed_are_repaired_as_any_others(method):
    # The unit scale centres and scales in units of a power of two near the largest value
    # (above 1e154 its mean square was inf). A power of two scales every step exactly: the
    # same repair, scaled, to the last bit, up to scaling.MAX_MAGNITUDE (1e100).
    _, gapped = gapped_clip()
    factor = 2.0 ** 320                                         # 2e96 (values to 1e99)
    huge = gapped.replace(positions=gapped.positions * factor)
    # Without the jump check, whose 40 mm floor is a length, not a scale (at 2^600 its
    # squared steps overflowed to an infinite threshold, which passed every fill).
    options = RepairOptions(method=method, max_jump_mm=0)
    mm, scaled = repair(gapped, options), repair(huge, options)
    assert [o.status for o in scaled.gaps] == [o.status for o in mm.gaps]
    np.testing.assert_array_equal(scaled.motion.positions, mm.motion.positions * factor)


def test_the_unit_scale_reads_observed_entries_only():
    # A missing entry may hold anything: divided by the unit of tiny observed values it
    # overflowed, with a warning (a property test's clip), though the value was dropped.
    import warnings

    from mocapfill.scaling import UnitScale

    matrix = np.full((3, 4), 1e300)
    matrix[:, 0] = [1e-310, 2e-310, 3e-310]
    observed = np.zeros((3, 4), bool)
    observed[:, 0] = True
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scale = UnitScale.fit(matrix, observed)
    np.testing.assert_array_equal(scale.centre[:, 0], matrix[:, 0])


@pytest.mark.parametrize("method", ["trnn", "linear"])
@pytest.mark.parametrize("value", [1e308, -1.7e308, 1e200, 2e100])
def test_a_coordinate_too_large_to_process_is_an_error_naming_it(method, value):
    # 1e308 crashed the unit scale (OverflowError: math range error, a traceback and exit
    # 1); from 1.3e154 up squares overflowed (the jump check's threshold became infinite).
    _, gapped = gapped_clip()
    positions = gapped.positions.copy()
    positions[10, 3, 1] = value
    huge = gapped.replace(positions=positions, path=Path("huge.csv"))
    with pytest.raises(FormatError, match=re.escape(
            f"huge.csv: a coordinate ({value:.6g}: marker {gapped.labels[3]}, frame 11) is "
            "too large to process (more than 1e+100 in magnitude")):
        repair(huge, RepairOptions(method=method))
    # Not a marker's (a C3D model output: never evidence, never filled): no error.
    fillable = np.ones(gapped.n_markers, bool)
    fillable[3] = False
    assert repair(huge.replace(fillable=fillable), RepairOptions(method=method)).filled


def test_marker_missing_for_the_whole_clip_is_left_missing_and_reported():
    _, gapped = gapped_clip()
    gapped = with_gap(gapped, 9, 0, gapped.n_frames)
    result = repair(gapped)
    assert not result.motion.observed[:, 9].any()
    statuses = {(o.gap.label, o.status) for o in result.gaps}
    assert ("MK09", "left: whole-clip missing") in statuses


def test_end_gaps_are_left_by_default_and_held_on_request():
    truth = smooth_clip(200, 8)
    gapped = with_gap(truth, 3, 180, 200)
    left = repair(gapped).motion
    assert not left.observed[180:, 3].any()
    held = repair(gapped, RepairOptions(ends="hold")).motion
    np.testing.assert_array_equal(held.positions[180:, 3],
                                  np.repeat(truth.positions[179:180, 3], 20, axis=0))


def test_extrapolated_end_stays_within_observed_range_plus_margin():
    truth = smooth_clip(200, 8)
    gapped = with_gap(truth, 3, 150, 200)
    filled = repair(gapped, RepairOptions(ends="extrapolate", max_jump_mm=0)).motion
    assert filled.observed.all()
    seen = truth.positions[:150, 3]
    span = seen.max(axis=0) - seen.min(axis=0)
    assert (filled.positions[150:, 3] <= seen.max(axis=0) + 0.1 * span + 1e-9).all()
    assert (filled.positions[150:, 3] >= seen.min(axis=0) - 0.1 * span - 1e-9).all()


def test_extrapolated_end_stays_within_what_the_source_file_can_store(monkeypatch):
    # Seen from 3000 to 3270 mm: the range + 10 % reaches 3297, past the 3276.7 an int16
    # word holds at scale 0.1; the fill (far above) is clamped to the file's limit instead.
    from types import SimpleNamespace

    from mocapfill import solvers

    monkeypatch.setitem(solvers.METHODS, "teleport", "tests.test_pipeline:teleport")
    truth = smooth_clip(200, 8)
    positions = truth.positions.copy()
    positions[:150, 3, :] = np.linspace(3000, 3270, 150)[:, None]
    gapped = with_gap(truth.with_positions(positions, truth.observed), 3, 150, 200)
    options = RepairOptions(method="teleport", ends="extrapolate", max_jump_mm=0)
    free = repair(gapped, options).motion
    np.testing.assert_allclose(free.positions[150:, 3], 3297.0)
    limited = repair(gapped.replace(source=SimpleNamespace(value_range=(-3276.8, 3276.7))),
                     options).motion
    np.testing.assert_array_equal(limited.positions[150:, 3], 3276.7)
    seen = gapped.observed
    np.testing.assert_array_equal(limited.positions[seen], gapped.positions[seen])
    np.testing.assert_array_equal(free.positions[seen], gapped.positions[seen])


@pytest.mark.parametrize("fill_ends", [True, False])
def test_a_long_clip_validates_its_end_gaps_in_its_first_and_last_windows(monkeypatch,
                                                                          fill_ends):
    # The windows of long clips run their candidates only where weighted, and gave the
    # clip's end gaps one candidate's fill, unvalidated; the windows holding the clip's
    # ends are now solved as a whole clip is, with stand-ins at those ends only (not at
    # the window's inner edge). Without --ends extrapolate none are hidden.
    from mocapfill import pipeline
    from mocapfill.solvers import gapwise

    monkeypatch.setenv("MOCAPFILL_THREADS", "1")        # the windows in this process
    calls = []
    real = gapwise.end_stand_ins

    def spy(train, groups, ends, rng, **options):
        calls.append((train.shape[1], ends))
        return real(train, groups, ends, rng, **options)

    monkeypatch.setattr(gapwise, "end_stand_ins", spy)
    truth = smooth_clip(1500, 8)
    gapped = with_gap(with_gap(with_gap(truth, 1, 0, 30), 2, 1470, 1500), 4, 700, 740)
    matrix, observed = gapped.matrix()
    n = matrix.shape[1]
    filled = pipeline.complete_matrix(matrix, observed, window_frames=400, window_overlap=100,
                                      fill_ends=fill_ends)
    assert np.isfinite(filled).all()
    if not fill_ends:
        assert calls == []
        return
    assert len(pipeline.window_bounds(n, 400, 100)) >= 3
    starts = [ends for width, ends in calls if any(a == 0 for _, a, _ in ends)]
    last = [ends for width, ends in calls if any(b == width for _, _, b in ends)]
    assert len(calls) == 2 and len(starts) == 1 and len(last) == 1
    assert all(a == 0 for _, a, _ in starts[0]) and all(b == 400 for _, _, b in last[0])


def test_max_gap_leaves_longer_gaps_missing():
    _, gapped = gapped_clip()
    result = repair(gapped, RepairOptions(max_gap_frames=30))
    assert not result.motion.observed[100:160, 2].any()
    assert result.motion.observed[200:230, 5].all()
    assert sum(o.status == "left: too long" for o in result.gaps) == 1


def test_markers_and_exclude_restrict_what_is_filled():
    _, gapped = gapped_clip()
    only = repair(gapped, RepairOptions(markers=("MK0[25]",))).motion
    assert only.observed[:, [2, 5]].all() and not only.observed[40:45, 7].any()
    without = repair(gapped, RepairOptions(exclude=("MK02",))).motion
    assert not without.observed[100:160, 2].any() and without.observed[:, 5].all()
    # Vicon labels carry a subject prefix the user need not type.
    prefixed = gapped.replace(labels=tuple(f"Male:{label}" for label in gapped.labels))
    assert repair(prefixed, RepairOptions(markers=("MK0[25]",))).motion.observed[:, [2, 5]].all()
    # A pattern that matches nothing is a mistake, not "0 gaps filled".
    with pytest.raises(ParameterError, match=r"--markers LASI MK9\* matches no marker "
                                             r"\(the clip has MK00, MK01, "):
        repair(gapped, RepairOptions(markers=("LASI", "MK9*")))
    # So are --exclude patterns that match nothing (a typo would fill the marker); beside
    # one that matches, as with --markers, they pass (a batch's subjects differ).
    with pytest.raises(ParameterError, match=r"--exclude MK2 MK9\* matches no marker "
                                             r"\(the clip has MK00, MK01, "):
        repair(gapped, RepairOptions(exclude=("MK2", "MK9*")))
    repair(gapped, RepairOptions(exclude=("MK0[12]", "Female:*")))


def test_a_single_pattern_given_as_a_string_is_one_pattern_not_its_letters():
    # markers="MK02" was read as the patterns M, K, 0, 2 (and "MK0*" as ..., "*": every
    # marker filled).
    _, gapped = gapped_clip()
    only = repair(gapped, RepairOptions(method="linear", markers="MK02")).motion
    assert only.observed[:, 2].all() and not only.observed[200:230, 5].any()
    without = repair(gapped, RepairOptions(method="linear", exclude="MK0*")).motion
    assert (without.observed == gapped.observed).all()


def test_non_marker_points_are_never_filled():
    _, gapped = gapped_clip()
    fillable = np.ones(gapped.n_markers, bool)
    fillable[2] = False
    result = repair(gapped.replace(fillable=fillable))
    assert not result.motion.observed[100:160, 2].any()


def test_one_frame_clip_is_rejected():
    clip = smooth_clip(1, 4)
    with pytest.raises(NothingToRepair):
        repair(clip)


@pytest.mark.parametrize("kwargs", [dict(ends="wrap"), dict(max_gap_frames=-1),
                                    dict(method="magic")])
def test_bad_options_are_rejected(kwargs):
    with pytest.raises(ParameterError):
        RepairOptions(**kwargs)


@pytest.mark.parametrize("solver_options", [
    {"rank": -1}, {"rank": 0}, {"rank": 2.5}, {"max_iter": 0}, {"max_iter": 10.5},
    {"tol": -1.0}, {"lam": 0.0}, {"eta0": -0.1}, {"mu": -1.0}, {"rho": 1.0}])
def test_solver_options_out_of_range_are_rejected_from_python_too(solver_options):
    # Only the command line checked these: from Python a negative rank was a bare
    # ValueError from inside the solver, and max_iter=0 or tol=-1 a silent repair.
    with pytest.raises(ParameterError, match="must be"):
        RepairOptions(method="trnn-lowrank", solver_options=solver_options)


@pytest.mark.parametrize("method", ["linear", "trnn"])
def test_the_rate_is_not_a_solver_option(method):
    # The repair gives every method the clip's rate; given again, linear (which names
    # rate in its signature) failed inside the repair with a duplicate-argument TypeError.
    with pytest.raises(ParameterError, match="rate is not a solver option"):
        RepairOptions(method=method, solver_options={"rate": 100})


@pytest.mark.parametrize("max_gap_frames", [2.5, float("nan"), float("inf"), "40", True])
def test_a_max_gap_that_is_not_a_whole_number_of_frames_is_rejected(max_gap_frames):
    # 2.5 acted as 2 (gap lengths are whole), nan and inf as no limit.
    with pytest.raises(ParameterError, match="max gap must be a whole number of frames"):
        RepairOptions(max_gap_frames=max_gap_frames)


def test_a_whole_max_gap_given_as_a_float_is_kept_as_frames():
    assert RepairOptions(max_gap_frames=40.0).max_gap_frames == 40
    assert type(RepairOptions(max_gap_frames=np.int64(40)).max_gap_frames) is int


@pytest.mark.parametrize("given", ["trial.c3d", Path("trial.c3d")])
def test_repair_given_a_file_name_says_to_read_it_first(given):
    # It failed inside: AttributeError: 'str' object has no attribute 'n_frames'.
    with pytest.raises(TypeError, match=r"repair\(\) takes a Motion as motion, got \w+: read "
                                        r"the file first, mocapfill.read\('trial.c3d'\)"):
        repair(given)


def test_repair_given_a_method_name_as_options_says_what_it_takes():
    with pytest.raises(TypeError, match=r"takes a RepairOptions as options, got str"):
        repair(smooth_clip(50, 3), "linear")


@pytest.mark.parametrize("method", ["trnn", "trnn-paper", "trnn-lowrank", "svt", "tsmc",
                                    "ialm", "psvt"])
def test_a_count_given_as_a_whole_float_is_that_count(method):
    # Accepted as a whole number, then a bare TypeError from the solver's loop.
    _, gapped = gapped_clip()
    options = RepairOptions(method=method, solver_options={"max_iter": 3.0})
    assert options.solver_options["max_iter"] == 3
    assert isinstance(options.solver_options["max_iter"], int)
    result = repair(gapped, options)
    np.testing.assert_array_equal(result.motion.positions[gapped.observed],
                                  gapped.positions[gapped.observed])


@pytest.mark.parametrize("method", sorted(METHODS))
def test_an_option_given_as_none_is_the_methods_default(method):
    # The range check lets None pass (the default); the solvers took it as a value and
    # failed with a bare TypeError ('<=' not supported between 'float' and 'NoneType'):
    # the checked options (rank ... max_iter) first, then the library-only ones
    # (svt's tau_factor, pca's min_cum_sv, ...).
    from mocapfill.solvers import get_method, option_names

    names = option_names(get_method(method))
    options = RepairOptions(method=method, solver_options=dict.fromkeys(names))
    assert options.solver_options == {}
    _, gapped = gapped_clip()
    np.testing.assert_array_equal(repair(gapped, options).motion.positions,
                                  repair(gapped, RepairOptions(method=method)).motion.positions)


@pytest.mark.parametrize(("method", "options", "message"), [
    ("trnn", {"lam": "0.5"}, "--lam must be a number, got '0.5'"),
    ("trnn", {"rank": True}, "--rank must be a number, got True"),
    ("svt", {"tau_factor": "5"}, "--tau-factor must be a number, got '5'"),
    ("pca", {"min_cum_sv": [0.99]}, "--min-cum-sv must be a number, got [0.99]"),
    ("pca", {"subtract_mean_trajectory": "no"},
     "--subtract-mean-trajectory must be True or False, got 'no'"),
])
def test_a_solver_option_of_the_wrong_kind_is_refused_by_name(method, options, message):
    # From Python (JSON configs, notebooks) such values reached the solvers: bare
    # TypeErrors ('>' not supported between 'str' and 'int'), or True taken as 1.
    with pytest.raises(ParameterError, match=re.escape(message)):
        RepairOptions(method=method, solver_options=options)


def test_no_method_gives_none_a_meaning_of_its_own():
    # What the test above relies on: an option that takes None has None as its default,
    # so dropping a None given for it loses nothing.
    import inspect

    from mocapfill.solvers import get_method

    for method in METHODS:
        fn = get_method(method)
        while fn is not None:
            for p in list(inspect.signature(fn).parameters.values())[2:]:
                if p.default is not None and p.default is not p.empty:
                    assert "None" not in str(p.annotation), (method, p.name)
            fn = getattr(fn, "forwards_to", None)


def teleport(matrix, observed, **_):
    """A broken method: fills every missing entry 1000 units away."""
    return np.where(observed, matrix, 1000.0)


def test_fill_with_a_boundary_jump_is_rejected_and_reported(monkeypatch):
    from mocapfill import solvers

    monkeypatch.setitem(solvers.METHODS, "teleport", "tests.test_pipeline:teleport")
    _, gapped = gapped_clip()
    result = repair(gapped, RepairOptions(method="teleport"))
    assert {o.status for o in result.gaps} == {"rejected: jump"}
    assert result.motion.observed.sum() == gapped.observed.sum()
    disabled = repair(gapped, RepairOptions(method="teleport", max_jump_mm=0))
    assert disabled.motion.observed.all()


def half_infinite(matrix, observed, **_):
    """A broken method: a plausible fill but for one coordinate of one sample (row 7 is
    the y of marker 2, inside its gap 100–160)."""
    out = np.where(observed, matrix, 0.0)
    out[7, 130] = np.inf
    return out


def test_a_fill_with_one_non_finite_coordinate_is_a_solver_error(monkeypatch):
    from mocapfill import solvers

    monkeypatch.setitem(solvers.METHODS, "half_infinite", "tests.test_pipeline:half_infinite")
    _, gapped = gapped_clip()
    with pytest.raises(SolverError, match="returned non-finite values"):
        repair(gapped, RepairOptions(method="half_infinite", max_jump_mm=0))


def test_boundary_jumps_of_all_gaps_match_the_one_gap_definition():
    from mocapfill.gaps import Gap
    from mocapfill.pipeline import _boundary_jumps

    rng = np.random.default_rng(5)
    n, markers = 60, 4
    positions = rng.normal(size=(n, markers, 3))
    observed = rng.random((n, markers)) > 0.35
    observed[:, 0] = True
    observed[0:3, 0] = observed[-2:, 0] = False          # end gaps
    gaps = [Gap(k, f"m{k}", a, b, n) for k in range(markers)
            for a, b in missing_runs(observed[:, k])]

    def one(values, seen, gap):         # the rule as stated, one gap at a time
        worst = [0.0, 0.0]              # ends with two observed samples, with one
        for edge, inside, step in ((gap.start - 1, gap.start, -1), (gap.stop, gap.stop - 1, 1)):
            if not 0 <= edge < n or not seen[edge]:
                continue
            before = edge + step
            ok = 0 <= before < n and seen[before]
            predicted = values[edge] + (values[edge] - values[before] if ok else 0.0)
            kind = 0 if ok else 1
            worst[kind] = max(worst[kind], float(np.linalg.norm(values[inside] - predicted)))
        return worst

    expected = np.array([one(positions[:, g.marker], observed[:, g.marker], g) for g in gaps])
    assert len(gaps) > 20 and any(g.at_start for g in gaps) and any(g.at_end for g in gaps)
    assert (expected > 0).sum(axis=0).min() > 5          # both kinds of ends occur
    np.testing.assert_allclose(np.array(_boundary_jumps(positions, observed, gaps)).T,
                               expected, rtol=1e-14, atol=0)


@pytest.mark.parametrize("block_values", [3 * 3 * 1, 3 * 3 * 5, 1 << 20])
def test_jump_thresholds_by_blocks_of_frames_are_the_whole_clips(monkeypatch, block_values):
    # The thresholds' steps and second differences are read by blocks of frames: whatever
    # the block, each marker's largest step and second difference between consecutive
    # observed frames must be those of the whole clip at once.
    from mocapfill import pipeline

    rng = np.random.default_rng(9)
    n = 203
    positions = rng.normal(size=(n, 5, 3)) * np.array([50.0, 150, 25, 500, 100])[:, None]
    observed = rng.random((n, 5)) > 0.3
    positions[~observed] = np.nan
    markers = [0, 2, 3]
    v, seen = positions[:, markers], observed[:, markers]
    step = np.linalg.norm(v[1:] - v[:-1], axis=2)
    accel = np.linalg.norm(v[2:] - 2 * v[1:-1] + v[:-2], axis=2)
    worst_step = np.max(step, axis=0, initial=0.0, where=seen[1:] & seen[:-1])
    worst_accel = np.max(accel, axis=0, initial=0.0, where=seen[2:] & seen[1:-1] & seen[:-2])
    monkeypatch.setattr(pipeline, "_THRESHOLD_VALUES", block_values)
    floor = pipeline.JUMP_FLOOR_MM
    moving, still = pipeline._jump_thresholds(positions, observed, markers, RepairOptions(),
                                              1.0)
    np.testing.assert_allclose(moving, np.maximum(floor, pipeline.JUMP_FACTOR * worst_accel),
                               rtol=1e-15)
    np.testing.assert_allclose(still, np.maximum(floor, worst_step
                                                 + pipeline.JUMP_FACTOR * worst_accel),
                               rtol=1e-15)
    assert (worst_step > floor).all()                   # the floor does not hide the maxima


def test_a_fast_marker_with_one_sample_beside_its_gaps_keeps_its_exact_fills(monkeypatch):
    # Random loss leaves single samples between gaps; a marker moving 60 mm per frame
    # there is 60 mm from a standing-still prediction even when filled exactly. Such
    # fills were rejected as jumps; a fill off by 300 mm still is.
    n = 300
    t = np.arange(n)
    positions = np.zeros((n, 2, 3))
    positions[:, 0, 0] = 60.0 * t                              # 60 mm/frame along x
    positions[:, 1, 1] = 1000.0 + 5.0 * np.sin(t / 10)         # a slow neighbour
    observed = np.ones((n, 2), bool)
    observed[[100, 101, 103, 104, 200, 202], 0] = False        # lone samples at 102, 201
    truth = Motion(positions, np.ones((n, 2), bool), ("fast", "slow"), 120.0, "mm")
    gapped = truth.with_positions(np.where(observed[:, :, None], positions, np.nan), observed)

    from mocapfill.scaling import UnitScale

    scale = UnitScale.fit(*gapped.matrix())     # methods see the clip in the unit scale

    def exact(matrix, seen, **_):
        return scale.forward(truth.matrix()[0])

    def off(matrix, seen, **_):
        return np.where(seen, matrix, scale.forward(truth.matrix()[0] + 300.0))

    # Two stand-in methods, by the name the pipeline looks them up with.
    monkeypatch.setattr("mocapfill.pipeline.get_method",
                        lambda name: {"exact": exact, "off": off}[name])
    kept = repair(gapped, RepairOptions(method="exact"))
    assert {o.status for o in kept.gaps} == {"filled"}
    np.testing.assert_array_equal(kept.motion.positions, positions)
    rejected = repair(gapped, RepairOptions(method="off"))
    assert {o.status for o in rejected.gaps} == {"rejected: jump"}


def test_smooth_fills_pass_the_default_jump_check():
    _, gapped = gapped_clip()
    for method in ("trnn", "spline", "linear"):
        result = repair(gapped, RepairOptions(method=method))
        assert all(o.status == "filled" for o in result.gaps), method


def test_window_bounds_cover_the_clip_with_overlap():
    from mocapfill.pipeline import window_bounds

    bounds = window_bounds(25_000, 10_000, 1_000)
    assert bounds[0] == (0, 10_000) and bounds[-1] == (15_000, 25_000)
    assert all(b[0] < a[1] - 999 for a, b in zip(bounds, bounds[1:]))


def test_a_window_starts_early_to_hold_a_gap_that_runs_out_of_the_window_before():
    # Marker 0 is missing over 700–1100: out of the first window [0, 1000), and into the
    # second at its usual start (800). The second window starts early enough to hold it
    # whole, and the windowed linear fill is then the whole clip's (the first window's
    # extrapolation weighs EDGE_GAP_WEIGHT); from fixed starts it was extrapolated from
    # each side and cross-faded.
    from mocapfill import pipeline

    truth = smooth_clip(3000, 6)
    matrix, observed = with_gap(with_gap(truth, 0, 700, 1100), 2, 1750, 1900).matrix()
    fixed = pipeline.window_bounds(3000, 1000, 200)
    assert fixed == [(0, 1000), (800, 1800), (1600, 2600), (2000, 3000)]
    bounds = pipeline.window_bounds(3000, 1000, 200, observed)
    assert bounds[0] == (0, 1000) and bounds[-1] == (2000, 3000)
    assert any(a < 700 and b > 1100 for a, b in bounds)
    assert all(b[0] - a[0] >= 500 for a, b in zip(bounds, bounds[1:-1]))
    # A gap longer than a window, or reaching the clip's end, moves nothing.
    far, _ = with_gap(with_gap(truth, 0, 700, 1800), 1, 900, 3000).matrix()
    assert pipeline.window_bounds(3000, 1000, 200, ~np.isnan(far)) == fixed
    whole = pipeline.complete_matrix(matrix, observed, "linear", window_frames=0)
    windowed = pipeline.complete_matrix(matrix, observed, "linear", window_frames=1000,
                                        window_overlap=200)
    assert np.abs(windowed - whole).max() < 1e-3 * np.abs(whole[0:3, 700:1100]).max()


def test_windows_hold_whole_every_interior_gap_shorter_than_a_window():
    from mocapfill.gaps import missing_runs
    from mocapfill.pipeline import window_bounds

    rng = np.random.default_rng(0)
    for _ in range(200):
        n, rows = int(rng.integers(1001, 6000)), int(rng.integers(1, 12))
        observed = np.ones((rows, n), bool)
        for _ in range(int(rng.integers(0, 8))):
            length = int(rng.integers(1, 999))
            start = int(rng.integers(0, n - length))
            observed[int(rng.integers(rows)), start:start + length] = False
        bounds = window_bounds(n, 1000, 200, observed)
        assert bounds[0][0] == 0 and bounds[-1][1] == n
        assert all(stop - start == 1000 for start, stop in bounds)
        assert all(a[0] < b[0] <= a[1] - 200 for a, b in zip(bounds, bounds[1:]))
        for row in observed:
            for start, stop in missing_runs(row):
                # (a gap of 998 frames or fewer, with a frame seen on either side; a gap
                # of 600 beginning in a window's first half was held by none, when
                # windows had to start at least half a window apart)
                if 0 < start and stop < n and stop - start <= 998:
                    assert any(a < start and stop < b for a, b in bounds), (start, stop)


def test_windowed_solve_is_close_to_the_whole_clip_solve():
    from mocapfill.pipeline import complete_matrix

    truth = smooth_clip(3000, 10)
    gapped = truth
    for marker, start in [(1, 400), (3, 990), (5, 1500), (7, 2200)]:
        gapped = with_gap(gapped, marker, start, start + 60)
    matrix, observed = gapped.matrix()
    whole = complete_matrix(matrix, observed, "spline", window_frames=0)
    windowed = complete_matrix(matrix, observed, "spline", window_frames=1000,
                               window_overlap=200)
    expected, _ = truth.matrix()
    missing = ~observed
    error_whole = np.sqrt(np.mean((whole - expected)[missing] ** 2))
    error_windowed = np.sqrt(np.mean((windowed - expected)[missing] ** 2))
    # A spline is local: windows change only the gap that straddles a window edge.
    assert error_windowed < 1.5 * error_whole
    np.testing.assert_array_equal(windowed[observed], matrix[observed])


def test_windows_are_streamed_into_the_clip_as_if_accumulated_and_divided():
    # 2650 frames in windows of 1000 with 200 of overlap: the last window starts at 1650,
    # so three windows cover frames 1650–1800 and the weights there do not sum to 1.
    # The weights are row by row (_window_trust): the gap of marker 1 runs into the second
    # window's first frame.
    from mocapfill.pipeline import _solve_scaled, _window_trust, complete_matrix, window_bounds

    truth = smooth_clip(2650, 6)
    gapped = truth
    for marker, start in [(0, 100), (1, 790), (2, 1620), (3, 1700), (4, 2500)]:
        gapped = with_gap(gapped, marker, start, start + 80)
    matrix, observed = gapped.matrix()
    bounds = window_bounds(2650, 1000, 200)
    assert [a for a, _ in bounds] == [0, 800, 1600, 1650]
    total, weight = np.zeros(matrix.shape), np.zeros(matrix.shape)
    ramp = np.linspace(0.0, 1.0, 202)[1:-1]
    for start, stop in bounds:
        w = np.ones(stop - start)
        if start > 0:
            w[:200] = ramp
        if stop < 2650:
            w[-200:] = ramp[::-1]
        w = w * _window_trust(observed[:, start:stop], start == 0, stop == 2650)
        total[:, start:stop] += w * _solve_scaled(matrix[:, start:stop],
                                                  observed[:, start:stop], "spline", {})
        weight[:, start:stop] += w
    expected = np.where(observed, matrix, total / weight)
    kept = matrix.copy()
    got = complete_matrix(matrix, observed, "spline", window_frames=1000, window_overlap=200)
    np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(matrix, kept)          # the input is left alone
    inplace = complete_matrix(matrix, observed, "spline", window_frames=1000,
                              window_overlap=200, overwrite=True)
    assert inplace is matrix
    np.testing.assert_array_equal(inplace, expected)


def test_a_window_gives_no_fill_to_a_marker_it_never_sees_and_little_past_its_edges():
    # Windows [0, 1000), [800, 1800), [1600, 2600), [2000, 3000). Marker 0 is missing over
    # 800–2200: the second window never sees it, and the first and third see the gap run
    # into their edges. Before, the second window filled it with the scale's centre (the
    # origin: 0, 0, 0 mm) and the cross-fades carried that into the neighbours' frames.
    from mocapfill.pipeline import EDGE_GAP_WEIGHT, _window_trust, complete_matrix

    truth = smooth_clip(3000, 6)
    matrix, observed = with_gap(with_gap(truth, 0, 800, 2200), 1, 1700, 1750).matrix()
    got = complete_matrix(matrix, observed, "spline", window_frames=1000,
                          window_overlap=200)
    # Frames 1000–1600 lie in the second window alone among those that see marker 0.
    assert np.isnan(got[0:3, 1000:1600]).all()
    assert np.isfinite(got[0:3, 800:1000]).all() and np.isfinite(got[0:3, 1600:2200]).all()
    assert np.isfinite(got[3:]).all()
    np.testing.assert_array_equal(got[observed], matrix[observed])
    trust = _window_trust(observed[:, 800:1800], False, False)
    assert (trust[0:3] == 0).all()
    assert (trust[3:6, 900:950] == 1).all()           # marker 1's gap lies inside
    first = _window_trust(observed[:, 0:1000], True, False)
    assert (first[0:3, 800:] == EDGE_GAP_WEIGHT).all() and (first[0:3, :800] == 1).all()


def test_a_gap_no_window_can_fill_is_left_whole_and_reported(monkeypatch):
    from functools import partial

    from mocapfill import pipeline

    truth = smooth_clip(3000, 6)
    gapped = with_gap(with_gap(truth, 0, 800, 2200), 1, 1700, 1750)
    monkeypatch.setattr(pipeline, "complete_matrix", partial(
        pipeline.complete_matrix, window_frames=1000, window_overlap=200))
    result = repair(gapped, RepairOptions(method="spline"))
    status = {o.gap.marker: o.status for o in result.gaps}
    assert status == {0: pipeline.LEFT_NO_WINDOW, 1: pipeline.FILLED}
    assert not result.motion.observed[800:2200, 0].any()
    assert np.isnan(result.motion.positions[800:2200, 0]).all()
    assert result.motion.observed[1700:1750, 1].all()


def test_long_clips_report_each_window_within_reporting_windows():
    from mocapfill.pipeline import complete_matrix, reporting_windows

    truth = smooth_clip(2650, 4)
    matrix, observed = with_gap(truth, 1, 900, 960).matrix()
    calls = []
    with reporting_windows(lambda done, total: calls.append((done, total))):
        complete_matrix(matrix, observed, "spline", window_frames=1000, window_overlap=200)
        complete_matrix(matrix[:, :900], observed[:, :900], "spline", window_frames=1000,
                        window_overlap=200)                   # one window: nothing to tell
    complete_matrix(matrix, observed, "spline", window_frames=1000, window_overlap=200)
    assert calls == [(0, 4), (1, 4), (2, 4), (3, 4), (4, 4)]


# A stand-in for a method that lends validation between windows (``fn.windowed``): the
# spline's fill, and a record of which validations each window was lent, kept in a file
# (the windows of a long clip may each be solved in a child process of their own).
WINDOWED_CALLS: dict = {}


def _windowed_calls() -> list:
    with open(WINDOWED_CALLS["path"]) as f:
        return [(tuple(name), tuple(tuple(lent) for lent in borrowed))
                for name, borrowed in map(json.loads, f)]


def fake_windowed_method(matrix, observed, **options):
    from mocapfill.solvers.interp import spline

    return spline(matrix, observed)


def _fake_windowed(matrix, observed, *, borrowed, **options):
    # A window is named by its first missing sample (row, frame), distinct in the test clip.
    name = tuple(int(v) for v in np.argwhere(~observed)[0])
    with open(WINDOWED_CALLS["path"], "a") as f:
        f.write(json.dumps([name, borrowed]) + "\n")
    return fake_windowed_method(matrix, observed), (None if borrowed else name)


fake_windowed_method.windowed = _fake_windowed


ENDS_SEEN: list = []


def fake_end_validating_method(matrix, observed, **options):
    from mocapfill.solvers.interp import spline

    ENDS_SEEN.append(options.get("validate_ends", "not given"))
    return spline(matrix, observed)


fake_end_validating_method.validates_ends = True


@pytest.mark.parametrize("ends, told", [("leave", False), ("hold", False),
                                        ("extrapolate", "not given")])
def test_a_method_validating_end_gaps_is_told_when_their_fills_will_not_be_used(
        monkeypatch, ends, told):
    # The default hides stand-ins at the clip's ends to weigh its end-gap fills; where the
    # repair leaves or holds the end gaps, that would only cost its interior fills data.
    from mocapfill import pipeline

    monkeypatch.setitem(METHODS, "ends", "tests.test_pipeline:fake_end_validating_method")
    ENDS_SEEN.clear()
    clip = with_gap(with_gap(smooth_clip(300, 4), 0, 0, 20), 1, 100, 120)
    repair(clip, RepairOptions(method="ends", ends=ends))
    matrix, observed = clip.matrix()
    pipeline.complete_matrix(matrix, observed, "ends")
    pipeline.complete_matrix(matrix, observed, "spline", fill_ends=False)   # no such option
    assert ENDS_SEEN == [told, "not given"]


@pytest.mark.parametrize("threads", ["1", "2", "3"])
def test_windows_between_validated_ones_borrow_their_neighbours_validations(monkeypatch,
                                                                            threads, tmp_path):
    from mocapfill import pipeline
    from mocapfill.solvers import METHODS

    monkeypatch.setitem(METHODS, "lender", "tests.test_pipeline:fake_windowed_method")
    monkeypatch.setattr(pipeline, "VALIDATE_EVERY", 2)
    monkeypatch.setenv("MOCAPFILL_THREADS", threads)
    monkeypatch.setitem(WINDOWED_CALLS, "path", tmp_path / "calls")
    (tmp_path / "calls").touch()
    truth = smooth_clip(4700, 5)
    gapped = truth
    for marker, start in [(0, 300), (1, 1200), (2, 2000), (3, 2900), (4, 3500), (0, 4400)]:
        gapped = with_gap(gapped, marker, start, start + 70)
    matrix, observed = gapped.matrix()
    bounds = pipeline.window_bounds(4700, 1000, 200)
    assert len(bounds) == 6
    names = [tuple(int(v) for v in np.argwhere(~observed[:, a:b])[0]) for a, b in bounds]
    got = pipeline.complete_matrix(matrix, observed, "lender", window_frames=1000,
                                   window_overlap=200)
    # Windows 0, 2, 4 and the last validate themselves; window 1 is lent the validations
    # of 0 and 2, window 3 those of 2 and 4. Each window is solved once.
    made = _windowed_calls()
    calls = dict(made)
    assert len(made) == 6 and set(calls) == set(names)
    assert {names.index(n) for n, lent in calls.items() if not lent} == {0, 2, 4, 5}
    assert calls[names[1]] == (names[0], names[2])
    assert calls[names[3]] == (names[2], names[4])
    # Solving ahead and holding windows does not change how the windows are stitched.
    expected = pipeline.complete_matrix(matrix, observed, "spline", window_frames=1000,
                                        window_overlap=200)
    np.testing.assert_array_equal(got, expected)


def test_a_windowed_repair_is_the_same_whatever_the_thread_count(monkeypatch):
    from mocapfill import pipeline

    clip = smooth_clip(2000, 5)
    for marker, start in [(0, 150), (1, 500), (2, 900), (3, 1300), (4, 1700), (1, 1850)]:
        clip = with_gap(clip, marker, start, start + 40)
    matrix, observed = clip.matrix()
    fills = []
    for threads in ("1", "2"):
        monkeypatch.setenv("MOCAPFILL_THREADS", threads)
        fills.append(pipeline.complete_matrix(matrix, observed, "trnn", window_frames=600,
                                              window_overlap=100))
    assert len(pipeline.window_bounds(2000, 600, 100)) >= 3
    np.testing.assert_array_equal(fills[0], fills[1])
    assert np.isfinite(fills[0]).all()


def test_a_failing_validated_window_fails_the_clip_with_its_own_error(monkeypatch):
    from mocapfill import pipeline
    from mocapfill.solvers import METHODS

    def broken(matrix, observed, *, borrowed, **options):
        if not borrowed and observed[:, -1].all() and not observed.all():
            raise SolverError("window broke")
        return _fake_windowed(matrix, observed, borrowed=borrowed)

    monkeypatch.setitem(METHODS, "lender", "tests.test_pipeline:fake_windowed_method")
    monkeypatch.setattr(fake_windowed_method, "windowed", broken)
    monkeypatch.setattr(pipeline, "VALIDATE_EVERY", 2)
    monkeypatch.setenv("MOCAPFILL_THREADS", "2")
    clip = smooth_clip(4700, 5)
    for marker, start in [(0, 300), (1, 1200), (2, 2000), (3, 2900), (4, 3500), (0, 4400)]:
        clip = with_gap(clip, marker, start, start + 70)
    matrix, observed = clip.matrix()
    with pytest.raises(SolverError, match="window broke"):
        pipeline.complete_matrix(matrix, observed, "lender", window_frames=1000,
                                 window_overlap=200)


def test_clip_with_every_sample_missing_is_refused():
    clip = smooth_clip(50, 3)
    empty = clip.with_positions(clip.positions, np.zeros_like(clip.observed))
    with pytest.raises(NothingToRepair, match="no marker has a single observed sample"):
        repair(empty)


def test_one_marker_clip_is_filled_along_time():
    clip = smooth_clip(120, 1)
    result = repair(with_gap(clip, 0, 40, 60))
    assert result.motion.observed.all()


def test_a_numerical_breakdown_of_the_method_is_a_clean_solver_error(monkeypatch):
    # Fuzzing found a corrupt C3D (coordinates near 3e38) on which an SVD inside TrNN
    # failed to converge; the repair must end in a SolverError, never a LinAlgError.
    from mocapfill import pipeline
    from mocapfill.errors import SolverError

    def breaks_down(matrix, observed, mu=1.0, **options):
        raise np.linalg.LinAlgError("SVD did not converge")

    monkeypatch.setattr(pipeline, "get_method", lambda name: breaks_down)
    _, gapped = gapped_clip()
    with pytest.raises(SolverError, match="broke down numerically.*SVD did not converge"
                                          ".*check the file's coordinates"):
        repair(gapped, RepairOptions(method="trnn"))
    # Options the user gave are suspects too, named first.
    with pytest.raises(SolverError, match=r"check the options given \(--mu 1e\+308\) or "):
        repair(gapped, RepairOptions(method="trnn", solver_options={"mu": 1e308}))


@pytest.mark.parametrize(("units", "mm"), [("mm", 1.0), ("M", 1000.0), ("in/0.45", 25.4 / 0.45),
                                          ("in", 25.4), ("in/0", None), ("in/x", None),
                                          ("parsecs", None), ("mm/2", 0.5)])
def test_millimetres_per_unit_of_plain_and_divided_units(units, mm):
    from mocapfill.metrics import mm_per_unit

    assert mm_per_unit(units) == (pytest.approx(mm) if mm is not None else None)


MEETING: dict = {}


def meeting_method(matrix, observed, **options):
    # Each call leaves a file in MEETING["folder"] (the windows may be solved in threads or
    # in child processes); the first two to arrive wait until both are there.
    folder = MEETING["folder"]
    (folder / f"{os.getpid()}-{time.monotonic_ns()}").touch()
    if len(list(folder.iterdir())) <= 2:
        deadline = time.monotonic() + 20
        while len(list(folder.iterdir())) < 2:
            assert time.monotonic() < deadline, "no second window came"
            time.sleep(0.01)
    return fake_windowed_method(matrix, observed)


def test_small_windows_are_solved_side_by_side_large_ones_one_at_a_time(monkeypatch,
                                                                        tmp_path):
    from mocapfill import pipeline
    from mocapfill.solvers import METHODS

    # 41 markers in 12,000-frame windows fit the budget several at a time; 300 do not.
    assert pipeline.windows_at_once(123, 12_000) >= 2
    assert pipeline.windows_at_once(900, 12_000) == 1
    # Two windows in progress at once: the first two to start must meet (one window at a
    # time, the first would wait alone and fail).
    monkeypatch.setitem(MEETING, "folder", tmp_path)
    monkeypatch.setitem(METHODS, "meeting", "tests.test_pipeline:meeting_method")
    monkeypatch.setenv("MOCAPFILL_THREADS", "2")
    clip = smooth_clip(2600, 5)
    for marker, start in [(0, 300), (1, 1200), (2, 2000)]:
        clip = with_gap(clip, marker, start, start + 50)
    matrix, observed = clip.matrix()
    got = pipeline.complete_matrix(matrix, observed, "meeting", window_frames=1000,
                                   window_overlap=200)
    assert len(list(tmp_path.iterdir())) == 3     # one call per window
    expected = pipeline.complete_matrix(matrix, observed, "spline", window_frames=1000,
                                        window_overlap=200)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("method", ["trnn", "pca"])
def test_the_rows_centres_are_the_pipelines_not_an_option(method):
    # The methods marked takes_centre get each row's centre in the unit scale from the
    # pipeline; one given by hand would be overridden, so it is refused.
    from mocapfill.pipeline import complete_matrix

    with pytest.raises(ParameterError, match="centre"):
        RepairOptions(method=method, solver_options={"centre": [0.0] * 6})
    matrix = np.random.default_rng(0).normal(size=(6, 100))
    observed = np.ones(matrix.shape, dtype=bool)
    observed[0:3, 40:50] = False
    with pytest.raises(ParameterError, match="'centre' is not an option"):
        complete_matrix(matrix, observed, method, centre=np.zeros(6))


@pytest.mark.parametrize(("options", "message"), [
    ({"rnak": 3}, "--rnak does not apply to method 'trnn-lowrank'"),
    ({"tol": -1.0}, "--tol must be > 0, got -1.0"),
    ({"tol": float("nan")}, "--tol must be finite, got nan"),
    ({"lam": -1.0}, "--lam must be > 0, got -1.0"),
    ({"max_iter": 2.5}, "--max-iter must be a whole number, got 2.5"),
    ({"rank": "3"}, "--rank must be a number, got '3'"),
])
def test_complete_matrix_refuses_the_options_repair_options_refuses(options, message):
    # A misspelt option gave the default's fill, a negative tol or lam was taken.
    from mocapfill.pipeline import complete_matrix

    matrix, observed = gapped_clip()[1].matrix()
    with pytest.raises(ParameterError, match=re.escape(message)):
        RepairOptions(method="trnn-lowrank", solver_options=options)
    with pytest.raises(ParameterError, match=re.escape(message)):
        complete_matrix(matrix, observed, "trnn-lowrank", **options)


def test_complete_matrix_takes_counts_as_whole_floats_and_none_as_the_default():
    from mocapfill.pipeline import complete_matrix

    matrix, observed = gapped_clip()[1].matrix()
    given = complete_matrix(matrix, observed, "trnn-lowrank", rank=3.0, tol=None, rate=120.0)
    np.testing.assert_array_equal(given, complete_matrix(matrix, observed, "trnn-lowrank",
                                                         rank=3))
