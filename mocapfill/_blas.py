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
- :func:`single_threaded` limits the loaded BLAS libraries at run time for the duration
  of a block: :func:`mocapfill.repair` and the parallel sections of the solvers run in
  one, so a program that imported numpy first gets the command's speed and the
  command's results, in whichever thread it calls them.

OpenBLAS built with its own threads (``pthreads``, as in numpy's and scipy's wheels)
keeps one thread count for the whole process, which any thread may set, and which the
solvers' worker threads use too. But threadpoolctl sets it only from the first Python
thread that did (3.8: other threads' limits do nothing, silently), so a block limited it
from the main thread only, and a repair called from another thread (a
``ThreadPoolExecutor``, a GUI's worker) ran with threaded BLAS: its fills differed from
the command's (cmu/02_05 with ml = 40: up to 1.17 mm), and it took 26 to 32 times as
long on the 2-vCPU machine (that clip: 26.4 s against 1.0 s; c3d.org's
Walking_Hybrid_2, ml = 40: 61 s against 1.9 s), OpenBLAS being called from the
solvers' threads at once. So these libraries are set directly, through their own
``openblas_get_num_threads`` and ``openblas_set_num_threads`` (the same functions
threadpoolctl calls; ``openblas_set_num_threads_local`` is no different in these
builds, 0.3.30 and 0.3.31: set to 1 in one thread, a dot product in another rounded as
with one thread), and the blocks of all threads share one limit: the first to open
sets it, the last to close restores the counts, so two repairs in two threads keep one
BLAS thread until both are done. The other libraries (MKL, BLIS, OpenBLAS built with
OpenMP, whose counts may be per thread) are limited through threadpoolctl while a block
is open in the main thread, as before.
"""
from __future__ import annotations

import ctypes
import os
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_by_default() -> None:
    """Set each BLAS thread variable to 1 where the environment does not set it."""
    for variable in VARIABLES:
        os.environ.setdefault(variable, "1")


def user_chose() -> bool:
    """Whether the environment sets a BLAS thread count (the user's, or ours at start-up)."""
    return any(variable in os.environ for variable in VARIABLES)


_lock = threading.Lock()    # guards the state below
_depth = 0                  # blocks open, in all threads together
_shared: list[tuple[Callable[[int], object], int]] = []  # setter, count before
_main_depth = 0             # blocks open in the main thread
_limiter = None             # threadpoolctl's limit on the other libraries (main thread)


@contextmanager
def single_threaded() -> Iterator[None]:
    """Run the block with the BLAS libraries on one thread, then restore their counts.

    A no-op where the environment sets a BLAS thread variable (:func:`user_chose`).
    OpenBLAS with its own threads, whose count is the process's: limited whichever thread
    opens the block, one limit shared by the blocks of all threads (nested ones too),
    set by the first to open and restored by the last to close. Other BLAS libraries:
    limited through threadpoolctl while a block is open in the main thread, nested
    blocks sharing the limit. scipy's BLAS is loaded first, so that it is limited too
    (the solvers load it anyway).
    """
    if user_chose():
        yield
        return
    main = threading.current_thread() is threading.main_thread()
    _open(main)
    try:
        yield
    finally:
        _close(main)


def _open(main: bool) -> None:
    global _depth, _shared, _main_depth, _limiter
    from .solvers._compiled import BLAS, module

    module(BLAS)                # scipy's own OpenBLAS, to be limited as well
    with _lock:
        if _depth == 0:
            _shared = _limit_shared()
        _depth += 1
        if main:
            if _main_depth == 0:
                _limiter = _limit_others()
            _main_depth += 1


def _close(main: bool) -> None:
    global _depth, _shared, _main_depth, _limiter
    with _lock:
        if main:
            _main_depth -= 1
            if _main_depth == 0 and _limiter is not None:
                _limiter.restore_original_limits()
                _limiter = None
        _depth -= 1
        if _depth == 0:
            for set_count, count in _shared:
                set_count(count)
            _shared = []


def _shared_count(info: dict) -> bool:
    """Whether a library (threadpoolctl's description) keeps one thread count for the
    whole process: OpenBLAS with its own threads."""
    return info.get("internal_api") == "openblas" and info.get("threading_layer") == "pthreads"


def _limit_shared() -> list[tuple[Callable[[int], object], int]]:
    """Put each OpenBLAS with a process-wide count on one thread, directly (threadpoolctl
    would not from a thread other than the first to set it); their setters and counts."""
    from threadpoolctl import threadpool_info

    saved = []
    for info in threadpool_info():
        if not _shared_count(info):
            continue
        try:        # the library is loaded: this only opens it again (RTLD_NOLOAD)
            library = ctypes.CDLL(info["filepath"], mode=getattr(os, "RTLD_NOLOAD", 0))
        except OSError:
            continue
        get_count = _symbol(library, "openblas_get_num_threads")
        set_count = _symbol(library, "openblas_set_num_threads")
        if get_count is None or set_count is None:
            continue
        count = get_count()
        if count != 1:
            set_count(1)
            saved.append((set_count, count))
    return saved


def _symbol(library: ctypes.CDLL, name: str) -> Callable | None:
    """``name`` in an OpenBLAS library, whose wheels rename it (numpy's
    ``scipy_openblas_get_num_threads64_``, scipy's ``scipy_openblas_get_num_threads``)."""
    for prefix in ("", "scipy_"):
        for suffix in ("", "64_", "_64"):
            found = getattr(library, f"{prefix}{name}{suffix}", None)
            if found is not None:
                return found
    return None


def _limit_others():
    """threadpoolctl's limit of one thread on the BLAS libraries that :func:`_limit_shared`
    leaves (None where there is none)."""
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController()
    others = [info["filepath"] for info in controller.info()
              if info["user_api"] == "blas" and not _shared_count(info)]
    if not others:
        return None
    return controller.select(filepath=others).limit(limits=1)


def threads_now() -> int:
    """The most threads any loaded BLAS library would use now (1 when none is loaded).

    Read from the libraries themselves (threadpoolctl): the environment does not tell
    when it was set after numpy loaded its BLAS.
    """
    from threadpoolctl import threadpool_info

    return max((info["num_threads"] for info in threadpool_info()
                if info["user_api"] == "blas"), default=1)
