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
