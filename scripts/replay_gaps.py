"""Catastrophic fills of the default on realistic hidden gaps of real clips.

Hides gaps of 5–120 frames in observed stretches of 18 real clips, often two or three
neighbouring markers together with overlapping spans (eleven such occlusions per repair,
four repairs per clip with fixed seeds), fills them with the default (``trnn``) and with
``linear``, ``spline`` and ``pca``, and counts the hidden gaps where the default's RMS 3-D
error exceeds max(2 × best, best + 10 mm), best being the least of the three others' on
that gap. Prints per clip the gaps, that count and the mean errors (mm). Needs
../shared/data. The fills of the three others do not depend on the default's code and are
cached (in the system's temporary folder unless ``--cache DIR``); the default is always
rerun. Example (the thirtieth session's table of docs/results.md, 15 of 1,557):

    python scripts/replay_gaps.py [--json FILE] [--cache DIR] [CLIP-SUBSTRING ...]
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import SHARED_DATA, _walkl_motion  # noqa: E402 (after the BLAS setting)
from mocapfill.formats import read  # noqa: E402 (after the BLAS setting)
from mocapfill.metrics import mm_per_unit  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import RepairOptions, repair  # noqa: E402 (after the BLAS setting)

OTHERS = ("linear", "spline", "pca")
TRIALS = 4          # repairs per clip
EPISODES = 11       # occlusions per repair (1–3 markers each)

CLIPS = {   # name -> (group, file under ../shared/data)
    "02_05": ("cmu", "cmu/02_05.c3d"),
    "85_02": ("cmu", "cmu/85_02.c3d"),
    "85_12": ("cmu", "cmu/85_12.c3d"),
    "10_01": ("cmu", "cmu/10_01.amc"),
    "basketball": ("cmu", "cmu/basketball_dribble_shoot.c3d"),
    "WalkL": ("walkl", "walkl/WalkL.mat"),
    "WalkL_0003": ("walkl", "walkl/WalkL_0003.mat"),
    "WalkL_0007": ("walkl", "walkl/WalkL_0007.mat"),
    "Dance": ("btk", "c3d/btk-sample13__Dance.c3d"),
    "golfswing": ("btk", "c3d/btk-sample13__golfswing.c3d"),
    "squat": ("vendor", "c3d/nimble-c3d__squat.c3d"),
    "freeform": ("vendor", "c3d/nimble-c3d__nick_freeform_001.c3d"),
    "tennis": ("vendor", "c3d/ktk-kinematics_tennis_serve.c3d"),
    "optitrack": ("vendor", "c3d/ktk-walkingOptiTrack.c3d"),
    "racing": ("vendor", "c3d/ktk-kinematics_racing_full.c3d"),
    "vicon": ("vendor", "c3d/ezc3d-Vicon.c3d"),
    "sprint.trc": ("trc", "trc/btk-SprintMotion.trc"),
    "JA1Gait35": ("vendor", "c3d/nimble-c3d__JA1Gait35.c3d"),
}


def load(relative: str):
    path = SHARED_DATA / relative
    if path.suffix == ".mat":
        return _walkl_motion(path)
    return read(path, units="mm") if path.suffix == ".amc" else read(path)


def hide(observed: np.ndarray, positions: np.ndarray, rng: np.random.Generator):
    """The mask with realistic occlusions hidden, and those gaps as (marker, start, stop)."""
    n, k = observed.shape
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)         # markers never seen
        mean = np.nanmean(np.where(observed[:, :, None], positions, np.nan), axis=0)
    dist = np.linalg.norm(mean[:, None] - mean[None], axis=2)
    dist = np.where(np.isfinite(dist), dist, np.inf)
    np.fill_diagonal(dist, np.inf)
    good = np.flatnonzero(observed.mean(axis=0) > 0.5)
    taken = np.zeros_like(observed)         # hidden spans with a margin of one frame
    gaps = []
    longest = min(120, n // 3)
    for _ in range(EPISODES):
        for _try in range(30):
            length = int(np.exp(rng.uniform(np.log(5), np.log(longest + 1))))
            length = max(5, min(length, longest))
            j = int(rng.choice(good))
            start = int(rng.integers(1, n - length - 1))
            members = [(j, start, start + length)]
            extra = rng.choice([0, 1, 1, 2])
            near = [m for m in np.argsort(dist[j])[:4] if np.isfinite(dist[j, m])]
            for m in rng.permutation(near)[:extra]:
                lm = int(np.clip(round(length * rng.uniform(0.5, 1.5)), 5, longest))
                sm = int(np.clip(start + rng.integers(-length // 2, length // 2 + 1), 1,
                                 n - lm - 1))
                members.append((int(m), sm, sm + lm))
            ok = [(m, a, b) for m, a, b in members
                  if observed[a - 1:b + 1, m].all() and not taken[a - 1:b + 1, m].any()]
            if not ok or ok[0][0] != j:
                continue
            for m, a, b in ok:
                if taken[a - 1:b + 1, m].any():
                    continue
                taken[a - 1:b + 1, m] = True
                gaps.append((m, a, b))
            break
    gapped = observed.copy()
    for m, a, b in gaps:
        gapped[a:b, m] = False
    return gapped, gaps


def gap_errors(truth: np.ndarray, filled: np.ndarray, gaps: list, mm: float) -> list:
    out = []
    for m, a, b in gaps:
        d = (filled[a:b, m] - truth[a:b, m]) * mm
        out.append(float(np.sqrt((d ** 2).sum(axis=1).mean())) if np.isfinite(d).all()
                   else None)
    return out


def run_clip(name: str, cache: Path) -> list[dict]:
    group, relative = CLIPS[name]
    motion = load(relative)
    mm = mm_per_unit(motion.units) or 1.0
    rows = []
    for trial in range(TRIALS):
        rng = np.random.default_rng(1000 + 17 * trial + sum(map(ord, name)))
        mask, gaps = hide(motion.observed, motion.positions, rng)
        gapped = motion.with_positions(
            np.where(mask[:, :, None], motion.positions, np.nan), mask)
        errors = {}
        for method in ("trnn", *OTHERS):
            cached = cache / f"{name}_{trial}_{method}.json"
            if method in OTHERS and cached.exists():
                errors[method] = json.loads(cached.read_text())
                continue
            result = repair(gapped, RepairOptions(method=method, max_jump_mm=0.0))
            errors[method] = gap_errors(motion.positions, result.motion.positions, gaps, mm)
            if method in OTHERS:
                cached.write_text(json.dumps(errors[method]))
        for i, (m, a, b) in enumerate(gaps):
            rows.append(dict(clip=name, group=group, trial=trial, marker=m, start=a, stop=b,
                             **{method: errors[method][i] for method in errors}))
    return rows


def catastrophic(row: dict) -> bool:
    best = min(row[m] for m in OTHERS if row[m] is not None)
    return row["trnn"] is not None and row["trnn"] > max(2 * best, best + 10)


def table(rows: list[dict]) -> None:
    print(f"{'clip':12s} {'group':6s} {'gaps':>5s} {'cat':>4s} {'trnn':>7s} {'best':>7s} "
          f"{'linear':>7s} {'spline':>7s} {'pca':>7s}")
    groups: dict[str, list[int]] = {}
    for clip in dict.fromkeys(r["clip"] for r in rows):
        clip_rows = [r for r in rows if r["clip"] == clip and r["trnn"] is not None]
        count = sum(map(catastrophic, clip_rows))
        group = clip_rows[0]["group"]
        tally = groups.setdefault(group, [0, 0])
        tally[0] += len(clip_rows)
        tally[1] += count

        def mean(key, rs=clip_rows):
            return np.mean([r[key] for r in rs if r[key] is not None])

        best = np.mean([min(r[m] for m in OTHERS if r[m] is not None) for r in clip_rows])
        print(f"{clip:12s} {group:6s} {len(clip_rows):5d} {count:4d} {mean('trnn'):7.2f} "
              f"{best:7.2f} {mean('linear'):7.2f} {mean('spline'):7.2f} {mean('pca'):7.2f}")
    total = sum(v[1] for v in groups.values())
    print("catastrophic:", ", ".join(f"{g} {v[1]} of {v[0]}" for g, v in groups.items()),
          f"- total {total} of {sum(v[0] for v in groups.values())}")


def main(argv: list[str]) -> int:
    json_path, cache, only = None, Path(tempfile.gettempdir()) / "mocapfill-replay-cache", []
    args = iter(argv)
    for arg in args:
        if arg == "--json":
            json_path = Path(next(args))
        elif arg == "--cache":
            cache = Path(next(args))
        else:
            only.append(arg)
    if not SHARED_DATA.is_dir():
        print(f"replay_gaps: {SHARED_DATA} not found (the shared real data)", file=sys.stderr)
        return 2
    cache.mkdir(parents=True, exist_ok=True)
    names = [n for n in CLIPS if not only or any(o in n for o in only)]
    rows: list[dict] = []
    start = time.perf_counter()
    for name in names:
        rows += run_clip(name, cache)
    if json_path is not None:
        json_path.write_text(json.dumps(rows))
    table(rows)
    print(f"({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
