import re

import numpy as np
import pytest

from mocapfill.errors import ParameterError
from mocapfill.gaps import find_gaps, missing_runs, simulate_gaps, summarise

from .helpers import smooth_clip, with_gap


def test_missing_runs_finds_interior_and_end_runs():
    observed = np.array([0, 1, 1, 0, 0, 1, 0], bool)
    assert missing_runs(observed) == [(0, 1), (3, 5), (6, 7)]


def test_find_gaps_flags_clip_ends():
    motion = with_gap(with_gap(smooth_clip(50, 3), 1, 0, 5), 2, 10, 20)
    gaps = find_gaps(motion)
    assert [(g.label, g.start, g.stop, g.at_start, g.at_end) for g in gaps] == [
        ("MK01", 0, 5, True, False), ("MK02", 10, 20, False, False)]


def test_summary_counts_missing_gaps_and_longest():
    motion = with_gap(with_gap(smooth_clip(100, 2), 0, 10, 40), 0, 60, 65)
    row = summarise(motion)[0]
    assert (row.missing, row.gaps, row.longest) == (35, 2, 30)
    assert row.longest_s == pytest.approx(30 / 120)


def test_random_missing_removes_fraction_of_markers_in_every_frame():
    motion = smooth_clip(200, 10)
    gapped = simulate_gaps(motion, mr=0.4, seed=3)
    removed = (~gapped.observed).sum(axis=1)
    assert (removed == 4).sum() >= 199  # one frame may keep a marker's last sample


def test_random_missing_close_to_one_keeps_a_marker_in_every_frame():
    # mr = 0.99 of 10 markers rounds to all 10: every frame lost every marker, and the
    # rule that keeps a marker's last sample put back frame 0 alone.
    gapped = simulate_gaps(smooth_clip(200, 10), mr=0.99, seed=1)
    assert ((~gapped.observed).sum(axis=1) == 9).all()


def test_continuous_missing_removes_interior_runs_of_ml_frames():
    motion = smooth_clip(300, 15)
    gapped = simulate_gaps(motion, ml=40, markers=10, seed=7)
    gaps = find_gaps(gapped)
    assert len(gaps) == 10
    assert all(g.length == 40 and not g.at_start and not g.at_end for g in gaps)


def test_simulation_is_reproducible_with_a_seed_and_keeps_existing_gaps():
    motion = with_gap(smooth_clip(300, 15), 0, 100, 120)
    a = simulate_gaps(motion, ml=30, seed=11)
    b = simulate_gaps(motion, ml=30, seed=11)
    np.testing.assert_array_equal(a.observed, b.observed)
    assert not a.observed[100:120, 0].any()


def test_random_missing_on_a_clip_with_gaps_removes_among_the_markers_seen():
    # 4 of 10 markers per frame; marker 0 is missing over frames 0–99 and markers 1–6 over
    # 50–59 (3 seen there: 2 of them go, never all). A pick of a marker already missing
    # removed nothing, and such frames lost fewer samples than asked.
    motion = smooth_clip(200, 10)
    motion = with_gap(motion, 0, 0, 100)
    for j in range(1, 7):
        motion = with_gap(motion, j, 50, 60)
    gapped = simulate_gaps(motion, mr=0.4, seed=3)
    removed = (motion.observed & ~gapped.observed).sum(axis=1)
    assert (removed[100:] == 4).sum() >= 99 and (removed[:50] == 4).all()
    assert (removed[50:60] == 2).all() and gapped.observed[50:60].any(axis=1).all()
    assert (gapped.observed <= motion.observed).all()


def test_continuous_missing_makes_new_gaps_of_ml_frames_away_from_the_clips_own():
    # Marker 0 is seen only at the start and the end, so no 32 frames in a row: another
    # marker takes its run. Markers 1–9 have end gaps and an interior gap: every run is
    # a new interior gap of exactly 30 frames, seen before and after (merged with an end
    # gap, its samples went unscored; with a gap, fewer samples went than asked).
    motion = smooth_clip(300, 15)
    motion = with_gap(motion, 0, 5, 295)
    for j in range(1, 10):
        motion = with_gap(with_gap(with_gap(motion, j, 0, 40), j, 260, 300), j, 120, 140)
    for seed in range(20):
        gapped = simulate_gaps(motion, ml=30, markers=10, seed=seed)
        new = motion.observed & ~gapped.observed
        assert new.sum() == 300 and new.any(axis=0).sum() == 10 and not new[:, 0].any()
        assert (gapped.observed <= motion.observed).all()
        for j in np.flatnonzero(new.any(axis=0)):
            frames = np.flatnonzero(new[:, j])
            a, b = frames[0], frames[-1] + 1
            assert b - a == 30 and motion.observed[a - 1:b + 1, j].all()


def test_continuous_missing_on_a_clip_without_gaps_draws_as_it_always_did():
    # The draws of the benchmarks' cells (gap-free clips) are the protocol's first ones,
    # unchanged: the runs of seed 7 start where the plain draws put them.
    motion = smooth_clip(300, 15)
    rng = np.random.default_rng(7)
    chosen = rng.choice(np.arange(15), size=10, replace=False)
    starts = [int(rng.integers(1, 300 - 40)) for _ in chosen]
    expected = np.ones_like(motion.observed)
    for j, s in zip(chosen, starts):
        expected[s:s + 40, j] = False
    np.testing.assert_array_equal(simulate_gaps(motion, ml=40, seed=7).observed, expected)


@pytest.mark.parametrize("kwargs", [dict(mr=1.0), dict(mr=-0.1), dict(ml=0), dict(ml=10_000),
                                    dict(), dict(mr=0.2, ml=10)])
def test_absurd_simulation_parameters_are_rejected(kwargs):
    with pytest.raises(ParameterError):
        simulate_gaps(smooth_clip(100, 5), **kwargs)


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(ml=40.5), "ml must be a whole number, got 40.5"),
    (dict(ml=True), "ml must be a whole number, got True"),
    (dict(ml="3"), "ml must be a whole number, got '3'"),
    (dict(ml=3, markers=2.5), "markers must be a whole number, got 2.5"),
    (dict(mr=0.3, markers=3), "markers applies to ml (continuous missing), not mr"),
    (dict(mr=0.3, markers=10), "markers applies to ml (continuous missing), not mr"),
    (dict(mr="0.4"), "mr must be a number in [0, 1), got '0.4'"),
    (dict(mr=True), "mr must be a number in [0, 1), got True"),
    (dict(mr=0.3, seed=1.5), "seed must be a whole number, got 1.5"),
    (dict(mr=0.3, seed=[1, 2]), "seed must be a whole number, got [1, 2]"),
])
def test_simulation_arguments_follow_the_command_lines_rules(kwargs, message):
    # ml=40.5 and ml=3.0 failed deep inside (slice indices must be integers), ml=True acted
    # as 1, markers given with mr was ignored.
    with pytest.raises(ParameterError, match=re.escape(message)):
        simulate_gaps(smooth_clip(100, 5), **kwargs)


def test_simulation_counts_given_as_numpy_integers_or_whole_floats_are_those_counts():
    motion = smooth_clip(100, 5)
    expected = simulate_gaps(motion, ml=3, markers=2, seed=4).observed
    for given in (dict(ml=3.0, markers=2.0, seed=4.0),
                  dict(ml=np.int64(3), markers=np.int64(2), seed=np.int64(4))):
        np.testing.assert_array_equal(simulate_gaps(motion, **given).observed, expected)


def test_gap_frames_lists_every_frame_of_every_run_in_order():
    from mocapfill.gaps import gap_frames

    starts, stops = np.array([3, 10, 10, 40]), np.array([5, 11, 14, 40])   # one empty run
    run, frames = gap_frames(starts, stops)
    expected = [(i, f) for i, (a, b) in enumerate(zip(starts, stops)) for f in range(a, b)]
    assert list(zip(run.tolist(), frames.tolist())) == expected
