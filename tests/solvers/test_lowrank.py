"""The low-rank warm start of TrNN and the Gaussian fill (``solvers.lowrank``)."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill.solvers._linalg import linear_fill
from mocapfill.solvers.lowrank import _top_subspace, low_rank_start, project_frames


def _rank_r_clip(m: int, n: int, r: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.normal(size=(m, r)) @ rng.normal(size=(r, n))


def _gapped(n: int, m: int, stretches: list[tuple[int, int, int]]) -> np.ndarray:
    observed = np.ones((m, n), dtype=bool)
    for row, start, stop in stretches:
        observed[row, start:stop] = False
    return observed


def test_complete_frames_give_the_exact_fill_of_a_rank_r_clip():
    X = _rank_r_clip(12, 200, 3, seed=0)
    observed = _gapped(200, 12, [(0, 20, 60), (5, 50, 90), (11, 150, 199)])
    out = low_rank_start(np.where(observed, X, np.nan), observed, rank=3)
    np.testing.assert_array_equal(out[observed], X[observed])
    # Exact but for the projection's ridge (1e−6 of the basis' unit Gram matrix).
    np.testing.assert_allclose(out, X, rtol=0, atol=1e-5)


def test_only_the_incomplete_frames_are_filled_and_as_when_every_frame_was_projected():
    # The fill of an incomplete frame is its own least-squares projection on the complete
    # frames' subspace, whichever other frames are projected beside it.
    X = _rank_r_clip(15, 300, 4, seed=1) + np.random.default_rng(2).normal(size=(15, 300))
    observed = _gapped(300, 15, [(1, 10, 40), (7, 30, 80), (14, 200, 260)])
    out = low_rank_start(X, observed, rank=4)
    complete = observed.all(axis=0)
    basis = _top_subspace(X[:, complete], 4)
    every = np.where(observed, X, basis @ project_frames(X, observed, basis))
    np.testing.assert_allclose(out, every, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out[:, complete], X[:, complete])


@pytest.mark.parametrize("missing_value", [0.0, np.nan])
def test_few_complete_frames_take_alternating_least_squares(missing_value):
    # Every frame lacks a coordinate: the subspace is re-estimated from the filled frames.
    X = _rank_r_clip(9, 120, 2, seed=3)
    observed = np.ones_like(X, dtype=bool)
    observed[np.arange(120) % 9, np.arange(120)] = False
    data = np.where(observed, X, missing_value)
    out = low_rank_start(data, observed, rank=2, rounds=30, ridge=1e-9)
    np.testing.assert_array_equal(out[observed], X[observed])
    start_error = np.abs(linear_fill(data, observed) - X)[~observed].max()
    assert np.abs(out - X)[~observed].max() < 1e-3 * start_error


@pytest.mark.parametrize("every_frame_gapped", [False, True])
def test_a_tall_clip_never_decomposes_a_rows_by_rows_matrix(monkeypatch, every_frame_gapped):
    # More rows than frames (1,000 markers over 100 frames): the subspace comes from the
    # thin SVD (rows × frames), not from the rows × rows X Xᵀ, whose eigendecomposition
    # took seconds, nine times per warm start. The fill is still the exact one.
    m, n = 240, 40
    X = _rank_r_clip(m, n, 3, seed=4)
    observed = np.ones((m, n), dtype=bool)
    if every_frame_gapped:
        observed[np.arange(n) % m, np.arange(n)] = False
    else:
        observed[[0, 1, 2], 10:20] = False
    sizes = []
    eigh = np.linalg.eigh

    def recording(a, *args, **kwargs):
        sizes.append(np.shape(a)[-1])
        return eigh(a, *args, **kwargs)

    monkeypatch.setattr(np.linalg, "eigh", recording)
    out = low_rank_start(np.where(observed, X, np.nan), observed, rank=3,
                         rounds=30, ridge=1e-9)
    assert max(sizes, default=0) <= n
    np.testing.assert_array_equal(out[observed], X[observed])
    np.testing.assert_allclose(out, X, rtol=0, atol=1e-4)
    assert np.allclose(_top_subspace(X, 3).T @ _top_subspace(X, 3), np.eye(3))
