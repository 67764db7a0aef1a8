"""BLAS on one thread while mocapfill computes, unless the user set a thread count."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from mocapfill._blas import VARIABLES

ROOT = Path(__file__).resolve().parents[1]

# Run in a fresh interpreter without the BLAS variables (the command line and the
# measuring scripts set them; a program importing mocapfill usually does not). BLAS is
# put on 3 threads first, so that the checks mean something on a one-core machine too.
# Both scripts start so, then spy on the repair's solve (noting the BLAS thread counts
# while it runs) and read the clip.
PRELUDE = r"""
import json, sys
import scipy.linalg
from threadpoolctl import threadpool_info, threadpool_limits

threadpool_limits(3, user_api="blas")

def counts():
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

import mocapfill
from mocapfill import pipeline

during = []
solve = pipeline._complete_clip

def spy(*args, **kwargs):
    during.append(counts())
    return solve(*args, **kwargs)

pipeline._complete_clip = spy
motion = mocapfill.read(sys.argv[1])
"""

SCRIPT = PRELUDE + r"""
import threading
from mocapfill._blas import single_threaded
from mocapfill.solvers._threads import run_all

out = {"before": counts()}
mocapfill.repair(motion, mocapfill.RepairOptions(method="linear"))
out["repair"] = during
out["after_repair"] = counts()
out["run_all"] = run_all([counts, counts], threads=2)
out["run_all_serial"] = run_all([counts], threads=1)
out["after_run_all"] = counts()

# Nested blocks: the inner one leaving keeps the limit; the outer one restores.
with single_threaded():
    with single_threaded():
        pass
    out["nested_inner_left"] = counts()
out["nested_outer_left"] = counts()
# Outside the main thread too (the count is the process's, whichever thread sets it).
seen = []
def other():
    with single_threaded():
        seen.append(counts())
worker = threading.Thread(target=other)
worker.start()
worker.join()
out["other_thread"] = seen
out["after_other_thread"] = counts()

# Blocks in two threads: the first to leave keeps the limit for the other.
a_in, b_in, a_out = threading.Event(), threading.Event(), threading.Event()
seen = []
def first():
    with single_threaded():
        a_in.set()
        b_in.wait()
    a_out.set()
def second():
    a_in.wait()
    with single_threaded():
        b_in.set()
        a_out.wait()
        seen.append(counts())
workers = [threading.Thread(target=first), threading.Thread(target=second)]
for worker in workers:
    worker.start()
for worker in workers:
    worker.join()
out["two_threads_first_left"] = seen
out["two_threads_both_left"] = counts()
out["layers"] = sorted({(i["internal_api"], i.get("threading_layer", ""))
                        for i in threadpool_info() if i["user_api"] == "blas"})
print(json.dumps(out))
"""

# A repair by the default method in the main thread, then the same in a thread of a
# ThreadPoolExecutor (as a GUI or a service calls it). BLAS is put on 3 threads first,
# through threadpoolctl from the main thread, which then ignores a limit that another
# thread sets through it (3.8): mocapfill must set OpenBLAS's count itself.
IN_A_THREAD = PRELUDE + r"""
import hashlib, time
from concurrent.futures import ThreadPoolExecutor

def repair():
    start = time.perf_counter()
    positions = mocapfill.repair(motion).motion.positions
    return hashlib.sha256(positions.tobytes()).hexdigest(), time.perf_counter() - start

out = {}
out["main"], out["main_s"] = repair()
with ThreadPoolExecutor(1) as pool:
    out["thread"], out["thread_s"] = pool.submit(repair).result()
out["during"] = during
out["after"] = counts()
out["layers"] = sorted({(i["internal_api"], i.get("threading_layer", ""))
                        for i in threadpool_info() if i["user_api"] == "blas"})
print(json.dumps(out))
"""


def run_script(extra_env: dict[str, str] | None = None, script: str = SCRIPT) -> dict:
    env = {k: v for k, v in os.environ.items() if k not in VARIABLES}
    env.update(extra_env or {})
    done = subprocess.run([sys.executable, "-c", script,
                           str(ROOT / "sample_data" / "walk_gapped.csv")],
                          capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)


def needs_one_count_per_process(out: dict) -> None:
    """Skip unless every BLAS library is OpenBLAS with its own threads, whose count, set
    in one thread, holds in all (MKL's, BLIS's and OpenMP's may be per thread, and
    mocapfill limits them from the main thread only)."""
    if any(layer != ["openblas", "pthreads"] for layer in out["layers"]):
        pytest.skip(f"BLAS libraries {out['layers']}: not all OpenBLAS with pthreads")


@pytest.fixture(scope="module")
def unset() -> dict:
    """The script's findings with no BLAS variable set (one interpreter for the tests)."""
    return run_script()


def test_repair_and_parallel_sections_run_blas_on_one_thread_then_restore(unset):
    out = unset
    assert out["before"] == [3]
    assert out["repair"] == [[1]]
    assert out["after_repair"] == [3]
    assert out["run_all"] == [[1], [1]]
    assert out["run_all_serial"] == [[1]]
    assert out["after_run_all"] == [3]


def test_nested_blocks_keep_the_limit_until_the_outermost_leaves(unset):
    out = unset
    assert out["nested_inner_left"] == [1]
    assert out["nested_outer_left"] == [3]


def test_a_block_outside_the_main_thread_limits_blas_then_restores(unset):
    out = unset
    needs_one_count_per_process(out)
    assert out["other_thread"] == [[1]]
    assert out["after_other_thread"] == [3]


def test_blocks_in_two_threads_keep_the_limit_until_both_have_left(unset):
    out = unset
    needs_one_count_per_process(out)
    assert out["two_threads_first_left"] == [[1]]
    assert out["two_threads_both_left"] == [3]


def test_a_repair_in_another_thread_gives_the_main_threads_bytes():
    """Called from a ThreadPoolExecutor, a repair ran with BLAS on 3 threads: its fills
    differed from the main thread's (and the command's), and it took 64 s against
    0.6 s on a 2-vCPU machine."""
    out = run_script(script=IN_A_THREAD)
    needs_one_count_per_process(out)
    assert out["thread"] == out["main"]
    assert out["during"] == [[1], [1]]
    assert out["after"] == [3]


def test_a_thread_count_set_in_the_environment_is_left_alone():
    out = run_script({"OMP_NUM_THREADS": "2"})
    assert out["repair"] == [[3]]
    assert out["run_all"] == [[3], [3]]


def test_threads_now_reads_the_libraries_not_the_environment():
    import numpy as np
    from threadpoolctl import threadpool_limits

    from mocapfill._blas import threads_now

    np.ones((2, 2)) @ np.ones((2, 2))           # numpy's BLAS is loaded
    with threadpool_limits(limits=1, user_api="blas"):
        assert threads_now() == 1
    with threadpool_limits(limits=2, user_api="blas"):    # as on a one-core machine too
        assert threads_now() == 2
