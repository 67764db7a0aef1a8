"""Clips with many markers for measuring the default method where CMU has 41: virtual
markers rigidly attached to a CMU clip's markers, with gaps, repaired and scored.

Each virtual marker sits on the local frame of one CMU marker and two of its three
nearest (mean distance over the clip), at a fixed offset of 20–80 mm in a random
direction, with 0.2 mm of noise; 5 % of the samples are then removed in 20–120-frame
gaps. Prints the default method's 3-D RMSE on the removed samples it filled (how many it
left, rejected for a jump at a gap end, is printed too) and the repair's time.
Needs ../shared/data/cmu. Example (the twenty-second session's rigid-donor table of
docs/results.md):

    python scripts/virtual_markers.py 85_12:300 85_12:100 02_05:200

Each argument is CLIP:MARKERS[:SEED] (seed 0 by default).
"""
from __future__ import annotations

import sys
import time

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import _cmu_motion  # noqa: E402 (after the BLAS setting)
from mocapfill.motion import Motion  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import RepairOptions, repair  # noqa: E402 (after the BLAS setting)


def virtual_clip(clip: Motion, markers: int, seed: int) -> Motion:
    """``markers`` virtual markers on ``clip``'s complete frames (no gaps of their own)."""
    rng = np.random.default_rng(seed)
    complete = clip.observed.all(axis=1)
    P = clip.positions[complete]                                        # (n, k, 3)
    k = P.shape[1]
    mean_distance = np.linalg.norm(P[:, :, None] - P[:, None, :], axis=3).mean(axis=0)
    np.fill_diagonal(mean_distance, np.inf)
    out = np.empty((P.shape[0], markers, 3))
    for v in range(markers):
        base = v % k
        first, second = rng.choice(np.argsort(mean_distance[base])[:3], 2, replace=False)
        e1 = P[:, first] - P[:, base]
        e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
        e2 = P[:, second] - P[:, base]
        e2 -= (e2 * e1).sum(axis=1, keepdims=True) * e1
        e2 /= np.linalg.norm(e2, axis=1, keepdims=True)
        frame = np.stack([e1, e2, np.cross(e1, e2)], axis=2)           # (n, 3, 3)
        direction = rng.normal(size=3)
        offset = rng.uniform(20, 80) * direction / np.linalg.norm(direction)
        out[:, v] = P[:, base] + frame @ offset + rng.normal(scale=0.2, size=(P.shape[0], 3))
    labels = tuple(f"V{v + 1:03d}" for v in range(markers))
    return Motion(out, np.ones(out.shape[:2], dtype=bool), labels, clip.rate, "mm")


def with_gaps(clip: Motion, share: float, seed: int) -> Motion:
    """``clip`` with ``share`` of its samples removed in interior 20–120-frame gaps."""
    rng = np.random.default_rng(seed + 1)
    observed = clip.observed.copy()
    n, k = observed.shape
    while (~observed).mean() < share:
        length = int(rng.integers(20, 121))
        marker, start = int(rng.integers(k)), int(rng.integers(1, n - length - 1))
        observed[start:start + length, marker] = False
    positions = np.where(observed[:, :, None], clip.positions, np.nan)
    return Motion(positions, observed, clip.labels, clip.rate, clip.units)


def main(cases: list[str]) -> None:
    for case in cases:
        name, markers, *seed = case.split(":")
        seed = int(seed[0]) if seed else 0
        truth = virtual_clip(_cmu_motion(name), int(markers), seed)
        gapped = with_gaps(truth, 0.05, seed)
        started = time.perf_counter()
        filled = repair(gapped, RepairOptions()).motion
        seconds = time.perf_counter() - started
        hidden = ~gapped.observed
        scored = hidden & filled.observed           # a fill rejected for a jump is left
        error = np.linalg.norm(filled.positions[scored] - truth.positions[scored], axis=1)
        print(f"{case}: {gapped.n_frames} frames, {hidden.sum()} samples removed "
              f"({(hidden & ~scored).sum()} left), 3-D RMSE "
              f"{np.sqrt(np.mean(error ** 2)):.3f} mm, {seconds:.1f} s", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
