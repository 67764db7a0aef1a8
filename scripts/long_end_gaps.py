"""The default's end-gap error on long clips, whose windows hold the clip's ends.

Builds ``scripts/long_clips.py``'s joined CMU clip of FRAMES frames (5 % of the samples
hidden in 20–120-frame gaps, seed SEED), hides 6 random markers over the first or last L
frames as well, repairs it with ``--ends extrapolate`` and prints the 3-D RMS error over
those end-gap samples (mm) and the seconds; then the same for its first and its last
12,000 frames alone (one window each). Needs ../shared/data/cmu. Example (docs/results.md,
thirty-sixth session):

    python scripts/long_end_gaps.py 36000 60 0 1
"""
from __future__ import annotations

import sys
import time

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)
from long_clips import long_clip  # noqa: E402 (scripts/, beside this one)

from mocapfill.motion import Motion  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import WINDOW_FRAMES, RepairOptions, repair  # noqa: E402

HIDDEN = 6          # markers hidden over an end


def main(frames: int, length: int, seeds: list[int]) -> None:
    for seed in seeds:
        truth, gapped = long_clip(frames, seed)
        rng = np.random.default_rng(100 + seed)
        observed = gapped.observed.copy()
        ends = np.zeros_like(observed)
        for marker in rng.choice(observed.shape[1], HIDDEN, replace=False):
            at_start = rng.random() < 0.5
            ends[slice(0, length) if at_start else slice(frames - length, frames), marker] = True
        observed &= ~ends
        positions = np.where(observed[:, :, None], truth, np.nan)
        cuts = (("whole", slice(None)), (f"first {WINDOW_FRAMES}", slice(0, WINDOW_FRAMES)),
                (f"last {WINDOW_FRAMES}", slice(frames - WINDOW_FRAMES, frames)))
        for name, cut in cuts:
            hidden = ends[cut]
            if not hidden.any():
                continue
            clip = Motion(positions[cut], observed[cut], gapped.labels, gapped.rate, "mm")
            started = time.perf_counter()
            result = repair(clip, RepairOptions(method="trnn", ends="extrapolate",
                                                max_jump_mm=0))
            seconds = time.perf_counter() - started
            error = result.motion.positions[hidden] - truth[cut][hidden]
            rms = np.sqrt(np.mean(np.sum(error ** 2, axis=1)))
            print(f"{frames} frames, seed {seed}, {name}: end gaps {rms:.2f} mm "
                  f"({int(hidden.sum())} samples), {seconds:.1f} s", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]), [int(s) for s in sys.argv[3:]] or [0])
