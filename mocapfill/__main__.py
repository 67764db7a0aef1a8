"""The ``mocapfill`` command (the console script, and ``python -m mocapfill``).

The command line is loaded under a SIGINT handler of its own: Ctrl-C during those first
tenths of a second printed the traceback of whatever import it fell in.
"""
from __future__ import annotations

import signal

from ._interrupt import die_interrupted, interrupted_while_loading, say_interrupted


def run() -> None:
    """Load :mod:`mocapfill.cli` with Ctrl-C handled, then run its command."""
    try:
        loading = signal.getsignal(signal.SIGINT) is signal.default_int_handler
        if loading:         # not where the caller ignores SIGINT (nohup, a background job)
            signal.signal(signal.SIGINT, interrupted_while_loading)
    except ValueError:      # not the main thread
        loading = False
    from .cli import run as command

    try:
        if loading:
            signal.signal(signal.SIGINT, signal.default_int_handler)
        command()
    except KeyboardInterrupt:       # between the two lines above
        say_interrupted()
        die_interrupted()


if __name__ == "__main__":  # pragma: no cover
    run()
