"""Gløersen & Federolf PCA filling: exact on rigidly coupled markers, graceful fallbacks."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocapfill.solvers import interp, pca

from ._synth import masked, rel, unit_rms


def coupled_markers(seed: int, markers: int = 15, n: int = 600, r: int = 6,
                    coupled: int = 3) -> np.ndarray:
    """Low-rank random motion; the last ``coupled`` markers are fixed affine combinations of
    4 others (weights summing to 1: they move rigidly with them)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 4 * np.pi, n)
    Z = np.vstack([np.sin((q + 1) * t / 2 + rng.uniform(0, 6)) for q in range(r)])
    Z += 0.1 * rng.standard_normal(Z.shape)
    free = markers - coupled
    base = (rng.standard_normal((3 * free, r)) @ Z
            + 3 * rng.standard_normal((3 * free, 1))).reshape(free, 3, n)
    extra = []
    for _ in range(coupled):
        c = rng.standard_normal(4)
        c /= c.sum()
        extra.append(np.tensordot(c, base[rng.choice(free, 4, replace=False)], axes=1))
    return unit_rms(np.concatenate([base, np.array(extra)]).reshape(3 * markers, n))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_recovers_rigidly_coupled_marker_in_long_gap(seed):
    M = coupled_markers(seed)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 150:450] = False          # half the clip
    out = pca.complete(masked(M, observed), observed, transform="inverse")
    assert rel(out, M, ~observed) < 1e-6
    np.testing.assert_array_equal(out[observed], M[observed])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_gapped_markers_exact_when_all_components_kept(seed):
    # With the 99 % singular-value cut a coupled marker whose partners are far (small
    # weights) can lose a component; keeping every component makes both fills exact.
    M = coupled_markers(seed)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 150:450] = False
    observed[-6:-3, 500:560] = False        # a second gapped marker, not overlapping
    out = pca.complete(masked(M, observed), observed, min_cum_sv=1.0, transform="inverse")
    assert rel(out, M, ~observed) < 1e-6


def test_published_transform_is_close_but_not_exact():
    # The default (published B = Vᵀ V₀) is only approximately exact on low-rank data.
    M = coupled_markers(0)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 150:450] = False
    err = rel(pca.complete(masked(M, observed), observed), M, ~observed)
    assert 1e-6 < err < 0.1


def walking_clip() -> np.ndarray:
    """The repository's walking sample (123 rows × 600 frames), rows unit RMS."""
    path = Path(__file__).resolve().parents[2] / "sample_data" / "walk_truth.csv"
    # Committed in the repository: absent, the tests fail rather than skip.
    assert path.is_file(), f"{path} is missing (it is part of the repository)"
    return unit_rms(np.genfromtxt(path, delimiter=",", skip_header=2)[:, 2:].T)


@pytest.mark.parametrize("seed", [0, 1])
def test_no_complete_frame_still_fills_better_than_linear(seed):
    M = walking_clip()
    rng = np.random.default_rng(seed)
    observed = np.ones(M.shape, dtype=bool)
    for j in range(M.shape[0] // 3):      # every marker has a gap: no complete frame
        start = int(rng.integers(0, M.shape[1] - 60))
        observed[3 * j:3 * j + 3, start:start + 60] = False
    data = masked(M, observed)
    out = pca.complete(data, observed)
    assert np.isfinite(out).all()
    assert rel(out, M, ~observed) < 0.6 * rel(interp.linear(data, observed), M, ~observed)


def test_never_observed_marker_is_zero_and_lonely_frames_finite():
    M = coupled_markers(4)
    observed = np.ones(M.shape, dtype=bool)
    observed[3:6] = False                   # marker 1 never observed
    observed[6:, 100:120] = False           # only marker 0 present in these frames
    observed[:, 300] = False                # a frame where nothing is observed
    out = pca.complete(masked(M, observed), observed)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out[3:6], 0.0)


def test_rejects_bad_options():
    M = coupled_markers(0)
    observed = np.ones(M.shape, dtype=bool)
    with pytest.raises(ValueError):
        pca.complete(M, observed, transform="nope")
    with pytest.raises(ValueError):
        pca.complete(M[:-1], observed[:-1])
    with pytest.raises(TypeError):
        pca.complete(M, observed, bogus=1)


def test_model_budget_leaves_the_rest_to_interpolation_and_keeps_observed():
    rng = np.random.default_rng(4)
    n, k = 400, 8
    M = unit_rms(np.cumsum(rng.normal(size=(3 * k, n)), axis=1))
    observed = np.ones(M.shape, dtype=bool)
    # Every marker loses stretches at different times: many predictor combinations.
    for j in range(k):
        for start in rng.integers(5, n - 30, size=6):
            observed[3 * j:3 * j + 3, start:start + 12] = False
    full = pca.complete(masked(M, observed), observed)
    budget = pca.complete(masked(M, observed), observed, max_models=1)
    np.testing.assert_array_equal(budget[observed], M[observed])
    assert np.isfinite(budget).all()
    assert not np.allclose(full[~observed], budget[~observed])


def test_pair_distances_match_a_pair_by_pair_count_mean_and_spread():
    from mocapfill.solvers._linalg import pair_distances

    rng = np.random.default_rng(9)
    n, k = 120, 7
    points = rng.normal(size=(n, k, 3))
    seen = rng.random((n, k)) > 0.3
    seen[:, 6] = False
    seen[:10, 6] = True                      # marker 6 only in frames 0–9 ...
    seen[:10, 5] = False                     # ... where marker 5 is never seen
    points[~seen] = np.nan
    count, mean, std = pair_distances(points, seen)
    for i in range(k):
        for j in range(k):
            both = seen[:, i] & seen[:, j]
            assert count[i, j] == both.sum()
            d = np.linalg.norm(points[both, i] - points[both, j], axis=1)
            # float32 distances (see distance_rows): a few parts in 10⁷
            np.testing.assert_allclose(mean[i, j], d.mean() if d.size else 0.0, rtol=2e-6)
            np.testing.assert_allclose(std[i, j], d.std() if d.size else 0.0, atol=2e-6)
    assert count[5, 6] == 0 and mean[5, 6] == 0
    assert pair_distances(points, seen, spread=False)[2] is None


def test_pair_distances_keep_their_precision_far_from_the_origin():
    # Lab coordinates 10 m away in mm: float32 positions there are 1 mm apart, so the
    # distances are taken from coordinates shifted near the markers first.
    from mocapfill.solvers._linalg import pair_distances

    rng = np.random.default_rng(10)
    points = rng.normal(size=(300, 5, 3)) * 50 + rng.normal(size=(1, 5, 3)) * 200
    seen = rng.random((300, 5)) > 0.2
    near = pair_distances(points, seen, extent=True)
    far = pair_distances(points + np.array([1e4, -2e4, 5e3]), seen, extent=True)
    np.testing.assert_array_equal(far[0], near[0])
    for a, b in zip(near[1:], far[1:]):
        finite = np.isfinite(a)
        np.testing.assert_array_equal(np.isfinite(b), finite)
        np.testing.assert_allclose(b[finite], a[finite], rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("markers", [5, 40, 64, 65, 130])
def test_visibility_patterns_are_those_of_numpy_unique_in_its_order(markers):
    # The fill's model budget goes to the frame groups in this order, so the packed-word
    # grouping must reproduce np.unique(axis=0) exactly, across word boundaries too.
    rng = np.random.default_rng(markers)
    visible = rng.random((markers, 400)) < 0.9
    visible[:, 200:] = visible[:, :200]             # repeated columns: shared patterns
    visible[rng.integers(markers), :50] = False
    expected, inverse = np.unique(visible.T, axis=0, return_inverse=True)
    patterns, groups = pca._patterns(visible)
    np.testing.assert_array_equal(patterns, expected)
    np.testing.assert_array_equal(groups, np.asarray(inverse).ravel())


def test_nearest_markers_rank_by_rms_distance_over_the_frames_seeing_both():
    from mocapfill.solvers._linalg import nearest_markers

    rng = np.random.default_rng(4)
    n, k = 200, 6
    # Markers along x at 0, 1, 3, 7, 12, 18 (plus a common motion and noise).
    spots = np.array([0.0, 1.0, 3.0, 7.0, 12.0, 18.0])
    points = rng.normal(size=(n, 1, 3)) * 5 + rng.normal(scale=0.01, size=(n, k, 3))
    points[:, :, 0] += spots
    seen = rng.random((n, k)) > 0.2
    seen[:, 5] = seen[:, 5] & ~seen[:, 4]        # 4 and 5 never seen together
    points[~seen] = np.nan
    near = nearest_markers(points, seen, 3)
    assert near.shape == (6, 3)
    assert near[0].tolist() == [1, 2, 3] and near[2].tolist() == [1, 0, 3]
    assert near[4].tolist() == [3, 2, 1]               # 5 is never beside it
    assert near[5].tolist() == [3, 2, 1]


def test_distance_spread_of_many_markers_measures_each_row_to_its_nearest():
    from mocapfill.solvers._linalg import nearest_markers, pair_distances
    from mocapfill.solvers.gapwise import distance_spread

    rng = np.random.default_rng(5)
    n, k = 150, 9
    points = rng.normal(size=(n, k, 3)) + rng.normal(size=(1, k, 3)) * 20
    seen = rng.random((n, k)) > 0.1
    points[~seen] = np.nan
    count, _, std = pair_distances(points, seen)
    full = np.where(count >= 10, std, np.inf)
    np.fill_diagonal(full, np.inf)
    # Few enough markers: every pair, as before.
    np.testing.assert_array_equal(distance_spread(points, seen, candidates=8), full)
    # Few enough markers, some rows: those rows whole, the same values, the others ∞.
    rows = distance_spread(points, seen, rows=[1, 6], candidates=8)
    np.testing.assert_array_equal(rows[[1, 6]], full[[1, 6]])
    assert np.isinf(np.delete(rows, [1, 6], axis=0)).all()
    # More: only the rows asked for, each to its 4 nearest, with the same values.
    near = nearest_markers(points, seen, 4)
    spread = distance_spread(points, seen, rows=[2, 7], candidates=4)
    for j in range(k):
        measured = np.isfinite(spread[j])
        assert measured.sum() == (4 if j in (2, 7) else 0)
        if j in (2, 7):
            assert set(np.flatnonzero(measured)) == set(near[j])
            np.testing.assert_allclose(spread[j, near[j]], full[j, near[j]], rtol=1e-12)


def test_rows_centred_one_by_one_with_their_centres_fill_as_the_true_positions():
    # The pipeline centres every row on its own mean; with those centres handed back the
    # distance weights are the markers' true ones and the fill is that of the true clip.
    M = coupled_markers(4) + np.random.default_rng(4).normal(scale=5.0, size=(45, 1))
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 150:300] = False
    observed[9:12, 200:260] = False
    centre = np.array([M[r, observed[r]].mean() for r in range(M.shape[0])])
    centred = masked(M - centre[:, None], observed)
    true = pca.complete(masked(M, observed), observed)
    back = pca.complete(centred, observed, centre=centre) + centre[:, None]
    np.testing.assert_allclose(back[~observed], true[~observed], atol=1e-8)
    bent = pca.complete(centred, observed) + centre[:, None]
    assert np.abs(bent[~observed] - true[~observed]).max() > 1e-3
    # The pipeline's to give, not a user's option.
    from mocapfill.solvers import option_names
    assert "centre" not in option_names(pca.complete) and "weight_scale" in option_names(
        pca.complete)


def test_models_from_the_complete_frames_sums_equal_models_from_their_own_frames():
    # Each model's Gram matrix is the complete frames' (summed once) plus its few other
    # training frames: the same model as one computed over all its frames.
    M = coupled_markers(3)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 150:300] = False
    observed[-6:-3, 250:400] = False            # overlaps: the first one's fallback
    observed[:3, 380:420] = False               # a third, elsewhere
    X = np.where(observed, M, np.nan).T
    mask = observed[::3]
    complete = mask.all(axis=0)
    moments = pca._Moments(X, complete)
    weights = np.append(np.linspace(1.0, 0.2, 12), 0.02)     # predictors, then its own
    predictors = list(range(12))                # marker 13 gapped on 250:400 is left out
    train = np.flatnonzero(mask[predictors + [14]].all(axis=0))
    assert 0 < (~complete[train]).sum() < len(train) / 2
    direct = pca._model(X, 14, predictors, train, weights, 0.99, "published")
    summed = pca._model(X, 14, predictors, train, weights, 0.99, "published", moments)
    for a, b in zip(direct, summed):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)
    # Where the complete frames are not most of the training frames, the model is made
    # from its own frames.
    assert moments.centred(X, train[~complete[train]], np.arange(6)) is None
    # A constant coordinate (a marker fixed in the lab along one axis) keeps no spread
    # at all about the complete frames' mean, as about a model's own first frame: the
    # normalisation leaves it alone.
    X[:, 4] = 0.1 + 0.2                         # a value whose sums round
    moments = pca._Moments(X, complete)
    summed = pca._model(X, 14, predictors, train, weights, 0.99, "published", moments)
    direct = pca._model(X, 14, predictors, train, weights, 0.99, "published")
    assert summed[2][4] == direct[2][4] == 1.0      # std: none, so 1
    for a, b in zip(direct, summed):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-12)


def _eigh_sizes(monkeypatch) -> list[int]:
    """The sizes of the matrices np.linalg.eigh is given from now on."""
    sizes: list[int] = []
    eigh = np.linalg.eigh

    def recording(a, *args, **kwargs):
        sizes.append(np.shape(a)[-1])
        return eigh(a, *args, **kwargs)

    monkeypatch.setattr(np.linalg, "eigh", recording)
    return sizes


def test_a_model_wider_than_its_frames_never_decomposes_a_columns_by_columns_matrix(
        monkeypatch):
    # Many markers over few frames (1,000 × 30 took two 3,003 × 3,003 eigendecompositions
    # per model): a model with more than twice as many columns as training frames, and
    # more than GRAM_COLUMNS, takes its axes from the training matrix. The fill is still
    # exact.
    M = coupled_markers(5, markers=60, n=30, r=4)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 10:20] = False                # 20 training frames, 180 columns
    sizes = _eigh_sizes(monkeypatch)
    out = pca.complete(masked(M, observed), observed, transform="inverse")
    assert max(sizes, default=0) <= 30
    assert rel(out, M, ~observed) < 1e-6
    np.testing.assert_array_equal(out[observed], M[observed])


@pytest.mark.parametrize("transform", ["published", "inverse"])
def test_a_wide_model_is_the_model_of_its_gram_matrix(monkeypatch, transform):
    # The thin SVD of the normalised training frames gives the Gram matrix's axes: the
    # same map and normalisation as the Gram path, to rounding.
    rng = np.random.default_rng(6)
    X = rng.standard_normal((25, 4)) @ rng.standard_normal((4, 150))
    X += 0.01 * rng.standard_normal(X.shape)
    X[:, 7] = 3.0                               # a constant column: no spread, std 1
    weights = np.append(np.exp(-rng.uniform(0, 3, 49)), 0.02)
    train = np.arange(2, 25)
    wide = pca._model(X, 49, list(range(49)), train, weights, 0.99, transform)
    monkeypatch.setattr(pca, "GRAM_COLUMNS", 10**6)
    sizes = _eigh_sizes(monkeypatch)
    gram = pca._model(X, 49, list(range(49)), train, weights, 0.99, transform)
    assert sizes == [150, 150]                  # (the wide one took none)
    for a, b in zip(gram, wide):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10)


def test_models_up_to_gram_columns_keep_the_gram_matrix_whatever_their_frames(
        monkeypatch):
    # A 41-marker clip (CMU's, the accuracy tables') keeps its fills bit for bit: its
    # widest model, 123 columns, is decomposed from its Gram matrix even on 20 frames.
    M = coupled_markers(7, markers=41, n=30, r=4)
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, 10:20] = False
    sizes = _eigh_sizes(monkeypatch)
    pca.complete(masked(M, observed), observed)
    assert 3 * 41 == pca.GRAM_COLUMNS and max(sizes) == pca.GRAM_COLUMNS


def test_gap_fill_joins_a_long_end_gap_to_the_sample_beside_it():
    # The blend's PCA candidate adds to an end gap of MIN_MODEL_GAP frames or more the
    # offset between the data and the model's prediction on the one frame seen beside
    # it, all along the gap; shorter end gaps, and every end gap where the end fills are
    # not used (``ends=False``), keep the model's prediction, as ``complete`` gives it.
    from mocapfill.solvers.gapwise import MIN_MODEL_GAP

    M = coupled_markers(3)
    n = M.shape[1]
    observed = np.ones(M.shape, dtype=bool)
    observed[-3:, n - 40:] = False                        # a long end gap
    observed[-6:-3, :MIN_MODEL_GAP - 1] = False          # a short one
    observed[-9:-6, 200:260] = False                     # an interior gap
    plain = pca.complete(masked(M, observed), observed)
    joined = pca.gap_fill(masked(M, observed), observed)
    unjoined = pca.gap_fill(masked(M, observed), observed, ends=False)
    shift = joined[-3:, n - 40:] - plain[-3:, n - 40:]
    assert np.abs(shift).max() > 1e-6
    np.testing.assert_allclose(shift, shift[:, :1].repeat(40, axis=1), atol=1e-12)
    np.testing.assert_array_equal(unjoined[-3:, n - 40:], plain[-3:, n - 40:])
    # Told one end only is the clip's (a window of a long clip), it joins the gaps there.
    np.testing.assert_array_equal(
        pca.gap_fill(masked(M, observed), observed, ends=(False, True)), joined)
    np.testing.assert_array_equal(
        pca.gap_fill(masked(M, observed), observed, ends=(True, False)), unjoined)
    for fill in (joined, unjoined):
        np.testing.assert_array_equal(fill[-6:-3, :MIN_MODEL_GAP - 1],
                                      plain[-6:-3, :MIN_MODEL_GAP - 1])
        np.testing.assert_array_equal(fill[observed], M[observed])
    np.testing.assert_array_equal(joined[-9:-6, 200:260], unjoined[-9:-6, 200:260])
