"""``_linalg.simplex_least_squares``: the blend's convex weights, min wᵀGw, w ≥ 0, Σw = 1."""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from mocapfill.solvers._linalg import simplex_least_squares


def _gram(rng: np.random.Generator, k: int, spread: float = 1.0) -> np.ndarray:
    """Errors of k candidates on 200 samples: a shared part plus each one's own, with
    scales spread over ``spread`` decades."""
    own = rng.standard_normal((200, k)) * 10.0 ** rng.uniform(-spread, spread, k)
    errors = own + rng.uniform(0, 2) * rng.standard_normal((200, 1))
    return errors.T @ errors


def _kkt_violation(G: np.ndarray, w: np.ndarray) -> float:
    """How far w is from optimal: feasibility, and (Gw)_j ≥ wᵀGw off the support with
    equality on it (relative to the objective)."""
    g = G @ w
    f = float(w @ g)
    on = w > 0
    return max(abs(w.sum() - 1.0), -w.min(),
               float(np.abs(g[on] - f).max()) / f,
               float(max(0.0, (f - g[~on]).max(initial=0.0))) / f)


def test_weights_are_the_penalised_nnls_solution_on_well_scaled_problems():
    # The formulation the blend used before: NNLS with Σw = 1 as a heavy extra row.
    rng = np.random.default_rng(11)
    for _ in range(200):
        k = int(rng.integers(2, 9))
        G = _gram(rng, k)
        values, vectors = np.linalg.eigh(G)
        R = np.sqrt(np.maximum(values, 0.0))[:, None] * vectors.T
        big = 1e3 * np.sqrt(G.trace())
        w_nnls = nnls(np.vstack([R, np.full((1, k), big)]), np.r_[np.zeros(k), big])[0]
        np.testing.assert_allclose(simplex_least_squares(G), w_nnls / w_nnls.sum(),
                                   rtol=0, atol=1e-6)


def test_weights_meet_the_optimality_conditions_when_scales_differ_by_1e10():
    # One candidate erring 10⁵ times more than another (a septic spline swinging): the
    # penalised NNLS stopped on a worse blend there; the exact conditions must hold.
    rng = np.random.default_rng(12)
    for _ in range(200):
        k = int(rng.integers(2, 9))
        G = _gram(rng, k, spread=5.0)
        w = simplex_least_squares(G)
        assert _kkt_violation(G, w) < 1e-8


def test_duplicate_candidates_share_or_take_the_weight_without_cycling():
    rng = np.random.default_rng(13)
    errors = rng.standard_normal((100, 3))
    errors[:, 2] = errors[:, 0]
    G = errors.T @ errors
    w = simplex_least_squares(G)
    assert _kkt_violation(G, w) < 1e-8
    single = np.eye(3)[0]
    assert w @ G @ w <= single @ G @ single


def test_a_perfect_candidate_takes_all_the_weight_and_opposite_errors_cancel():
    e = np.random.default_rng(14).standard_normal((50, 1))
    zero = np.hstack([2 * e, 0 * e, e]).T @ np.hstack([2 * e, 0 * e, e])
    np.testing.assert_array_equal(simplex_least_squares(zero), [0.0, 1.0, 0.0])
    opposite = np.hstack([e, -3 * e]).T @ np.hstack([e, -3 * e])
    np.testing.assert_allclose(simplex_least_squares(opposite), [0.75, 0.25], atol=1e-12)
