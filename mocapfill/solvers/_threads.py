"""Run independent fills side by side on the machine's cores.

The command line keeps BLAS on one thread (many small products, where BLAS threads cost
more than they give), so on a 2-core laptop one core sat idle while the blend computed
its candidate fills one after the other. The fills are independent pure functions of
their inputs and spend their time in numpy, BLAS and pocketfft, which release the GIL,
so Python threads run them in parallel and the result is the same whatever the order.

The windows of a long clip are solved side by side by :func:`in_order`, their fills in
one queue for the same threads: a window's serial steps (validation bookkeeping, the blend)
and the last long fill of its batch no longer leave a core idle.

Threads still spent much of their time waiting for each other at the interpreter's lock.
Where the system allows it, the blend's runs whose results are small (its validation) go
to a forked child process (:func:`run_all`'s ``apart``), and the windows of a long clip
each to a child process of their own (:func:`in_order`'s ``apart``).

``MOCAPFILL_THREADS`` sets how many threads (a positive integer; default: the cores this
process may use, at most 8). The batch runner's worker processes set it to 1, since they
already fill every core with one file each.
"""
from __future__ import annotations

import os
import pickle
import queue
import sys
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import TypeVar

from .._blas import single_threaded
from .._blas import threads_now as blas_threads_now
from .._memory import release_memory
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


def run_all(jobs: Sequence[Callable[[], T]], threads: int | None = None, *,
            apart: Sequence[int] = ()) -> list[T]:
    """``[job() for job in jobs]``, computed by up to ``threads`` threads.

    Jobs are started in the order given (put the long ones first). The first exception
    raised by a job is raised here once all started jobs have finished. The threads are
    daemons: an interrupt (Ctrl-C) in the calling thread ends the process at once rather
    than after the running jobs. Called without ``threads`` inside a job of
    :func:`in_order`, the jobs join the queue of the threads shared by all its jobs.

    ``apart``: indices of jobs whose results are small; where the process may fork
    (:func:`_may_fork`), they run in a child process while this one runs the others
    (:func:`_run_apart`), each with its share of the threads.
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
        if apart and len(apart) < len(jobs) and _may_fork():
            return _run_apart(jobs, apart, threads)
        return _run_threaded(jobs, threads)


def _may_fork() -> bool:
    """Whether a child process may be forked here: on Linux (macOS frameworks are not
    safe to use after a fork), from a process whose only thread is this one (a fork
    copies no other thread, and a lock another thread held would stay locked in the
    child), not itself a daemonic worker process, with BLAS on one thread. Where the user
    asked for threaded BLAS (``OPENBLAS_NUM_THREADS=2``), two processes would each run
    their BLAS threads on the same cores: 85_02 ml = 40 took 21 s so, against 7.8 s with
    threads (and 1 s with one BLAS thread)."""
    return (sys.platform.startswith("linux") and hasattr(os, "fork")
            and threading.active_count() == 1 and not _daemonic()
            and blas_threads_now() == 1)


def _daemonic() -> bool:
    """Whether this is a daemonic ``multiprocessing`` process (the workers of a
    ``multiprocessing.Pool``, of Dask's nanny), which may not start children of its own."""
    mp = sys.modules.get("multiprocessing")     # not imported: not such a process
    return mp is not None and bool(mp.current_process().daemon)


def _run_apart(jobs: Sequence[Callable[[], T]], apart: Sequence[int], threads: int
               ) -> list[T]:
    """:func:`run_all` with the jobs ``apart`` in a forked child process.

    Why a process: the candidate fills of the blend are numpy code, but on a clip of a
    few thousand frames many of their operations are small, and threads then wait for
    the interpreter's lock more than they compute. Measured on the 810-frame 85_02 (ml =
    40), one core each: the Gaussian fill took 0.17 s alone and 0.31 s beside a second
    one in another thread (0.17 s in another process); the blend's sixteen fills took
    0.85 s in two threads and 0.56 s split between two processes.

    The child takes the jobs apart one at a time, in their order; this process takes
    those left once its own are done (so neither core waits on the other's last jobs).
    The child inherits the jobs and their inputs (nothing is copied until written) and
    sends back its results through a pipe, pickled: hence small results only (the blend
    sends its validation errors, and keeps the full fills here). Standard output and
    error are flushed before the fork, so the child does not write this process's
    buffered text a second time (tested), and the child leaves by ``os._exit``. An
    exception raised by a child's job is raised here (as a RuntimeError with its message
    where it cannot be pickled); if the child dies without an answer (killed, out of
    memory), its jobs run here; where no child can be started, threads run them all.

    The child is made by ``os.fork`` itself, the jobs handed out through a pipe
    (:class:`_Tickets`): ``multiprocessing``'s import, shared counter and process start
    took 23–30 ms of every repair's serial path, a fork and two pipes 1–1.5 ms (and a
    shared counter needs POSIX semaphores, which some containers lack).
    """
    away = set(apart)
    mine = [k for k in range(len(jobs)) if k not in away]
    sent = [jobs[k] for k in apart]
    child_threads = max(1, threads // 2)
    try:
        tickets = _Tickets(len(sent))
    except (OSError, ValueError):           # no pipe (out of descriptors), too many jobs
        return _run_threaded(jobs, threads)
    try:
        receiver, sender = os.pipe()
    except OSError:
        tickets.close()
        return _run_threaded(jobs, threads)
    _flush_std_streams()
    parent = os.getpid()
    try:
        child = os.fork()
    except OSError:                         # a process limit, no memory to map
        for fd in (receiver, sender):
            os.close(fd)
        tickets.close()
        return _run_threaded(jobs, threads)
    if child == 0:
        try:
            os.close(receiver)
            _child(sent, tickets, child_threads, sender, parent)
        finally:
            os._exit(0)
    os.close(sender)
    try:
        results = dict(zip(mine, run_all([jobs[k] for k in mine],
                                         max(1, threads - child_threads))))
        # Then the jobs apart that the child has not taken yet, here.
        here: dict[int, T] = {}
        _taking(sent, tickets, here)()
        answer = _read_all(receiver)
        if answer:
            status, value = pickle.loads(answer)
        else:                                   # the child died without an answer
            rest = [k for k in range(len(sent)) if k not in here]
            status, value = "ok", dict(zip(rest, run_all([sent[k] for k in rest], threads)))
        if status != "ok":
            raise value
        results.update((apart[k], v) for k, v in {**here, **value}.items())
    finally:
        os.close(receiver)
        tickets.close()
        _end(child)
    return [results[k] for k in range(len(jobs))]


class _Tickets:
    """The jobs apart handed out in their order between a parent and its forked child:
    their indices as 4-byte tokens in a pipe both read, each read taking the next (a
    pipe's reads and writes of up to PIPE_BUF bytes are atomic, so no token is split or
    taken twice, by either process or by any of their threads), and the end once it is
    empty: the writing end is closed before the fork."""

    def __init__(self, count: int):
        tokens = b"".join(k.to_bytes(4, sys.byteorder) for k in range(count))
        # Written at once before any reader exists: at most PIPE_BUF (4,096 bytes on
        # Linux), what every pipe holds even where the system shrinks their buffers.
        if len(tokens) > 4096:
            raise ValueError(f"{count} jobs apart")
        self._fd, write = os.pipe()
        try:
            os.write(write, tokens)
        finally:
            os.close(write)

    def next(self) -> int | None:
        """The index of the next job not taken yet, or None."""
        token = os.read(self._fd, 4)
        return int.from_bytes(token, sys.byteorder) if len(token) == 4 else None

    def close(self) -> None:
        os.close(self._fd)


def _read_all(fd: int) -> bytes:
    """What the child wrote to the pipe ``fd`` until it closed its end (b"" if nothing)."""
    chunks = []
    while chunk := os.read(fd, 1 << 16):
        chunks.append(chunk)
    return b"".join(chunks)


def _end(child: int) -> None:
    """Reap the forked ``child``, ending it first (SIGTERM) if it still runs."""
    import signal

    try:
        if os.waitpid(child, os.WNOHANG)[0] == 0:
            os.kill(child, signal.SIGTERM)
            os.waitpid(child, 0)
    except (ChildProcessError, ProcessLookupError):         # reaped already
        pass


def _taking(jobs: Sequence[Callable[[], T]], tickets: _Tickets, done: dict[int, T]
            ) -> Callable[[], None]:
    """A job that takes the next of ``jobs`` not yet taken by anyone sharing
    ``tickets``, runs it into ``done`` and goes on until none is left."""
    def take() -> None:
        while (k := tickets.next()) is not None:
            done[k] = jobs[k]()
    return take


def _child(jobs: Sequence[Callable[[], T]], tickets: _Tickets, threads: int, sender: int,
           parent: int) -> None:
    """The body of :func:`_run_apart`'s child: run the jobs it takes and answer ("ok",
    {index: result}) or ("error", exception) (:func:`_answer`) through the pipe
    ``sender``."""
    done: dict[int, T] = {}

    def take_all() -> dict[int, T]:
        run_all([_taking(jobs, tickets, done)] * threads, threads)
        return done

    _answer(take_all, _PipeEnd(sender), parent)


class _PipeEnd:
    """The writing end ``fd`` of a pipe as :func:`_answer` uses a connection: the answer
    pickled, then the end closed (the reader reads to the end of the pipe)."""

    def __init__(self, fd: int):
        self._fd = fd

    def send(self, answer) -> None:
        data = memoryview(pickle.dumps(answer, protocol=pickle.HIGHEST_PROTOCOL))
        while data:
            data = data[os.write(self._fd, data):]

    def close(self) -> None:
        os.close(self._fd)
        _flush_std_streams()                        # what the jobs wrote, before _exit


def _flush_std_streams() -> None:
    """Flush standard output and error, as far as they can be (None, closed, a broken
    pipe): before a fork, so the child does not write the parent's buffered text again,
    and in the child before it leaves by ``os._exit``."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass


def _answer(compute: Callable[[], T], sender, parent: int) -> None:
    """In a forked child: send ("ok", compute()) or ("error", exception) to the parent.

    Ctrl-C is left to the parent, which ends the child on its way out (SIGTERM, whose
    default action is restored, as SIGHUP's: a handler the program installed would keep
    the child alive); the child also ends when the parent dies (Linux's parent-death signal),
    rather than compute on for no one. Nothing escapes: ``multiprocessing`` would print a
    traceback. An exception that cannot be pickled is sent as a RuntimeError with its
    message.
    """
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if hasattr(signal, "SIGHUP"):               # the command's handler, like SIGTERM's
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
    _die_with(parent)
    try:
        answer = ("ok", compute())
    except BaseException as exc:  # re-raised in the parent
        try:
            pickle.loads(pickle.dumps(exc))
        except Exception:
            exc = RuntimeError(f"{type(exc).__name__}: {exc}")
        answer = ("error", exc)
    try:
        sender.send(answer)
        sender.close()
    except OSError:                             # the parent is gone
        pass


def _die_with(parent: int) -> None:
    """Have this (forked) process sent SIGTERM when its parent dies."""
    import ctypes
    import signal

    try:
        ctypes.CDLL(None).prctl(1, signal.SIGTERM)          # PR_SET_PDEATHSIG
    except (OSError, AttributeError, TypeError):            # not Linux's C library
        return
    if os.getppid() != parent:                  # the parent died before the call
        os._exit(0)


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
             threads: int | None = None, *, apart: bool = False) -> Iterator[T]:
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

    With ``apart``, where the process may fork (:func:`_may_fork`), each job runs in a
    forked child process instead (:func:`_in_order_forked`).
    """
    if apart and at_once > 1 and count > 1 and _may_fork():
        yield from _in_order_forked(count, needs, job, at_once, ahead)
        return
    outputs: dict[int, T] = {}
    lends: dict[int, L] = {}
    started: set[int] = set()
    failed: set[int] = set()
    state = {"next": 0, "stop": False}
    errors: list[BaseException] = []
    cond = threading.Condition()
    pool = _Pool(thread_count() if threads is None else threads)

    def coordinate() -> None:
        _local.pool = pool
        while True:
            with cond:
                while True:
                    if state["stop"] or errors or len(started) == count:
                        return
                    k = _startable(state["next"], count, ahead, needs, started, lends)
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
    # BLAS on one thread meanwhile: the threads run with the count set here (OpenBLAS's
    # is the process's, mocapfill._blas).
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


def _startable(following: int, count: int, ahead: int, needs: Mapping[int, Sequence[int]],
               started: set[int], lends: Mapping[int, object]) -> int | None:
    """:func:`in_order`'s next job to start: the lowest index not started, less than
    ``ahead`` past the next output due (``following``), whose needed lends are all in."""
    for k in range(following, min(count, following + ahead)):
        if k not in started and all(j in lends for j in needs.get(k, ())):
            return k
    return None


def _in_order_forked(count: int, needs: Mapping[int, Sequence[int]],
                     job: Callable[[int, dict[int, L]], tuple[T, L]], at_once: int,
                     ahead: int) -> Iterator[T]:
    """:func:`in_order` with every job in a forked child process of its own, up to
    ``at_once`` at a time, each on one thread; the output and lend come back pickled.

    Why: the windows of a long clip, solved side by side in threads, waited for each
    other at the interpreter's lock. On the bench's 30-minute clip (216,000 frames of
    41 markers, 21 windows) two threads took 48.7 s wall for 66 s of user and 12.5 s of
    system time (321,578 futex calls), where one thread took 76.7 s for 69 and 6.8 s.

    The children are forked by this (the only) thread, so no lock is held in them; a
    window's output (its fill: 12,000 frames × 123 rows, 12 MB) costs a few milliseconds
    to send. This process only schedules, and the caller assembles each output while the
    children compute. A child whose job fails sends the exception: no job starts after
    that, and it is raised here once the outputs before it have been yielded (children
    still running then are ended). A child that dies without an answer (killed, out of
    memory) has its job run here; where no child can be started, the job runs here too.
    The children ignore Ctrl-C and end with this process, as :func:`_run_apart`'s does
    (:func:`_answer`).
    """
    import multiprocessing
    from multiprocessing.connection import wait

    context = multiprocessing.get_context("fork")
    outputs: dict[int, T] = {}
    lends: dict[int, L] = {}
    started: set[int] = set()
    running: dict = {}                  # receiver → (k, lent, child process)
    error: tuple[int, BaseException] | None = None
    following = 0                       # the next output to yield

    def finished(k: int, result: tuple[T, L]) -> None:
        outputs[k], lends[k] = result

    try:
        while following < count:
            while error is None and len(running) < at_once:
                k = _startable(following, count, ahead, needs, started, lends)
                if k is None:
                    break
                started.add(k)
                lent = {j: lends[j] for j in needs.get(k, ())}
                receiver, sender = context.Pipe(duplex=False)
                child = context.Process(target=_job_child,
                                        args=(job, k, lent, sender, os.getpid()),
                                        name=f"mocapfill-job-{k}", daemon=True)
                try:
                    child.start()
                except OSError:             # no child to be had: the job runs here
                    receiver.close()
                    sender.close()
                    finished(k, job(k, lent))
                    continue
                sender.close()
                running[receiver] = (k, lent, child)
            if following in outputs:
                output = outputs.pop(following)
                following += 1
                yield output
                del output
                continue
            if error is not None and error[0] <= following:
                break
            if not running:     # cannot happen: every job's needs come before it is due
                raise RuntimeError(f"no job can start (job {following} is due)")
            for receiver in wait(list(running)):
                k, lent, child = running.pop(receiver)
                try:
                    status, value = receiver.recv()
                except EOFError:            # the child died without an answer
                    status, value = "ok", job(k, lent)
                finally:
                    receiver.close()
                    child.join()
                if status == "ok":
                    finished(k, value)
                elif error is None or k < error[0]:
                    error = (k, value)
    finally:
        for receiver, (_, _, child) in running.items():
            receiver.close()
            if child.is_alive():
                child.terminate()
            child.join()
    if error is not None:
        raise error[1]


def _job_child(job: Callable[[int, dict[int, L]], tuple[T, L]], k: int, lent: dict[int, L],
               sender, parent: int) -> None:
    """The body of a child of :func:`_in_order_forked`: answer job(k, lent) as
    :func:`_answer` does, the job's :func:`run_all` calls on one thread (the other jobs'
    processes have the other cores)."""
    def compute() -> tuple[T, L]:
        os.environ[VARIABLE] = "1"
        return job(k, lent)

    _answer(compute, sender, parent)
