"""TrNN (Hu et al. 2018) and the default ``trnn`` method: defining properties."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.pipeline import complete_matrix
from mocapfill.solvers._linalg import linear_fill, second_difference_matrix, temporal_solve
from mocapfill.solvers.trnn import complete, trnn
from tests.conftest import shared_file

from ._synth import scattered


def test_dct_temporal_step_equals_dense_solve():
    rng = np.random.default_rng(0)
    n, eta, mu = 37, 0.7, 100.0
    T = second_difference_matrix(n)
    B = rng.normal(size=(5, n))
    dense = np.linalg.solve((eta * np.eye(n) + mu * T.T @ T).T, B.T).T
    np.testing.assert_allclose(temporal_solve(B, eta, mu), dense, atol=1e-10, rtol=0)


def test_rpca_mode_recovers_low_rank_part_of_paper_synthetic_data():
    rng = np.random.default_rng(1)
    m, n, r0, cr = 1000, 200, 10, 0.1
    X_star = rng.normal(size=(m, r0)) @ rng.normal(size=(r0, n))
    S_star = np.where(rng.random((m, n)) < cr, rng.uniform(-10, 10, (m, n)), 0.0)
    D = X_star + S_star
    result = trnn(D, np.ones((m, n), bool), rank=r0, d=r0, lam=1 / np.sqrt(max(m, n)),
                  mu=0.0, rho=1.5, eta0=1.25 / np.linalg.norm(D, 2), tol=1e-7)
    nre = np.linalg.norm(result.X - X_star) / np.linalg.norm(X_star)
    assert nre < 1e-5


def test_complete_matrix_returns_a_complete_matrix_unchanged():
    rng = np.random.default_rng(2)
    matrix = rng.normal(size=(12, 80)) * 100 + 500
    out = complete_matrix(matrix, np.ones_like(matrix, bool), "trnn")
    np.testing.assert_array_equal(out, matrix)


def _smooth_low_rank_clip(n: int = 600, markers: int = 12, seed: int = 3) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 120.0
    latent = np.sin(2 * np.pi * np.array([0.5, 0.9, 1.4, 2.1])[:, None] * t
                    + rng.uniform(0, 6, (4, 1)))
    return rng.normal(size=(3 * markers, 4)) @ latent


def test_complete_beats_linear_on_a_long_gap_and_joins_both_ends():
    X = _smooth_low_rank_clip()
    observed = np.ones_like(X, bool)
    a, b = 200, 290                                   # 90 frames of marker 2
    observed[6:9, a:b] = False
    filled = complete(np.where(observed, X, 0.0), observed)
    linear = linear_fill(X, observed)
    err = np.sqrt(np.mean((filled[6:9, a:b] - X[6:9, a:b]) ** 2))
    err_linear = np.sqrt(np.mean((linear[6:9, a:b] - X[6:9, a:b]) ** 2))
    assert err < 0.2 * err_linear
    # No jump: the step into and out of the gap is no larger than the clip's own steps.
    max_step = np.abs(np.diff(X[6:9], axis=1)).max()
    assert np.abs(filled[6:9, a] - X[6:9, a - 1]).max() <= 1.5 * max_step
    assert np.abs(X[6:9, b] - filled[6:9, b - 1]).max() <= 1.5 * max_step


def test_complete_keeps_observed_entries():
    X = _smooth_low_rank_clip(n=300, markers=8)
    observed = np.ones_like(X, bool)
    observed[3:6, 100:130] = False
    filled = complete(np.where(observed, X, 0.0), observed)
    np.testing.assert_allclose(filled[observed], X[observed], atol=1e-12)


def test_the_default_runs_trnn_once_where_the_clip_validates_itself(monkeypatch):
    import mocapfill.solvers.trnn as module

    monkeypatch.setenv("MOCAPFILL_THREADS", "1")        # the calls are seen here
    X = _smooth_low_rank_clip(n=300, markers=8)
    observed = np.ones_like(X, bool)
    observed[3:6, 100:130] = False
    observed[9:12, 200:203] = False
    masks = []
    solve = module.complete_lowrank

    def counted(matrix, seen, **options):
        masks.append(seen.copy())
        return solve(matrix, seen, **options)

    monkeypatch.setattr(module, "complete_lowrank", counted)
    complete(np.where(observed, X, 0.0), observed)
    # One run, on the validation clip (the real gaps and the stand-ins missing).
    assert len(masks) == 1
    assert (masks[0] <= observed).all() and masks[0].sum() < observed.sum()


def test_a_window_lent_only_empty_validations_validates_itself():
    from mocapfill.solvers.gapwise import Validation
    from mocapfill.solvers.trnn import complete_window

    X = _smooth_low_rank_clip(n=300, markers=8)
    observed = np.ones_like(X, bool)
    observed[3:6, 100:130] = False
    observed[9:12, 200:203] = False
    matrix = np.where(observed, X, 0.0)
    own_fill, own = complete_window(matrix, observed)
    assert own.by_class                           # the clip's own stand-ins
    empty = Validation(own.names, {}, {})         # e.g. from a window without gaps
    other = Validation(own.names[:-1], own.by_class, {})   # other candidates
    fill, used = complete_window(matrix, observed, borrowed=[None, empty, other])
    assert used is not empty and used.by_class and used.by_gap
    np.testing.assert_array_equal(fill, own_fill)
    lent_fill, lent = complete_window(matrix, observed, borrowed=[own])
    assert lent.by_class == own.by_class and not lent.by_gap
    np.testing.assert_allclose(lent_fill[observed], X[observed], atol=1e-12)


def _cmu_85_02():
    from mocapfill.formats import read

    return read(shared_file("cmu/85_02.c3d"))


def test_default_beats_spline_on_cmu_85_02_continuous_gaps():
    from mocapfill.gaps import simulate_gaps
    from mocapfill.metrics import score
    from mocapfill.pipeline import RepairOptions, repair

    truth = _cmu_85_02()
    gapped = simulate_gaps(truth, ml=40, seed=0)
    errors = {m: score(truth, repair(gapped, RepairOptions(method=m)).motion, gapped).rmse_mm
              for m in ("trnn", "spline")}
    assert errors["trnn"] < 0.5 * errors["spline"]


@pytest.mark.slow
def test_walkl_default_beats_pca_on_average_and_holds_its_measured_level():
    # Issue 4's target is a mean <= 2.0 mm and below pca on every file; measured
    # (docs/results.md, second session): mean 2.52 mm against pca 3.51, below pca on all
    # ten files. This guards the level reached; tighten it as the target is approached.
    from mocapfill import bench

    shared_file("walkl/WalkL.mat")
    rows = [r for c in bench.cases(False) if c.dataset == "walkl"
            for r in bench.run_case(c, ["trnn", "pca"])]
    by = {(r["case"], r["method"]): r["rmse_3d_mm"] for r in rows}
    files = sorted({case for case, _ in by})
    mean_trnn = np.mean([by[(f, "trnn")] for f in files])
    assert mean_trnn <= 2.6
    assert mean_trnn < np.mean([by[(f, "pca")] for f in files])
    # One file of slack: WalkL_0003 is won by 0.11 mm, and float32 products differ
    # slightly between CPUs.
    assert sum(by[(f, "trnn")] < by[(f, "pca")] for f in files) >= 9


@pytest.mark.slow
def test_default_beats_tsmc_on_02_05_random_loss():
    # Issue 4's cell 02_05 mr = 0.4, lost to TSMC until the default blended a TSMC fill on
    # scattered loss (docs/results.md, sixteenth session: 0.4260 against 0.4289 mm).
    from mocapfill import bench

    shared_file("cmu/02_05.c3d")
    rows = [r for seed in bench.SEEDS
            for r in bench.run_case(bench._cmu_case("02_05", ("mr", 0.4), seed), ["trnn", "tsmc"])]
    mean = {m: np.mean([r["rmse_mm"] for r in rows if r["method"] == m]) for m in ("trnn", "tsmc")}
    assert mean["trnn"] < mean["tsmc"]


def test_float32_iteration_matches_float64_and_returns_float64():
    rng = np.random.default_rng(5)
    m, n, r = 30, 240, 4
    t = np.arange(n) / 60.0
    X_star = rng.normal(size=(m, r)) @ np.sin(np.outer(rng.uniform(0.5, 2, r), t) * 6)
    observed = rng.random((m, n)) > 0.2
    # ε = 1e−5 as the default method uses it (float32 cannot resolve much tighter).
    kwargs = dict(rank=r, lam=100 / np.sqrt(n), rho=1.2, eta0=0.05, tol=1e-5, max_iter=400)
    double = trnn(X_star, observed, **kwargs)
    single = trnn(X_star, observed, dtype=np.float32, **kwargs)
    assert single.X.dtype == np.float64 and single.converged
    scale = np.linalg.norm(X_star)
    assert np.linalg.norm(single.X - double.X) / scale < 1e-2
    assert np.linalg.norm(single.X - X_star) / scale < 0.05
    with pytest.raises(ValueError, match="dtype"):
        trnn(X_star, observed, dtype=np.int32, **kwargs)


def test_padding_to_a_fast_dct_length_keeps_the_shape_and_observed_entries():
    from mocapfill.solvers._linalg import fast_length
    from mocapfill.solvers.trnn import complete_lowrank

    for n in (227, 409, 4300, 4499):      # primes and lengths with large prime factors
        fast = fast_length(n)
        assert fast >= n and fast - n < 0.05 * n + 8
        rest = fast
        for p in (2, 3, 5):
            while rest % p == 0:
                rest //= p
        assert rest == 1
    rng = np.random.default_rng(6)
    m, n = 12, 227
    X = np.cumsum(rng.normal(size=(m, n)), axis=1)
    X = (X - X.mean(axis=1, keepdims=True)) / X.std()
    observed = np.ones((m, n), bool)
    observed[3:6, 100:130] = False
    out = complete_lowrank(np.where(observed, X, 0.0), observed, rank=3)
    assert out.shape == (m, n)
    np.testing.assert_array_equal(out[observed], X[observed])
    assert np.isfinite(out).all()


def test_default_completes_rows_that_are_not_markers():
    # 4 rows (not x, y, z triples) with 300 complete frames: the marker-only fillers
    # (rigid body, PCA) must stay out instead of failing.
    rng = np.random.default_rng(7)
    X = np.cumsum(rng.normal(size=(4, 300)), axis=1)
    observed = np.ones_like(X, dtype=bool)
    observed[3, 100:140] = False
    out = complete(X, observed)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out[observed], X[observed])


def _textbook_trnn(D, observed, *, rank, lam, mu, rho, eta0, iterations):
    """MODEL.md Algorithm 1 written as plainly as possible (dense T, explicit inverses)."""
    m, n = D.shape
    PD = np.where(observed, D, 0.0)
    X = linear_fill(D, observed)
    Us, sv, Vts = np.linalg.svd(X, full_matrices=False)
    L, R = Us * np.sqrt(sv), Vts.T * np.sqrt(sv)
    U, V = Us[:, :rank].T, Vts[:rank]
    M, S = X.copy(), PD - X
    Y1, Y2 = np.zeros_like(X), np.zeros_like(X)
    T = second_difference_matrix(n)
    eta = eta0
    for _ in range(iterations):
        W = M + PD - S + (Y1 + Y2) / eta
        L = (eta * W @ R + U.T @ V @ R) @ np.linalg.inv(np.eye(m) + 2 * eta * R.T @ R)
        R = (eta * W.T @ L + V.T @ U @ L) @ np.linalg.inv(np.eye(m) + 2 * eta * L.T @ L)
        X = L @ R.T
        Tm = PD - X + Y2 / eta
        soft = np.sign(Tm) * np.maximum(np.abs(Tm) - lam / eta, 0.0)
        S = np.where(observed, soft, Tm)
        M = (eta * X - Y1) @ np.linalg.inv(eta * np.eye(n) + mu * T.T @ T)
        P, _, Qt = np.linalg.svd(L @ (V @ R).T, full_matrices=False)
        U = Qt.T @ P.T
        P, _, Qt = np.linalg.svd(R @ (U @ L).T, full_matrices=False)
        V = Qt.T @ P.T
        Y1 = Y1 + eta * (M - X)
        Y2 = Y2 + eta * (PD - X - S)
        eta = rho * eta
    return X, S


def _noisy_low_rank(seed, m, n, r, *, noise, missing):
    """A rank-r (m, n) matrix plus Gaussian noise, and a mask missing that share."""
    rng = np.random.default_rng(seed)
    D = rng.normal(size=(m, r)) @ rng.normal(size=(r, n)) + noise * rng.normal(size=(m, n))
    return D, rng.random((m, n)) > missing


def test_iteration_equals_the_textbook_updates():
    # The in-place loop (buffers, Cholesky inverses, Y₂ rewritten as η·P_Ω(clip)) must be
    # the same algorithm as the plain transcription of MODEL.md, step for step.
    r = 3
    D, observed = _noisy_low_rank(6, 12, 50, r, noise=0.01, missing=0.25)
    kwargs = dict(rank=r, lam=0.3, mu=5.0, rho=1.3, eta0=0.5)
    X_ref, S_ref = _textbook_trnn(D, observed, iterations=8, **kwargs)
    result = trnn(D, observed, max_iter=8, tol=0.0, **kwargs)
    assert result.iterations == 8
    np.testing.assert_allclose(result.X, X_ref, atol=1e-8, rtol=0)
    np.testing.assert_allclose(result.S, S_ref, atol=1e-8, rtol=0)


def test_iteration_falls_back_to_the_explicit_v_step_on_rank_deficient_factors(monkeypatch):
    # Exactly rank-1 data with r = 3: the Gram route of the V step, (U L) RᵀR (U L)ᵀ,
    # is singular, and the loop must take the explicit n × r argument (SVD) instead.
    import mocapfill.solvers.trnn as module

    explicit = []
    original = module._orthonormal_maximiser

    def counting(G):
        if G.shape[0] == 50:                # the V step's n × r argument
            explicit.append(G.shape)
        return original(G)

    monkeypatch.setattr(module, "_orthonormal_maximiser", counting)
    rng = np.random.default_rng(3)
    D = np.outer(rng.normal(size=12), rng.normal(size=50))
    observed = np.ones_like(D, dtype=bool)
    kwargs = dict(rank=3, lam=0.3, mu=5.0, rho=1.3, eta0=0.5)
    X_ref, _ = _textbook_trnn(D, observed, iterations=8, **kwargs)
    result = trnn(D, observed, max_iter=8, tol=0.0, **kwargs)
    assert len(explicit) == 8
    # The null directions of a singular argument are arbitrary, in the SVD as anywhere.
    np.testing.assert_allclose(result.X, X_ref, atol=1e-3 * np.abs(D).max(), rtol=0)


def test_times_spd_inverse_matches_the_product_with_the_inverse():
    from mocapfill.solvers._linalg import times_spd_inverse

    rng = np.random.default_rng(9)
    G = rng.normal(size=(40, 9))
    A = np.eye(9) + 2.0 * G.T @ G
    B = rng.normal(size=(5, 9))
    for dtype, tol in ((np.float64, 1e-10), (np.float32, 1e-4)):
        product = times_spd_inverse(B.astype(dtype), A.astype(dtype))
        assert product.dtype == dtype
        np.testing.assert_allclose(product @ A, B, atol=tol * np.abs(B).max())
    indefinite = np.diag([1.0, -2.0, 3.0])
    np.testing.assert_allclose(times_spd_inverse(B[:, :3], indefinite),
                               B[:, :3] @ np.linalg.inv(indefinite))


def test_iteration_stops_at_the_first_iterate_meeting_both_criteria():
    # The loop judges the constraint residual only once the change of X is small enough;
    # it must still stop exactly where the textbook iteration first meets both. Here the
    # change criterion is met three iterations before the residual one.
    r = 2
    D, observed = _noisy_low_rank(7, 10, 40, r, noise=0.05, missing=0.2)
    kwargs = dict(rank=r, lam=1.0, mu=5.0, rho=1.02, eta0=1.0)
    tol = 3e-3
    result = trnn(D, observed, tol=tol, max_iter=200, **kwargs)
    assert result.converged
    PD = np.where(observed, D, 0.0)

    def criteria(k):
        X, S = _textbook_trnn(D, observed, iterations=k, **kwargs)
        X_prev, _ = _textbook_trnn(D, observed, iterations=k - 1, **kwargs)
        return (np.linalg.norm(PD - X - S) / np.linalg.norm(PD),
                np.linalg.norm(X - X_prev) / np.linalg.norm(X))

    k = result.iterations
    assert max(criteria(k)) <= tol
    residual, change = criteria(k - 1)
    assert residual > tol >= change


def test_spd_inverse_matches_lu_and_falls_back_on_an_indefinite_matrix():
    from mocapfill.solvers._linalg import spd_inverse

    rng = np.random.default_rng(7)
    G = rng.normal(size=(40, 9))
    A = np.eye(9) + 2.0 * G.T @ G
    for dtype, tol in ((np.float64, 1e-10), (np.float32, 1e-4)):
        inverse = spd_inverse(A.astype(dtype))
        assert inverse.dtype == dtype
        np.testing.assert_allclose(inverse @ A.astype(dtype), np.eye(9), atol=tol)
    indefinite = np.diag([1.0, -2.0, 3.0])
    np.testing.assert_allclose(spd_inverse(indefinite), np.linalg.inv(indefinite))


def test_orthonormal_maximiser_is_the_svd_solution_and_survives_rank_deficiency():
    from mocapfill.solvers.trnn import _orthonormal_maximiser

    rng = np.random.default_rng(8)
    for rows in (40, 2000):
        G = rng.normal(size=(rows, 5)) * np.array([100.0, 10.0, 1.0, 0.1, 0.05])
        P, _, Qt = np.linalg.svd(G, full_matrices=False)
        for dtype, tol in ((np.float64, 1e-9), (np.float32, 1e-4)):
            U = _orthonormal_maximiser(G.astype(dtype))
            assert U.dtype == dtype and U.shape == (5, rows)
            np.testing.assert_allclose(U, Qt.T @ P.T, atol=tol)
    # Rank 2 of 3: the Gram route cannot resolve the null direction; the SVD's answer
    # is still orthonormal and attains the maximum tr(U G) = Σσ.
    G = rng.normal(size=(50, 2)) @ rng.normal(size=(2, 3))
    U = _orthonormal_maximiser(G)
    np.testing.assert_allclose(U @ U.T, np.eye(3), atol=1e-10)
    assert np.trace(U @ G) == pytest.approx(np.linalg.svd(G, compute_uv=False).sum())


@pytest.mark.parametrize("shape", [(30, 400), (45, 20)])
def test_rank_from_the_gram_matrix_matches_the_svd(shape):
    from mocapfill.rank import estimate_rank

    rng = np.random.default_rng(10)
    m, n = shape
    scales = np.r_[np.geomspace(10.0, 0.5, 6), np.zeros(min(m, n) - 6)]
    U, _ = np.linalg.qr(rng.normal(size=(m, min(m, n))))
    V, _ = np.linalg.qr(rng.normal(size=(n, min(m, n))))
    D = (U * scales) @ V.T + 1e-4 * rng.normal(size=(m, n))
    observed = rng.random((m, n)) > 0.1
    exact = estimate_rank(D, observed)
    fast = estimate_rank(D, observed, exact=False)
    assert fast.rank == exact.rank
    np.testing.assert_allclose(fast.singular_values, exact.singular_values,
                               atol=1e-7 * exact.singular_values[0])


def _spied_blend(monkeypatch) -> list[tuple[dict, dict]]:
    """Record the candidates and the options of every call to ``gapwise.blend``."""
    from mocapfill.solvers import gapwise

    calls = []
    original = gapwise.blend

    def spy(matrix, observed, candidates, **options):
        calls.append((dict(candidates), options))
        return original(matrix, observed, candidates, **options)

    monkeypatch.setattr(gapwise, "blend", spy)
    return calls


def _sines(seed: int) -> np.ndarray:
    """12 rows of sines of random frequency and phase over 300 frames."""
    rng = np.random.default_rng(seed)
    t = np.arange(300) / 60.0
    return np.vstack([np.sin(2 * np.pi * f * t + p) for f, p in rng.uniform(0.2, 1, (12, 2))])


@pytest.mark.parametrize("skip", [False, True])
def test_a_window_may_skip_every_unweighted_candidate_but_the_spline(monkeypatch, skip):
    from mocapfill.solvers.trnn import PCA_MODELS, WINDOW_PCA_MODELS, complete_window

    calls = _spied_blend(monkeypatch)
    matrix = _sines(0)
    observed = np.ones_like(matrix, dtype=bool)
    observed[3:6, 100:130] = False
    filled, _ = complete_window(matrix, observed, skip_unweighted=skip)
    names, options = calls[-1]
    assert "spline" in names and "spline" not in options["optional"]
    expected = set(names) - {"spline"} if skip else set()
    assert set(options["optional"]) == expected
    # A window's validation run of TrNN stops at a looser tolerance, and its PCA (seeing
    # the short gaps filled first) has the smaller model budget.
    assert set(options["validators"] or {}) == ({"trnn"} if skip else set())
    assert names["pca"].__wrapped__.keywords["max_models"] == (WINDOW_PCA_MODELS if skip
                                                               else PCA_MODELS)
    np.testing.assert_array_equal(filled[observed], matrix[observed])
    assert np.isfinite(filled).all()


def test_the_default_blends_tsmc_on_scattered_loss_only(monkeypatch):
    calls = _spied_blend(monkeypatch)
    matrix = _sines(1)
    long_gaps = np.ones_like(matrix, dtype=bool)
    long_gaps[3:6, 100:130] = False
    for observed, offered in ((long_gaps, False), (scattered(1, *matrix.shape, 0.2), True)):
        filled = complete(matrix, observed)
        assert ("tsmc" in calls[-1][0]) == offered
        np.testing.assert_array_equal(filled[observed], matrix[observed])
        assert np.isfinite(filled).all()


def _staggered_gaps(markers: int, n: int, length: int, shift: int) -> np.ndarray:
    """A mask where marker j misses ``length`` frames from frame 10 + ``shift``·j."""
    observed = np.ones((3 * markers, n), dtype=bool)
    for j in range(markers):
        observed[3 * j:3 * j + 3, 10 + shift * j:10 + shift * j + length] = False
    return observed


def test_pca_is_offered_without_complete_frames_where_its_models_are_few(monkeypatch):
    from mocapfill.solvers.gapwise import row_groups
    from mocapfill.solvers.trnn import pca_offered

    # Four markers each losing 80 frames in turn: no complete frame from frame 10 to
    # 284, and a few sets of visible markers. PCA drops the gapped predictors, offered.
    few = _staggered_gaps(4, 300, 80, 65)
    assert few.all(axis=0).sum() < 60
    assert pca_offered(few, row_groups(few))
    calls = _spied_blend(monkeypatch)
    filled = complete(_sines(2), few)
    assert "pca" in calls[-1][0]
    np.testing.assert_array_equal(filled[few], _sines(2)[few])
    # 41 markers each losing 60 stretches of 5-9 frames at random: 25 complete frames,
    # and thousands of sets of visible markers, a model search for each (random loss:
    # 0.7-3.9 s per run for nothing).
    rng = np.random.default_rng(3)
    many = np.ones((123, 1000), dtype=bool)
    for j in range(41):
        for start in rng.choice(np.arange(10, 980, 7), 60, replace=False):
            many[3 * j:3 * j + 3, start:start + rng.integers(5, 10)] = False
    groups = row_groups(many)
    assert many.all(axis=0).sum() < 60
    assert not pca_offered(many, groups)
    # With 60 complete frames it is offered whatever the gaps.
    many[:, 500:560] = True
    assert pca_offered(many, groups)


def test_the_default_starts_its_costly_candidates_first(monkeypatch):
    from mocapfill.solvers.trnn import RUN_ORDER

    calls = _spied_blend(monkeypatch)
    matrix = _sines(1)
    offered = set()
    for observed in (np.ones_like(matrix, dtype=bool), scattered(1, *matrix.shape, 0.2)):
        observed[3:6, 100:130] = False
        complete(matrix, observed)
        names, options = calls[-1]
        offered |= set(names)
        assert options["costly"] == RUN_ORDER
    # A misspelt name would be passed over in silence (blend starts only the candidates
    # it has): every name is one the default offers, and the cheap splines come last.
    assert set(RUN_ORDER) <= offered
    assert RUN_ORDER[:2] == ("trnn", "gaussian")
    assert not {"spline", "quintic", "septic"} & set(RUN_ORDER)



def test_the_pca_candidate_joins_the_gap_ends(monkeypatch):
    # The blend adds no ramp of its own: a candidate off the data at a gap's ends puts a
    # step into and out of the gap, in proportion to its weight. The PCA fill predicts a
    # gap from the other markers only, so where the gapped marker also moves on its own
    # it was off by the model's error there (7.4 and 3.9 times the clip's largest step
    # here; on real clips a median 9.5 mm, one gap in ten over 50 mm).
    from mocapfill.solvers import gapwise, pca
    from mocapfill.solvers.trnn import complete_window

    X = _smooth_low_rank_clip(n=600, markers=12)
    t = np.arange(X.shape[1]) / 120.0
    X[6:9] += 0.8 * np.sin(2 * np.pi * 3.1 * t + np.array([[0.0], [1.0], [2.0]]))
    observed = np.ones_like(X, bool)
    spans = [(200, 290), (400, 460)]              # two gaps of marker 2
    for a, b in spans:
        observed[6:9, a:b] = False
    matrix = np.where(observed, X, 0.0)
    captured = {}
    blend = gapwise.blend

    def capturing(matrix, mask, candidates, **options):
        captured["pca"] = candidates["pca"](matrix, mask)
        return blend(matrix, mask, candidates, **options)

    monkeypatch.setattr(gapwise, "blend", capturing)
    complete_window(matrix, observed)
    fill = captured["pca"]
    max_step = np.abs(np.diff(X[6:9], axis=1)).max()
    for a, b in spans:
        assert np.abs(fill[6:9, a] - X[6:9, a - 1]).max() <= 1.5 * max_step
        assert np.abs(X[6:9, b] - fill[6:9, b - 1]).max() <= 1.5 * max_step
        # The published fill plus a straight ramp along each gap; observed samples kept.
        ramp = fill[6:9, a:b] - pca.complete(matrix, observed)[6:9, a:b]
        np.testing.assert_allclose(np.diff(ramp, 2, axis=1), 0.0, atol=1e-9)
    np.testing.assert_array_equal(fill[observed], X[observed])
