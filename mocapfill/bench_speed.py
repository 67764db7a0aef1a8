"""Speed benchmark (``make bench``, ``mocapfill bench speed``).

Every case times the real command, ``mocapfill repair IN OUT``, in a fresh Python process
(start-up, reading and writing included): min / median / max wall time over ``runs`` runs
and the peak resident memory of the child, which runs the candidate fills side by side on
the cores as users get it. The solver is also timed in-process, one candidate at a time,
to report iterations, milliseconds per iteration and the floor computed for one iteration on this
machine (its FLOPs at the measured matrix-product rate plus its memory passes at the
measured copy bandwidth plus its temporal solve), and the same clip is repaired with
``trnn-paper`` and ``tsmc`` for a side-by-side ratio.
"""
from __future__ import annotations

import math
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import formats
from .bench import SHARED_DATA
from .gaps import simulate_gaps
from .motion import Motion


@dataclass
class SpeedRow:
    """One benchmark case."""

    case: str
    method: str
    frames: int
    markers: int
    runs: int
    wall_min_s: float
    wall_median_s: float
    wall_max_s: float
    peak_rss_mb: float
    target_s: float | None = None
    iterations: int | None = None
    ms_per_iteration: float | None = None
    floor_ms_per_iteration: float | None = None
    notes: list[str] = field(default_factory=list)


# Runs its arguments as a command and prints "wall-seconds peak-memory-KB exit-status". The
# command is started from this small, fresh process, not from the benchmark's: on Linux a
# process forked from a large one reports that one's resident size as its own peak (the
# address space it replaced at exec counts), so 85_12's repair, a 208 MB process, was
# reported at 478 MB once the benchmark had grown that large.
# The command's memory is that of all its processes: the repair forks children (the
# blend's validation, the windows of a long clip), which share the parent's pages until
# one of them writes. So the peak is the larger of the command's own peak RSS (with its
# descendants', each alone) and the largest sum, sampled every 0.1 s in a thread (the wall
# time is the exit's), of the proportional set sizes (PSS: a shared page counted once,
# split between its sharers) of the command and its descendants (Linux's /proc).
_TIMER = """
import os, subprocess, sys, threading, time

def tree(pid):
    pids = [pid]
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/children") as f:
                for child in f.read().split():
                    pids += tree(int(child))
    except OSError:
        pass
    return pids

def pss_kb(pid):
    try:
        with open(f"/proc/{pid}/smaps_rollup") as f:
            for line in f:
                if line.startswith("Pss:"):
                    return int(line.split()[1])
    except OSError:
        pass
    return 0

def sample(pid, done, peak):
    while not done.wait(0.1):
        peak[0] = max(peak[0], sum(pss_kb(p) for p in tree(pid)))

started = time.perf_counter()
child = subprocess.Popen(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
done, peak = threading.Event(), [0]
sampler = threading.Thread(target=sample, args=(child.pid, done, peak), daemon=True)
sampler.start()
_, status, usage = os.wait4(child.pid, 0)
wall = time.perf_counter() - started
done.set()
sampler.join()
print(wall, max(peak[0], usage.ru_maxrss), os.waitstatus_to_exitcode(status))
"""


def _run_child(args: list[str]) -> tuple[float, float, int]:
    """Wall seconds, peak memory (MB, see ``_TIMER``) and exit status of one command in a
    new process."""
    timer = subprocess.run([sys.executable, "-c", _TIMER, *args], capture_output=True,
                           text=True, check=True)
    wall, rss_kb, code = timer.stdout.split()
    return float(wall), int(rss_kb) / 1024.0, int(code)


def time_command(args: list[str], runs: int) -> tuple[list[float], float]:
    walls, peak = [], 0.0
    for _ in range(runs):
        wall, rss, code = _run_child(args)
        if code != 0:
            raise RuntimeError(f"{' '.join(args)} exited with {code}")
        walls.append(wall)
        peak = max(peak, rss)
    return walls, peak


def _cli() -> list[str]:
    return [sys.executable, "-m", "mocapfill"]             # what the console script runs


def iteration_floor_ms(m: int, n: int, d: int | None = None, dtype: type = np.float64
                       ) -> float:
    """The floor of one TrNN iteration on an m × n clip, measured on this machine.

    FLOPs: three m×n×d products (W R, Wᵀ L, L Rᵀ) at 2mnd each plus two d×d Gram
    products; memory: about ten passes over m×n arrays of ``dtype``; one temporal solve.
    """
    d = m if d is None else d
    rng = np.random.default_rng(0)
    a = rng.standard_normal((m, n)).astype(dtype)
    b = rng.standard_normal((n, d)).astype(dtype)
    best_gemm = min(_timed(lambda: a @ b) for _ in range(5))
    gemm_rate = 2.0 * m * n * d / best_gemm
    out = np.empty_like(a)
    best_pass = min(_timed(lambda: np.add(a, a, out=out)) for _ in range(5))
    bandwidth = 3 * a.nbytes / best_pass            # two reads and a write
    from .solvers._linalg import temporal_solve

    # The temporal step as the solver does it (DCT, or banded Cholesky for awkward n).
    best_temporal = min(_timed(lambda: temporal_solve(a, 0.5, 100.0)) for _ in range(3))
    flops = 3 * 2.0 * m * n * d + 2 * 2.0 * (m + n) * d * d
    return 1000.0 * (flops / gemm_rate + 10 * a.nbytes / bandwidth + best_temporal)


def _floor_for(method: str, m: int, n: int) -> float:
    """The floor of the iteration ``method`` runs: the default ``trnn`` iterates in float32
    on the clip padded to a fast DCT length, ``trnn-paper`` in float64 on the clip as is."""
    if method == "trnn":
        from .solvers._linalg import fast_length

        return iteration_floor_ms(m, fast_length(n), dtype=np.float32)
    return iteration_floor_ms(m, n)


def _timed(fn) -> float:
    started = time.perf_counter()
    fn()
    return time.perf_counter() - started


def _solver_stats(path: Path, method: str) -> tuple[int | None, float | None]:
    """Iterations and ms per iteration of the TrNN iterations for one repair, in-process.

    The candidates run one after the other here (``MOCAPFILL_THREADS=1``): the floor is
    one core's, and two solves side by side would share the memory bandwidth and caches.
    The wall times come from the command as users run it, threads included.
    """
    from .batch import temporary_environment
    from .solvers import trnn as trnn_module
    from .solvers._threads import VARIABLE

    calls: list[tuple[int, float]] = []
    original = trnn_module.trnn

    def recording(*args, **kwargs):
        started = time.perf_counter()
        result = original(*args, **kwargs)
        calls.append((result.iterations, time.perf_counter() - started))
        return result

    trnn_module.trnn = recording
    try:
        from .pipeline import RepairOptions, repair

        with temporary_environment({VARIABLE: "1"}):
            repair(formats.read(path), RepairOptions(method=method))
    finally:
        trnn_module.trnn = original
    iterations = sum(c[0] for c in calls)
    if not iterations:
        return None, None
    return iterations, 1000.0 * sum(c[1] for c in calls) / iterations


def random_gaps(rng: np.random.Generator, frames: int, markers: int, missing: float
                ) -> np.ndarray:
    """(frames, markers) observed mask with ~``missing`` of the samples in 20–120-frame
    gaps of random markers, none touching the clip's first or last frame."""
    observed = np.ones((frames, markers), bool)
    budget = int(missing * frames * markers)
    while budget > 0:
        length = int(rng.integers(20, 121))
        start = int(rng.integers(1, frames - length - 1))
        observed[start:start + length, int(rng.integers(markers))] = False
        budget -= length
    return observed


def _synthetic(frames: int, markers: int, missing: float, seed: int) -> Motion:
    """A smooth, low-rank-ish clip with ~``missing`` of samples in 20-120-frame gaps."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 120.0
    k = 8
    latent = np.sin(2 * np.pi * rng.uniform(0.2, 2.5, (k, 1)) * t + rng.uniform(0, 6, (k, 1)))
    data = 80 * rng.standard_normal((3 * markers, k)) @ latent
    data += 400 * rng.standard_normal((3 * markers, 1))
    data += rng.standard_normal(data.shape) * 0.3
    positions = data.reshape(markers, 3, frames).transpose(2, 0, 1)
    observed = random_gaps(rng, frames, markers, missing)
    labels = tuple(f"M{j:03d}" for j in range(markers))
    return Motion(positions, observed, labels, 120.0, "mm")


# Cases with more marker samples than this (85_12: 184,459) are timed once, alone.
BIG_CASE_SAMPLES = 1_000_000


def byte_compile_package() -> None:
    """Write mocapfill's bytecode, so that the timed commands start as an installed one.

    pip compiles a wheel's modules when it installs them, and Python writes the bytecode
    of a checkout on its first run; but where ``PYTHONDONTWRITEBYTECODE`` is set (the
    machine of docs/results.md sets it) an editable checkout is compiled again by every
    command: 0.05–0.1 s of every timed run, which users do not pay. A folder that cannot
    be written is left as it is.
    """
    import compileall

    try:
        compileall.compile_dir(str(Path(__file__).resolve().parent), quiet=2)
    except OSError:
        pass


def run_speed(runs: int = 5, quick: bool = False, compare: bool = True,
              big_runs: int = 1) -> list[SpeedRow]:
    """Run the speed cases; clips that need ../shared/data are skipped when it is absent.

    The 30-minute and 300-marker clips take a minute or more per run: they run
    ``big_runs`` times (the issue's targets are medians of 5; ``--big-runs 5`` measures
    them so, in about 10 minutes more).

    The package is byte-compiled first (:func:`byte_compile_package`).
    """
    byte_compile_package()
    rows: list[SpeedRow] = []
    with tempfile.TemporaryDirectory(prefix="mocapfill-bench-") as tmp:
        work = Path(tmp)
        walls, rss = time_command(_cli() + ["--help"], runs)
        rows.append(SpeedRow("mocapfill --help", "-", 0, 0, runs, min(walls),
                             statistics.median(walls), max(walls), rss, target_s=0.3))
        cases: list[tuple[str, Path, float | None]] = []
        for name, target in (("85_12", 1.0), ("85_02", 0.4)):
            clip = SHARED_DATA / "cmu" / f"{name}.c3d"
            if not clip.exists():
                rows.append(SpeedRow(f"{name} ml40", "trnn", 0, 0, 0, np.nan, np.nan, np.nan,
                                     np.nan, notes=["skipped: ../shared/data absent"]))
                continue
            gapped = work / f"{name}_ml40.c3d"
            formats.write(simulate_gaps(formats.read(clip), ml=40, seed=1), gapped)
            cases.append((f"cmu/{name}.c3d simulate --ml 40 --seed 1", gapped, target))
        if not quick:
            long_clip = work / "synthetic_216000x41.npz"
            formats.write(_synthetic(216_000, 41, 0.05, 1), long_clip)
            cases.append(("synthetic 41 markers x 216000 frames, 5% gaps", long_clip, 60.0))
            wide = work / "synthetic_10000x300.npz"
            formats.write(_synthetic(10_000, 300, 0.05, 2), wide)
            cases.append(("synthetic 300 markers x 10000 frames, 5% gaps", wide, None))
        methods = ["trnn"] + (["trnn-paper", "tsmc"] if compare else [])
        for label, path, target in cases:
            motion = formats.read(path)
            # The 30-minute and the 300-marker clips take a minute or more each: big_runs
            # runs of the default, no comparison methods, no in-process iteration count.
            big = motion.n_frames * motion.n_markers > BIG_CASE_SAMPLES
            case_runs = big_runs if big else runs
            for method in methods:
                if method != "trnn" and big:
                    continue
                out = work / f"out{path.suffix}"
                walls, rss = time_command(
                    _cli() + ["repair", str(path), str(out), "--method", method],
                    case_runs if method == "trnn" else 1)
                row = SpeedRow(label, method, motion.n_frames, motion.n_markers, len(walls),
                               min(walls), statistics.median(walls), max(walls), rss,
                               target_s=target if method == "trnn" else None)
                if method in ("trnn", "trnn-paper") and not big:
                    row.iterations, row.ms_per_iteration = _solver_stats(path, method)
                    row.floor_ms_per_iteration = _floor_for(method, 3 * motion.n_markers,
                                                            motion.n_frames)
                rows.append(row)
    return rows


def format_speed_table(rows: list[SpeedRow]) -> str:
    """A markdown table of the rows."""
    def f(value, digits=3):
        if value is None or (isinstance(value, float) and np.isnan(value)):
            return "-"
        return f"{value:.{digits}f}" if isinstance(value, float) else str(value)

    lines = ["| case | method | wall min / median / max (s) | target (s) | iterations | "
             "ms/iter | floor ms/iter | peak memory (MB) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.case} | {r.method} | {f(r.wall_min_s)} / {f(r.wall_median_s)} / "
                     f"{f(r.wall_max_s)} | {f(r.target_s, 1)} | {f(r.iterations)} | "
                     f"{f(r.ms_per_iteration, 1)} | {f(r.floor_ms_per_iteration, 1)} | "
                     f"{f(r.peak_rss_mb, 0)} |" + (f" {'; '.join(r.notes)}" if r.notes else ""))
    return "\n".join(lines)


def rows_as_dicts(rows: list[SpeedRow]) -> list[dict]:
    """The rows for ``--json``: a timing a skipped case does not have (NaN) is null, as
    NaN is not JSON."""
    def value(v):
        return None if isinstance(v, float) and math.isnan(v) else v

    return [{k: value(v) for k, v in asdict(r).items()} for r in rows]
