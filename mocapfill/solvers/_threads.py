"""Run independent fills side by side on the machine's cores.

The command line keeps BLAS on one thread (many small products, where BLAS threads cost
more than they give), so on a 2-core laptop one core sat idle while the blend computed
its candidate fills one after the other. The fills are independent pure functions of
their inputs and spend their time in numpy, BLAS and pocketfft, which release the GIL,
so Python threads run them in parallel and the result is the same whatever the order.

``MOCAPFILL_THREADS`` sets how many threads (a positive integer; default: the cores this
process may use, at most 8). The batch runner's worker processes set it to 1, since they
already fill every core with one file each.
"""
from __future__ import annotations

import functools
import os
import threading
from collections.abc import Sequence
from typing import Callable, TypeVar

from .._blas import single_threaded
from ..errors import ParameterError

T = TypeVar("T")

VARIABLE = "MOCAPFILL_THREADS"
MAX_DEFAULT = 8


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
    than after the running jobs.
    """
    threads = thread_count() if threads is None else threads
    # BLAS on one thread in every case: threaded BLAS under these threads would
    # oversubscribe the cores, and rounds differently (mocapfill._blas), which would make
    # the result depend on the thread count.
    with single_threaded():
        if threads <= 1 or len(jobs) <= 1:
            return [job() for job in jobs]
        return _run_threaded(jobs, threads)


def _run_threaded(jobs: Sequence[Callable[[], T]], threads: int) -> list[T]:
    results: list = [None] * len(jobs)
    errors: list[BaseException | None] = [None] * len(jobs)
    queue = iter(range(len(jobs)))
    lock = threading.Lock()

    def work() -> None:
        while True:
            with lock:
                index = next(queue, None)
            if index is None:
                return
            try:
                results[index] = jobs[index]()
            except BaseException as exc:  # re-raised in the calling thread below
                errors[index] = exc
            release_memory()            # this job's temporaries, not kept in its arena

    workers = [threading.Thread(target=work, daemon=True, name=f"mocapfill-{k}")
               for k in range(min(threads, len(jobs)))]
    for worker in workers:
        worker.start()
    for worker in workers:
        worker.join()
    for error in errors:
        if error is not None:
            raise error
    return results
