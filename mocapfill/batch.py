"""Batch repair of many files: discovery, output planning, local or Dask execution, report.

``repair_many`` is the entry point. It plans one ``FileJob`` per input (where its output
goes, or that it is skipped because its output is newer than it), runs ``repair_file`` on
every job — in this process, in a pool of local worker processes, or on a
``dask.distributed`` cluster — and returns a ``BatchReport``.

What each status means:

- ``repaired``: at least one gap was filled and the output written.
- ``unchanged``: nothing was filled — the clip has no gaps, or the gap policy left all of
  them (``--max-gap``, ``--ends leave``, ...). With an output
  folder the output is still written (a faithful copy, or a conversion with ``suffix``)
  so the mirrored tree is complete and a resumed batch skips it; in place, nothing is
  written.
- ``skipped``: the output exists and is newer than the input (``force`` redoes it).
- ``failed``: the file could not be read, repaired or written, or holds nothing to repair
  from (one frame, or no marker with a single sample: bad input, as for a single file);
  ``reason`` says why. One failure never stops the batch.

Like the rest of the core this module never prints and never exits; numpy and the format
modules are imported inside the per-file function so worker processes can limit BLAS
threads before numpy loads.
"""
from __future__ import annotations

import glob
import os
import secrets
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from .errors import FormatError, MocapfillError, NothingToRepair, ParameterError, named

REPAIRED = "repaired"
UNCHANGED = "unchanged"
SKIPPED = "skipped"
FAILED = "failed"
STATUSES = (REPAIRED, UNCHANGED, SKIPPED, FAILED)

EXIT_OK = 0
EXIT_CHECK_FAILED = 1
EXIT_FAILED = 123

# Too generic to pick up while walking a folder (README.txt, notes.txt, ...); a .txt named
# explicitly is still read as CSV.
NOT_DISCOVERED = frozenset({".txt"})

# Environment a local worker sets before numpy loads: one BLAS thread per process, so N
# workers on N cores do not each start N threads and fight over the cores.
SINGLE_THREADED = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                   "MKL_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1",
                   "NUMEXPR_NUM_THREADS": "1", "MOCAPFILL_THREADS": "1"}

DASK_MISSING = ("--scheduler needs dask.distributed, which is not installed: "
                "pip install 'dask[distributed]', or '.[dask]' in mocapfill's checkout")


# ---------------------------------------------------------------- records


@dataclass(frozen=True)
class FileJob:
    """One file of a batch: where it is read, where it is written and how it is repaired.

    Picklable and small, so it travels to worker processes and Dask workers, which read
    and write the files themselves.
    """

    input: Path
    output: Path
    options: object = None  # RepairOptions | None; typed loosely to keep imports lazy
    zero_is_missing: str = "auto"
    max_gap_s: float | None = None
    in_place: bool = False
    # The token in the names of its temporary files (formats.temp_token): the batch's, so
    # that stopping it removes its own only; None, that of the process writing it.
    temp_token: str | None = None


@dataclass(frozen=True)
class FileRecord:
    """What happened to one file."""

    input: str
    output: str
    status: str
    reason: str = ""
    gaps_filled: int = 0
    gaps_left: int = 0
    seconds: float = 0.0
    frames: int = 0
    # What the reader worked around (a Frame column that skips numbers, a row cut short:
    # report.reader_notes), then what the output's format could not hold (formats.write).
    notes: tuple[str, ...] = ()


@dataclass
class BatchReport:
    """Per-file records of a batch, its counts, its summary line and its exit code."""

    records: list[FileRecord] = field(default_factory=list)
    seconds: float = 0.0

    def count(self, status: str) -> int:
        return sum(r.status == status for r in self.records)

    @property
    def repaired(self) -> int:
        return self.count(REPAIRED)

    @property
    def unchanged(self) -> int:
        return self.count(UNCHANGED)

    @property
    def skipped(self) -> int:
        return self.count(SKIPPED)

    @property
    def failed(self) -> int:
        return self.count(FAILED)

    @property
    def failures(self) -> list[FileRecord]:
        return [r for r in self.records if r.status == FAILED]

    @property
    def frames(self) -> int:
        """Frames of the files processed (repaired or unchanged) in this run."""
        return sum(r.frames for r in self.records if r.status in (REPAIRED, UNCHANGED))

    @property
    def gaps_left(self) -> int:
        return sum(r.gaps_left for r in self.records)

    def exit_code(self, check: bool = False) -> int:
        """0 all ok; 123 some file failed; 1 with ``check`` when gaps were left open."""
        if self.failed:
            return EXIT_FAILED
        if check and self.gaps_left:
            return EXIT_CHECK_FAILED
        return EXIT_OK

    def summary(self) -> str:
        """'412 repaired, 3 unchanged, 2 failed, 17 gaps left in 38.1 s' (zero counts
        after the first are left out): the gaps left say why ``--check`` exits 1."""
        parts = [f"{self.repaired} repaired"]
        parts += [f"{self.count(s)} {s}" for s in (UNCHANGED, SKIPPED, FAILED) if self.count(s)]
        if self.gaps_left:
            parts.append(f"{self.gaps_left} gap{'s' if self.gaps_left != 1 else ''} left")
        return f"{', '.join(parts)} in {self.seconds:.1f} s"

    def as_dict(self) -> dict:
        processed = self.repaired + self.unchanged
        return {
            "summary": {
                "files": len(self.records),
                **{status: self.count(status) for status in STATUSES},
                "gaps_filled": sum(r.gaps_filled for r in self.records),
                "gaps_left": self.gaps_left,
                "frames": self.frames,
                "seconds": round(self.seconds, 3),
                "files_per_s": round(processed / self.seconds, 3) if self.seconds else None,
                "frames_per_s": round(self.frames / self.seconds, 1) if self.seconds else None,
            },
            "files": [asdict(r) for r in self.records],
        }

    def write_json(self, path: str | os.PathLike) -> None:
        """Write the report (summary and one entry per file) as JSON."""
        import json

        path = Path(path)
        if path.suffix.lower() != ".json":
            raise FormatError(path, "the batch report must be a .json file", exit_code=2)
        # Atomically: a report cut short (Ctrl-C twice, a full disk) would replace the
        # last good one with half a JSON document.
        from .formats import write_text_atomically

        write_text_atomically(path, json.dumps(self.as_dict(), indent=1) + "\n")


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C during a batch. ``report`` holds the files finished before it; no output is
    left half-written and the workers are stopped."""

    def __init__(self, report: BatchReport):
        super().__init__()
        self.report = report


# ---------------------------------------------------------------- discovery and planning


def _known_suffixes() -> dict[str, str]:
    from .formats import FORMATS

    return FORMATS


def _is_motion_file(path: Path, named: str | None = None) -> bool:
    """Whether a file found (not named) is picked up; ``named``: a suffix of
    ``NOT_DISCOVERED`` that the glob which found it names (``'data/*.txt'``)."""
    suffix = path.suffix.lower()
    return (suffix in _known_suffixes() and (suffix not in NOT_DISCOVERED or suffix == named)
            and not path.name.startswith(".")
            # A link to no file is taken, and fails naming it: skipped, a missing trial
            # went unnoticed.
            and (path.is_file() or (path.is_symlink() and not path.exists())))


def _named_suffix(pattern: str) -> str | None:
    """The suffix a glob's last part spells out ('*.TXT' -> '.txt'), if it has no
    wildcard."""
    suffix = Path(pattern).suffix
    return suffix.lower() if suffix and not glob.has_magic(suffix) else None


def _walk(directory: Path, exclude: Path | None) -> list[Path]:
    """Motion files under ``directory``, recursively, hidden folders and ``exclude`` left out."""
    found = []
    for root, dirs, files in os.walk(directory):
        root_path = Path(root)
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                         and not _same_path(root_path / d, exclude))
        found += [root_path / f for f in sorted(files) if _is_motion_file(root_path / f)]
    return found


def _same_path(a: Path, b: Path | None) -> bool:
    return b is not None and a.exists() and b.exists() and os.path.samefile(a, b)


def _inside(path: Path, folder: Path | None) -> bool:
    """Whether ``path`` is ``folder`` or lies under it (a glob's match in the output
    folder)."""
    if folder is None or not folder.exists():
        return False
    return _real(path).is_relative_to(_real(folder))


def _real(path: Path) -> Path:
    """``path`` with its symbolic links resolved as far as they lead. Not Path.resolve(),
    which raises RuntimeError on a link loop (before Python 3.13): a traceback, exit 1."""
    return Path(os.path.realpath(path))


def _glob_base(pattern: str) -> Path:
    """The folder part of a glob before its first wildcard: 'data/*/x*.c3d' -> 'data'."""
    parts = Path(pattern).parts
    fixed = []
    for part in parts[:-1]:
        if glob.has_magic(part):
            break
        fixed.append(part)
    return Path(*fixed) if fixed else Path(".")


def _glob(pattern: str) -> list[Path]:
    """``glob.glob(pattern, recursive=True)``, except that ``**`` does not go into symbolic
    links to folders, as walking a folder does not: a link to a folder above it (``ln -s ..
    loop``) made glob find the same file once per round of the loop up to the system's
    path limit (41 times, its output written 400 characters deep), and two such links made
    it run for ever (its work grows exponentially with depth). Other components match as
    glob matches them, one level each, links included: that ends."""
    parts = Path(pattern).parts
    if "**" not in parts:
        return [Path(match) for match in glob.glob(pattern)]
    fixed = 0
    while fixed < len(parts) - 1 and not glob.has_magic(parts[fixed]):
        fixed += 1
    rest = [part for k, part in enumerate(parts[fixed:], fixed)
            if not (part == "**" and k > fixed and parts[k - 1] == "**")]   # **/** is **
    found = [Path(*parts[:fixed])] if fixed else [Path(".")]
    for k, part in enumerate(rest):
        last = k == len(rest) - 1
        if part == "**":
            # A final ** matches everything under the folders: discover walks them.
            found = found if last else [f for folder in found for f in _folders(folder)]
        elif glob.has_magic(part):
            found = [Path(match) for folder in found
                     for match in glob.glob(os.path.join(glob.escape(str(folder)), part))]
        else:
            found = [folder / part for folder in found if os.path.lexists(folder / part)]
        if not last:
            found = [folder for folder in found if folder.is_dir()]
    return [path for path in found if os.path.lexists(path)]


def _folders(top: Path) -> list[Path]:
    """``top`` and the folders under it that ``**`` matches: not hidden, not reached
    through a symbolic link."""
    found = [top]
    for root, dirs, _files in os.walk(top):
        dirs[:] = sorted(d for d in dirs
                         if not d.startswith(".") and not os.path.islink(os.path.join(root, d)))
        found += [Path(root) / d for d in dirs]
    return found


def discover(paths: Iterable[str | os.PathLike],
             exclude: str | os.PathLike | None = None) -> list[tuple[Path, Path]]:
    """Expand files, folders and globs into ``(file, relative output path)`` pairs.

    Folders are walked recursively for known suffixes (case-insensitive; ``.txt`` only when
    named explicitly, as a file or by a glob ending in it: ``'data/*.txt'``); the output
    path mirrors the file's place under the folder. A glob's matches mirror their place
    under the glob's fixed leading folder; a plain file keeps just its name; a glob's
    ``**`` does not go into symbolic links to folders (``_glob``). Hidden files and
    folders, and the folder ``exclude`` (the output folder, when it lies inside an input
    folder or a glob matches in it), are never picked up. A file reached twice is listed
    once.

    Raises
    ------
    ParameterError
        A path that does not exist, a glob that matches no motion file, or no motion
        file at all.
    FormatError
        A file named explicitly whose suffix is not a motion format (exit code 2).
    """
    from .formats import format_module

    exclude_path = None if exclude is None else Path(exclude)
    texts = [os.fspath(given) for given in paths]
    pairs: list[tuple[Path, Path]] = []
    for text in texts:
        path = Path(text)
        if path.is_dir():
            pairs += [(f, f.relative_to(path)) for f in _walk(path, exclude_path)]
        elif path.exists():
            if path.suffix.lower() not in _known_suffixes():
                format_module(path)  # raises the helpful "unknown / wrong suffix" error
            pairs.append((path, Path(path.name)))
        elif glob.has_magic(text):
            matches = sorted(_glob(text))
            if not matches:
                raise ParameterError(f"{text}: no file matches this pattern")
            base, named, before = _glob_base(text), _named_suffix(text), len(pairs)
            for match in matches:
                if _inside(match, exclude_path):    # the outputs of an earlier run
                    continue
                if match.is_dir():
                    pairs += [(f, f.relative_to(base)) for f in _walk(match, exclude_path)]
                elif _is_motion_file(match, named):
                    pairs.append((match, match.relative_to(base)))
            if len(pairs) == before:    # as one that matches nothing: not a batch of 0
                raise ParameterError(f"{text}: none of the {len(matches)} path(s) this "
                                     "pattern matches is a motion file")
        else:
            raise ParameterError(f"{text}: no such file or folder")
    if not pairs:
        searched = sorted(set(_known_suffixes()) - NOT_DISCOVERED)
        raise ParameterError(f"no motion file in {', '.join(texts)} (folders are searched "
                             f"for {' '.join(searched)}; a .txt is read when named, alone "
                             "or by a glob)")
    unique: dict[Path, tuple[Path, Path]] = {}
    for file, relative in pairs:
        unique.setdefault(_real(file), (file, relative))
    return list(unique.values())


def _is_up_to_date(source: Path, output: Path) -> bool:
    # Strictly newer: on a coarse-clock file system an equal time could hide an input
    # changed after its output was written; redoing a file is safe, skipping it is not.
    # A folder where the output goes is no output: the file is repaired and its write
    # fails, naming the folder, rather than skipped on every rerun. Nor is an empty file
    # (`touch`, a copy that failed): outputs are written whole, and no format's is empty.
    import stat

    try:
        written = output.stat()
        return (not stat.S_ISDIR(written.st_mode) and written.st_size > 0
                and written.st_mtime_ns > _input_time(source))
    except OSError:         # absent, a link loop, ...: redone, and its write says why
        return False


def _input_time(source: Path) -> int:
    """The latest modification time of what a repair of ``source`` reads: the file, and
    an AMC's skeleton (an edited ``.asf`` left the output of its AMC skipped, with the old
    skeleton copied beside it)."""
    latest = source.stat().st_mtime_ns
    if source.suffix.lower() == ".amc":
        from .errors import FormatError
        from .formats.acclaim import find_asf

        try:
            latest = max(latest, find_asf(source).stat().st_mtime_ns)
        except (FormatError, OSError):  # no skeleton: the repair fails and says so
            pass
    return latest


def plan(paths: Iterable[str | os.PathLike], out_dir: str | os.PathLike | None = None, *,
         options=None, in_place: bool = False, force: bool = False,
         zero_is_missing: str = "auto", max_gap_s: float | None = None,
         suffix: str | None = None) -> tuple[list[FileJob], list[FileRecord]]:
    """Jobs to run and records of the files skipped as up to date.

    Raises ``ParameterError`` for a batch that cannot be planned safely: neither or both of
    ``out_dir`` and ``in_place``, an output that would overwrite an input, two inputs
    mapped to the same output; and for a ``max_gap_s`` or ``zero_is_missing`` out of range.
    """
    if (out_dir is None) == (not in_place):
        raise ParameterError("give an output folder (-o OUTDIR) or in-place (--in-place), "
                             "not both")
    # Checked once here: each file would otherwise fail alone with the same error.
    if max_gap_s is not None and not 0 <= max_gap_s < float("inf"):
        raise ParameterError(f"--max-gap must be a finite number of seconds ≥ 0, got "
                             f"{max_gap_s}")
    if zero_is_missing not in ("auto", "on", "off"):
        raise ParameterError(f"--zero-is-missing must be auto, on or off, got "
                             f"{zero_is_missing!r}")
    if suffix is not None:
        suffix = suffix if suffix.startswith(".") else f".{suffix}"
        if in_place:
            raise ParameterError("--suffix changes the output format; it cannot be used in place")
        if suffix.lower() not in _known_suffixes():
            raise ParameterError(f"--suffix {suffix}: unknown format; known: "
                                 f"{', '.join(sorted(_known_suffixes()))}")
    out_root = None if out_dir is None else Path(out_dir)
    found = discover(paths, exclude=out_root)
    inputs = {_real(file) for file, _ in found}
    jobs: list[FileJob] = []
    skipped: list[FileRecord] = []
    claimed: dict[Path, Path] = {}
    for file, relative in found:
        if in_place:
            output = file
        else:
            output = out_root / relative
            if suffix is not None:
                output = output.with_suffix(suffix)
            key = _real(output)
            if key in inputs:
                raise ParameterError(f"{output} is an input; refusing to overwrite it "
                                     "(choose another output folder, or --in-place)")
            if key in claimed:
                hint = ("they differ only in their suffix, which --suffix replaces: run the "
                        "batch once per input format, into different folders"
                        if Path(claimed[key]).with_suffix("") == file.with_suffix("")
                        else "pass their common folder instead")
                raise ParameterError(f"{claimed[key]} and {file} would both be written to "
                                     f"{output}; {hint}")
            claimed[key] = file
            if not force and _is_up_to_date(file, output):
                skipped.append(FileRecord(str(file), str(output), SKIPPED,
                                          "output is newer than input"))
                continue
        jobs.append(FileJob(file, output, options, zero_is_missing, max_gap_s, in_place))
    return jobs, skipped


def _with_gaps_left(record: FileRecord, zero_is_missing: str) -> FileRecord:
    """A skipped file's record with the gaps its output still has (what a ``--check`` on
    a resumed batch must see: the run that wrote the output may have left gaps), or
    failed where the output cannot be read."""
    from .gaps import find_gaps

    output = Path(record.output)
    try:
        motion = _read(output, zero_is_missing)
    except (MocapfillError, OSError) as exc:
        # The record names the input; the reason names the output it could not read.
        problem = str(exc) if isinstance(exc, FormatError) else f"{output}: {exc}"
        return replace(record, status=FAILED,
                       reason=f"up to date, but its output cannot be read for --check "
                              f"({problem}); --force redoes it")
    return replace(record, gaps_left=len(find_gaps(motion)))


# ---------------------------------------------------------------- one file


def _write_in_place(motion, path: Path, read_as: tuple[int, int, int] | None = None
                    ) -> tuple[str, ...]:
    """Replace ``path`` atomically: write a sibling temp file with the same suffix (through
    ``formats.write``, itself atomic), rename it over; ``formats.atomic_output`` gives it
    the input's mode, owner and group. A symbolic link is followed: its target is replaced
    and the link kept (renaming over the link would have replaced it by a plain file and
    left the target unrepaired). With ``read_as`` (:func:`_state` when the file was read), a
    file changed since is left as it is: its new content would be lost under the repair of
    the old."""
    from . import formats

    given, path = path, _real(path)
    with formats.atomic_output(path, suffix=f".inplace{path.suffix}") as tmp:
        try:
            notes = formats.write(motion, tmp, final_path=path)
        except FormatError as exc:
            if exc.path != tmp:
                raise
            # It names the temporary file formats.write was given (a full disk while
            # writing it); the user knows the file they repair.
            raise FormatError(given, exc.problem, exit_code=exc.exit_code) from None
        if read_as is not None and _state(path) != read_as:
            raise FormatError(given, CHANGED_WHILE_REPAIRED + "; left as it is")
        return notes


# What a batch says of an input that changed between its reading and its output's writing
# (a file still being copied in, edited meanwhile).
CHANGED_WHILE_REPAIRED = "changed while it was repaired"


def _state(path: Path) -> tuple[int, int, int] | None:
    """(modification time, size, inode) of a file, or None where it cannot be read."""
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_mtime_ns, info.st_size, info.st_ino


def _not_newer_than_input(output: Path, source: Path) -> bool:
    """Where the input changed after it was read, give the output the input's time, so
    that it is not newer (:func:`_is_up_to_date`) and the next run redoes it; whether it
    did."""
    try:
        info = os.stat(source)
        os.utime(output, ns=(info.st_atime_ns, info.st_mtime_ns))
    except OSError:
        return False
    return True


def _temp_patterns(output: Path, token: str) -> list[str]:
    """Globs of the temporary files ``formats.write`` and ``_write_in_place`` leave beside
    ``output`` while writing it with the token ``token``; beside an AMC, also the skeleton
    copied for it (``acclaim.companions``), whose name the writer chooses."""
    from .formats import _RANDOM_CHARS, temp_prefix

    skeleton = []
    if output.suffix.lower() == ".amc":
        from .formats.acclaim import _asf_names

        # Any name, and those it takes beside this output cut short as temp_prefix cuts
        # a long one (".asf" itself may be cut: an output of 236 bytes).
        skeleton = [f".*.[aA][sS][fF].{glob.escape(token)}.*.tmp",
                    *(f"{glob.escape(temp_prefix(name, '.tmp', token))}*.tmp"
                      for name in _asf_names(output))]

    in_place = f".inplace{output.suffix}"
    outer = temp_prefix(output.name, in_place, token)
    # formats.write's own temporary for that one, named after it: cut short as
    # temp_prefix cuts it (a long name), its random part then matched by "?" (NUL here).
    inner = temp_prefix(f"{outer}{chr(0) * _RANDOM_CHARS}{in_place}", ".tmp", token)
    return [f"{glob.escape(temp_prefix(output.name, '.tmp', token))}*.tmp",
            f"{glob.escape(outer)}*{glob.escape(in_place)}",
            f"{glob.escape(inner).replace(chr(0), '?')}*.tmp", *skeleton]


def remove_temp_files(jobs: Iterable[FileJob]) -> None:
    """Delete temporary files of interrupted writes (a worker killed mid-write): those
    named with the job's token (``FileJob.temp_token``, else this process's), so not those
    of another batch or command writing the same output name in the same folder."""
    from .formats import temp_token

    for job in jobs:
        # In place, the write goes beside the symbolic link's target (_write_in_place).
        output = _real(job.output) if job.in_place else job.output
        for pattern in _temp_patterns(output, job.temp_token or temp_token()):
            for leftover in output.parent.glob(pattern):
                leftover.unlink(missing_ok=True)


def _read(path: Path, zero_is_missing: str):
    """``formats.read``, with ``zero_is_missing`` for the formats that take it."""
    from . import formats

    extra = ({"zero_is_missing": zero_is_missing}
             if path.suffix.lower() in formats.ZERO_FORMATS else {})
    return formats.read(path, **extra)


def _options_for(job: FileJob, rate: float):
    from . import formats
    from .pipeline import RepairOptions, frames_in_seconds, whole_frames_within

    options = job.options or RepairOptions()
    if job.max_gap_s is not None:
        frames = frames_in_seconds(job.max_gap_s, rate, job.input, f"{job.max_gap_s:g}s")
        options = replace(options, max_gap_frames=whole_frames_within(frames))
    if formats.same_skeleton_format(job.input, job.output):
        options = replace(options, space="channels")
    return options


def repair_file(job: FileJob) -> FileRecord:
    """Read, repair and write one file; every error becomes a ``failed`` record.

    Runs wherever the batch runs (this process, a local worker, a Dask worker). Ctrl-C
    (KeyboardInterrupt) and SystemExit propagate; ``formats.write`` removes its temporary
    file on the way out. Its temporary files are named with ``job.temp_token``.
    """
    from . import formats

    token = formats.TEMP_TOKEN.set(job.temp_token)
    try:
        return _repair_file(job)
    finally:
        formats.TEMP_TOKEN.reset(token)


def _repair_file(job: FileJob) -> FileRecord:
    from . import formats
    from .pipeline import repair
    from .report import reader_notes

    if _TERMINATING:        # a stopped worker's pool handed it the next file: none is started
        os._exit(128 + _TERMINATING[0])
    started = time.perf_counter()
    frames = 0

    read_notes: tuple[str, ...] = ()

    def record(status: str, reason: str = "", filled: int = 0, left: int = 0,
               notes: tuple[str, ...] = ()) -> FileRecord:
        return FileRecord(str(job.input), str(job.output), status, reason, filled, left,
                          round(time.perf_counter() - started, 4), frames,
                          read_notes + tuple(notes))

    problem = formats.skeleton_output_problem(job.output, job.input)
    if problem is not None:         # known before reading: no solve thrown away
        return record(FAILED, problem)
    try:
        read_as = _state(job.input)
        motion = _read(job.input, job.zero_is_missing)
        frames = motion.n_frames
        read_notes = reader_notes(motion)       # as `repair IN OUT` prints them
        try:
            result = repair(motion, _options_for(job, motion.rate))
        except NothingToRepair as exc:
            # An empty clip (one frame, no marker with a sample) is bad input, as
            # `mocapfill repair IN OUT` reports it (exit 123): failed, and nothing written.
            return record(FAILED, _problem(exc, job.input))
        # Made here, not by the planner, so Dask workers create the tree on their side;
        # after the repair, so a file that fails leaves no empty folder behind.
        job.output.parent.mkdir(parents=True, exist_ok=True)
        # The notes of the output's format (model outputs left out of a TRC, lengths
        # converted to mm) go in the record, as `repair IN OUT` prints them.
        if result.filled and job.in_place:
            notes = _write_in_place(result.motion, job.output, read_as)
        else:
            notes = () if job.in_place else formats.write(result.motion, job.output)
        if (not job.in_place and _state(job.input) != read_as
                and _not_newer_than_input(job.output, job.input)):
            # The output repairs what was read: written, and redone by the next run.
            notes += (f"{CHANGED_WHILE_REPAIRED}: the output repairs the content read, and "
                      "the next run redoes it",)
        if result.filled:
            return record(REPAIRED, _not_filled(result), result.filled, result.left, notes)
        reason = f"no gap filled ({_not_filled(result)})" if result.gaps else "no gaps"
        return record(UNCHANGED, reason, 0, result.left, notes)
    except FormatError as exc:
        # The record goes out under the input's name; an error about another file (the
        # output: "No space left on device" while writing it) keeps that file's name, which
        # was dropped, as if the input's disk were full.
        if exc.path is None or Path(exc.path) == job.input:
            return record(FAILED, exc.problem)
        return record(FAILED, str(exc))
    except MocapfillError as exc:
        return record(FAILED, _problem(exc, job.input))
    except OSError as exc:
        name = f"{exc.filename}: " if exc.filename is not None else ""
        return record(FAILED, f"{name}{exc.strerror or exc}")
    except Exception as exc:  # noqa: BLE001 - a bug on one file must not stop the other 2,599
        return record(FAILED, f"{type(exc).__name__}: {exc}")


def _problem(exc: Exception, path) -> str:
    """The error's message without the ``named(path)`` it starts with (the record names
    the file)."""
    message, prefix = str(exc), named(path)
    return message[len(prefix):] if message.startswith(prefix) else message


def _not_filled(result) -> str:
    """'2 left: end; 1 rejected: jump' — the gaps a repair did not fill, by status."""
    from collections import Counter

    from .pipeline import FILLED

    counts = Counter(o.status for o in result.gaps if o.status != FILLED)
    return "; ".join(f"{n} {status}" for status, n in sorted(counts.items()))


# ---------------------------------------------------------------- runners

Progress = Callable[[int, int, "FileRecord | None"], None]


def _single_threaded_worker(parent: int | None = None) -> None:
    """Initializer of a local worker process: BLAS variables (again, for anything that
    reads them late), signal handling, and a watch on the pool's process ``parent``."""
    import signal
    import threading

    os.environ.update(SINGLE_THREADED)
    # The parent owns Ctrl-C: it stops the workers itself (SIGTERM, below), so a terminal
    # Ctrl-C does not print one traceback per worker. The same for a terminal's hang-up,
    # which killed the workers mid-write (their temporaries left behind).
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "SIGHUP"):
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit_on_terminate)
    if parent is not None:
        threading.Thread(target=_watch_parent, args=(parent,), name="parent-watch",
                         daemon=True).start()


_PARENT_POLL = 0.5      # seconds between two looks at the parent
_PARENT_GRACE = 2.0     # seconds a worker orphaned mid-file has to unwind


def _watch_parent(parent: int) -> None:
    """Stop this worker once the pool's process is gone.

    A batch stopped by SIGTERM (``timeout``, a job scheduler's cancel), SIGKILL or the
    out-of-memory killer has no chance to stop its workers, and an idle worker waits on
    the pool's queue for ever: it holds that pipe's writing end itself, so no end of file
    comes (measured: a worker of ``timeout 2 mocapfill repair DIR -o OUT -j 2`` still
    asleep half a minute later, 58 MB, with the pool's resource tracker beside it). The
    worker is stopped as the pool would stop it (SIGTERM: a file being written loses its
    temporary), then ended if it has not left by itself.
    """
    import signal

    while os.getppid() == parent:
        time.sleep(_PARENT_POLL)
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(_PARENT_GRACE)
    os._exit(128 + signal.SIGTERM)


_TERMINATING: list[int] = []      # the signal that stops this worker process, once sent


def _exit_on_terminate(signum, frame) -> None:
    # SystemExit unwinds through formats.write, which deletes its temporary file. The
    # pool's worker loop catches it as the job's exception and would go on to the next
    # queued file (which was then written after Ctrl-C, unreported): repair_file exits
    # before starting another.
    # The exit is raised wherever the worker happens to be; what it leaves half-built (a
    # ZipFile in np.savez, an import's module lock) fails again in its __del__ or weakref
    # callback, and Python prints each as "Exception ignored in ..." with a traceback, on
    # the terminal of the user who pressed Ctrl-C. Those are silenced from here on.
    sys.unraisablehook = _ignore
    _TERMINATING.append(signum)
    raise SystemExit(128 + signum)


def _ignore(*_args) -> None:
    return None


@contextmanager
def temporary_environment(values: dict[str, str]):
    """Set environment variables for the duration of a block (child processes, solvers)."""
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _run_here(jobs: Sequence[FileJob], done: Callable[[FileRecord], None]) -> None:
    for job in jobs:
        done(repair_file(job))


def _stop_pool(executor, grace: float = 5.0) -> None:
    """Cancel what has not started, stop the workers (SIGTERM, then SIGKILL), wait."""
    # Taken before shutdown(), which forgets them. (Python 3.14 has terminate_workers().)
    processes = list((getattr(executor, "_processes", None) or {}).values())
    manager = getattr(executor, "_executor_manager_thread", None)
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    # A worker's death is read from its sentinel, not from Process.join: the pool's
    # manager thread joins the same processes, and whichever thread's waitpid comes
    # second gets ECHILD, which join() takes for "still running" until the first thread
    # records the exit code — on a loaded machine the worker then showed as alive after
    # this function returned.
    alive = {process.sentinel: process for process in processes}
    _drop_dead(alive, grace)
    for process in alive.values():
        process.kill()
    _drop_dead(alive, None)
    # The manager thread has seen them die (or will, now) and records their exit codes.
    if manager is not None:
        manager.join(timeout=grace)
    for process in processes:
        process.join(timeout=grace)


def _drop_dead(alive: dict, timeout: float | None) -> None:
    """Remove from ``alive`` (sentinel → process) the processes that end within ``timeout``."""
    from multiprocessing.connection import wait

    deadline = None if timeout is None else time.monotonic() + timeout
    while alive:
        left = None if deadline is None else max(deadline - time.monotonic(), 0.0)
        ready = wait(list(alive), left)
        if not ready:
            return
        for sentinel in ready:
            del alive[sentinel]


@contextmanager
def _hang_ups_ignored():
    """SIGHUP ignored while the pool's processes start (its resource tracker with its
    queues, its workers with the submits): they keep that across exec. A terminal's
    hang-up reaches every process of its group, and the tracker (which ignores SIGINT and
    SIGTERM only) died of it, was started again and printed a KeyError traceback per
    semaphore; the command stops the workers itself (see ``mocapfill._interrupt``)."""
    import signal

    try:
        previous = signal.signal(signal.SIGHUP, signal.SIG_IGN)
    except (AttributeError, ValueError):        # no SIGHUP (Windows), not the main thread
        previous = None
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGHUP, previous)


# Why a file is failed when its worker process died under it (and only then: see _run_pool).
WORKER_DIED = "worker process died (killed or out of memory)"


def _run_pool(jobs: Sequence[FileJob], workers: int,
              done: Callable[[FileRecord], None]) -> None:
    """Run ``jobs`` in local worker processes, calling ``done`` with each record.

    A worker that dies (SIGKILL, the out-of-memory killer) breaks the whole pool: every
    file not finished gets BrokenProcessPool, including those never started. Only a file
    that was running can be to blame, so a new pool takes the files that had not started,
    after the ones that had started and not finished (the suspects) are run again one at a
    time, each in a pool of its own: a suspect that dies alone is failed, the others
    (killed with the pool, or whose result was lost with it) are repaired. Each worker
    marks a file as started by creating a file named after its index in a folder of
    this function's; a creation is atomic, so a worker killed any time leaves it or not.
    """
    import shutil
    import tempfile

    started = tempfile.mkdtemp(prefix="mocapfill-started-")
    try:
        todo = list(enumerate(jobs))
        while todo:
            given = len(todo)
            unfinished = _pool_pass(todo, min(workers, len(todo)), done, started)
            if not unfinished:
                return
            marked = {int(name) for name in os.listdir(started)}
            suspects = [(i, job) for i, job in unfinished if i in marked]
            todo = [(i, job) for i, job in unfinished if i not in marked]
            # Their temporaries: a worker killed outright does not remove its own.
            remove_temp_files(job for _, job in suspects)
            for item in suspects:
                if _pool_pass([item], 1, done, started):
                    remove_temp_files([item[1]])
                    done(_lost(item[1], WORKER_DIED))
            if not suspects and len(unfinished) == given:
                # A pool that breaks before it starts any file (a worker that cannot even
                # start) would break again: the files are failed, not retried for ever.
                for _, job in todo:
                    done(_lost(job, WORKER_DIED))
                return
    finally:
        shutil.rmtree(started, ignore_errors=True)


def _repair_started(job: FileJob, mark: str) -> FileRecord:
    """``repair_file`` in a local worker, once ``mark`` records that it started."""
    os.close(os.open(mark, os.O_CREAT | os.O_WRONLY, 0o600))
    return repair_file(job)


def _pool_pass(items: Sequence[tuple[int, FileJob]], workers: int,
               done: Callable[[FileRecord], None], started: str) -> list[tuple[int, FileJob]]:
    """One pool over ``items`` (index, job); the items it lost when it broke, if it did."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    # spawn, not fork: a fresh interpreter reads the BLAS variables when it loads numpy
    # (a forked child inherits the parent's BLAS already set up for all cores). The
    # variables are in the environment the workers are started with — they start during
    # the submits — because a spawned child re-imports the caller's __main__, which may
    # import numpy before any initializer runs.
    with _hang_ups_ignored():
        executor = ProcessPoolExecutor(max_workers=workers,
                                       mp_context=multiprocessing.get_context("spawn"),
                                       initializer=_single_threaded_worker,
                                       initargs=(os.getpid(),))
    futures: dict = {}
    reported: set = set()
    lost: list[tuple[int, FileJob]] = []
    try:
        with temporary_environment(SINGLE_THREADED), _hang_ups_ignored():
            for index, job in items:
                mark = os.path.join(started, str(index))
                futures[executor.submit(_repair_started, job, mark)] = (index, job)
        for future in as_completed(futures):
            reported.add(future)
            try:
                record = future.result()
            except BrokenProcessPool:
                lost.append(futures[future])
                continue
            except Exception as exc:  # noqa: BLE001 - e.g. a result that cannot be sent back
                record = _lost(futures[future][1], f"{type(exc).__name__}: {exc}")
            done(record)
    except BaseException:
        _stop_pool(executor)
        # Files finished before the stop whose results were not handed out yet (the
        # batch was paused, then Ctrl-C): their outputs are written, so they are reported.
        for future in futures:
            if (future not in reported and future.done() and not future.cancelled()
                    and future.exception() is None):
                done(future.result())
        raise
    executor.shutdown(wait=True)
    return sorted(lost, key=lambda item: item[0])


def _lost(job: FileJob, reason: str) -> FileRecord:
    return FileRecord(str(job.input), str(job.output), FAILED, reason)


def _run_dask(jobs: Sequence[FileJob], address: str,
              done: Callable[[FileRecord], None]) -> None:
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise ParameterError(DASK_MISSING) from None
    try:
        client = Client(address, timeout="20s")
    except (OSError, TimeoutError) as exc:
        raise ParameterError(f"cannot reach the Dask scheduler at {address} ({exc})") from None
    except ValueError as exc:       # Dask parses it first: 'garbage', '', no port
        raise ParameterError(f"--scheduler: not a Dask scheduler address {address!r} ({exc}); "
                             "give one such as tcp://host:8786") from None
    # Workers see the files through a shared file system: send absolute paths (the
    # workers' working folder is not ours), never the data.
    remote = [replace(job, input=job.input.absolute(), output=job.output.absolute())
              for job in jobs]
    futures = []
    try:
        futures = client.map(repair_file, remote, pure=False)
        index = {future.key: job for future, job in zip(futures, jobs)}
        for future in as_completed(futures):
            job = index[future.key]
            try:
                record = future.result()
            except Exception as exc:  # noqa: BLE001 - KilledWorker, no mocapfill there, ...
                record = _lost(job, f"Dask: {type(exc).__name__}: {exc}")
            done(replace(record, input=str(job.input), output=str(job.output)))
    except BaseException:
        client.cancel(futures)
        raise
    finally:
        client.close()


# ---------------------------------------------------------------- the public entry point


def repair_many(paths: Iterable[str | os.PathLike] | str | os.PathLike,
                out_dir: str | os.PathLike | None = None, *, options=None,
                jobs: int | None = None, scheduler: str | None = None,
                in_place: bool = False, force: bool = False, zero_is_missing: str = "auto",
                max_gap_s: float | None = None, suffix: str | None = None,
                progress: Progress | None = None, check: bool = False) -> BatchReport:
    """Repair every motion file under ``paths`` into ``out_dir`` (or in place).

    Parameters
    ----------
    paths
        Files, folders (walked recursively for known suffixes) and globs.
    out_dir
        Output folder; the input tree is mirrored under it (relative to each folder given,
        a glob's fixed leading folder, or just the name of a file given directly).
    options
        ``RepairOptions`` applied to every file (default: ``RepairOptions()``).
    jobs
        Local worker processes (default: all cores), each with single-threaded BLAS;
        1 runs in this process. Not with ``scheduler``.
    scheduler
        Address of a ``dask.distributed`` scheduler (``"tcp://host:8786"``); the workers
        read and write the files, which they must see at the same paths.
    in_place
        Replace each input atomically instead of writing to ``out_dir``.
    force
        Redo files whose output is newer than their input (skipped otherwise).
    zero_is_missing
        C3D, TRC and CSV: "auto", "on" or "off" (see ``mocapfill.formats.c3d`` and
        ``mocapfill.formats._text.read_zero_gaps``).
    max_gap_s
        Leave gaps longer than this many seconds, converted with each file's own rate
        (overrides ``options.max_gap_frames``).
    suffix
        Output format for every file (".c3d", ".csv", ...); default: the input's own.
    progress
        Called as ``progress(done, total, record)``: once with ``(0, total, None)`` before
        the first file, then after each file (skipped files are not counted in ``total``).
    check
        Count the gaps left in skipped outputs too (``--check``): each is read, and its
        record's ``gaps_left`` is the gaps it still has; one that cannot be read is a
        failure. Without it a skipped output counts no gap.

    Returns
    -------
    BatchReport
        One record per file, sorted by input path; ``exit_code()`` is 0 or 123.

    Raises
    ------
    TypeError
        ``options`` that is not a ``RepairOptions`` (a dict of its fields).
    ParameterError
        Nothing safe to plan (see ``plan``), bad ``jobs`` (or any with ``scheduler``), Dask
        missing or unreachable, a malformed scheduler address.
    BatchInterrupted
        Ctrl-C; carries the report of the files finished so far.
    """
    started = time.perf_counter()
    if options is not None:
        # Loaded already where the caller made a RepairOptions. Refused once here: a dict
        # ({'method': 'linear'}) failed every file alone.
        from .pipeline import RepairOptions

        if not isinstance(options, RepairOptions):
            hint = (": mocapfill.RepairOptions(**options) makes one of a dict"
                    if isinstance(options, dict) else "")
            raise TypeError(f"repair_many() takes a RepairOptions as options, got "
                            f"{type(options).__name__}{hint}")
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    if jobs is not None and jobs < 1:
        raise ParameterError(f"--jobs must be ≥ 1, got {jobs}")
    if jobs is not None and scheduler is not None:
        raise ParameterError("--jobs does not apply with --scheduler: the cluster's workers "
                             "(dask worker --nworkers) repair the files")
    todo, skipped = plan(paths, out_dir, options=options, in_place=in_place, force=force,
                         zero_is_missing=zero_is_missing, max_gap_s=max_gap_s, suffix=suffix)
    # This batch's own, wherever its files are written (workers, Dask, other machines).
    token = secrets.token_hex(4)
    todo = [replace(job, temp_token=token) for job in todo]
    if check:
        skipped = [_with_gaps_left(record, zero_is_missing) for record in skipped]
    finished: list[FileRecord] = []
    report = BatchReport()

    def done(record: FileRecord) -> None:
        finished.append(record)
        if progress is not None:
            progress(len(finished), len(todo), record)

    def collect() -> BatchReport:
        report.records = sorted(skipped + finished, key=lambda r: r.input)
        report.seconds = time.perf_counter() - started
        return report

    if progress is not None:
        progress(0, len(todo), None)
    workers = min(jobs or os.cpu_count() or 1, len(todo))
    try:
        if scheduler is not None:
            _run_dask(todo, scheduler, done)
        elif workers <= 1:
            _run_here(todo, done)
        else:
            _run_pool(todo, workers, done)
    except KeyboardInterrupt:
        finished_inputs = {r.input for r in finished}
        remove_temp_files(j for j in todo if str(j.input) not in finished_inputs)
        raise BatchInterrupted(collect()) from None
    return collect()
