"""The speed benchmark's machinery (timings themselves are never asserted)."""
import sys

import numpy as np
import pytest

from mocapfill.bench_speed import SpeedRow, _synthetic, format_speed_table, iteration_floor_ms


def test_synthetic_long_clip_has_the_requested_shape_and_gap_share():
    clip = _synthetic(3000, 7, 0.05, seed=1)
    assert clip.positions.shape == (3000, 7, 3)
    missing = 1 - clip.observed.mean()
    assert 0.04 < missing < 0.08
    assert clip.observed[0].all() and clip.observed[-1].all()


def test_floor_is_a_positive_number_of_milliseconds():
    floor = iteration_floor_ms(30, 500)
    assert np.isfinite(floor) and floor > 0


def test_table_lists_every_case():
    rows = [SpeedRow("a", "trnn", 10, 2, 3, 0.1, 0.2, 0.3, 50.0, target_s=1.0, iterations=7,
                     ms_per_iteration=1.5, floor_ms_per_iteration=0.5),
            SpeedRow("b", "tsmc", 10, 2, 1, 0.4, 0.4, 0.4, 60.0)]
    table = format_speed_table(rows)
    assert table.count("\n") == 3
    assert "| a | trnn | 0.100 / 0.200 / 0.300 | 1.0 | 7 | 1.5 | 0.5 | 50 |" in table


def test_big_cases_are_timed_big_runs_times_without_the_comparison_methods(monkeypatch,
                                                                         tmp_path):
    from mocapfill import bench_speed

    calls = []

    def timed(args, runs):
        calls.append((args[args.index("repair") + 1] if "repair" in args else "--help",
                      args[-1] if "--method" in args else "-", runs))
        return [0.1] * runs, 10.0

    small = bench_speed._synthetic
    monkeypatch.setattr(bench_speed, "time_command", timed)
    monkeypatch.setattr(bench_speed, "_solver_stats", lambda path, method: (5, 1.0))
    monkeypatch.setattr(bench_speed, "SHARED_DATA", tmp_path)     # CMU clips: skipped
    # The 216,000 × 41 clip as 400 × 41 (16,400 samples, "big" below), the 10,000 × 300
    # one as 300 × 10 (3,000 samples).
    monkeypatch.setattr(bench_speed, "_synthetic", lambda frames, markers, missing, seed:
                        small(400, 41, missing, seed) if markers == 41
                        else small(300, 10, missing, seed))
    monkeypatch.setattr(bench_speed, "BIG_CASE_SAMPLES", 10_000)
    rows = bench_speed.run_speed(runs=3)
    timed_cases = [(path.rsplit("/", 1)[-1], method, runs) for path, method, runs in calls
                   if path != "--help"]
    assert timed_cases == [("synthetic_216000x41.npz", "trnn", 1),
                           ("synthetic_10000x300.npz", "trnn", 3),
                           ("synthetic_10000x300.npz", "trnn-paper", 1),
                           ("synthetic_10000x300.npz", "tsmc", 1)]
    long_row = next(r for r in rows if "216000" in r.case)
    assert long_row.iterations is None and long_row.runs == 1
    calls.clear()
    rows = bench_speed.run_speed(runs=3, compare=False, big_runs=5)
    assert [(path.rsplit("/", 1)[-1], runs) for path, method, runs in calls
            if path != "--help"] == [("synthetic_216000x41.npz", 5),
                                     ("synthetic_10000x300.npz", 3)]
    assert next(r for r in rows if "216000" in r.case).runs == 5


def test_a_childs_peak_memory_is_its_own_not_the_benchmarks():
    from mocapfill.bench_speed import _run_child

    ballast = np.ones(25_000_000)            # 200 MB resident in this process
    wall, rss_mb, code = _run_child([sys.executable, "-c", "import sys; sys.exit(3)"])
    assert ballast[-1] == 1.0
    assert code == 3 and wall > 0
    assert 0 < rss_mb < 100                 # a bare interpreter, not this process's 200 MB


_TWO_PROCESSES = """
import os, time
pid = os.fork()
ballast = bytearray(200 * 2**20)            # 200 MB in each process, written: private
time.sleep(1.5)
if pid == 0:
    os._exit(0)
os.waitpid(pid, 0)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc is Linux's")
def test_a_commands_peak_memory_counts_all_its_processes_at_once():
    from mocapfill.bench_speed import _run_child

    wall, memory_mb, code = _run_child([sys.executable, "-c", _TWO_PROCESSES])
    assert code == 0 and wall > 1.5
    assert memory_mb > 380                   # both at once; each alone peaks at ~210


def test_the_benchmark_times_the_package_byte_compiled(monkeypatch):
    # The timed commands must not compile mocapfill's modules on every start (an editable
    # checkout under PYTHONDONTWRITEBYTECODE would): run_speed writes the bytecode first.
    import importlib.util
    from pathlib import Path

    from mocapfill import bench_speed, cli

    compiled = Path(importlib.util.cache_from_source(cli.__file__))
    compiled.unlink(missing_ok=True)
    monkeypatch.setattr(bench_speed, "time_command", lambda args, runs: ([0.1] * runs, 1.0))
    monkeypatch.setattr(bench_speed, "SHARED_DATA", Path("/nonexistent"))
    bench_speed.run_speed(runs=1, quick=True)
    assert compiled.exists()
    assert compiled.stat().st_mtime >= Path(cli.__file__).stat().st_mtime


def test_json_rows_of_a_skipped_case_are_strict_json():
    # A case skipped without ../shared/data has no timings: they were NaN in --json, which
    # is not JSON (json.loads of other languages and jq refuse it); null, as info --json.
    import json

    from mocapfill.bench_speed import rows_as_dicts

    skipped = SpeedRow("85_02 ml40", "trnn", 0, 0, 0, np.nan, np.nan, np.nan, np.nan,
                       notes=["skipped: ../shared/data absent"])
    text = json.dumps(rows_as_dicts([skipped]), allow_nan=False)
    row = json.loads(text)[0]
    assert row["wall_min_s"] is None and row["peak_rss_mb"] is None
    assert row["notes"] == ["skipped: ../shared/data absent"]
