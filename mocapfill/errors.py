"""Typed errors. Core code raises these; only the CLI turns them into messages and exit codes."""
from __future__ import annotations

from os import PathLike


def named(path: str | PathLike | None) -> str:
    """``"PATH: "`` to start a message about a file, ``""`` for a clip built in memory."""
    return f"{path}: " if path is not None else ""


class MocapfillError(Exception):
    """Base of every error mocapfill reports to a user as one line (see cli for exit codes)."""


class FormatError(MocapfillError):
    """A file cannot be read or written: wrong suffix, corrupt, truncated, empty, unparsable.

    The message always starts with the file name.
    """

    def __init__(self, path: str | PathLike | None, problem: str, *, exit_code: int = 123):
        self.path = None if path is None else str(path)
        self.problem = problem
        self.exit_code = exit_code  # 2 when the user named a wrong file (usage), else 123
        super().__init__(problem if path is None else f"{path}: {problem}")


class ParameterError(MocapfillError, ValueError):
    """An option is outside its valid range (negative rank, mr >= 1, ...)."""


class NothingToRepair(MocapfillError):
    """The clip holds no marker that can be filled (every sample missing, no markers, ...)."""


class SolverError(MocapfillError):
    """A completion method failed (non-finite output, no convergence it can report)."""
