"""Run independent fills side by side on the machine's cores.

The command line keeps BLAS on one thread (many small products, where BLAS threads cost
more than they give), so on a 2-core laptop one core sat idle while the blend computed
its candidate fills one after the other. The fills are independent pure functions of
their inputs and spend their time in numpy, BLAS and pocketfft, which release the GIL,
so Python threads run them in parallel and the result is the same whatever the order.

The windows of a long clip are solved side by side by :func:`in_order`, their fills in
one queue for the same threads: a window's serial steps (validation bookkeeping, the blend)
and the last long fill of its batch no longer leave a core idle.

``MOCAPFILL_THREADS`` sets how many threads (a positive integer; default: the cores this
process may use, at most 8). The batch runner's worker processes set it to 1, since they
already fill every core with one file each.
"""
from __future__ import annotations

import functools
import os
import queue
import threading
from collections.abc import Iterator, Mapping, Sequence
from typing import Callable, TypeVar

from .._blas import single_threaded
from ..errors import ParameterError

T = TypeVar("T")
L = TypeVar("L")

VARIABLE = "MOCAPFILL_THREADS"
MAX_DEFAULT = 8

# Per thread: ``pool``, the shared :class:`_Pool` that :func:`run_all` hands its jobs to in
# the coordinating threads of :func:`in_order`; ``in_pool``, set in that pool's threads,
# where a nested :func:`run_all` runs its jobs in order.
_local = threading.local()


def thread_count() -> int:
    """Threads for :func:`run_all`: ``$MOCAPFILL_THREADS`` or the usable cores (≤ 8)."""
    value = os.environ.get(VARIABLE, "").strip()
    if not value:
        try:
            cores = len(os.sched_getaffinity(0))
        except AttributeError:  # not on Linux
            cores = os.cpu_count() or 1
        return max(1, min(cores, MAX_DEFAULT))
    try:
        count = int(value)
    except ValueError:
        count = 0
    if count < 1:
        raise ParameterError(f"{VARIABLE} must be a positive integer, got {value!r}")
    return count


def release_memory() -> None:
    """Hand the C heap's free pages back to the system (glibc's ``malloc_trim``).

    Each thread allocates from its own malloc arena, and freed arrays of a few MB stayed
    there: on a long clip solved in windows the resident memory crept up window after
    window (a 40,000-frame clip: 440 → 760 MB). A no-op where the C library has no
    ``malloc_trim`` (not glibc).
    """
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.lru_cache(maxsize=1)
def _malloc_trim():
    import ctypes

    try:
        # The process's own symbols: the C library on Linux, without searching for it.
        return ctypes.CDLL(None).malloc_trim
    except (OSError, AttributeError, TypeError):   # no malloc_trim; Windows has no CDLL(None)
        return None


def run_all(jobs: Sequence[Callable[[], T]], threads: int | None = None) -> list[T]:
    """``[job() for job in jobs]``, computed by up to ``threads`` threads.

    Jobs are started in the order given (put the long ones first). The first exception
    raised by a job is raised here once all started jobs have finished. The threads are
    daemons: an interrupt (Ctrl-C) in the calling thread ends the process at once rather
    than after the running jobs. Called without ``threads`` inside a job of
    :func:`in_order`, the jobs join the queue of the threads shared by all its jobs.
    """
    pool = getattr(_local, "pool", None)
    if threads is None and pool is not None:
        return pool.run(jobs)
    if getattr(_local, "in_pool", False):
        threads = 1
    threads = thread_count() if threads is None else threads
    # BLAS on one thread in every case: threaded BLAS under these threads would
    # oversubscribe the cores, and rounds differently (mocapfill._blas), which would make
    # the result depend on the thread count.
    with single_threaded():
        if threads <= 1 or len(jobs) <= 1:
            return [job() for job in jobs]
        return _run_threaded(jobs, threads)


def _run_threaded(jobs: Sequence[Callable[[], T]], threads: int) -> list[T]:
    pool = _Pool(min(threads, len(jobs)))
    try:
        return pool.run(jobs)
    finally:
        pool.close()


class _Pool:
    """Daemon threads that run the jobs handed to them in the order they were handed over
    (the queue is shared by the callers of :meth:`run`): those of one :func:`run_all`
    call, or those of all the jobs of :func:`in_order`."""

    def __init__(self, threads: int):
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._threads = [threading.Thread(target=self._work, daemon=True,
                                          name=f"mocapfill-{k}") for k in range(threads)]
        for thread in self._threads:
            thread.start()

    def _work(self) -> None:
        _local.in_pool = True
        while True:
            item = self._queue.get()
            if item is None:
                return
            job, outcome, done = item
            try:
                outcome.append(job())
            except BaseException as exc:  # re-raised in the caller of run()
                outcome.append(_Failed(exc))
            release_memory()            # this job's temporaries, not kept in its arena
            done.release()

    def run(self, jobs: Sequence[Callable[[], T]]) -> list[T]:
        """``[job() for job in jobs]`` on the pool's threads (:func:`run_all`'s contract)."""
        done = threading.Semaphore(0)
        outcomes: list[list] = [[] for _ in jobs]
        for job, outcome in zip(jobs, outcomes):
            self._queue.put((job, outcome, done))
        for _ in jobs:
            done.acquire()
        for (value,) in outcomes:
            if isinstance(value, _Failed):
                raise value.error
        return [value for (value,) in outcomes]

    def close(self) -> None:
        """Let the threads end once the jobs handed over so far are done."""
        for _ in self._threads:
            self._queue.put(None)


class _Failed:
    def __init__(self, error: BaseException):
        self.error = error


def in_order(count: int, needs: Mapping[int, Sequence[int]],
             job: Callable[[int, dict[int, L]], tuple[T, L]], at_once: int, ahead: int,
             threads: int | None = None) -> Iterator[T]:
    """The outputs of ``job(k, lent)`` for k = 0 … count − 1, in that order, with up to
    ``at_once`` jobs in progress side by side.

    ``job`` returns (output, lend): the output is yielded, the lend is handed to the jobs
    that need it (``needs[k]``: the indices whose lends job k is given, as
    ``{index: lend}``). A job starts once every job it needs is done, and only while k is
    less than ``ahead`` past the next output to yield, which bounds the outputs held (it
    must reach every index a job needs); of the jobs that may start, the lowest index
    starts first. The :func:`run_all` calls of the jobs share one queue and ``threads``
    threads (default :func:`thread_count`): a job's candidate fills wait in line behind
    those of the jobs before it, and a job alone gets every thread. The first exception
    raised by a job is raised here once the running jobs have finished (the outputs before
    it that were started are yielded first); closing the generator early starts no more
    of them.
    """
    outputs: dict[int, T] = {}
    lends: dict[int, L] = {}
    started: set[int] = set()
    failed: set[int] = set()
    state = {"next": 0, "stop": False}
    errors: list[BaseException] = []
    cond = threading.Condition()
    pool = _Pool(thread_count() if threads is None else threads)

    def startable() -> int | None:
        for k in range(state["next"], min(count, state["next"] + ahead)):
            if k not in started and all(j in lends for j in needs.get(k, ())):
                return k
        return None

    def coordinate() -> None:
        _local.pool = pool
        while True:
            with cond:
                while True:
                    if state["stop"] or errors or len(started) == count:
                        return
                    k = startable()
                    if k is not None:
                        break
                    cond.wait()
                started.add(k)
                lent = {j: lends[j] for j in needs.get(k, ())}
            try:
                output, lend = job(k, lent)
            except BaseException as exc:  # re-raised in the calling thread below
                with cond:
                    errors.append(exc)
                    failed.add(k)
                    cond.notify_all()
                return
            with cond:
                outputs[k], lends[k] = output, lend
                cond.notify_all()
            del output

    coordinators = [threading.Thread(target=coordinate, daemon=True,
                                     name=f"mocapfill-window-{w}")
                    for w in range(max(1, min(at_once, count)))]
    # BLAS on one thread meanwhile: the threads run with the count set in this thread.
    with single_threaded():
        for thread in coordinators:
            thread.start()
        try:
            for k in range(count):
                with cond:
                    # After a failure, the outputs of the jobs already started still come.
                    while k not in outputs and not (errors and (k not in started or k in failed)):
                        cond.wait()
                    if k not in outputs:
                        break
                    output = outputs.pop(k)
                yield output
                del output
                with cond:                  # the consumer is done with output k
                    state["next"] = k + 1
                    cond.notify_all()
        finally:
            with cond:
                state["stop"] = True
                cond.notify_all()
            pool.close()
        for thread in coordinators:
            thread.join()
        if errors:
            raise errors[0]
