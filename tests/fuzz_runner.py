"""Mutation fuzzing of the readers and the repair command, run in a child process.

``python -m tests.fuzz_runner SEED CASES WORKDIR FILE...`` mutates bytes of the given real
files (flips, random bytes, insertions, deletions, truncation, forged header words),
runs ``mocapfill info`` and, for some, ``mocapfill repair`` on each mutant in-process, and
prints one JSON object: the cases that ended other than in success or a clean mocapfill
error (non-zero documented exit code, one line on stderr, no traceback), took longer than
the time limit, or changed their input file. The parent test sets the memory limit.
"""
from __future__ import annotations

import json
import signal
import sys
import time
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from mocapfill.cli import main
from mocapfill.formats.acclaim import find_asf

TIME_LIMIT_S = 10
CLEAN_CODES = {0, 1, 2, 123}


class Hang(BaseException):
    """The time limit, raised from SIGALRM inside the command: a BaseException (as
    KeyboardInterrupt is), so that the command's handler of unexpected exceptions (exit
    70, a bug) lets it through to :func:`run_case`."""


def _alarm(_signum, _frame):
    raise Hang()


def mutate(data: bytes, rng: np.random.Generator) -> bytes:
    buf = bytearray(data)
    kind = rng.integers(6)
    n = len(buf)
    if n == 0:
        return bytes(rng.integers(0, 256, 16, dtype=np.uint8))
    if kind == 0:      # flip a few random bytes
        for i in rng.integers(0, n, rng.integers(1, 9)):
            buf[i] ^= int(rng.integers(1, 256))
    elif kind == 1:    # forge the first 1 KiB (headers, counts, offsets)
        for i in rng.integers(0, min(n, 1024), rng.integers(1, 6)):
            buf[i] = int(rng.integers(0, 256))
    elif kind == 2:    # truncate
        del buf[int(rng.integers(0, n)):]
    elif kind == 3:    # delete a run
        start = int(rng.integers(0, n))
        del buf[start:start + int(rng.integers(1, 200))]
    elif kind == 4:    # insert random bytes
        start = int(rng.integers(0, n))
        buf[start:start] = bytes(rng.integers(0, 256, int(rng.integers(1, 64)), dtype=np.uint8))
    else:              # replace digits/words in a text file (or bytes in a binary one)
        for i in rng.integers(0, n, rng.integers(1, 20)):
            buf[i] = int(rng.choice(list(b"0123456789-.,;\t\n eEnaN")))
    return bytes(buf)


def run_case(args: list[str], watched: Path) -> tuple[str | None, float]:
    before = watched.read_bytes()
    started = time.perf_counter()
    signal.alarm(TIME_LIMIT_S)
    try:
        result = CliRunner().invoke(main, args)
    except Hang:
        return f"hang > {TIME_LIMIT_S} s", time.perf_counter() - started
    finally:
        signal.alarm(0)
    elapsed = time.perf_counter() - started
    if watched.read_bytes() != before:
        return "input file modified", elapsed
    if isinstance(result.exception, Hang):
        return f"hang > {TIME_LIMIT_S} s", elapsed
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        return f"uncaught {type(result.exception).__name__}: {result.exception}", elapsed
    if result.exit_code not in CLEAN_CODES:
        return f"exit code {result.exit_code}", elapsed
    if result.exit_code not in (0, 1):
        lines = result.stderr.strip().splitlines()
        if len(lines) != 1 or "Traceback" in result.output:
            return f"error output is not one line: {result.stderr[:200]!r}", elapsed
    return None, elapsed


def main_(seed: int, cases: int, workdir: Path, files: list[Path]) -> dict:
    signal.signal(signal.SIGALRM, _alarm)
    rng = np.random.default_rng(seed)
    failures, slowest = [], 0.0
    for case in range(cases):
        original = files[case % len(files)]
        mutant = workdir / f"case{case:04d}{original.suffix}"
        mutant.write_bytes(mutate(original.read_bytes(), rng))
        if original.suffix.lower() == ".amc":  # an AMC needs its skeleton beside it
            mutant.with_suffix(".asf").write_bytes(find_asf(original).read_bytes())
        commands = [["info", str(mutant)]]
        if case % 4 == 0:
            commands.append(["repair", str(mutant), str(workdir / f"out{case}{original.suffix}"),
                             "--method", "linear" if case % 8 else "trnn"])
        for args in commands:
            problem, elapsed = run_case(args, mutant)
            slowest = max(slowest, elapsed)
            if problem:
                failures.append({"case": case, "source": original.name, "command": args[0],
                                 "problem": problem})
        mutant.unlink()
        mutant.with_suffix(".asf").unlink(missing_ok=True)
    return {"cases": cases, "failures": failures, "slowest_s": round(slowest, 2)}


if __name__ == "__main__":
    seed, cases, workdir = int(sys.argv[1]), int(sys.argv[2]), Path(sys.argv[3])
    print(json.dumps(main_(seed, cases, workdir, [Path(p) for p in sys.argv[4:]])))
