"""One BLAS thread unless the user chose otherwise.

The solvers make many small matrix products, where BLAS threads cost more than they give,
and the default method already runs its candidate fills side by side in Python threads
(:mod:`mocapfill.solvers._threads`): threaded BLAS under them oversubscribes the cores.
Measured on a 2-vCPU machine, ``mocapfill.repair`` called from Python with OpenBLAS's
default two threads took 9.1 s on 85_02 and 8–10 s on 85_12 (ml = 40), against 1.1 and
1.6 s with one thread.

Two ways to get one thread, both leaving any choice the user made in the environment
alone:

- :func:`one_thread_by_default` sets the thread variables before numpy is first imported
  (the BLAS libraries read them when they load). The command line does
  (``mocapfill/cli.py``), and so do the measuring scripts, so that their figures are the
  command's: threaded BLAS rounds differently, and the default method's validated choices
  could flip on that (WalkL_0001 gave 1.694 mm with two BLAS threads and 1.726 with one
  before the weights were bagged).
- :func:`single_threaded` limits the loaded BLAS libraries at run time (threadpoolctl)
  for the duration of a block: :func:`mocapfill.repair` and the parallel sections of the
  solvers run in one, so a program that imported numpy first gets the command's speed
  and the command's results.
"""
from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_by_default() -> None:
    """Set each BLAS thread variable to 1 where the environment does not set it."""
    for variable in VARIABLES:
        os.environ.setdefault(variable, "1")


def user_chose() -> bool:
    """Whether the environment sets a BLAS thread count (the user's, or ours at start-up)."""
    return any(variable in os.environ for variable in VARIABLES)


_depth = 0          # nesting of single_threaded blocks (main thread only)
_limiter = None


@contextmanager
def single_threaded() -> Iterator[None]:
    """Run the block with the BLAS libraries on one thread, then restore their counts.

    A no-op where the environment sets a BLAS thread variable (:func:`user_chose`), and
    outside the main thread: OpenBLAS takes its thread count from the main thread only
    (0.3.31: a count set from another thread changed nothing, neither there nor in the
    main thread), and it is that count the solvers' worker threads use. Nested blocks
    share the limit; the outermost restores the previous counts. scipy's BLAS is loaded
    first, so that it is limited too (the solvers load it anyway).
    """
    global _depth, _limiter
    if user_chose() or threading.current_thread() is not threading.main_thread():
        yield
        return
    if _depth == 0:
        from threadpoolctl import threadpool_limits

        from .solvers._compiled import BLAS, module

        module(BLAS)                # scipy's own OpenBLAS, to be limited as well

        _limiter = threadpool_limits(limits=1, user_api="blas")
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if _depth == 0 and _limiter is not None:
            _limiter.restore_original_limits()
            _limiter = None


def threads_now() -> int:
    """The most threads any loaded BLAS library would use now (1 when none is loaded).

    Read from the libraries themselves (threadpoolctl): the environment does not tell
    when it was set after numpy loaded its BLAS.
    """
    from threadpoolctl import threadpool_info

    return max((info["num_threads"] for info in threadpool_info()
                if info["user_api"] == "blas"), default=1)
