"""Candidate fills run side by side (mocapfill.solvers._threads) without changing results."""
from __future__ import annotations

import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from mocapfill.errors import ParameterError
from mocapfill.solvers._threads import run_all, thread_count
from mocapfill.solvers.trnn import complete

from ._synth import marker_gaps, smooth_low_rank


def test_jobs_run_concurrently_and_results_keep_the_jobs_order():
    # Both jobs must be inside at the same time to pass the barrier: run one after the
    # other, the first would wait for a partner that never comes and time out.
    barrier = threading.Barrier(2, timeout=10)

    def job(value, delay):
        def run():
            barrier.wait()
            time.sleep(delay)       # the first job finishes last
            return value
        return run

    assert run_all([job("a", 0.2), job("b", 0.0)], threads=2) == ["a", "b"]


def test_one_thread_runs_in_order_in_the_caller():
    seen = []
    jobs = [lambda k=k: seen.append((k, threading.current_thread().name)) or k
            for k in range(4)]
    assert run_all(jobs, threads=1) == [0, 1, 2, 3]
    assert seen == [(k, threading.current_thread().name) for k in range(4)]


def test_a_failing_job_raises_in_the_caller():
    def boom():
        raise ValueError("job failed")

    with pytest.raises(ValueError, match="job failed"):
        run_all([lambda: 1, boom, lambda: 3], threads=2)


def test_thread_count_reads_the_environment(monkeypatch):
    monkeypatch.setenv("MOCAPFILL_THREADS", "3")
    assert thread_count() == 3
    monkeypatch.delenv("MOCAPFILL_THREADS")
    assert 1 <= thread_count() <= 8
    for bad in ("0", "-2", "two", "1.5"):
        monkeypatch.setenv("MOCAPFILL_THREADS", bad)
        with pytest.raises(ParameterError, match="MOCAPFILL_THREADS"):
            thread_count()


def test_default_fill_is_identical_whatever_the_thread_count(monkeypatch):
    X = smooth_low_rank(3, m=36, n=400, r=4)
    observed = marker_gaps(4, 36, 400, length=40, every=2)
    data = np.where(observed, X, 0.0)
    monkeypatch.setenv("MOCAPFILL_THREADS", "1")
    one = complete(data, observed)
    monkeypatch.setenv("MOCAPFILL_THREADS", "4")
    four = complete(data, observed)
    assert np.array_equal(one, four)
    assert not np.array_equal(one[~observed], data[~observed])   # the gaps were filled


def test_in_order_yields_in_order_and_lends_to_the_jobs_that_need_them():
    from mocapfill.solvers._threads import in_order

    needs = {1: (0, 3), 2: (0, 3), 4: (3, 5)}
    seen = {}

    def job(k, lent):
        seen[k] = dict(lent)
        time.sleep(0.01 * (k % 3))
        return f"out{k}", f"lend{k}"

    assert list(in_order(6, needs, job, at_once=3, ahead=4)) == [f"out{k}" for k in range(6)]
    assert seen[1] == seen[2] == {0: "lend0", 3: "lend3"}
    assert seen[4] == {3: "lend3", 5: "lend5"}
    assert seen[0] == seen[3] == seen[5] == {}


def test_in_order_runs_jobs_side_by_side_but_not_beyond_its_lookahead():
    from mocapfill.solvers._threads import in_order

    running, most, lock = set(), [0], threading.Lock()
    consumed = []
    barrier = threading.Barrier(2, timeout=10)      # jobs 0 and 1 must overlap

    def job(k, lent):
        with lock:
            running.add(k)
            # Never more than ``ahead`` past the next output not yet taken.
            assert k < len(consumed) + 2
            most[0] = max(most[0], len(running))
        if k < 2:
            barrier.wait()
        time.sleep(0.005)
        with lock:
            running.discard(k)
        return k, None

    for out in in_order(8, {}, job, at_once=4, ahead=2):
        consumed.append(out)
    assert consumed == list(range(8)) and most[0] == 2


def test_run_all_inside_in_order_shares_one_pool_of_threads():
    from mocapfill.solvers._threads import in_order

    def job(k, lent):
        # Each window's jobs run on the shared pool's threads, and a run_all nested in one
        # of those jobs runs in that thread, in order.
        names = run_all([lambda: threading.current_thread().name] * 3)
        nested = run_all([lambda: run_all([lambda: threading.current_thread().name] * 2)])
        return (names, nested[0]), None

    results = list(in_order(3, {}, job, at_once=2, ahead=3, threads=2))
    for names, nested in results:
        assert set(names) <= {"mocapfill-0", "mocapfill-1"}
        assert len(set(nested)) == 1 and nested[0] in {"mocapfill-0", "mocapfill-1"}


def test_in_order_raises_the_first_failure_and_stops():
    from mocapfill.solvers._threads import in_order

    started = []

    def job(k, lent):
        started.append(k)
        if k == 2:
            raise ValueError("window 2 failed")
        if k > 2:
            time.sleep(0.05)
        return k, None

    got = []
    with pytest.raises(ValueError, match="window 2 failed"):
        for out in in_order(40, {}, job, at_once=2, ahead=3):
            got.append(out)
    assert got == [0, 1] and max(started) < 6
    # A failing candidate inside a window's run_all reaches the caller the same way.

    def failing(k, lent):
        return run_all([lambda: 1, lambda: 1 / 0]), None

    with pytest.raises(ZeroDivisionError):
        list(in_order(3, {}, failing, at_once=2, ahead=3, threads=2))


@pytest.fixture
def forkable():
    """This process with no thread but the main one (pools of earlier tests wound down),
    on a system where run_all may put jobs in a forked child."""
    if not sys.platform.startswith("linux"):
        pytest.skip("jobs run apart in a forked child only on Linux")
    for thread in threading.enumerate():
        if thread is not threading.main_thread():
            thread.join(timeout=10)
    assert threading.active_count() == 1


def _busy(seconds: float):
    """A job of this process that keeps it busy while the child takes the jobs apart."""
    return lambda: time.sleep(seconds) or os.getpid()


def test_jobs_apart_run_in_a_child_process_and_results_keep_the_jobs_order(forkable):
    jobs = [lambda k=k: (k, os.getpid(), np.arange(k + 1.0)) for k in range(6)]
    jobs[0] = lambda: (0, _busy(0.5)(), np.arange(1.0))
    results = run_all(jobs, threads=2, apart=[1, 3, 4])
    assert [k for k, _, _ in results] == list(range(6))
    for k, pid, values in results:
        assert (pid != os.getpid()) == (k in (1, 3, 4))
        assert np.array_equal(values, np.arange(k + 1.0))


def test_this_process_takes_the_jobs_apart_left_once_its_own_are_done(forkable):
    apart = [lambda k=k: (k, time.sleep(0.3) or os.getpid()) for k in range(6)]
    results = run_all([os.getpid, *apart], threads=2, apart=range(1, 7))
    assert [k for k, _ in results[1:]] == list(range(6))
    where = {pid == os.getpid() for _, pid in results[1:]}
    assert where == {True, False}               # some here, some in the child


def test_a_failing_job_apart_raises_in_the_caller(forkable):
    class Unpicklable(Exception):
        def __init__(self, message, *, code):
            super().__init__(message)

    def boom():
        raise ValueError("apart failed")

    def odd():
        raise Unpicklable("cannot travel", code=3)

    with pytest.raises(ValueError, match="apart failed"):
        run_all([_busy(0.5), boom, lambda: 3], threads=2, apart=[1])
    with pytest.raises(RuntimeError, match="Unpicklable: cannot travel"):
        run_all([_busy(0.5), odd], threads=2, apart=[1])


def test_the_jobs_of_a_child_that_dies_run_in_the_caller(forkable):
    parent = os.getpid()

    def dies_in_a_child():
        if os.getpid() != parent:
            os._exit(3)
        return "here"

    assert run_all([_busy(0.5), dies_in_a_child], threads=2, apart=[1]) == [parent, "here"]


def test_no_child_where_blas_runs_threads_of_its_own(forkable, monkeypatch):
    from mocapfill.solvers import _threads

    monkeypatch.setattr(_threads, "blas_threads_now", lambda: 2)
    assert run_all([_busy(0.2), os.getpid], threads=2, apart=[1]) == [os.getpid()] * 2


def _pids_of_jobs_apart(_) -> tuple[int, list[int]]:
    return os.getpid(), run_all([_busy(0.2), os.getpid], threads=2, apart=[1])


def test_no_child_in_a_daemonic_worker_process(forkable):
    # A multiprocessing.Pool's workers are daemonic, and may not start children: the jobs
    # apart run in the worker (before, Process.start raised an AssertionError there).
    import multiprocessing

    with multiprocessing.get_context("fork").Pool(1) as pool:
        worker, pids = pool.map(_pids_of_jobs_apart, [0])[0]
    assert pids == [worker, worker]


def test_threads_do_the_work_where_no_child_can_be_started(forkable, monkeypatch):
    from mocapfill.solvers import _threads

    def refused():
        raise OSError(11, "Resource temporarily unavailable")       # fork's EAGAIN

    monkeypatch.setattr(_threads.os, "fork", refused)
    names = run_all([lambda: threading.current_thread().name] * 2, threads=2, apart=[1])
    assert set(names) <= {"mocapfill-0", "mocapfill-1"}


def test_no_child_while_another_thread_runs(forkable):
    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    try:
        pids = run_all([os.getpid, os.getpid], threads=2, apart=[1])
    finally:
        release.set()
        other.join()
    assert pids == [os.getpid()] * 2


def test_the_child_does_not_write_buffered_output_again(tmp_path):
    script = ("import os, sys, time\n"
              "from mocapfill.solvers._threads import run_all\n"
              "sys.stdout.write('before ')\n"
              "busy = lambda: time.sleep(0.5) or os.getpid()\n"
              "pids = run_all([busy, os.getpid], threads=2, apart=[1])\n"
              "sys.stdout.write(str(pids[0] != pids[1]))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True, env={**os.environ, "MOCAPFILL_THREADS": "2"}).stdout
    expected = "before True" if sys.platform.startswith("linux") else "before False"
    assert out == expected


_LONG_CHILD = """
import os, signal, sys, time
from mocapfill.solvers._threads import run_all

def away():
    with open(sys.argv[1], "w") as f:
        f.write(str(os.getpid()))
    time.sleep(60)

# A program's own SIGTERM handler must not keep the child alive once the parent ends it.
signal.signal(signal.SIGTERM, lambda *_: None)
try:
    run_all([lambda: time.sleep(60), away], threads=2, apart=[1])
except KeyboardInterrupt:
    sys.exit(130)
"""


# The same with the jobs of in_order, each in a child of its own.
_LONG_JOBS = """
import os, signal, sys, time
from mocapfill.solvers._threads import in_order

def job(k, lent):
    if k == 1:
        with open(sys.argv[1], "w") as f:
            f.write(str(os.getpid()))
    time.sleep(60)
    return k, None

signal.signal(signal.SIGTERM, lambda *_: None)
try:
    list(in_order(2, {}, job, at_once=2, ahead=2, apart=True))
except KeyboardInterrupt:
    sys.exit(130)
"""


def _child_pid(path, process) -> int:
    for _ in range(200):
        if path.exists() and path.read_text():
            return int(path.read_text())
        assert process.poll() is None, process.communicate()
        time.sleep(0.05)
    raise AssertionError("the child never started")


def _ended(pid: int) -> bool:
    """Whether the process is gone (or a zombie waiting for a reaper)."""
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            with open(f"/proc/{pid}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] == "Z":
                    return True
        except FileNotFoundError:
            return True
        time.sleep(0.05)
    return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a forked child on Linux")
@pytest.mark.parametrize("script", [_LONG_CHILD, _LONG_JOBS], ids=["run_all", "in_order"])
def test_ctrl_c_ends_the_child_and_the_parent_quietly(tmp_path, script):
    import signal

    process = subprocess.Popen([sys.executable, "-c", script, str(tmp_path / "pid")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                               start_new_session=True)
    child = _child_pid(tmp_path / "pid", process)
    os.killpg(process.pid, signal.SIGINT)       # as a terminal's Ctrl-C: the whole group
    _, err = process.communicate(timeout=20)
    assert process.returncode == 130 and err == ""
    assert _ended(child)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="a forked child on Linux")
@pytest.mark.parametrize("script", [_LONG_CHILD, _LONG_JOBS], ids=["run_all", "in_order"])
def test_the_child_ends_when_its_parent_is_killed(tmp_path, script):
    import signal

    process = subprocess.Popen([sys.executable, "-c", script, str(tmp_path / "pid")],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    child = _child_pid(tmp_path / "pid", process)
    process.send_signal(signal.SIGKILL)
    process.wait(timeout=20)
    assert _ended(child)


MEETING: dict = {}


def _timed_job(k, lent):
    """A job of in_order run apart: its process, when it ran, what it was lent. Each job
    leaves a file in MEETING["folder"]; the first two to arrive wait until both are there,
    so that two jobs surely run at once however late a loaded machine starts the second
    (with a sleep alone, the test once saw no overlap at all)."""
    start = time.monotonic()
    folder = MEETING["folder"]
    (folder / str(k)).touch()
    if len(list(folder.iterdir())) <= 2:
        deadline = start + 20
        while len(list(folder.iterdir())) < 2:
            assert time.monotonic() < deadline, "no second job came"
            time.sleep(0.01)
    time.sleep(0.2)
    return (k, os.getpid(), start, time.monotonic(), dict(lent)), f"lend{k}"


def test_in_order_apart_runs_each_job_in_a_child_and_lends_between_them(forkable,
                                                                       monkeypatch,
                                                                       tmp_path):
    from mocapfill.solvers._threads import in_order

    monkeypatch.setitem(MEETING, "folder", tmp_path)
    needs = {1: (0, 3), 2: (0, 3), 4: (3, 5)}
    consumed = {}
    outputs = []
    for out in in_order(6, needs, _timed_job, at_once=2, ahead=4, apart=True):
        consumed[out[0]] = time.monotonic()
        outputs.append(out)
    assert [k for k, *_ in outputs] == list(range(6))
    assert os.getpid() not in {pid for _, pid, *_ in outputs}
    lent = {k: seen for k, _, _, _, seen in outputs}
    assert lent[1] == lent[2] == {0: "lend0", 3: "lend3"} and lent[4] == {3: "lend3", 5: "lend5"}
    assert lent[0] == lent[3] == lent[5] == {}
    # Two at a time, never more, and no job more than ``ahead`` past the next output due.
    # (The jobs running at each job's start: the most at once is reached at some start. A
    # count of the spans each one overlaps would also count two that ran one after the
    # other beside a long one.)
    spans = sorted((start, stop) for _, _, start, stop, _ in outputs)
    running = [sum(a <= start < b for a, b in spans) for start, _ in spans]
    assert max(running) == 2
    for k, _, start, _, _ in outputs:
        assert k < 4 or start >= consumed[k - 4]


def _failing_job(k, lent):
    if k == 2:
        raise ValueError("window 2 failed")
    time.sleep(0.05)
    return k, None


class _Unpicklable(Exception):
    def __init__(self, message, *, code):
        super().__init__(message)


def _unpicklable_failure(k, lent):
    raise _Unpicklable("cannot travel", code=3)


def test_in_order_apart_raises_the_first_failure_after_the_outputs_before_it(forkable):
    from mocapfill.solvers._threads import in_order

    before = set(_our_children())               # (an earlier test's may still be ending)
    got = []
    with pytest.raises(ValueError, match="window 2 failed"):
        for out in in_order(40, {}, _failing_job, at_once=2, ahead=3, apart=True):
            got.append(out)
    assert got == [0, 1]
    with pytest.raises(RuntimeError, match="_Unpicklable: cannot travel"):
        list(in_order(3, {}, _unpicklable_failure, at_once=2, ahead=3, apart=True))
    assert not set(_our_children()) - before    # every child ended and reaped


def _our_children() -> list[int]:
    with open(f"/proc/{os.getpid()}/task/{threading.get_native_id()}/children") as f:
        return [int(pid) for pid in f.read().split()]


def test_in_order_apart_runs_the_job_of_a_child_that_dies_here(forkable):
    from mocapfill.solvers._threads import in_order

    parent = os.getpid()

    def dies_in_a_child(k, lent):
        if os.getpid() != parent:
            os._exit(3)
        return (k, os.getpid()), None

    assert list(in_order(3, {}, dies_in_a_child, at_once=2, ahead=3, apart=True)) == \
        [(k, parent) for k in range(3)]


def test_in_order_apart_runs_jobs_here_where_no_child_can_be_started(forkable, monkeypatch):
    import multiprocessing.context

    from mocapfill.solvers._threads import in_order

    def refused(self):
        raise OSError(11, "Resource temporarily unavailable")       # fork's EAGAIN

    monkeypatch.setattr(multiprocessing.context.ForkProcess, "start", refused)
    outputs = list(in_order(3, {}, lambda k, lent: ((k, os.getpid()), None), at_once=2,
                            ahead=3, apart=True))
    assert outputs == [(k, os.getpid()) for k in range(3)]


def _names_of_fills(k, lent):
    return run_all([lambda: threading.current_thread().name] * 3), None


def test_the_jobs_apart_fill_on_one_thread_each(forkable, monkeypatch):
    from mocapfill.solvers._threads import in_order

    monkeypatch.setenv("MOCAPFILL_THREADS", "2")
    for names in in_order(2, {}, _names_of_fills, at_once=2, ahead=2, apart=True):
        assert names == ["MainThread"] * 3


def test_in_order_apart_uses_threads_beside_another_thread(forkable):
    from mocapfill.solvers._threads import in_order

    release = threading.Event()
    other = threading.Thread(target=release.wait)
    other.start()
    try:
        pids = list(in_order(2, {}, lambda k, lent: (os.getpid(), None), at_once=2,
                             ahead=2, apart=True))
    finally:
        release.set()
        other.join()
    assert pids == [os.getpid()] * 2
