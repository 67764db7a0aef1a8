"""The default's error and time on long real clips, as the windows of long clips see them.

Builds a clip of the requested length from CMU 85_12, 02_05 and 85_02 (their complete
frames, forward and reversed, each piece translated to start where the last one ended and
cross-faded into it over 60 frames, repeated as needed), hides 5 % of its samples in
20–120-frame gaps with the seed, repairs it with the default method in this process and
prints the 3-D RMS error over the hidden samples (mm) and the seconds. Needs
../shared/data/cmu. Example (the thirty-first session's windows table of
docs/results.md; run it from two checkouts to compare them):

    python scripts/long_clips.py 12001:0 12001:1 14400:0 [FRAMES:SEED ...]
"""
from __future__ import annotations

import sys
import time

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import SHARED_DATA  # noqa: E402 (after the BLAS setting)
from mocapfill.bench_speed import random_gaps  # noqa: E402 (after the BLAS setting)
from mocapfill.formats import read  # noqa: E402 (after the BLAS setting)
from mocapfill.motion import Motion  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import RepairOptions, repair  # noqa: E402 (after the BLAS setting)

CLIPS = ("85_12", "02_05", "85_02")
FADE = 60           # frames over which each piece is faded in from the last pose
MISSING = 0.05      # share of the samples hidden


def pieces() -> tuple[list[np.ndarray], tuple[str, ...], float]:
    """The clips' complete frames forward and reversed, markers in the first clip's
    order (matched without the ``Subject:`` prefix), its labels and its rate."""
    first = None
    out = []
    for name in CLIPS:
        clip = read(SHARED_DATA / "cmu" / f"{name}.c3d")
        first = first or clip
        bare = [label.split(":")[-1] for label in clip.labels]
        order = [bare.index(label.split(":")[-1]) for label in first.labels]
        complete = clip.observed[:, order].all(axis=1)
        positions = clip.positions[complete][:, order]
        out += [positions, positions[::-1]]
    return out, first.labels, first.rate


def long_clip(frames: int, seed: int) -> tuple[np.ndarray, Motion]:
    """(truth, gapped): ``frames`` frames of the joined pieces, ``MISSING`` of the samples
    hidden in 20–120-frame gaps of random markers."""
    parts, labels, rate = pieces()
    joined, total = [], 0
    while total < frames:
        for piece in parts:
            piece = piece.copy()
            if joined:
                last = joined[-1][-1]
                piece += (last - piece[0]).mean(axis=0)
                w = np.linspace(0.0, 1.0, FADE)[:, None, None]
                piece[:FADE] = (1 - w) * last + w * piece[:FADE]
            joined.append(piece)
            total += len(piece)
    truth = np.concatenate(joined)[:frames]
    observed = random_gaps(np.random.default_rng(seed), frames, truth.shape[1], MISSING)
    positions = np.where(observed[:, :, None], truth, np.nan)
    return truth, Motion(positions, observed, labels, rate, "mm")


def main(specs: list[str]) -> int:
    if not (SHARED_DATA / "cmu").is_dir():
        print(f"needs {SHARED_DATA / 'cmu'} (the shared data)", file=sys.stderr)
        return 2
    for spec in specs or ["12001:0"]:
        frames, _, seed = spec.partition(":")
        truth, gapped = long_clip(int(frames), int(seed or 0))
        started = time.perf_counter()
        result = repair(gapped, RepairOptions(method="trnn"))
        seconds = time.perf_counter() - started
        hidden = ~gapped.observed
        error = result.motion.positions[hidden] - truth[hidden]
        filled = np.isfinite(error).all(axis=1)
        rms = np.sqrt(np.mean(np.sum(error[filled] ** 2, axis=1)))
        print(f"{frames:>7} frames, seed {seed or 0}: {rms:.4f} mm, "
              f"{int((~filled).sum())} unfilled, {seconds:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
