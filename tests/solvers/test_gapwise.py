"""Validation stand-ins of the default blend (mocapfill.solvers.gapwise.pseudo_gaps)."""
from __future__ import annotations

import numpy as np

from mocapfill.solvers.gapwise import GapSet, interior_gaps, pseudo_gaps, row_groups


def _mask(n_markers: int, n: int, gaps: list[tuple[int, int, int]]) -> np.ndarray:
    seen = np.ones((n_markers, n), bool)
    for marker, a, b in gaps:
        seen[marker, a:b] = False
    return np.repeat(seen, 3, axis=0)


def _stand_ins(observed: np.ndarray, seed: int = 0, **options):
    groups = row_groups(observed)
    gapset = GapSet(groups, interior_gaps(observed, groups))
    return gapset, pseudo_gaps(observed, gapset, np.random.default_rng(seed), **options)


def _check_stand_ins(observed, gapset, chosen, fraction=0.1):
    seen = observed[0::3]
    hidden = np.zeros_like(seen)
    for (g, s, t), source in chosen:
        _, a, b = gapset.gaps[source]
        assert t - s == b - a                      # same length as the real gap
        assert seen[g, s - 1:t + 1].all()          # an interior gap of observed frames
        # one observed, unhidden frame between it and any other stand-in of that marker
        assert not hidden[g, max(s - 1, 0):t + 1].any()
        hidden[g, s:t] = True
    assert hidden.sum() <= fraction * seen.sum()


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
