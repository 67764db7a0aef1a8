"""``_linalg.simplex_least_squares``: the blend's convex weights, min wᵀGw, w ≥ 0, Σw = 1."""
from __future__ import annotations

import numpy as np
from scipy.optimize import nnls

from mocapfill.solvers._linalg import _simplex_support_solutions, simplex_least_squares


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


def test_a_stack_of_problems_is_solved_as_each_alone():
    # Problems of every kind side by side: different supports, step counts and scales,
    # one with a zero best error and one whose best error is subnormal beside the others.
    rng = np.random.default_rng(15)
    grams = [_gram(rng, 6, spread=float(rng.uniform(0, 5))) for _ in range(60)]
    e = rng.standard_normal((50, 1))
    grams.append(np.hstack([2 * e, 0 * e, e, e, e, e]).T @ np.hstack([2 * e, 0 * e, e, e, e, e]))
    grams.append(np.diag([1e-310, 1e10, 1.0, 1.0, 1.0, 1.0]))
    together = simplex_least_squares(np.stack(grams))
    assert together.shape == (62, 6)
    for G, w in zip(grams, together):
        np.testing.assert_allclose(w, simplex_least_squares(G), rtol=0, atol=1e-12)
    for G, w in zip(grams[:60], together):
        assert _kkt_violation(G, w) < 1e-8


def test_a_singular_support_in_a_stack_is_solved_on_its_own():
    # Columns 0 and 1 equal: their support's KKT system is singular, which must not stop
    # the stack's other system from being solved exactly.
    rng = np.random.default_rng(16)
    errors = rng.standard_normal((100, 3))
    errors[:, 1] = errors[:, 0]
    singular = errors.T @ errors
    regular = _gram(rng, 3)
    z = _simplex_support_solutions(np.stack([singular, regular]),
                                   np.array([[True, True, False], [True, False, True]]))
    assert np.isfinite(z).all() and np.allclose(z.sum(axis=1), 1.0)
    assert z[0, 2] == 0.0 and z[1, 1] == 0.0
    G = regular[np.ix_([0, 2], [0, 2])]
    expected = np.linalg.solve(G, np.ones(2))
    np.testing.assert_allclose(z[1, [0, 2]], expected / expected.sum(), rtol=1e-12)
