"""How the ``mocapfill`` command ends after Ctrl-C: one line on stderr, then death by SIGINT.

A shell running the command in a loop (``for f in *.c3d; do mocapfill repair "$f" ...;
done``) stops the loop only when the command died of the signal. A command that catches
Ctrl-C and exits 130 by itself tells the shell it handled the interruption, and the loop
goes on to the next file: one Ctrl-C per file, thousands of them. Python ends this way
after an uncaught KeyboardInterrupt; mocapfill catches it to clean up and print one line,
so it must end that way itself. The shell reports 130 (128 + SIGINT) either way; a parent
in Python sees returncode −2.

Kept apart from :mod:`mocapfill.cli` so that :mod:`mocapfill.__main__` can use it before
loading the command line (click and every command's definition), which takes a tenth of
a second of every command.
"""
from __future__ import annotations

import os
import signal

EXIT_INTERRUPTED = 130


def say_interrupted() -> None:
    """The one line, written straight to stderr (it may come from a signal handler)."""
    try:
        os.write(2, b"mocapfill: error: interrupted\n")
    except OSError:
        pass


def die_interrupted() -> None:
    """End this process by SIGINT, at once (no finalisation), exit 130 if that fails."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])
        os.kill(os.getpid(), signal.SIGINT)
    finally:
        os._exit(EXIT_INTERRUPTED)


def interrupted_while_loading(signum, frame) -> None:
    """SIGINT handler while the command line loads: what a KeyboardInterrupt inside a
    command does, instead of a traceback of the import it fell in."""
    say_interrupted()
    die_interrupted()
