"""The default blend's validation: stand-ins (pseudo_gaps) and the weights they give."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from mocapfill.solvers._linalg import simplex_least_squares
from mocapfill.solvers.gapwise import (
    GapSet,
    _bagged,
    _bagged_many,
    _cross_validated,
    _cross_validated_stacks,
    _resampled_sums,
    _stack,
    _without_outliers,
    evidence,
    interior_gaps,
    join_ends,
    length_class,
    length_classes,
    pseudo_gaps,
    ramp,
    row_groups,
)


def _mask(n_markers: int, n: int, gaps: list[tuple[int, int, int]]) -> np.ndarray:
    seen = np.ones((n_markers, n), bool)
    for marker, a, b in gaps:
        seen[marker, a:b] = False
    return np.repeat(seen, 3, axis=0)


def _stand_ins(observed: np.ndarray, seed: int = 0, **options):
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    return gapset, pseudo_gaps(observed, gapset, np.random.default_rng(seed), **options)


def _check_stand_ins(observed, gapset, chosen, fraction=0.1, plain=True):
    """Stand-ins are gaps of the real gap's length between observed frames, apart from
    each other, within the budget; ``plain``: made of observed frames only."""
    seen = observed[0::3]
    window = np.zeros_like(seen)
    hidden = 0
    for (g, s, t), source in chosen:
        _, a, b = gapset.gaps[source]
        assert t - s == b - a                      # same length as the real gap
        assert seen[g, s - 1] and seen[g, t]       # observed on both sides
        assert seen[g, s:t].any()                  # something hidden to score
        assert not plain or seen[g, s:t].all()
        # one observed, unhidden frame between it and any other stand-in of that marker
        assert not window[g, max(s - 1, 0):t + 1].any()
        window[g, s:t] = True
        hidden += seen[g, s:t].sum()
    assert hidden <= fraction * seen.sum()


def test_stand_ins_are_observed_stretches_of_the_same_marker_and_length():
    gaps = [(0, 100, 140), (3, 400, 430), (5, 700, 702), (7, 250, 251)]
    observed = _mask(10, 1000, gaps)
    gapset, chosen = _stand_ins(observed)
    _check_stand_ins(observed, gapset, chosen)
    assert chosen
    for (g, _, _), source in chosen:
        assert g == gapset.gaps[source][0]


def test_stand_ins_respect_the_budget_on_a_crowded_mask():
    rng = np.random.default_rng(3)
    gaps = [(int(rng.integers(12)), int(a), int(a + rng.integers(1, 80)))
            for a in rng.integers(1, 1800, 60)]
    observed = _mask(12, 2000, gaps)
    for fraction in (0.02, 0.1):
        gapset, chosen = _stand_ins(observed, seed=1, fraction=fraction)
        _check_stand_ins(observed, gapset, chosen, fraction)


def test_length_classes_of_an_array_are_each_lengths_class():
    # Every power of two and its neighbours (where the class changes), up to 2^40 frames.
    lengths = np.unique([max(p + d, 0) for p in (2 ** np.arange(41)).tolist()
                         for d in (-1, 0, 1)])
    classes = length_classes(lengths)
    assert classes.dtype == np.int64
    assert classes.tolist() == [length_class(int(x)) for x in lengths]
    assert length_classes(np.array([1, 2, 3, 4, 5, 8, 9])).tolist() == [0, 1, 2, 2, 3, 3, 4]


def test_dense_loss_gets_long_stand_ins_that_absorb_missing_frames():
    # 60 % of frames missing at random, one marker at a time: runs of 7+ observed frames
    # are rare, so long real gaps could not get stand-ins made of observed frames only.
    rng = np.random.default_rng(5)
    seen = rng.random((8, 3000)) > 0.6
    seen[:, [0, -1]] = True
    observed = np.repeat(seen, 3, axis=0)
    gapset, chosen = _stand_ins(observed)
    _check_stand_ins(observed, gapset, chosen, plain=False)
    long_real = sum(b - a >= 5 for _, a, b in gapset.gaps)
    long_stand_ins = [(g, s, t) for (g, s, t), _ in chosen if t - s >= 5]
    assert long_real > 50 and len(long_stand_ins) >= 50
    # Most of these absorb real missing frames, and score only the frames they hid.
    assert sum(not seen[g, s:t].all() for g, s, t in long_stand_ins) > len(long_stand_ins) / 2


def test_odd_spline_fill_takes_the_cubic_where_one_side_lacks_support():
    from scipy.interpolate import make_interp_spline

    from mocapfill.solvers.gapwise import odd_spline_fill
    from mocapfill.solvers.interp import spline

    n = 200
    t = np.arange(n, dtype=float)
    row = np.sin(t / 9.0) + 0.3 * np.cos(t / 4.0)
    observed = np.ones((1, n), bool)
    observed[0, 1:3] = False         # one sample before it: too little for degree 5
    observed[0, 100:103] = False     # well inside
    observed[0, n - 4:n - 2] = False  # two samples after it
    matrix = np.where(observed, row, np.nan)
    out = odd_spline_fill(matrix, observed, degree=5)
    cubic = spline(matrix, observed)
    quintic = make_interp_spline(t[observed[0]], row[observed[0]], k=5)(t)
    for a, b in ((1, 3), (n - 4, n - 2)):
        np.testing.assert_array_equal(out[0, a:b], cubic[0, a:b])
    np.testing.assert_allclose(out[0, 100:103], quintic[100:103], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out[observed], row[observed[0]])


def test_convex_fit_from_gram_matrices_minimises_the_stacked_error():
    rng = np.random.default_rng(3)
    blocks = [rng.normal(size=(12, 3)) * [1.0, 1.3, 2.0] for _ in range(20)]
    gram = sum(b.T @ b for b in blocks)
    w = simplex_least_squares(gram)
    assert w.min() >= 0 and np.isclose(w.sum(), 1.0)
    E = np.vstack(blocks)
    best = min(((a, b, 1 - a - b) for a in np.linspace(0, 1, 201)
                for b in np.linspace(0, 1, 201) if a + b <= 1),
               key=lambda v: float(((E @ np.array(v)) ** 2).sum()))
    assert ((E @ w) ** 2).sum() <= ((E @ np.array(best)) ** 2).sum() + 1e-9
    # Opposite errors cancel: the blend is the midpoint.
    e = rng.normal(size=(30, 1))
    assert np.allclose(simplex_least_squares(evidence(np.hstack([e, -e]))[0]), [0.5, 0.5],
                       atol=1e-6)


def test_convex_fit_keeps_a_candidate_whose_error_is_next_to_nothing_beside_the_others():
    # Dividing by a subnormal best error overflowed (a warning, inf in the products).
    gram = np.array([[1e-310, 0.0], [0.0, 1e10]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert simplex_least_squares(gram).tolist() == [1.0, 0.0]


def test_bagged_weights_keep_a_clear_winner_and_hedge_a_close_call():
    rng = np.random.default_rng(0)
    z = rng.normal(size=(40, 10))
    # Clear: candidate 1 errs ten times less than the others on every stand-in.
    clear = [evidence(np.stack([z[i], 0.1 * z[i], 1.5 * z[i]], axis=1)) for i in range(40)]
    assert np.allclose(_bagged(clear, np.random.default_rng(1)), [0, 1, 0])
    # Close: both candidates share the bulk of their errors, and each is the better one on
    # half of the stand-ins by a few per cent; one hard choice stakes everything on
    # whichever the stand-ins' sample favours, the bagged weights share between the two.
    close = []
    for i in range(12):
        shrink = 0.97 if i % 2 else 1.03
        close.append(evidence(np.stack([z[i], shrink * z[i] + 0.01 * z[i + 20]], axis=1)))
    hard = _cross_validated(_stack(close))
    bagged = _bagged(close, np.random.default_rng(1))
    assert np.isclose(bagged.sum(), 1.0)
    assert 0.15 < bagged[0] < 0.85
    assert hard.max() > bagged.max()
    # Deterministic for a given generator.
    assert np.array_equal(bagged, _bagged(close, np.random.default_rng(1)))


def test_resamples_side_by_side_are_each_resample_alone():
    # The bagged resamples are solved together; each must be what its own two-fold fit
    # gives, from the sums of exactly its stand-ins (repeats counted).
    rng = np.random.default_rng(4)
    z = rng.normal(size=(60, 12))
    # Two close contenders (each better on half of the stand-ins) and a worse third: the
    # blend generalises on some resamples and not on others.
    blocks = [evidence(np.stack([z[i], (0.97 if i % 2 else 1.03) * z[i] + 0.1 * z[i + 30],
                                 1.5 * z[i] + 0.2 * z[i + 1]], axis=1)) for i in range(30)]
    stack = _stack(blocks)
    orders = rng.integers(0, 30, (40, 30))
    together = _cross_validated_stacks([stack], [orders])[0]
    sums = _resampled_sums(stack[0], orders)
    def alone(order):     # the two-fold rule, one resample at a time
        gram = sum(blocks[i][0] for i in order)
        folds = [sum(blocks[i][0] for i in half) for half in (order[0::2], order[1::2])]
        blend_err = single_err = 0.0
        for fit, test in (folds, folds[::-1]):
            w = simplex_least_squares(fit)
            blend_err += w @ test @ w
            single_err += test.diagonal()[np.argmin(fit.diagonal())]
        return (simplex_least_squares(gram) if blend_err < single_err
                else np.eye(3)[np.argmin(gram.diagonal())])

    blended = 0
    for order, w, total in zip(orders, together, sums):
        np.testing.assert_allclose(total, sum(blocks[i][0] for i in order), rtol=1e-12)
        np.testing.assert_allclose(w, alone(order), rtol=0, atol=1e-12)
        blended += int((w > 0).sum() > 1)
    assert 0 < blended < len(orders)      # both outcomes of the rule are exercised
    # Fewer than four stand-ins: the best single candidate of the resample.
    few = _cross_validated_stacks([stack], [orders[:, :3]])[0]
    np.testing.assert_array_equal(few, np.eye(3)[[np.argmin(np.diag(g)) for g in
                                                  _resampled_sums(stack[0], orders[:, :3])]])


def test_several_gaps_bagged_together_are_each_bagged_alone_in_turn():
    # Stand-in lists of different sizes (3: the best single candidate, no fit), one a
    # clear call and others close: solved side by side, each must get exactly the weights
    # it gets alone, with the generator drawn in the same order.
    rng = np.random.default_rng(8)
    def blocks(count, spread):
        return [evidence(rng.normal(size=(30, 3)) * [1.0, 1.0 + spread, 1.5])
                for _ in range(count)]
    lists = [blocks(6, 0.02), blocks(3, 0.0), blocks(11, 0.5), blocks(8, 0.01)]
    together = _bagged_many(lists, np.random.default_rng(2))
    alone_rng = np.random.default_rng(2)
    alone = [_bagged(b, alone_rng) for b in lists]
    for w, expected in zip(together, alone):
        np.testing.assert_array_equal(w, expected)
    assert any(((w > 0) & (w < 1)).any() for w in together)   # some hedged (blended)
    assert _bagged_many([], np.random.default_rng(2)) == []


def test_the_bootstrap_resamples_are_the_generators_draws_round_by_round(monkeypatch):
    # All of a list's rounds are drawn in one call; the resamples (and every later draw)
    # must be those of one call per round, as the measured figures were made with.
    from mocapfill.solvers import gapwise

    seen = []
    original = gapwise._cross_validated_stacks
    monkeypatch.setattr(gapwise, "_cross_validated_stacks",
                        lambda stacks, orders: seen.append(orders) or original(stacks, orders))
    rng = np.random.default_rng(5)
    lists = [[evidence(rng.normal(size=(4, 3)))] * size for size in (7, 1, 30, 2)]
    rng, reference = np.random.default_rng(9), np.random.default_rng(9)
    rng.integers(0, 3, 3), reference.integers(0, 3, 3)   # an odd start of the stream
    _bagged_many(lists, rng, rounds=5)
    for orders, blocks in zip(seen[0], lists):
        expected = [reference.integers(0, len(blocks), len(blocks)) for _ in range(5)]
        np.testing.assert_array_equal(orders, expected)
    assert rng.integers(0, 1 << 40) == reference.integers(0, 1 << 40)


def test_join_ends_adds_each_gaps_ramp_for_marker_and_single_row_groups():
    # All gaps at once must be the per-gap ramp of the offsets at the samples just outside.
    rng = np.random.default_rng(3)
    for split in (False, True):
        observed = rng.random((12, 200)) > 0.3
        if not split:
            observed = np.repeat(observed[0::3], 3, axis=0)
        groups = row_groups(observed)
        assert groups.shape[1] == (1 if split else 3)
        gapset = GapSet(groups, interior_gaps(observed, groups))
        matrix, fill = rng.normal(size=(2, 12, 200))
        expected = np.where(observed, matrix, fill)
        for g, a, b in gapset.gaps:
            rows = groups[g]
            expected[rows, a:b] = fill[rows, a:b] + ramp(
                matrix[rows, a - 1] - fill[rows, a - 1], matrix[rows, b] - fill[rows, b], b - a)
        assert len(gapset.gaps) > 50
        np.testing.assert_array_equal(join_ends(fill, matrix, observed, gapset), expected)


def _one_gap(w, fills, **options):
    """``_without_outliers`` on a single gap (it takes a batch of gaps of one length)."""
    return _without_outliers(np.asarray(w)[None], np.stack(fills)[None], **options)[0]


def test_a_candidate_gone_wild_on_a_gap_loses_its_weight_there():
    rng = np.random.default_rng(11)
    truth = np.cumsum(rng.normal(size=(3, 40)), axis=1)
    fills = [truth + 0.1 * rng.normal(size=truth.shape) for _ in range(6)]
    w = np.array([0.4, 0.2, 0.2, 0.1, 0.07, 0.03])
    np.testing.assert_array_equal(_one_gap(w, fills), w)      # all agree
    fills[5] = truth + 30.0                                             # 300× the others' spread
    trimmed = _one_gap(w, fills)
    assert trimmed[5] == 0 and trimmed.sum() == pytest.approx(1.0)
    np.testing.assert_allclose(trimmed[:5], w[:5] / 0.97)
    # Only the outlier had weight: the weights stand (nothing better is known).
    np.testing.assert_array_equal(_one_gap(np.eye(6)[5], fills), np.eye(6)[5])
    # Identical fills (distance 0 for most): nothing is judged an outlier.
    same = [truth] * 5 + [truth + 1.0]
    np.testing.assert_array_equal(_one_gap(w, same), w)


def test_long_gaps_judge_outliers_more_strictly_than_short_ones():
    # A fill 2.5× the typical distance from the median fill: kept on a short gap, where
    # candidates agree closely and the spread is the fills' own; left out on a long gap,
    # where candidates go wild (see OUTLIER_FACTOR).
    from mocapfill.solvers.gapwise import LONG_GAP, outlier_factor

    rng = np.random.default_rng(14)
    truth = np.cumsum(rng.normal(size=(3, LONG_GAP)), axis=1)
    offsets = [-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.5]
    fills = [truth + d for d in offsets]      # the median fill is truth; typical distance 0.2
    w = np.full(7, 1 / 7)
    distance = np.sqrt(((np.stack(fills) - np.median(np.stack(fills), axis=0)) ** 2)
                       .mean(axis=(1, 2)))
    assert 2 < distance[6] / np.median(distance) < 3
    assert outlier_factor(LONG_GAP - 1) == 3.0 and outlier_factor(LONG_GAP) == 2.0
    short = _one_gap(w, fills, factor=outlier_factor(LONG_GAP - 1))
    long = _one_gap(w, fills, factor=outlier_factor(LONG_GAP))
    np.testing.assert_allclose(short, w)
    assert long[6] == 0 and long.sum() == pytest.approx(1.0)


def test_outliers_are_judged_again_around_the_median_of_the_others():
    # Three wild fills drag the first median towards themselves: the first round only
    # catches them, the second one also the fill 10× farther off than the good ones.
    rng = np.random.default_rng(12)
    truth = np.cumsum(rng.normal(size=(3, 30)), axis=1)
    fills = [truth + 0.1 * rng.normal(size=truth.shape) for _ in range(4)]
    fills += [truth + 1.0] + [truth + 20.0] * 3
    w = np.full(8, 1 / 8)
    once = _one_gap(w, fills, rounds=1)
    np.testing.assert_allclose(once, np.r_[np.full(5, 0.2), np.zeros(3)])
    again = _one_gap(w, fills)
    np.testing.assert_allclose(again, np.r_[np.full(4, 0.25), np.zeros(4)])


def test_outliers_of_many_gaps_at_once_are_those_of_each_gap_alone():
    # The batched rule against a plain per-gap transcription with np.median, bit for bit,
    # on gaps with no outlier, one, a cluster, identical fills and all-zero weights.
    def alone(w, stack, rounds=3):
        inlier = np.ones(len(w), dtype=bool)
        for _ in range(rounds):
            centre = np.median(stack[inlier], axis=0)
            distance = np.sqrt(((stack - centre) ** 2).mean(axis=(1, 2)))
            typical = float(np.median(distance[inlier]))
            if typical <= 0:
                break
            judged = distance <= 3.0 * typical
            if (judged == inlier).all():
                break
            inlier = judged
        kept = np.where(inlier, w, 0.0)
        return kept / kept.sum() if kept.sum() > 0 else w

    rng = np.random.default_rng(13)
    k, length = 7, 12
    truth = np.cumsum(rng.normal(size=(60, 1, 3, length)), axis=3)
    segments = truth + 0.1 * rng.normal(size=(60, k, 3, length))
    segments[10:20, 6] += 30.0
    segments[20:30, 4:] += rng.choice([1.0, 20.0], size=(10, 3, 1, 1))
    segments[30:35] = truth[30:35]
    w = rng.dirichlet(np.ones(k), size=60)
    w[40:45] = np.eye(k)[6]
    w[45:50] = 0.0
    batched = _without_outliers(w, segments)
    for g in range(60):
        np.testing.assert_array_equal(batched[g], alone(w[g], segments[g]))
    assert (batched[10:20, 6] == 0).all()


@pytest.fixture
def in_this_process(monkeypatch):
    """Candidates run in this process, one after the other, so that the calls they record
    are seen here (with more threads, the validation runs may go to a forked child)."""
    monkeypatch.setenv("MOCAPFILL_THREADS", "1")


def _counting(fn, calls: list, name: str):
    def candidate(matrix, observed):
        calls.append((name, observed.copy()))
        return fn(matrix, observed)
    return candidate


def test_a_borrowed_validation_weighs_the_fill_without_running_the_candidates_twice(
        in_this_process):
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import Validation, blend

    t = np.arange(600) / 60.0
    truth = np.vstack([np.sin(1.3 * (j + 1) * t + j) for j in range(18)])   # 6 markers

    def clip(gaps):
        observed = _mask(6, 600, gaps)
        return np.where(observed, truth, 0.0), observed

    calls: list = []
    candidates = {"exact": _counting(lambda a, o: truth.copy(), calls, "exact"),
                  "linear": _counting(linear_fill, calls, "linear")}
    first, first_mask = clip([(0, 100, 130), (2, 300, 320), (4, 450, 460)])
    _, report = blend(first, first_mask, candidates, default="linear")
    assert sorted(name for name, _ in calls) == ["exact", "exact", "linear", "linear"]
    lent = report.validation
    assert lent.by_class and lent.by_gap          # evidence per class and per real gap

    calls.clear()
    second, second_mask = clip([(1, 200, 226), (3, 500, 512)])
    filled, second_report = blend(second, second_mask, candidates, default="linear",
                                  validation=Validation.pooled([lent]))
    # Once each, on the real mask; the evidence says "exact", so the gaps are exact.
    assert sorted(name for name, _ in calls) == ["exact", "linear"]
    assert all((mask == second_mask).all() for _, mask in calls)
    assert second_report.pseudo_gaps == 0
    np.testing.assert_allclose(filled, truth, atol=1e-12)


def test_pooled_validations_add_their_class_evidence_and_drop_the_per_gap_evidence():
    from mocapfill.solvers.gapwise import Validation

    block = evidence(np.ones((4, 2)))
    a = Validation(("x", "y"), {0: [block], 3: [block]}, {5: [block]})
    b = Validation(("x", "y"), {3: [block, block]}, {})
    pooled = Validation.pooled([a, b])
    assert {cls: len(blocks) for cls, blocks in pooled.by_class.items()} == {0: 1, 3: 3}
    assert pooled.by_gap == {}
    assert len(a.by_class[3]) == 1                 # the lenders are left as they were
    with pytest.raises(ValueError, match="different candidates"):
        Validation.pooled([a, Validation(("x", "z"), {}, {})])


def test_costly_candidates_start_first_and_the_fill_does_not_depend_on_the_order(monkeypatch):
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import blend
    from mocapfill.solvers.interp import spline

    monkeypatch.setenv("MOCAPFILL_THREADS", "1")        # jobs run in the order given
    t = np.arange(400) / 60.0
    truth = np.vstack([np.sin(0.7 * (j + 1) * t) for j in range(12)])
    observed = _mask(4, 400, [(0, 50, 62), (1, 200, 203), (3, 300, 340)])
    matrix = np.where(observed, truth, 0.0)
    results = {}
    for costly in ((), ("slow",)):
        calls: list = []
        candidates = {"linear": _counting(linear_fill, calls, "linear"),
                      "spline": _counting(spline, calls, "spline"),
                      "slow": _counting(lambda a, o: spline(a, o) + 0.0, calls, "slow")}
        results[costly], _ = blend(matrix, observed, candidates, default="spline",
                                   costly=costly)
        names = [name for name, _ in calls]
        assert names[:2] == (["slow", "slow"] if costly else ["linear", "linear"])
    np.testing.assert_array_equal(results[()], results[("slow",)])


def test_optional_candidates_without_weight_are_not_run_on_the_real_mask(in_this_process):
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import Validation, blend

    t = np.arange(600) / 60.0
    truth = np.vstack([np.sin(1.1 * (j + 1) * t + j) for j in range(18)])   # 6 markers
    # Interior gaps, and one at the clip's start (the default candidate's to fill).
    observed = _mask(6, 600, [(0, 100, 130), (2, 300, 320), (4, 450, 460), (5, 0, 25)])
    matrix = np.where(observed, truth, 0.0)
    calls: list = []
    candidates = {"exact": _counting(lambda a, o: truth.copy(), calls, "exact"),
                  "linear": _counting(linear_fill, calls, "linear"),
                  "wild": _counting(lambda a, o: truth + 50.0, calls, "wild")}

    # (the end gap unvalidated: the default's fill; validated, that of the candidate its
    # stand-ins weigh, test_end_gaps_take_the_candidates_their_own_stand_ins_weigh)
    filled, report = blend(matrix, observed, candidates, default="wild", validate_ends=False)
    assert sorted(name for name, _ in calls) == ["exact", "exact", "linear", "linear",
                                                 "wild", "wild"]
    np.testing.assert_allclose(filled[15:18, :25], truth[15:18, :25] + 50.0)

    calls.clear()
    filled, report = blend(matrix, observed, candidates, default="wild", optional=("wild",))
    # "wild" ran on the stand-ins only (its weight is 0 on every gap); "exact" took every
    # interior gap and, with the most weight, the end gap in place of the default.
    assert sorted(name for name, _ in calls) == ["exact", "exact", "linear", "linear",
                                                 "wild"]
    wild_masks = [mask for name, mask in calls if name == "wild"]
    assert not (wild_masks[0] == observed).all()
    np.testing.assert_allclose(filled, truth, atol=1e-12)

    calls.clear()
    borrowed = Validation.pooled([report.validation])
    filled, _ = blend(matrix, observed, candidates, default="wild", optional=("wild",),
                      validation=borrowed)
    assert sorted(name for name, _ in calls) == ["exact", "linear"]
    np.testing.assert_allclose(filled, truth, atol=1e-12)


def test_a_validator_runs_in_place_of_its_candidate_on_the_stand_ins_only(in_this_process):
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import blend

    t = np.arange(600) / 60.0
    truth = np.vstack([np.sin(0.9 * (j + 1) * t + j) for j in range(18)])   # 6 markers
    observed = _mask(6, 600, [(0, 100, 130), (2, 300, 320), (4, 450, 460)])
    matrix = np.where(observed, truth, 0.0)
    calls: list = []
    candidates = {"exact": _counting(lambda a, o: truth.copy(), calls, "exact"),
                  "linear": _counting(linear_fill, calls, "linear")}
    # The validator of "exact" errs wildly on the stand-ins: "linear" wins the weights, and
    # the real gaps are filled (almost) as "linear" fills them, although "exact" itself
    # ran on the real mask.
    noise = 50.0 * np.random.default_rng(0).standard_normal(truth.shape)
    validators = {"exact": _counting(lambda a, o: truth + noise, calls, "cheap exact")}
    filled, report = blend(matrix, observed, candidates, default="exact",
                           validators=validators)
    masks = {name: [mask for n, mask in calls if n == name] for name, _ in calls}
    assert sorted(masks) == ["cheap exact", "exact", "linear"]
    assert len(masks["cheap exact"]) == 1 and not (masks["cheap exact"][0] == observed).all()
    assert len(masks["exact"]) == 1 and (masks["exact"][0] == observed).all()
    assert len(masks["linear"]) == 2
    linear = linear_fill(matrix, observed)
    error, linear_error = (np.linalg.norm((f - truth)[~observed]) for f in (filled, linear))
    assert 0.9 * linear_error < error < 1.1 * linear_error


def test_a_candidate_run_once_fills_the_real_gaps_from_its_validation_run(in_this_process):
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import blend

    t = np.arange(600) / 60.0
    truth = np.vstack([np.sin(0.8 * (j + 1) * t + j) for j in range(18)])   # 6 markers
    observed = _mask(6, 600, [(0, 100, 130), (2, 300, 320), (4, 450, 460), (5, 0, 25)])
    matrix = np.where(observed, truth, 0.0)
    results = {}
    for once in ((), ("linear",)):
        calls: list = []
        candidates = {"linear": _counting(linear_fill, calls, "linear"),
                      "shifted": _counting(lambda a, o: truth + 7.0, calls, "shifted")}
        # (Not the end gap's own-marker stand-in, which lengthens the real end gap in the
        # validation run: end_stand_ins.)
        results[once], report = blend(matrix, observed, candidates, default="shifted",
                                      once=once, validate_ends=False)
        masks = [mask for name, mask in calls if name == "linear"]
        assert len(masks) == (1 if once else 2)
        assert report.pseudo_gaps > 0 and not (masks[0] == observed).all()
    # Linear interpolation depends on a gap's end samples alone, and stand-ins keep an
    # observed frame between themselves and a real gap: the fill of the real gaps from the
    # validation run is the fill on the real mask, and the weights the same.
    np.testing.assert_array_equal(results[()], results[("linear",)])


def test_a_fill_run_once_is_joined_to_the_real_gap_ends_a_stand_in_took_in():
    from mocapfill.solvers.gapwise import _stand_in_errors_and_fill

    t = np.arange(300) / 60.0
    truth = np.vstack([np.sin(0.5 * (j + 1) * t) for j in range(6)])        # 2 markers
    observed = _mask(2, 300, [(1, 150, 160)])
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    # A dense-loss stand-in [140, 170) took in the real gap: the validation run's fill
    # of 140–169 meets the data at 139 and 170, not at the real gap's ends 149 and 160.
    train = observed.copy()
    train[3:6, 140:170] = False
    rows = np.repeat(groups[1][None, :], 20, axis=0)
    frames = np.r_[140:150, 160:170]
    errors, values = _stand_in_errors_and_fill(lambda a, o: truth + 7.0,
                                               np.where(train, truth, 0.0), train,
                                               np.where(observed, truth, 0.0), observed,
                                               gapset, rows, frames)
    np.testing.assert_allclose(errors, 7.0)          # scored on the hidden samples
    # The candidate's constant offset, removed by the ramp between the real ends.
    np.testing.assert_allclose(values, truth[~observed], atol=1e-12)


def test_nearest_frames_are_those_of_sorting_every_frame_by_distance():
    from mocapfill.solvers.gapwise import _nearest_frames

    for n in (1, 2, 7, 30):
        for a in range(n + 1):
            for b in range(a, n + 1):
                outside = np.r_[0:a, b:n]
                distance = np.maximum(a - outside, outside - b + 1)
                for count in range(0, n + 3):
                    expected = np.sort(outside[np.argsort(distance, kind="stable")[:count]])
                    np.testing.assert_array_equal(_nearest_frames(a, b, n, count), expected)


@pytest.mark.parametrize("name", ["rigid_fill", "regression_fill"])
def test_a_per_gap_fill_asked_for_some_gaps_fills_those_exactly_as_in_a_full_run(name):
    # The validation run asks these candidates for the stand-ins only (FILLS_GAPS_ALONE):
    # those fills must be the full run's, and the other gaps keep the linear fill.
    from mocapfill.solvers import gapwise
    from mocapfill.solvers._linalg import linear_fill

    fill = getattr(gapwise, name)
    assert fill in gapwise.FILLS_GAPS_ALONE
    rng = np.random.default_rng(3)
    t = np.arange(400) / 60.0
    base = rng.normal(size=(3, 3))
    turns = np.stack([np.sin(t + p) for p in rng.uniform(0, 6, 3)])      # (3, n)
    matrix = np.vstack([base @ turns + rng.normal(size=(3, 1)) * 5 for _ in range(6)])
    gaps = [(0, 50, 80), (2, 120, 160), (4, 200, 212), (0, 300, 340), (5, 10, 13)]
    observed = _mask(6, 400, gaps)
    wanted = frozenset([(0, 50, 80), (4, 200, 212), (5, 10, 13)])
    full = fill(matrix, observed)
    some = fill(matrix, observed, only=wanted)
    linear = linear_fill(matrix, observed)
    for g, a, b in gaps:
        rows = slice(3 * g, 3 * g + 3)
        expected = full if (g, a, b) in wanted else linear
        np.testing.assert_array_equal(some[rows, a:b], expected[rows, a:b])
    assert not np.array_equal(full[0:3, 300:340], linear[0:3, 300:340])   # a real model
    np.testing.assert_array_equal(some[observed], matrix[observed])


def test_regression_predicts_from_the_markers_nearest_the_gap_at_most_max_predictors():
    # 8 markers near the gapped one, 6 far away; with 8 predictors allowed the far
    # markers' data cannot change the fill, with all 13 it does.
    from mocapfill.solvers.gapwise import regression_fill

    rng = np.random.default_rng(5)
    t = np.arange(500) / 60.0
    turns = np.stack([np.sin(t * f + p) for f, p in zip(rng.uniform(0.5, 2, 3),
                                                       rng.uniform(0, 6, 3))])
    near = [rng.normal(size=(3, 3)) @ turns + rng.normal(size=(3, 1)) * 20 for _ in range(9)]
    far = [rng.normal(size=(3, 3)) @ turns + 1000 + rng.normal(size=(3, 1)) * 20
           for _ in range(6)]
    matrix = np.vstack(near + far)
    observed = _mask(15, 500, [(0, 200, 260)])
    moved = matrix.copy()
    moved[27:] += rng.normal(size=(18, 500)).cumsum(axis=1)          # the far markers wander
    gap = (slice(0, 3), slice(200, 260))
    assert np.array_equal(regression_fill(matrix, observed, max_predictors=8)[gap],
                          regression_fill(moved, observed, max_predictors=8)[gap])
    assert not np.allclose(regression_fill(matrix, observed)[gap],
                           regression_fill(moved, observed)[gap])
    # Moving one of the near markers does change it.
    nudged = matrix.copy()
    nudged[3:6] += rng.normal(size=(3, 500)).cumsum(axis=1)
    assert not np.allclose(regression_fill(matrix, observed, max_predictors=8)[gap],
                           regression_fill(nudged, observed, max_predictors=8)[gap])
    # Rows grouped singly (a mask split within a marker: a channel matrix) keep every
    # predictor.
    split = observed.copy()
    split[1, 50:55] = False
    assert not np.allclose(regression_fill(matrix, split, max_predictors=8)[0, 200:260],
                           regression_fill(moved, split, max_predictors=8)[0, 200:260])


def test_stand_ins_leave_half_of_the_complete_frames(in_this_process):
    """Stand-ins that would leave the validation clip fewer than half of the clip's
    complete frames are dropped (the global candidate's warm start is their subspace)."""
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import blend
    from mocapfill.solvers.interp import spline

    rng = np.random.default_rng(0)
    t = np.arange(1200)
    matrix = np.vstack([np.sin(t / rng.uniform(10, 40) + rng.uniform(0, 6)) for _ in range(24)])
    seen = np.ones((8, t.size), dtype=bool)
    for j in (0, 1):                                 # two markers with 40-frame gaps
        for start in range(50 + 100 * j, t.size - 100, 200):
            seen[j, start:start + 40] = False
    observed = np.repeat(seen, 3, axis=0)
    complete = observed.all(axis=0).sum()
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    placed = pseudo_gaps(observed, gapset, np.random.default_rng(0), fraction=0.1)
    masks = []

    def recording(matrix, observed):
        masks.append(observed.copy())
        return linear_fill(matrix, observed)

    _, report = blend(matrix, observed, {"linear": recording, "spline": spline},
                      default="linear", seed=0)
    train = next(mask for mask in masks if not np.array_equal(mask, observed))
    assert 0 < report.pseudo_gaps < len(placed)     # the floor dropped some
    assert complete // 2 <= train.all(axis=0).sum() < complete


def test_each_gap_takes_the_blend_of_its_own_weights_and_end_gaps_the_default(
        in_this_process):
    # Two length classes whose evidence favours different candidates: every gap of a class
    # must take its class's candidate (the gaps are grouped by equal weights before the
    # blend is written), and a clip whose only gaps touch its ends takes the default's fill.
    from mocapfill.solvers.gapwise import Validation, blend

    t = np.arange(600) / 60.0
    truth = np.vstack([np.sin(1.1 * (j + 1) * t + j) for j in range(18)])
    short, long = 0, 4                                  # classes of 1 and 9–16 frames
    errors = np.array([[1.0, 0.0], [0.0, 1.0]])         # "one" errs, "two" does not; swapped
    validation = Validation(("one", "two"),
                            {short: [evidence(errors[[0]].repeat(40, axis=0))] * 40,
                             long: [evidence(errors[[1]].repeat(40, axis=0))] * 40}, {})
    candidates = {"one": lambda a, o: np.full_like(truth, 1.0),
                  "two": lambda a, o: np.full_like(truth, 2.0)}
    gaps = [(0, 100, 101), (1, 200, 212), (2, 300, 301), (3, 400, 410), (5, 50, 51)]
    observed = _mask(6, 600, gaps)
    filled, _ = blend(np.where(observed, truth, 0.0), observed, candidates, default="one",
                      validation=validation)
    for marker, a, b in gaps:
        expected = 2.0 if b - a == 1 else 1.0           # the short class trusts "two"
        assert (filled[3 * marker:3 * marker + 3, a:b] == expected).all()
    np.testing.assert_array_equal(filled[observed], truth[observed])

    ends = _mask(6, 600, [(0, 0, 30), (4, 570, 600)])
    filled, _ = blend(np.where(ends, truth, 0.0), ends, candidates, default="two",
                      validation=validation)
    assert (filled[~ends] == 2.0).all()
    np.testing.assert_array_equal(filled[ends], truth[ends])


def test_end_gaps_take_the_candidates_their_own_stand_ins_weigh(in_this_process):
    # The default candidate is off by 1 on every missing sample, the other exact: the
    # interior gaps' stand-ins give the exact one all the weight there, and the end gaps'
    # own stand-ins (other markers hidden at the same end over the same frames) give it
    # theirs; told the end fills will not be used, the blend hides none there and the end
    # gaps keep the default's fill, as they all did before.
    from mocapfill.solvers.gapwise import blend, end_gaps, end_stand_ins, row_groups

    t = np.arange(600) / 60.0
    truth = np.vstack([np.sin(1.1 * (j + 1) * t + j) for j in range(30)])
    candidates = {"off": lambda a, o: np.where(o, a, truth + 1.0),
                  "exact": lambda a, o: truth.copy()}
    gaps = [(0, 100, 101), (1, 200, 212), (2, 300, 305), (3, 0, 20), (4, 585, 600)]
    observed = _mask(10, 600, gaps)
    ends = end_gaps(observed, row_groups(observed))
    assert ends == [(3, 0, 20), (4, 585, 600)]
    placed = end_stand_ins(observed, row_groups(observed), ends, np.random.default_rng(0))
    # First each end gap's own marker beside its gap (its end gap twice as long there),
    # then two other markers over the gap's frames.
    assert placed[0] in ((3, 20, 40), (4, 570, 585))
    assert {(3, 20, 40), (4, 570, 585)} <= set(placed) and len(placed) == 6
    others = set(placed) - {(3, 20, 40), (4, 570, 585)}
    assert {(a, b) for _, a, b in others} == {(0, 20), (585, 600)}
    assert not any(g in (3, 4) for g, _, _ in others)
    matrix = np.where(observed, truth, 0.0)
    for validate, at_ends in ((True, truth), (False, truth + 1.0)):
        filled, _ = blend(matrix, observed, candidates, default="off",
                          validate_ends=validate)
        for marker, a, b in gaps:
            rows = slice(3 * marker, 3 * marker + 3)
            expected = at_ends if a == 0 or b == 600 else truth
            np.testing.assert_allclose(filled[rows, a:b], expected[rows, a:b], atol=1e-12)
        np.testing.assert_array_equal(filled[observed], truth[observed])


def test_an_end_gap_under_min_model_gap_frames_gets_no_own_marker_stand_in():
    # The random loss of the paper's protocol: short end gaps validated on their own
    # marker beside them lost accuracy (docs/results.md, thirty-sixth session).
    from mocapfill.solvers.gapwise import MIN_MODEL_GAP, end_gaps, end_stand_ins, row_groups

    short, long = MIN_MODEL_GAP - 1, MIN_MODEL_GAP
    observed = _mask(10, 600, [(0, 0, short), (1, 600 - long, 600)])
    ends = end_gaps(observed, row_groups(observed))
    placed = end_stand_ins(observed, row_groups(observed), ends, np.random.default_rng(0))
    assert (1, 600 - 2 * long, 600 - long) in placed
    assert not any(g == 0 for g, _, _ in placed)
    assert len(placed) == 5


def test_end_stand_ins_hide_no_sample_twice_and_keep_the_frame_beside_each():
    # A marker seen only between its two end gaps: its own-marker stand-ins at both ends
    # hid the same frames twice (n = 16) or all it shows (n = 20), its end gaps then
    # joined in the validation run. Other markers taken at both ends of a clip whose end
    # gaps nearly meet did the same.
    from mocapfill.solvers.gapwise import end_gaps, end_stand_ins, row_groups

    cases = [_mask(200, n, [(0, 0, 5), (0, n - 5, n)]) for n in (16, 20, 30)]
    cases.append(_mask(200, 40, [(0, 0, 25), (1, 15, 40)]))
    for observed in cases:
        groups = row_groups(observed)
        n = observed.shape[1]
        for seed in range(5):
            placed = end_stand_ins(observed, groups, end_gaps(observed, groups),
                                   np.random.default_rng(seed))
            hidden = np.zeros((len(groups), n), int)
            for g, a, b in placed:
                hidden[g, a:b] += 1
            assert hidden.max() <= 1
            for g, a, b in placed:
                beside = b if a == 0 or (b < n and not observed[3 * g, a - 1]) else a - 1
                assert observed[3 * g, beside] and not hidden[g, beside], (g, a, b)


def test_a_wild_end_gap_fill_loses_its_weight_beside_identical_fills():
    # At an open end the splines, the rigid and the regression fills give one fill: counted
    # apart, their distance from the median fill (0) was the typical distance and no fill
    # was an outlier. Among the distinct fills the wild one is dropped, on long end gaps.
    from mocapfill.solvers.gapwise import MIN_MODEL_GAP, _end_gap_inliers

    rng = np.random.default_rng(0)
    same = rng.normal(size=(3, 12))
    segments = {0: same + 40.0, 1: same, 2: same.copy(), 3: same.copy(),
                4: same + 0.1 * rng.normal(size=(3, 12)),
                5: same + 0.1 * rng.normal(size=(3, 12))}
    w = np.array([0.3, 0.1, 0.1, 0.1, 0.2, 0.2])
    kept = _end_gap_inliers(w, segments, 12)
    np.testing.assert_array_equal(kept, [0.0, 0.1, 0.1, 0.1, 0.2, 0.2])
    assert 12 >= MIN_MODEL_GAP
    # Fewer than four distinct fills: nothing is judged (of three, two agreeing on a wrong
    # fill would make the right one the outlier).
    np.testing.assert_array_equal(_end_gap_inliers(w[:5], {k: segments[k] for k in range(5)},
                                                   12), w[:5])


def _turning_body(seed: int, n: int, amplitude: float, hz: float, speed: float, *,
                  offset=(0.0, 0.0, 0.0), bob: float = 0.0) -> np.ndarray:
    """(18, n) six markers of one rigid body at 120 Hz, turning about the vertical axis
    (``amplitude`` rad at ``hz``) while moving along x at ``speed`` and bobbing by ``bob``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 120.0
    angle = amplitude * np.sin(2 * np.pi * hz * t)
    c, s = np.cos(angle), np.sin(angle)
    body = rng.normal(scale=100.0, size=(6, 3)) + offset
    x = c[None] * body[:, :1] - s[None] * body[:, 1:2] + speed * t[None]
    y = s[None] * body[:, :1] + c[None] * body[:, 1:2]
    z = body[:, 2:3] + bob * np.sin(t)[None]
    return np.stack([x, y, z], axis=1).reshape(18, n)


def test_short_gaps_filled_first_give_a_long_gap_its_rigid_donors():
    # Six markers of one rigid body turning and moving smoothly; marker 0 loses 40 frames
    # while each of the others flickers (1–2 frames missing) inside that stretch, so no
    # marker is seen all through it and the rigid fill alone can only draw a line.
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import ShortRunsFirst, rigid_fill
    from mocapfill.solvers.interp import spline

    n = 400
    matrix = _turning_body(0, n, 0.8, 0.5, 50.0, bob=20.0)
    flicker = [(j, 150 + 7 * j, 150 + 7 * j + 1 + j % 2) for j in range(1, 6)]
    observed = _mask(6, n, [(0, 150, 190), *flicker])
    gap = (slice(0, 3), slice(150, 190))

    alone = rigid_fill(matrix, observed)
    np.testing.assert_array_equal(alone[gap], linear_fill(matrix, observed)[gap])
    first = ShortRunsFirst()(rigid_fill)(matrix, observed)
    assert np.abs(first[gap] - matrix[gap]).max() < 0.01 * np.abs(alone[gap] - matrix[gap]).max()
    assert np.abs(first[gap] - matrix[gap]).max() < 0.05                  # mm, of ~100 mm moves
    # The short gaps keep the cubic spline's fill; observed samples are untouched.
    cubic = spline(matrix, observed)
    for j, a, b in flicker:
        np.testing.assert_array_equal(first[3 * j:3 * j + 3, a:b], cubic[3 * j:3 * j + 3, a:b])
    np.testing.assert_array_equal(first[observed], matrix[observed])
    # The validation run's request for some gaps alone (FILLS_GAPS_ALONE) passes through.
    wrapped = ShortRunsFirst()(rigid_fill)
    assert wrapped.fills_gaps_alone
    some = wrapped(matrix, observed, only=frozenset([(0, 150, 190)]))
    np.testing.assert_array_equal(some[gap], first[gap])
    # Without short gaps the candidate runs as it is.
    plain = _mask(6, n, [(0, 150, 190)])
    np.testing.assert_array_equal(ShortRunsFirst()(rigid_fill)(matrix, plain),
                                  rigid_fill(matrix, plain))


def test_rigid_fill_carries_an_end_gap_with_its_body_from_the_one_seen_side():
    # At the clip's ends the rigid fills held the last sample (as the splines do) and so
    # could not extrapolate a marker whose body keeps moving: they now carry it with its
    # donors from the one frame seen beside the gap, whatever its length. Exact on a rigid
    # body, as the long interior gap is; a short interior gap keeps its linear fill.
    from mocapfill.solvers._linalg import linear_fill
    from mocapfill.solvers.gapwise import MIN_MODEL_GAP, rigid_fill

    n = 400
    truth = _turning_body(2, n, 0.9, 0.6, 80.0, bob=15.0)
    gaps = [(0, 0, 40), (1, 350, 400), (2, 0, 2), (4, 397, 400), (3, 150, 190),
            (5, 100, 100 + MIN_MODEL_GAP - 1)]
    observed = _mask(6, n, gaps)
    matrix = np.where(observed, truth, 0.0)
    held = linear_fill(matrix, observed)
    for weighted, donors in ((False, 3), (True, 6)):
        filled = rigid_fill(matrix, observed, donors=donors, weighted=weighted)
        for marker, a, b in gaps:
            rows = slice(3 * marker, 3 * marker + 3)
            if b - a >= MIN_MODEL_GAP or a == 0 or b == n:
                np.testing.assert_allclose(filled[rows, a:b], truth[rows, a:b], atol=1e-8)
                assert np.abs(held[rows, a:b] - truth[rows, a:b]).max() > 0.5       # mm
            else:
                np.testing.assert_array_equal(filled[rows, a:b], held[rows, a:b])
        np.testing.assert_array_equal(filled[observed], matrix[observed])
        # Told the end fills will not be used, it holds them, as before; told that one
        # end only is the clip's (a window of a long clip), it carries the gaps there.
        for ends in (False, (True, False), (False, True)):
            unused = rigid_fill(matrix, observed, donors=donors, weighted=weighted,
                                ends=ends)
            for marker, a, b in gaps:
                rows = slice(3 * marker, 3 * marker + 3)
                carried = ends and ends[a != 0] if a == 0 or b == n else True
                expected = filled if carried else held
                np.testing.assert_array_equal(unused[rows, a:b], expected[rows, a:b])


def test_the_default_carries_end_gaps_rigidly_only_where_their_fills_are_used(monkeypatch):
    # A window of a long clip has end gaps at its inner edges; under ``--ends leave`` its
    # most weighted candidate fills them and the clip blends that in (an audit: a rigid
    # carry there moved 570 interior samples of a windowed clip). So the rigid candidates
    # carry end gaps, and the PCA candidate joins them to the data, only where the end
    # fills are validated and used: a window holding one of the clip's ends, at that end
    # only (its inner edge's gaps are not the clip's).
    from mocapfill.solvers import gapwise, pca, trnn

    asked = []

    def recording(original):
        def candidate(matrix, observed, **options):
            asked.append(options["ends"])
            return original(matrix, observed, **options)
        return candidate

    monkeypatch.setattr(gapwise, "rigid_fill", recording(gapwise.rigid_fill))
    monkeypatch.setattr(pca, "gap_fill", recording(pca.gap_fill))
    monkeypatch.setenv("MOCAPFILL_THREADS", "1")
    n = 300
    truth = _turning_body(5, n, 0.9, 0.6, 80.0, bob=15.0)
    observed = _mask(6, n, [(0, 0, 20), (1, 100, 130), (2, 280, 300)])
    matrix = np.where(observed, truth, 0.0)
    for validate in (False, True, (True, False)):
        asked.clear()
        trnn.complete(matrix, observed, validate_ends=validate)
        assert len(asked) >= 6 and set(asked) == {validate}    # 3 candidates, 2 runs


def test_an_end_gaps_own_stand_in_asks_the_rigid_fill_for_the_gap_that_holds_it(
        in_this_process):
    # An end gap's own stand-in hides the marker over the frames beside the real gap, so
    # in the validation run the two are one end gap. The rigid fills, asked for the
    # stand-ins' gaps alone (FILLS_GAPS_ALONE), were asked for the stand-in's frames, found
    # no such gap, and left the hold there: validation scored the hold under their name.
    from mocapfill.solvers.gapwise import _gap_holding, blend, rigid_fill

    observed = _mask(4, 100, [(0, 90, 100), (1, 0, 7), (2, 40, 45)])
    train = observed.copy()
    train[0:3, 80:90] = False
    train[3:6, 7:14] = False
    groups = row_groups(observed)
    assert _gap_holding(train, groups, (0, 80, 90)) == (0, 80, 100)
    assert _gap_holding(train, groups, (1, 7, 14)) == (1, 0, 14)
    assert _gap_holding(train, groups, (2, 40, 45)) == (2, 40, 45)

    n = 400
    truth = _turning_body(3, n, 0.9, 0.6, 80.0, bob=15.0)
    observed = _mask(6, n, [(0, 370, 400), (1, 100, 110)])
    asked = []

    def rigid(a, o, only=None):
        asked.append(only)
        return rigid_fill(a, o, only=only)

    rigid.fills_gaps_alone = True
    off = {"off": lambda a, o: np.where(o, a, truth + 5.0)}
    filled, _ = blend(np.where(observed, truth, 0.0), observed, {**off, "rigid": rigid},
                      default="off", validate_ends=True)
    assert any((0, 340, 400) in only for only in asked if only is not None)
    np.testing.assert_allclose(filled[0:3, 370:400], truth[0:3, 370:400], atol=1e-8)


def test_rigid_fill_of_row_centred_data_moves_the_marker_with_its_true_body():
    # Six markers of one rigid body turning about a far axis while walking off; the rows
    # centred one by one, as the pipeline's unit scale does, which moves each marker by
    # its own mean position and bends the body.
    from mocapfill.solvers.gapwise import rigid_fill

    n = 400
    truth = _turning_body(1, n, 1.2, 0.4, 300.0, offset=(800.0, 0.0, 900.0))
    observed = _mask(6, n, [(0, 150, 210)])
    centre = np.array([truth[r, observed[r]].mean() for r in range(18)])
    centred = np.where(observed, truth - centre[:, None], 0.0)
    gap = (slice(0, 3), slice(150, 210))

    true_body = rigid_fill(centred, observed, centre=centre)
    np.testing.assert_allclose(true_body[gap], (truth - centre[:, None])[gap], atol=1e-6)
    np.testing.assert_array_equal(true_body[observed], centred[observed])
    bent = rigid_fill(centred, observed)
    assert np.abs(bent[gap] - (truth - centre[:, None])[gap]).max() > 10.0      # mm
    # Uncentred data needs no centre: the same fill, shifted.
    np.testing.assert_allclose(rigid_fill(np.where(observed, truth, 0.0), observed)[gap],
                               truth[gap], atol=1e-6)


def test_held_short_runs_leave_end_runs_missing_when_asked():
    from mocapfill.solvers.gapwise import held_short_runs

    observed = _mask(2, 30, [(0, 0, 2), (0, 10, 12), (0, 20, 27), (1, 28, 30)])
    groups = row_groups(observed)
    every = held_short_runs(observed, groups, 5)
    inner = held_short_runs(observed, groups, 5, ends=False)
    assert every[0, :2].all() and every[3, 28:].all() and every[0, 10:12].all()
    assert not inner[0, :2].any() and not inner[3, 28:].any() and inner[0:3, 10:12].all()
    assert not inner[0, 20:27].any() and not every[0, 20:27].any()        # 7 frames: long


def test_candidates_wrapped_by_one_short_runs_first_instance_share_its_spline_fill(monkeypatch):
    from mocapfill.solvers import interp
    from mocapfill.solvers.gapwise import ShortRunsFirst, regression_fill, rigid_fill

    calls = []
    cubic = interp.spline
    monkeypatch.setattr(interp, "spline", lambda a, o: calls.append(1) or cubic(a, o))
    rng = np.random.default_rng(1)
    matrix = np.cumsum(rng.normal(size=(12, 200)), axis=1)
    observed = _mask(4, 200, [(0, 50, 80), (1, 60, 62), (2, 70, 71)])
    first = ShortRunsFirst()
    wrapped = [first(rigid_fill), first(regression_fill)]
    fills = [w(matrix, observed) for w in wrapped]
    assert len(calls) == 1
    for w, fill in zip(wrapped, fills):        # as each alone would fill
        np.testing.assert_array_equal(fill, ShortRunsFirst()(w.__wrapped__)(matrix, observed))
    wrapped[0](matrix.copy(), observed)        # other arrays: filled again
    assert len(calls) == 4


def _rigid_clip(n: int = 400, seed: int = 21):
    """(rows × n) matrix of four markers on one turning, moving rigid body (markers 0–3)
    and a fifth moving on its own, with 0.002 of noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    body = np.array([[0.3, 0.0, 0.1], [0.0, 0.25, 0.0], [-0.2, -0.1, 0.15], [0.1, 0.1, -0.3]])
    angle = 0.8 * np.sin(1.3 * t)
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.array([[c, -s, 0 * c], [s, c, 0 * c], [0 * c, 0 * c, 1 + 0 * c]])
    centre = np.stack([np.sin(0.7 * t), 0.5 * np.cos(0.4 * t), 0.2 * t])      # (3, n)
    markers = [np.einsum("abn,b->an", rotation, p) + centre for p in body]
    markers.append(np.stack([np.cos(2.1 * t), np.sin(1.7 * t), np.cos(0.9 * t)]))
    return np.vstack(markers) + 0.002 * rng.normal(size=(15, n))


def _fixed(values: np.ndarray):
    """A candidate that fills every gap with ``values``."""
    return lambda matrix, observed: values


def _partner_blend(fills: dict, prior: dict, gap=(0, 150, 180), **options):
    from mocapfill.solvers.gapwise import Validation, blend

    truth = _rigid_clip()
    observed = _mask(5, truth.shape[1], [gap])
    candidates = {name: _fixed(f(truth)) for name, f in fills.items()}
    shift = options.pop("shift", None)
    matrix = np.where(observed, truth, 0.0)
    if shift is not None:            # the unit scale's row-wise centring, with its centres
        matrix = np.where(observed, matrix - shift[:, None], 0.0)
        candidates = {name: _fixed(f(truth) - shift[:, None]) for name, f in fills.items()}
        options["centre"] = shift
    filled, _ = blend(matrix, observed, candidates, default=next(iter(fills)),
                      validation=Validation(tuple(fills), {}, {}), prior=prior,
                      prior_share=1.0, **options)
    if shift is not None:
        filled = filled + shift[:, None]
    j, a, b = gap
    return truth, filled[3 * j:3 * j + 3, a:b], truth[3 * j:3 * j + 3, a:b]


def _three_fills(off: float, half: float) -> dict:
    """The truth, and bumps of ``off`` and ``half`` on the gap (see :func:`_bump`)."""
    return {"good": lambda t: t.copy(), "off": _bump(off), "half": _bump(half)}


def _bump(size: float, gap=(0, 150, 180)):
    """A fill of marker 0 pushed ``size`` off the truth along x in the middle of the gap
    (0 at its ends), the rest the truth."""
    j, a, b = gap

    def fill(truth):
        out = truth.copy()
        out[3 * j, a:b] += size * np.sin(np.pi * np.arange(1, b - a + 1) / (b - a + 1))
        return out
    return fill


def test_a_fill_that_leaves_its_rigid_partners_loses_its_weight():
    # Three fills of a marker of a rigid body: the truth, one pushed 0.2 off its partners
    # and one 0.1 off. The median rule keeps all three (the median fill is the middle one,
    # the other two lie equally far from it), but the two pushed off leave the band of
    # distances to the body's other markers (which vary by ~0.003 over the clip): the
    # truth alone fills the gap.
    fills = _three_fills(0.2, 0.1)
    _, gap_fill, gap_truth = _partner_blend(fills, {"good": 0.2, "off": 0.4, "half": 0.4})
    np.testing.assert_allclose(gap_fill, gap_truth, atol=1e-12)
    segments = np.stack([f(_rigid_clip())[0:3, 150:180] for f in fills.values()])
    np.testing.assert_array_equal(_one_gap([0.2, 0.4, 0.4], list(segments), factor=2.0),
                                  [0.2, 0.4, 0.4])


def test_the_partner_check_measures_true_distances_given_the_rows_centres():
    # The blend sees the unit scale's rows, each centred on its own mean: the distances
    # between markers are those of the data only with the centres added back.
    shift = np.random.default_rng(3).normal(size=15)
    _, gap_fill, gap_truth = _partner_blend(_three_fills(0.2, 0.1),
                                            {"good": 0.2, "off": 0.4, "half": 0.4}, shift=shift)
    np.testing.assert_allclose(gap_fill, gap_truth, atol=1e-12)


@pytest.mark.parametrize("off, half, prior, bump", [
    # Every weighted fill leaves the partners' band: the weights stand.
    (0.2, 0.1, {"good": 0.0, "off": 0.5, "half": 0.5}, 0.15),
    # Fills 0.001 apart (under the noise) all stay in the band: the blend is unchanged.
    (0.001, 0.0005, {"good": 0.2, "off": 0.4, "half": 0.4}, 0.0006),
])
def test_the_weights_stand_where_no_fill_or_every_weighted_fill_leaves_the_band(
        off, half, prior, bump):
    _, gap_fill, gap_truth = _partner_blend(_three_fills(off, half), prior)
    expected = gap_truth.copy()
    expected[0] += bump * np.sin(np.pi * np.arange(1, 31) / 31)
    np.testing.assert_allclose(gap_fill, expected, atol=1e-12)


def test_weighted_rigid_fill_leans_on_the_rigid_donors_among_loose_ones():
    # Marker 0 is carried by markers 1-3 (one rigid body, 0.01 mm of noise) and, more
    # loosely, by markers 4-6 (skin markers that slide 3-12 mm against it): six donors
    # counted alike follow the loose ones' sliding; weighted by 1/spread² they give the
    # rigid body's motion, as the three most rigid alone do.
    from mocapfill.solvers.gapwise import rigid_fill

    rng = np.random.default_rng(5)
    n = 500
    t = np.arange(n) / 100.0
    angle = 0.9 * np.sin(1.1 * t)
    c, s, zero, one = np.cos(angle), np.sin(angle), 0 * t, 1 + 0 * t
    rotation = np.array([[c, -s, zero], [s, c, zero], [zero, zero, one]])     # (3, 3, n)
    centre = np.stack([300 * np.sin(0.5 * t), 200 * np.cos(0.3 * t), 900 + 50 * t])
    body = rng.uniform(-150, 150, size=(7, 3))
    slide = np.zeros((7, 3, n))
    for k, amplitude in zip((4, 5, 6), (3.0, 6.0, 12.0)):
        slide[k] = amplitude * np.sin(2.3 * t + k)[None] * rng.normal(size=(3, 1))
    markers = [np.einsum("abn,b->an", rotation, body[k]) + centre + slide[k]
               + 0.01 * rng.normal(size=(3, n)) for k in range(7)]
    truth = np.vstack(markers)
    observed = _mask(7, n, [(0, 200, 300)])
    matrix = np.where(observed, truth, 0.0)
    gap = (slice(0, 3), slice(200, 300))

    def error(fill):
        return np.abs(fill[gap] - truth[gap]).max()

    three = rigid_fill(matrix, observed)
    weighted = rigid_fill(matrix, observed, donors=6, weighted=True)
    alike = rigid_fill(matrix, observed, donors=6)
    assert error(three) < 0.5 and error(weighted) < 0.5                       # mm
    assert error(alike) > 5 * error(weighted)
    np.testing.assert_array_equal(weighted[observed], matrix[observed])


def test_rigid_fill_takes_a_trajectory_held_under_several_labels_once():
    # c3d.org's Qualisys Sample26 Walking_Hybrid_2 holds every marker three times (NAME,
    # NAME_2, NAME_3, the same samples): the copies of the steadiest donor were taken as
    # the three donors, one point, which leaves the body's rotation undefined.
    from mocapfill.solvers.gapwise import rigid_fill

    truth = _rigid_clip()[:12]                      # markers 0-3: one turning, moving body
    noise = 0.002 * np.random.default_rng(21).normal(size=(15, 400))[3:6]
    truth[3:6] -= noise                             # marker 1 the steadiest: no noise
    copies = np.vstack([truth, truth[3:6], truth[3:6]])     # markers 4, 5: copies of 1
    gap = [(0, 150, 200)]
    alone = rigid_fill(np.where(_mask(4, 400, gap), truth, 0.0), _mask(4, 400, gap))
    doubled = rigid_fill(np.where(_mask(6, 400, gap), copies, 0.0), _mask(6, 400, gap))
    np.testing.assert_allclose(doubled[:12], alone, atol=1e-9)
    assert np.abs(alone[0:3, 150:200] - truth[0:3, 150:200]).max() < 0.05


def test_the_partner_check_counts_a_trajectory_held_under_several_labels_once():
    # Marker 0's fill mirrored through marker 1 keeps its distance to marker 1 and leaves
    # markers 2 and 3. With marker 1 held three times (copies as markers 5 and 6, the
    # steadiest partners), its copies outvoted the others and the fill passed the check.
    from mocapfill.solvers.gapwise import (
        GapSet,
        _partner_bands,
        _rigid_partner_violations,
        _seen_before,
        interior_gaps,
    )

    truth = _rigid_clip()
    truth[3:6] -= 0.002 * np.random.default_rng(21).normal(size=(15, 400))[3:6]
    copies = np.vstack([truth, truth[3:6], truth[3:6]])
    observed = _mask(7, 400, [(0, 150, 200)])
    matrix = np.where(observed, copies, 0.0)
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    mirrored = 2 * copies[3:6, 150:200] - copies[0:3, 150:200]
    segments = np.stack([copies[0:3, 150:200], mirrored])[None]       # (1 gap, 2, 3, 50)
    off = _rigid_partner_violations(matrix, None, _seen_before(observed), groups,
                                    gapset.spans, segments,
                                    _partner_bands(matrix, observed, gapset, None))
    assert off.tolist() == [[False, True]]


def test_the_donors_of_all_gaps_at_once_are_those_chosen_gap_by_gap():
    # _distinct_donors_of_gaps takes the first finite columns where they hold no copies
    # and goes gap by gap elsewhere: against _distinct_donors on random spreads with
    # infinite entries, ties and copied positions.
    from mocapfill.solvers.gapwise import _distinct_donors, _distinct_donors_of_gaps

    rng = np.random.default_rng(8)
    gaps, columns = 300, 9
    spread = rng.choice([0.5, 1.0, 2.0, 3.0, np.inf], size=(gaps, columns)) \
        + rng.uniform(0, 0.1, size=(gaps, columns)) * rng.integers(0, 2, (gaps, columns))
    positions = rng.normal(size=(gaps, columns, 3)) * 100
    copied = rng.random(gaps) < 0.3                     # a third of the gaps hold a copy
    positions[copied, 1] = positions[copied, 4]
    positions[copied, 6] = positions[copied, 4]

    def at(g, cols):
        return np.take_along_axis(positions[g], cols[:, :, None], axis=1)

    for count in (1, 3, 6, 12):
        chosen = _distinct_donors_of_gaps(spread, count, at)
        for g in range(gaps):
            one = _distinct_donors(positions[g], np.argsort(spread[g], kind="stable"),
                                   spread[g], count)
            assert chosen[g].tolist() == one.tolist() + [-1] * (count - one.size)
    # (and the copies did change some choices: a gap by gap answer skipped a column)
    first = np.argsort(spread, axis=1, kind="stable")[:, :6]
    first = np.where(np.isfinite(np.take_along_axis(spread, first, axis=1)), first, -1)
    assert (_distinct_donors_of_gaps(spread, 6, at) != first).any(axis=1).sum() >= 5


def test_rigid_fill_in_batches_of_few_frames_fills_alike(monkeypatch):
    # The gaps are filled in batches of at most _RIGID_BATCH gap frames: batches cut
    # anywhere give the same fill (one gap longer than a batch is a batch of its own).
    from mocapfill.solvers import gapwise

    truth = _rigid_clip()
    observed = _mask(5, 400, [(0, 20, 31), (0, 150, 230), (1, 40, 47), (4, 300, 390),
                              (2, 60, 66), (0, 260, 268)])
    matrix = np.where(observed, truth, 0.0)
    whole = gapwise.rigid_fill(matrix, observed, donors=4, weighted=True)
    monkeypatch.setattr(gapwise, "_RIGID_BATCH", 9)
    np.testing.assert_allclose(gapwise.rigid_fill(matrix, observed, donors=4,
                                                  weighted=True), whole, rtol=0, atol=1e-9)
    assert not np.array_equal(whole[~observed], gapwise.linear_fill(matrix,
                                                                    observed)[~observed])


def _two_bodies(n: int = 600, seed: int = 3):
    """(rows × n) six markers: 0–3 on one turning, moving rigid body (head-like), 4 and 5
    on a second body that turns against it (a neck), all with 0.002 of noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0

    def turning(angle):
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, -s, 0 * c], [s, c, 0 * c], [0 * c, 0 * c, 1 + 0 * c]])

    centre = np.stack([np.sin(0.7 * t), 0.5 * np.cos(0.4 * t), 0.2 * t])
    head, neck = turning(0.6 * np.sin(1.3 * t)), turning(0.5 * np.sin(6.0 * t + 1.0))
    points = [(head, p) for p in ([0.3, 0.0, 0.1], [0.0, 0.25, 0.0], [-0.2, -0.1, 0.15],
                                  [0.1, 0.1, -0.3])]
    points += [(neck, p) for p in ([0.0, -0.2, -0.5], [0.15, 0.2, -0.6])]
    markers = [np.einsum("abn,b->an", R, np.array(p)) + centre for R, p in points]
    return np.vstack(markers) + 0.002 * rng.normal(size=(18, n))


def test_the_rigid_fill_tried_beside_a_gap_errs_as_on_the_gap():
    # Marker 0's gap [300, 360): with its body's markers 1-3 seen, the rigid fill tried
    # beside the gap errs at the noise's level, as on the gap; with markers 1 and 2
    # occluded with it, the fill moves it with marker 3 and the neck's markers, and errs
    # far more, beside the gap as on it.
    from mocapfill.solvers.gapwise import rigid_fill, rigid_local_errors

    truth = _two_bodies()
    gap = np.array([[0, 300, 360]])
    errors = {}
    for name, gaps in (("seen", [(0, 300, 360)]),
                       ("occluded", [(0, 300, 360), (1, 295, 365), (2, 298, 362)])):
        observed = _mask(6, 600, gaps)
        matrix = np.where(observed, truth, 0.0)
        local = rigid_local_errors(matrix, observed, gap)[0]
        fill = rigid_fill(matrix, observed)[0:3, 300:360]
        errors[name] = local, np.sqrt(((fill - truth[0:3, 300:360]) ** 2).mean())
    (seen_local, seen_gap), (occluded_local, occluded_gap) = errors["seen"], \
        errors["occluded"]
    assert seen_local < 0.01 and seen_gap < 0.01
    assert occluded_local > 5 * seen_local and occluded_gap > 5 * seen_gap
    assert 0.3 < occluded_local / occluded_gap < 3
    # No window beside the gap where the marker and its donors are all seen: NaN.
    observed = _mask(6, 600, [(0, 300, 360), (1, 235, 299), (1, 361, 425)])
    assert np.isnan(rigid_local_errors(np.where(observed, truth, 0.0), observed, gap)[0])


def test_local_checks_scale_a_candidates_weight_by_its_typical_over_its_local_error():
    # Two candidates, the second checked; its stand-in errors have median RMS 1 in the
    # long gaps' class. Tried beside the gaps it errs 4 (weight halved: the factor
    # stops at 1/2), 1.5 (2/3), 1 (kept), NaN (not tried: kept), 0.25 (doubled).
    from mocapfill.solvers.gapwise import (
        LOCAL_CLIP,
        _locally_checked,
        evidence,
        length_class,
    )

    observed = _mask(2, 400, [(0, 10, 30), (0, 60, 80), (0, 110, 130), (0, 160, 180),
                              (0, 210, 230), (1, 300, 302)])
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    cls = length_class(20)
    errors = {cls: [evidence(np.array([[2.0 * s, s]] * 4)) for s in (0.5, 1.0, 3.0)]}
    shared = np.array([0.5, 0.5])
    weights = [shared] * len(gapset.gaps)
    tried = {1: np.array([4.0, 1.5, 1.0, np.nan, 0.25])}
    out = _locally_checked(weights, gapset, errors, tried)
    factors = [1 / LOCAL_CLIP, 1 / 1.5, 1.0, 1.0, LOCAL_CLIP]
    for w, f in zip(out[:5], factors):
        np.testing.assert_allclose(w, np.array([0.5, 0.5 * f]) / (0.5 + 0.5 * f), rtol=1e-5)
    assert out[5] is shared                                 # a short gap: untouched
    assert weights[0] is shared and shared.tolist() == [0.5, 0.5]
    # Exact data: the candidate's errors on the stand-ins and beside the gaps are rounding
    # (0 and 1e-15 here): its weight is kept, not halved.
    exact = {cls: [evidence(np.array([[1.0, 0.0]] * 4))]}
    out = _locally_checked(weights, gapset, exact, {1: np.full(5, 1e-15)})
    for w in out[:5]:
        np.testing.assert_allclose(w, shared)


def test_a_long_gaps_own_stand_ins_scale_every_candidates_weight_on_it():
    # Three candidates, the first also checked beside the gaps. The class's stand-ins give
    # each a median RMS of 1. Gap 0's own stand-in: errors 4, 1, 0.5 -> factors 1/2, 1, 2,
    # times the first's factor from ``tried`` (2 there: 1 in all). Gap 1 has no stand-in of
    # its own: only ``tried`` counts. Gap 2 has two, pooled: RMS sqrt((1 + 9) / 2) = √5
    # for the first candidate (factor 1/2, the clip), 1 and 1 for the others.
    from mocapfill.solvers.gapwise import _locally_checked, evidence, length_class

    observed = _mask(1, 200, [(0, 10, 30), (0, 60, 80), (0, 110, 130)])
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    errors = {length_class(20): [evidence(np.array([[s, s, s]] * 6)) for s in (0.5, 1, 3)]}
    own = {0: [evidence(np.array([[4.0, 1.0, 0.5]] * 6))],
           2: [evidence(np.array([[1.0, 1.0, 1.0]] * 6)),
               evidence(np.array([[3.0, 1.0, 1.0]] * 6))]}
    shared = np.full(3, 1 / 3)
    tried = {0: np.array([0.5, 0.5, np.nan])}
    out = _locally_checked([shared] * 3, gapset, errors, tried, own)
    for w, factors in zip(out, ([2 / 2, 1, 2], [2, 1, 1], [1 / 2, 1, 1])):
        np.testing.assert_allclose(w, np.array(factors) / sum(factors), rtol=1e-5)
    # Without ``tried`` (no rigid candidate), the own stand-ins still count.
    out = _locally_checked([shared] * 3, gapset, errors, {}, own)
    np.testing.assert_allclose(out[0], np.array([0.5, 1, 2]) / 3.5, rtol=1e-5)
    assert out[1] is shared


def test_the_partner_check_computes_nothing_invalid_for_partners_it_lacks():
    # Marker 1's gap has one partner (marker 2); marker 0 is seen only inside that gap, so
    # its band to marker 1 is empty (∞ spread, an inverted extent). The check, made for
    # three partners at once, filled the two it lacks from marker 0's band, and ∞ − ∞
    # gave a RuntimeWarning on stderr (found by the property test in a fresh clone).
    from mocapfill.solvers.gapwise import (
        GapSet,
        _partner_bands,
        _rigid_partner_violations,
        _seen_before,
        interior_gaps,
    )

    truth = _rigid_clip()[:9]
    seen = np.ones((3, 400), dtype=bool)
    seen[1, 50:70] = False
    seen[0, :52] = seen[0, 68:] = False
    observed = np.repeat(seen, 3, axis=0)
    matrix = np.where(observed, truth, 0.0)
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    spans = gapset.spans[gapset.spans[:, 0] == 1]
    fills = np.stack([truth[3:6, 50:70], truth[3:6, 50:70] + 1.0])[None]   # (1, 2, 3, 20)
    bands = _partner_bands(matrix, observed, gapset, None)
    assert not np.isfinite(bands[1][0][0])          # marker 0: no band to marker 1
    with np.errstate(all="raise"):
        off = _rigid_partner_violations(matrix, None, _seen_before(observed), groups,
                                        spans, fills, bands)
    assert off.tolist() == [[False, True]]


def test_a_gap_in_frames_where_nothing_is_seen_is_the_temporal_candidates_alone():
    # Marker 0's gaps: 20–22 lie in frames no marker is seen in (a dropped frame), 60–62
    # does not (marker 1 is seen there). Candidates: a cross-marker one and the spline.
    from mocapfill.solvers.gapwise import _blind_gaps_temporal

    observed = _mask(2, 100, [(0, 20, 22), (1, 18, 24), (0, 60, 62)])
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    shared = np.array([0.9, 0.1])
    out = _blind_gaps_temporal([shared] * len(gapset.gaps), gapset, observed, [1])
    blind = [i for i, (g, a, b) in enumerate(gapset.gaps) if (g, a, b) == (0, 20, 22)]
    assert len(blind) == 1
    for i, w in enumerate(out):
        np.testing.assert_allclose(w, [0.0, 1.0] if i in blind else shared)
    assert shared.tolist() == [0.9, 0.1]                    # the shared array untouched
    # A candidate the weights gave nothing still takes the blind gap.
    out = _blind_gaps_temporal([np.array([1.0, 0.0])] * len(gapset.gaps), gapset, observed, [1])
    np.testing.assert_allclose(out[blind[0]], [0.0, 1.0])


def test_the_default_fills_a_dropped_frame_of_smooth_data_as_a_spline_does():
    # An audit's case: data without noise (rounded to 0.001), one frame of every marker
    # lost. The default filled 13 of 41 markers about 30 mm off and refused 28 as jumps:
    # the validation never shows a whole frame lost, and TrNN stops before moving it.
    from mocapfill.motion import Motion
    from mocapfill.pipeline import RepairOptions, repair

    n, m = 300, 12
    rng = np.random.default_rng(0)
    t = np.arange(n)[:, None, None]
    positions = np.round(rng.normal(0, 200, (1, m, 3)) + rng.normal(0, 60, (1, m, 3))
                         * np.sin(2 * np.pi * t / 120 + rng.uniform(0, 6, (1, m, 3))), 3)
    observed = np.ones((n, m), bool)
    observed[150] = False
    clip = Motion(np.where(observed[..., None], positions, np.nan), observed,
                  tuple(f"M{j}" for j in range(m)), 120.0)
    result = repair(clip, RepairOptions())
    assert result.left == 0
    assert np.abs(result.motion.positions[150] - positions[150]).max() < 0.01
