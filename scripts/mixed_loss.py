"""Long occlusions with flicker on top: the paper's two CMU protocols at once.

Each CMU clip first loses ``ml`` frames of 10 markers (the continuous protocol, seed s),
then a fraction ``mr`` of its markers in every frame (the random protocol, seed s + 100):
long gaps among markers that drop out for a frame or two all through the clip, as raw
optical captures have them. Prints, per clip and seed, each method's 3-D RMSE over all
removed samples, over those of the long gaps, and over the rest, and the repair's time.
Needs ../shared/data/cmu. Example (the twenty-sixth session's table of docs/results.md):

    python scripts/mixed_loss.py 40 0.05 trnn pca
"""
from __future__ import annotations

import sys
import time

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import CMU_CLIPS, _cmu_motion  # noqa: E402 (after the BLAS setting)
from mocapfill.gaps import simulate_gaps  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import RepairOptions, repair  # noqa: E402 (after the BLAS setting)

SEEDS = (0, 1)


def _rmse_3d(truth, repaired, mask: np.ndarray) -> float:
    scored = mask & repaired.observed
    if not scored.any():
        return float("nan")
    errors = np.linalg.norm(repaired.positions[scored] - truth.positions[scored], axis=1)
    return float(np.sqrt(np.mean(errors ** 2)))


def main(ml: int, mr: float, methods: list[str]) -> None:
    for clip in CMU_CLIPS:
        truth = _cmu_motion(clip)
        for seed in SEEDS:
            occluded = simulate_gaps(truth, ml=ml, seed=seed)
            gapped = simulate_gaps(occluded, mr=mr, seed=seed + 100)
            removed = truth.observed & ~gapped.observed
            long = removed & ~occluded.observed
            for method in methods:
                started = time.perf_counter()
                repaired = repair(gapped, RepairOptions(method=method)).motion
                seconds = time.perf_counter() - started
                print(f"{clip} seed {seed} ml={ml} mr={mr:g} {method:8s} "
                      f"all {_rmse_3d(truth, repaired, removed):8.3f}  "
                      f"long {_rmse_3d(truth, repaired, long):8.3f}  "
                      f"rest {_rmse_3d(truth, repaired, removed & ~long):7.3f} mm  "
                      f"{seconds:5.1f} s", flush=True)


if __name__ == "__main__":
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    main(int(sys.argv[1]), float(sys.argv[2]), sys.argv[3:])
