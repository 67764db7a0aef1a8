"""Candidate fills run side by side (mocapfill.solvers._threads) without changing results."""
from __future__ import annotations

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
