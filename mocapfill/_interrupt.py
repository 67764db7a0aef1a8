"""How the ``mocapfill`` command ends when stopped: one line on stderr, then death by the
signal that stopped it.

Ctrl-C (SIGINT): a shell running the command in a loop (``for f in *.c3d; do mocapfill
repair "$f" ...; done``) stops the loop only when the command died of the signal. A
command that catches Ctrl-C and exits 130 by itself tells the shell it handled the
interruption, and the loop goes on to the next file: one Ctrl-C per file, thousands of
them. Python ends this way after an uncaught KeyboardInterrupt; mocapfill catches it to
clean up and print one line, so it must end that way itself. The shell reports 130
(128 + SIGINT) either way; a parent in Python sees returncode −2.

SIGTERM (``timeout``, a job scheduler's cancel or time limit, ``kill``) and SIGHUP (the
terminal or the ssh session closed): the command stops as after Ctrl-C — a file being
written loses its temporary, a batch stops its workers and writes its report of the files
finished — then ends by that signal (143 or 129 to a shell, 124 from ``timeout``). Their
default action ended the command where it stood, temporaries and all.

Kept apart from :mod:`mocapfill.cli` so that :mod:`mocapfill.__main__` can use it before
loading the command line (click and every command's definition), which takes a tenth of
a second of every command.
"""
from __future__ import annotations

import os
import signal
import sys

EXIT_INTERRUPTED = 130

_TERMINATED: list[int] = []     # the signal (SIGTERM, SIGHUP) that stopped the command

# The signals that stop the command as Ctrl-C does, and how its error line names them.
_REASONS = {signal.SIGTERM: "terminated"}
if hasattr(signal, "SIGHUP"):                   # not on Windows
    _REASONS[signal.SIGHUP] = "hung up"


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, raised where the command is so that it stops as after Ctrl-C."""


def stop_on_signals() -> None:
    """Have SIGTERM and SIGHUP raise :class:`Terminated` in this (main) thread from now
    on, each unless the caller chose what it does (a handler, or SIG_IGN as ``nohup``
    sets for SIGHUP)."""
    try:
        for signum in _REASONS:
            if signal.getsignal(signum) == signal.SIG_DFL:
                signal.signal(signum, _terminate)
    except ValueError:          # not the main thread
        pass


def _terminate(signum, frame) -> None:
    # Once: ``timeout`` sends SIGTERM twice (to the command, then to its process group),
    # and a second Terminated would break off the stopping of the first half-way.
    if _TERMINATED:
        return
    _TERMINATED.append(signum)
    raise Terminated


def reason() -> str:
    """What stopped the command, as its error line says it."""
    return _REASONS[_TERMINATED[0]] if _TERMINATED else "interrupted"


def say_interrupted() -> None:
    """The one line, written straight to stderr's descriptor (it may come from a signal
    handler). Not where the command started without stderr (``2>&-``): descriptor 2 may
    then belong to a file the command opened."""
    if sys.stderr is None:
        return
    try:
        os.write(sys.stderr.fileno(), f"mocapfill: error: {reason()}\n".encode())
    except (OSError, ValueError):
        pass


def die_interrupted() -> None:
    """End this process by the signal that stopped it (SIGINT, SIGTERM or SIGHUP), at once
    (no finalisation); 128 + its number if that fails."""
    stop = _TERMINATED[0] if _TERMINATED else signal.SIGINT
    try:
        signal.signal(stop, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, [stop])
        os.kill(os.getpid(), stop)
    finally:
        os._exit(128 + stop)


def interrupted_while_loading(signum, frame) -> None:
    """SIGINT handler while the command line loads: what a KeyboardInterrupt inside a
    command does, instead of a traceback of the import it fell in."""
    say_interrupted()
    die_interrupted()
