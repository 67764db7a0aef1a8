"""Errors of the default's candidates on end gaps (gaps touching the clip's first or last
frame), which ``--ends extrapolate`` fills.

Per-coordinate RMS error (mm) on the end-gap samples / the interior gap samples, seeds 1
and 2, of some candidates run alone on the unit-RMS clip as the blend runs them (TrNN,
Gaussian, TSMC, PCA, the six-donor rigid fill), and of the default method's fill
(``complete_matrix``, every gap filled). Cases: the
paper's random loss (``mr 0.6``), or ``end L``: 5 random markers hidden over the first or
last L frames. Needs ../shared/data/cmu. Example (docs/results.md, thirty-fifth session):

    python scripts/end_gaps.py 10_01 end 10
    python scripts/end_gaps.py 02_05 mr 0.6

``sums SEEDS [CASES]`` prints only the default's end-gap error (and its interior one) for
each case and seed, and their sum over cases and seeds; CASES (comma-separated, e.g.
``"10_01 end 30,85_02 mr 0.4"``) defaults to the seven of the thirty-fifth session's
table (docs/results.md, thirty-sixth session):

    python scripts/end_gaps.py sums 6,7,8
"""
from __future__ import annotations

import sys
from functools import partial

from mocapfill._blas import one_thread_by_default

one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import _cmu_motion  # noqa: E402
from mocapfill.gaps import simulate_gaps  # noqa: E402
from mocapfill.pipeline import complete_matrix  # noqa: E402
from mocapfill.scaling import UnitScale  # noqa: E402
from mocapfill.solvers import gapwise  # noqa: E402
from mocapfill.solvers.gaussian import gap_fill as gaussian_fill  # noqa: E402
from mocapfill.solvers.pca import gap_fill as pca_fill  # noqa: E402
from mocapfill.solvers.trnn import complete_lowrank  # noqa: E402
from mocapfill.solvers.tsmc import complete as tsmc  # noqa: E402


def gapped(truth, kind: str, value: float, seed: int):
    if kind == "mr":
        return simulate_gaps(truth, mr=value, seed=seed)
    rng = np.random.default_rng(seed)
    positions, observed = truth.positions.copy(), truth.observed.copy()
    length = int(value)
    for marker in rng.choice(truth.n_markers, 5, replace=False):
        frames = (slice(0, length) if rng.random() < 0.5
                  else slice(truth.n_frames - length, None))
        observed[frames, marker] = False
        positions[frames, marker] = np.nan
    return truth.with_positions(positions, observed)


CASES = ("10_01 end 10,85_02 end 60,02_05 end 60,85_12 end 240,10_01 mr 0.6,02_05 mr 0.6,"
         "85_02 mr 0.6")


def end_and_interior(observed: np.ndarray, seen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Masks of the end-gap and the interior-gap samples that the truth holds."""
    groups = gapwise.row_groups(observed)
    inside = np.zeros_like(observed)
    for g, a, b in gapwise.interior_gaps(observed, groups):
        inside[groups[g], a:b] = True
    return ~observed & ~inside & seen, inside & seen


def sums(seeds: list[int], cases: str = CASES) -> None:
    total = 0.0
    for case in cases.split(","):
        clip, kind, value = case.split()
        truth = _cmu_motion(clip)
        T, seen = truth.matrix()
        line = []
        for seed in seeds:
            M, observed = gapped(truth, kind, float(value), seed).matrix()
            ends, inside = end_and_interior(observed, seen)
            errors = (complete_matrix(M, observed, "trnn") - T) ** 2
            total += np.sqrt(errors[ends].mean())
            within = f"{np.sqrt(errors[inside].mean()):.3f}" if inside.any() else "–"
            line.append(f"{np.sqrt(errors[ends].mean()):.2f} / {within}")
        print(f"{case}: " + " | ".join(line), flush=True)
    print(f"sum of the end-gap errors {total:.2f} mm")


def main(clip: str, kind: str, value: float) -> None:
    truth = _cmu_motion(clip)
    T, seen = truth.matrix()
    for seed in (1, 2):
        M, observed = gapped(truth, kind, value, seed).matrix()
        scale = UnitScale.fit(M, observed)
        X = scale.forward(np.where(observed, M, 0.0))
        centre = scale.centre[:, 0] / scale.scale
        ends, inside = end_and_interior(observed, seen)
        short_runs_first = gapwise.ShortRunsFirst()
        candidates = {"trnn": complete_lowrank, "gaussian": gaussian_fill, "tsmc": tsmc,
                      "pca": short_runs_first(partial(pca_fill, centre=centre)),
                      "rigid6": short_runs_first(partial(gapwise.rigid_fill, centre=centre,
                                                         donors=6, weighted=True))}
        line = []
        fills = {name: scale.inverse(fill(X, observed)) for name, fill in candidates.items()}
        fills["default"] = complete_matrix(M, observed, "trnn")
        for name, filled in fills.items():
            errors = (filled - T) ** 2
            within = f"{np.sqrt(errors[inside].mean()):.3f}" if inside.any() else "–"
            line.append(f"{name} {np.sqrt(errors[ends].mean()):.2f} / {within}")
        print(f"{clip} {kind} {value:g} seed {seed}: {int(ends.sum())} end samples;",
              " | ".join(line), flush=True)


if __name__ == "__main__":
    if sys.argv[1] == "sums":
        sums([int(seed) for seed in sys.argv[2].split(",")], *sys.argv[3:4])
    else:
        main(sys.argv[1], sys.argv[2], float(sys.argv[3]))
