"""The command line. The only module that imports click; it parses, calls the core, reports.

Exit codes: 0 ok; 1 ``--check`` found gaps left unfilled; 2 usage (bad option, parameter
out of range, missing input, unknown file type); 123 a file could not be read, repaired or
written (one line on stderr names it); 130 interrupted; 143 terminated (SIGTERM); 129 hung
up (SIGHUP). The last three end the process by that signal (``mocapfill._interrupt``).
Heavy imports (numpy, scipy) happen inside the commands so ``mocapfill --help`` is quick.
"""
from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import click

from ._blas import one_thread_by_default
from ._interrupt import EXIT_INTERRUPTED, die_interrupted, say_interrupted, stop_on_signals
from ._interrupt import reason as stop_reason
from ._memory import tune_heap

# One BLAS thread unless the user chose otherwise (set OPENBLAS_NUM_THREADS etc. to
# override), and the C heap's thresholds for numpy's many arrays of a few MB (set glibc's
# MALLOC_* variables to override). This runs before numpy is first imported by any command.
one_thread_by_default()
tune_heap()

EXIT_CHECK_FAILED = 1
EXIT_USAGE = 2
EXIT_FAILED = 123
# An exception mocapfill does not expect (a bug): sysexits.h's EX_SOFTWARE. Python's own
# exit code for it, 1, is --check's "gaps left": a script checking a batch read a crash
# as unfilled gaps.
EXIT_INTERNAL = 70

METHOD_NAMES = ("trnn", "trnn-paper", "trnn-lowrank", "linear", "spline", "pchip", "pca",
                "gaussian", "svt", "tsmc", "ialm", "psvt")


def _fail(message: str, code: int) -> None:
    # File content quoted in a message may hold undecodable bytes (surrogate escapes) or
    # newlines; the error stays one printable line whatever the file contained.
    text = " ".join(message.split())
    text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    try:
        click.echo(f"mocapfill: error: {text}", err=True)
    except OSError:         # no stderr left (a terminal hung up): the exit code stands
        pass
    sys.exit(code)


class _Group(click.Group):
    """Turns mocapfill's typed errors into one line and an exit code, never a traceback."""

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True,
             **extra):
        # click prints usage errors as a usage block plus an error line; ours are one line
        # like every other error (the usage stays one --help away).
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, **extra)
        except click.UsageError as exc:
            where = f" (see '{exc.ctx.command_path} --help')" if exc.ctx is not None else ""
            _fail(f"{exc.format_message()}{where}", EXIT_USAGE)
        except click.ClickException as exc:
            _fail(exc.format_message(), exc.exit_code)
        except click.Abort:
            _fail(stop_reason(), EXIT_INTERRUPTED)
        sys.exit(code if isinstance(code, int) else 0)

    def invoke(self, ctx: click.Context):
        import warnings

        from .errors import FormatError, MocapfillError, ParameterError

        try:
            with warnings.catch_warnings():
                # numpy's floating-point RuntimeWarnings (overflow on corrupt values, ...)
                # are not messages for users; the outcome is reported as an error or not.
                warnings.simplefilter("ignore", RuntimeWarning)
                return super().invoke(ctx)
        except ParameterError as exc:
            _fail(str(exc), EXIT_USAGE)
        except FormatError as exc:
            _fail(str(exc), exc.exit_code)
        except MocapfillError as exc:
            _fail(str(exc), EXIT_FAILED)
        except KeyboardInterrupt:
            _fail(stop_reason(), EXIT_INTERRUPTED)
        except OSError as exc:  # disk full, permission denied, ...
            name = f"{exc.filename}: " if exc.filename else ""
            _fail(f"{name}{exc.strerror or exc}", EXIT_FAILED)
        except MemoryError:
            # (A file declaring more than fits is named as it is read: formats.read.) The
            # command's input is named, as a batch names the file it failed on.
            from .errors import named

            _fail(f"{named(ctx.meta.get(_INPUT))}not enough memory to finish the command",
                  EXIT_FAILED)
        except (click.ClickException, click.exceptions.Exit, click.Abort):
            raise
        except Exception as exc:
            # A bug: its traceback is what a report of it needs, so it is printed, then
            # one line saying so, with an exit code of its own.
            import traceback

            traceback.print_exc()
            _fail(f"internal error (a bug in mocapfill: please report it with the "
                  f"traceback above): {type(exc).__name__}: {exc}", EXIT_INTERNAL)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="mocapfill")
def main() -> None:
    """Repair gaps in motion-capture marker data (C3D, TRC, CSV, BVH, ASF/AMC).

    Exit codes: 0 ok, 1 --check found unfilled gaps, 2 usage error, 123 a file failed,
    130 interrupted, 143 terminated (SIGTERM), 129 hung up (SIGHUP), 70 internal error.
    """


# ---------------------------------------------------------------- shared option helpers


def _refuse_folder_name(value, param=None, ctx=None, param_hint=None) -> None:
    """A file to write named with a trailing '/', or not named at all (``''``), is a usage
    error (exit 2): pathlib drops the slash, so ``-o plots/`` used to write a file called
    ``plots``, and reads ``''`` as ``.``, which was reported as "unknown file type"."""
    if value == "":
        raise click.BadParameter("the path is empty: name a file to write", ctx=ctx,
                                 param=param, param_hint=param_hint)
    if isinstance(value, str) and value.endswith(("/", os.sep)):
        raise click.BadParameter(f"{value!r} ends with '{value[-1]}': name a file to write, "
                                 "not a folder", ctx=ctx, param=param, param_hint=param_hint)


class _OutputFile(click.Path):
    """A file the command writes (see :func:`_refuse_folder_name`). An existing one is
    replaced, whatever its permissions (as :class:`_InputFile`, not checked for reading)."""

    def __init__(self) -> None:
        super().__init__(path_type=Path, readable=False)

    def convert(self, value, param, ctx):
        _refuse_folder_name(value, param, ctx)
        return super().convert(value, param, ctx)


class _InputFile(click.Path):
    """A file the command reads (repair's paths: files, folders and OUT). Not checked for
    read permission: click's check made an unreadable IN a usage error (exit 2, "Path 'x'
    is not readable"), where the reader reports it as it does any file it cannot read,
    one line naming it and exit 123 (in a batch, a failed file)."""

    def __init__(self, path_type=Path) -> None:
        super().__init__(path_type=path_type, readable=False)


class _OutputFolder(click.Path):
    """A folder the command writes into; an empty name (pathlib's ``.``) is refused."""

    def __init__(self) -> None:
        super().__init__(path_type=Path, file_okay=False)

    def convert(self, value, param, ctx):
        if value == "":
            self.fail("the path is empty: name a folder to write into", param, ctx)
        return super().convert(value, param, ctx)


_zero_option = click.option(
    "--zero-is-missing", type=click.Choice(["auto", "on", "off"]), default="auto",
    show_default=True,
    help="C3D, TRC and CSV: treat samples at exactly x = y = z = 0 as missing. auto = on "
         "for Qualisys C3D files, which store gaps that way, off for other files.")


# The key under which a command's context records its input (the first file it reads: IN,
# score's TRUTH), which an error without a file of its own names (running out of memory).
_INPUT = "mocapfill.input"


def _read(path: Path, zero_is_missing: str = "auto", notes: list[str] | None = None):
    """Read IN; a note that ``--zero-is-missing on`` cannot apply to its format is printed
    now, or added to ``notes`` (a command that prints its notes once it has succeeded)."""
    from . import formats

    click.get_current_context().meta.setdefault(_INPUT, path)

    if path.suffix.lower() in formats.ZERO_FORMATS:
        return formats.read(path, zero_is_missing=zero_is_missing)
    if zero_is_missing == "on":     # asked for explicitly: say it cannot apply here
        note = ("--zero-is-missing on applies to C3D, TRC and CSV files only; samples at "
                "exactly (0, 0, 0) in this file are read as data")
        if notes is None:
            click.echo(f"mocapfill: note: {path}: {note}", err=True)
        else:
            notes.append(note)
    return formats.read(path)


def _parse_max_gap(text: str | None, rate: float, path: Path | None = None) -> int | None:
    """'40' frames or '0.5s' seconds -> frames (None = unlimited); seconds need a rate."""
    from .errors import ParameterError
    from .pipeline import frames_in_seconds, whole_frames_within

    if text is None:
        return None
    raw = text.strip().lower()
    try:
        if raw.endswith("s"):
            seconds = float(raw[:-1])
        else:
            frames = float(raw)
            if math.isfinite(frames) and frames != int(frames):
                raise ValueError
    except ValueError:
        raise ParameterError(f"--max-gap must be frames (40) or seconds (0.5s), got {text!r}") \
            from None
    if raw.endswith("s"):       # out of the try: the rate's error is a ValueError too
        frames = frames_in_seconds(seconds, rate, path, text)
    if not math.isfinite(frames) or frames < 0:
        raise ParameterError(f"--max-gap must be a finite number ≥ 0 (at this file's rate), "
                             f"got {text!r}")
    return whole_frames_within(frames)


def _summary_line(result, in_path: Path, out_path: Path) -> str:
    from collections import Counter

    left = Counter(o.status for o in result.gaps if o.status != "filled")
    detail = ", ".join(f"{n} {status.split(': ', 1)[-1]}" for status, n in sorted(left.items()))
    return (f"{in_path} -> {out_path}: {result.filled} gaps filled, {result.left} left"
            f"{f' ({detail})' if detail else ''} in {result.seconds:.2f} s")


# ---------------------------------------------------------------- repair


@main.command()
@click.argument("paths", nargs=-1, required=True, metavar="IN... [OUT]",
              type=_InputFile(path_type=None))
@click.option("-o", "--out-dir", type=_OutputFolder(), default=None,
              help="Batch: repair every IN (files, folders walked recursively for known "
                   "suffixes, quoted globs) into this folder, mirroring the input tree. "
                   "Outputs newer than their input are skipped, so a rerun resumes.")
@click.option("--in-place", is_flag=True,
              help="Batch: replace each IN with its repair (atomically) instead of -o.")
@click.option("--force", is_flag=True,
              help="Batch: redo files whose output is newer than their input.")
@click.option("-j", "--jobs", type=int, default=None,
              help="Batch: worker processes on this machine (each with single-threaded "
                   "BLAS). Default: all cores; 1 runs in this process. Not with "
                   "--scheduler.")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="Batch: run on a dask.distributed cluster (tcp://host:8786) whose workers "
                   "see the same files (pip install 'dask[distributed]').")
@click.option("--report", "report_path", type=_OutputFile(), default=None,
              help="Batch: write FILE.json with every file's status, reason, gaps filled "
                   "and left, frames and seconds.")
@click.option("--suffix", default=None, metavar=".c3d",
              help="Batch: output format (.c3d, .csv, .npz, ...). Default: each input's own.")
@click.option("--method", type=click.Choice(METHOD_NAMES), default="trnn", show_default=True,
              help="Completion method. trnn: our converged TrNN (default); trnn-paper: the "
                   "published algorithm and settings; trnn-lowrank: our TrNN alone, without "
                   "the validated per-gap blend (faster); linear/spline/pchip: interpolation "
                   "along time; pca: Gløersen & Federolf 2016; gaussian: the EM conditional "
                   "fill of a normal law over the frames; svt, tsmc, ialm, psvt: the paper's "
                   "comparison methods.")
@click.option("--rank", type=int, default=None,
              help="Truncated rank r (number of singular values not penalised). Default: "
                   "min(15, estimated rank) (trnn, trnn-lowrank, trnn-paper, gaussian) / 10 "
                   "(psvt).")
@click.option("--lam", type=float, default=None,
              help="λ, weight of the sparse-outlier term (unitless; data are scaled to unit "
                   "RMS before solving). Default 100/sqrt(max(m, n)) (trnn, trnn-lowrank, "
                   "trnn-paper, tsmc) / 1/sqrt(max(m, n)) (ialm, psvt).")
@click.option("--mu", type=float, default=None,
              help="μ, weight of the temporal smoothness term (unitless). Default 100 "
                   "(trnn, trnn-lowrank, trnn-paper, tsmc).")
@click.option("--rho", type=float, default=None,
              help="ρ > 1, growth factor of the penalty η per iteration. Default 1.2 "
                   "(trnn, trnn-lowrank, tsmc) / 1.4 (trnn-paper) / 1.5 (ialm) / 1.1 (psvt).")
@click.option("--eta0", type=float, default=None,
              help="η₀ > 0, initial penalty. Default 0.05 (trnn, trnn-lowrank) / 1e-5 "
                   "(trnn-paper) / 0.01 (tsmc).")
@click.option("--tol", type=float, default=None,
              help="ε, relative stopping tolerance. Default 1e-4 (trnn, trnn-lowrank, "
                   "trnn-paper, gaussian, svt) / 1e-5 (tsmc) / 1e-7 (ialm, psvt).")
@click.option("--max-iter", type=int, default=None,
              help="Iteration cap. Default 500 (trnn, trnn-lowrank, trnn-paper, tsmc) / "
                   "1000 (svt, ialm, psvt) / 60 (gaussian).")
@click.option("--max-gap", default=None, metavar="FRAMES|SECONDSs",
              help="Leave gaps longer than this missing (and report them): frames (40) or "
                   "seconds (0.5s, at the file's frame rate; refused for a file that states "
                   "none, an AMC). Default: fill every length.")
@click.option("--ends", type=click.Choice(["leave", "hold", "extrapolate"]), default="leave",
              show_default=True,
              help="Gaps touching the first or last frame: leave them missing, hold the "
                   "nearest observed value, or extrapolate (clamped to the marker's observed "
                   "range ± 10%).")
@click.option("--markers", multiple=True, metavar="NAME|GLOB",
              help="Fill only these markers (repeatable; shell globs like 'L*'). All others "
                   "still serve as evidence. Patterns that together match no marker are an "
                   "error (exit 2).")
@click.option("--exclude", multiple=True, metavar="NAME|GLOB",
              help="Never fill these markers (repeatable; globs). Patterns that together "
                   "match no marker are an error, as for --markers.")
@click.option("--gaps-report", type=_OutputFile(), default=None,
              help="One file: write one row per gap (marker, first/last frame, length in "
                   "frames and seconds, method, status) to FILE.csv or FILE.json.")
@click.option("--max-jump", "max_jump_mm", type=float, default=None, metavar="MM",
              help="Reject (leave missing, report) a fill whose first sample at a gap end "
                   "misses the constant-velocity prediction from the observed side by more "
                   "than MM millimetres (file units where the clip's unit is not a known "
                   "length, a BVH's). Default: the larger of 40 mm and 5x the marker's "
                   "largest observed frame-to-frame acceleration (plus its largest step "
                   "where one observed sample stands alone); 0 disables the check.")
@click.option("--check", is_flag=True,
              help="Exit with code 1 when any gap is left unfilled (in any file; a "
                   "batch's skipped outputs are read to count theirs).")
@_zero_option
def repair(paths: tuple[Path, ...], out_dir, in_place, force, jobs, scheduler, report_path,
           suffix, method: str, rank, lam, mu, rho, eta0, tol, max_iter, max_gap, ends, markers,
           exclude, max_jump_mm, gaps_report, check, zero_is_missing) -> None:
    """Fill the gaps of IN and write OUT; only missing samples change.

    The output format follows OUT's suffix; a same-format repair patches a copy of IN
    (C3D: only the four words of each filled sample change, residual word 0 marks them).
    IN is never modified (but by --in-place); OUT is written atomically.

    Batch: `mocapfill repair IN... -o OUTDIR` repairs files, folders and globs on all
    cores (-j) or a Dask cluster (--scheduler), mirrors the tree under OUTDIR, keeps going
    past failed files, prints one summary line and exits 123 if any file failed.
    """
    from .pipeline import RepairOptions

    raw, paths = paths, tuple(Path(p) for p in paths)
    solver_options = _solver_options(rank=rank, lam=lam, mu=mu, rho=rho, eta0=eta0, tol=tol,
                                     max_iter=max_iter)

    def options(max_gap_frames: int | None, space: str = "positions") -> RepairOptions:
        return RepairOptions(method=method, solver_options=solver_options,
                             max_gap_frames=max_gap_frames, ends=ends,
                             markers=tuple(markers), exclude=tuple(exclude),
                             max_jump_mm=max_jump_mm, space=space)

    if out_dir is not None or in_place:
        frames, seconds = _batch_max_gap(max_gap)
        _repair_batch(paths, options(frames), max_gap_s=seconds, out_dir=out_dir,
                      in_place=in_place, force=force, jobs=jobs, scheduler=scheduler,
                      report_path=report_path, suffix=suffix, gaps_report=gaps_report,
                      check=check, zero_is_missing=zero_is_missing)
        return
    _refuse_batch_options(paths, force=force, jobs=jobs, scheduler=scheduler,
                          report=report_path, suffix=suffix)
    _refuse_folder_name(raw[-1], param_hint="'OUT'")
    in_path, out_path = paths
    from . import formats
    from .pipeline import repair as run_repair

    if in_path.is_dir():
        from .errors import FormatError

        raise FormatError(in_path, "is a folder; to repair the files in it give -o OUTDIR "
                          "(or --in-place): mocapfill repair FOLDER -o OUTDIR", exit_code=2)
    formats.check_output(out_path, in_path)
    if gaps_report is not None:
        _check_gaps_report(gaps_report, in_path, out_path)
    notes: list[str] = []
    motion = _read(in_path, zero_is_missing, notes)
    # A BVH/AMC written back to its own format is completed in joint-channel space.
    space = "channels" if formats.same_skeleton_format(in_path, out_path) else "positions"
    from .pipeline import reporting_windows

    with _WindowProgress() as progress, reporting_windows(progress):
        result = run_repair(motion, options(_parse_max_gap(max_gap, motion.rate, in_path), space))
    from .report import reader_notes

    # What the reader worked around (a cut last row: the user should know), shown with
    # the writer's notes once OUT is written: a repair that fails shows its error alone.
    # The gaps report is written with OUT (see _write_noting): one failing leaves neither.
    beside = None
    if gaps_report is not None:
        from .report import gaps_report_text

        beside = (gaps_report, gaps_report_text(result, gaps_report))
    _write_noting(result.motion, out_path, read=(in_path, (*notes, *reader_notes(motion))),
                  beside=beside)
    click.echo(_summary_line(result, in_path, out_path), err=True)
    if check and result.left:
        sys.exit(EXIT_CHECK_FAILED)


def _check_gaps_report(report: Path, in_path: Path, out_path: Path) -> None:
    """Before any work: a .csv/.json name in an existing folder, neither IN nor OUT."""
    from .errors import ParameterError

    if report.suffix.lower() not in (".csv", ".json"):
        raise ParameterError(f"--gaps-report must name a .csv or .json file, got {report}")
    folder = report.parent if str(report.parent) else Path(".")
    if not folder.is_dir():
        raise ParameterError(f"--gaps-report {report}: folder {folder} does not exist")
    if report.is_dir():
        raise ParameterError(f"--gaps-report {report} is a folder; name a .csv or .json file")
    for other, role in ((in_path, "the input"), (out_path, "the output")):
        # realpath, not Path.resolve(), which raises on a link loop (before Python 3.13).
        if os.path.realpath(report) == os.path.realpath(other) or (
                report.exists() and other.exists() and os.path.samefile(report, other)):
            raise ParameterError(f"--gaps-report {report} is {role} file")


def _refuse_batch_options(paths, **batch_only) -> None:
    from .errors import ParameterError

    given = [f"--{name}" for name, value in batch_only.items() if value not in (None, False)]
    if given:
        verb = "applies" if len(given) == 1 else "apply"
        raise ParameterError(f"{', '.join(given)} {verb} to batches: add -o OUTDIR or "
                             "--in-place")
    if len(paths) != 2:
        raise ParameterError(f"got {len(paths)} path(s): give IN OUT for one file, or "
                             "IN... -o OUTDIR (or --in-place) for a batch")


def _batch_max_gap(text: str | None) -> tuple[int | None, float | None]:
    """--max-gap for a batch: frames apply as they are; seconds convert per file (rates
    differ between files), so they travel as seconds."""
    if text is None:
        return None, None
    frames = _parse_max_gap(text, 1.0)  # validates; exact when given in frames
    if text.strip().lower().endswith("s"):
        return None, float(text.strip()[:-1])
    return frames, None


def _stderr_is_a_terminal() -> bool:
    # sys.stderr is None where the command was started with it closed (``2>&-``).
    return sys.stderr is not None and sys.stderr.isatty()


class _WindowProgress:
    """The progress bar of one long clip's windows (clips over 12,000 frames are solved in
    windows; a 30-minute clip takes minutes): stderr, only when it is a terminal."""

    def __init__(self) -> None:
        self.bar = None

    def __enter__(self) -> _WindowProgress:
        return self

    def __call__(self, done: int, total: int) -> None:
        if self.bar is None and _stderr_is_a_terminal():
            self.bar = click.progressbar(length=total, label="solving windows",
                                         file=sys.stderr, show_pos=True, show_eta=True)
            self.bar.__enter__()
        if self.bar is not None:
            self.bar.update(done - self.bar.pos)

    def __exit__(self, *exc) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


class _BatchProgress:
    """The progress bar of a batch: stderr, and only when stderr is a terminal (click's
    default is stdout, and off a terminal it would print its label once)."""

    def __init__(self) -> None:
        self.bar = None
        self.started = 0.0

    def __call__(self, done: int, total: int, record) -> None:
        import time

        if record is None:
            if _stderr_is_a_terminal() and total:
                self.started = time.monotonic()
                self.bar = click.progressbar(length=total, label="repairing", file=sys.stderr,
                                             show_pos=True, show_eta=True,
                                             item_show_func=self._rate)
                self.bar.__enter__()
        elif self.bar is not None:
            self.bar.update(1, record)

    def _rate(self, record) -> str | None:
        import time

        elapsed = time.monotonic() - self.started
        if record is None or self.bar is None or elapsed <= 0:
            return None
        return f"{(self.bar.pos + 1) / elapsed:.1f} files/s"

    def close(self) -> None:
        if self.bar is not None:
            self.bar.__exit__(None, None, None)
            self.bar = None


def _repair_batch(paths, options, *, max_gap_s, out_dir, in_place, force, jobs, scheduler,
                  report_path, suffix, gaps_report, check, zero_is_missing) -> None:
    from .batch import BatchInterrupted, repair_many
    from .errors import ParameterError

    if gaps_report is not None:
        raise ParameterError("--gaps-report is for one file; a batch writes --report FILE.json")
    # The output folder the batch is about to create may hold the report (-o out --report
    # out/batch.json); it is made for the report if no file's output made it.
    in_out_dir = (report_path is not None and out_dir is not None
                  and os.path.abspath(report_path.parent) == os.path.abspath(out_dir)
                  and not out_dir.exists())
    if report_path is not None and (report_path.suffix.lower() != ".json"
                                    or not (report_path.parent.is_dir() or in_out_dir)
                                    or report_path.is_dir()):
        # Checked now, not after hours of repairs.
        raise ParameterError(f"--report must name a .json file in an existing folder (or "
                             f"in the -o folder), got {report_path}")
    if report_path is not None and out_dir is not None and Path(
            os.path.abspath(out_dir)).is_relative_to(os.path.abspath(report_path)):
        # The batch makes that folder: the report's write failed after every repair.
        raise ParameterError(f"--report {report_path} is where the -o folder {out_dir} "
                             "goes; name a .json file beside it or in it")
    progress = _BatchProgress()
    try:
        report = repair_many(paths, out_dir, options=options, jobs=jobs, scheduler=scheduler,
                             in_place=in_place, force=force, zero_is_missing=zero_is_missing,
                             max_gap_s=max_gap_s, suffix=suffix, progress=progress,
                             check=check)
    except BatchInterrupted as exc:
        progress.close()
        _finish_batch(exc.report, report_path)
        _fail(stop_reason(), EXIT_INTERRUPTED)
    finally:
        progress.close()
    _finish_batch(report, report_path)
    code = report.exit_code(check)
    if code:
        sys.exit(code)


def _finish_batch(report, report_path: Path | None) -> None:
    """Failures one line each, the JSON report, then the summary line; all on stderr."""
    for record in report.failures:
        # The reason may quote file content: keep it one printable line, like _fail's.
        line = " ".join(f"{record.input}: {record.reason}".split())
        click.echo(f"mocapfill: error: {line.encode('utf-8', 'backslashreplace').decode()}",
                   err=True)
    if report_path is not None:
        try:
            # In the -o folder (checked before the batch): made here if no output made it.
            report_path.parent.mkdir(parents=True, exist_ok=True)
            report.write_json(report_path)
        except BaseException:
            # The batch's outcome is not lost with its report (a full disk): the summary
            # line comes before the error about the report.
            click.echo(report.summary(), err=True)
            raise
    click.echo(report.summary(), err=True)


def _solver_options(**values) -> dict:
    from .pipeline import check_solver_options

    options = {k: v for k, v in values.items() if v is not None}   # finite: RepairOptions
    check_solver_options(options)       # before reading any file
    return options


# ---------------------------------------------------------------- simulate


@main.command()
@click.argument("in_path", metavar="IN", type=_InputFile())
@click.argument("out_path", metavar="OUT", type=_OutputFile())
@click.option("--mr", type=float, default=None,
              help="Random missing: fraction in [0, 1) of the markers removed in every frame "
                   "(among those seen there, never all of them).")
@click.option("--ml", type=int, default=None,
              help="Continuous missing: number of consecutive frames removed from each of "
                   "--markers random markers (new interior gaps: never touching the clip "
                   "ends or the clip's own gaps).")
@click.option("--markers", "n_markers", type=int, default=None,
              help="Number of markers hit by --ml (default 10); --mr takes no --markers.")
@click.option("--seed", type=int, default=None,
              help="Random seed; the same seed gives the same gaps.")
@_zero_option
def simulate(in_path: Path, out_path: Path, mr, ml, n_markers, seed, zero_is_missing) -> None:
    """Add gaps to IN with the paper's protocols (on top of its own gaps), write OUT."""
    from . import formats
    from .gaps import (
        channel_simulation_candidates,
        simulate_channel_gaps,
        simulate_gaps,
        simulation_candidates,
    )

    if n_markers is not None and mr is not None and ml is None:
        from .errors import ParameterError

        # --mr removes a fraction of every frame's markers: a count would be ignored.
        raise ParameterError("--markers applies to --ml (continuous missing), not --mr")
    n_markers = 10 if n_markers is None else n_markers
    formats.check_output(out_path, in_path)
    notes: list[str] = []       # shown once OUT is written (a failure prints its error alone)
    motion = _read(in_path, zero_is_missing, notes)
    # A skeleton clip written back to its own format loses joint channels (nan cells);
    # otherwise the protocols remove marker (or joint position) samples.
    channels = formats.same_skeleton_format(in_path, out_path)
    simulate = simulate_channel_gaps if channels else simulate_gaps
    gapped = simulate(motion, mr=mr, ml=ml, markers=n_markers if ml is not None else None,
                      seed=seed)
    if ml is not None:
        # --ml hits at most every candidate; say so rather than run fewer than asked quietly.
        candidates = (channel_simulation_candidates if channels
                      else simulation_candidates)
        hittable = candidates(motion, ml).size
        if n_markers > hittable:
            kind = "joints with channels" if channels else "markers with data"
            # (the run and a frame each side seen: a new gap, never one the clip had)
            room = ("" if hittable == candidates(motion).size else
                    f" and {ml + 2} frames seen in a row")
            notes.append(f"--markers {n_markers} but the clip has {hittable} {kind}{room}; "
                         f"--ml hit all {hittable}")
    _write_noting(gapped, out_path, read=(in_path, tuple(notes)))
    removed = int((motion.observed & ~gapped.observed).sum())
    # In channel space the protocols remove joints' channels, and every joint those
    # channels move loses its position: the count of position samples (what info and
    # repair count) is then larger than the joint samples hit (--ml 30 --markers 5: 150).
    hit = (f" (joint positions; the channels of {_joint_samples_removed(motion, gapped)} "
           "joint samples were removed, and the joints they move follow)" if channels else "")
    click.echo(f"{in_path} -> {out_path}: {removed} samples removed{hit}", err=True)


def _joint_samples_removed(motion, gapped) -> int:
    """Joint samples (a joint with channels, in one frame) that had all their channels in
    ``motion`` and lack one in ``gapped``."""
    from .gaps import joint_samples_observed

    return int((joint_samples_observed(motion) & ~joint_samples_observed(gapped)).sum())


# ---------------------------------------------------------------- rank


@main.command()
@click.argument("in_path", metavar="IN", type=_InputFile())
@click.option("--theta", type=float, default=1e-3, show_default=True,
              help="Threshold on consecutive singular-value gaps, relative to the largest "
                   "singular value of the centred, unit-RMS matrix.")
@click.option("--json", "as_json", is_flag=True,
              help='Print {"rank": r, "singular_values": [...]}.')
@_zero_option
def rank(in_path: Path, theta: float, as_json: bool, zero_is_missing: str) -> None:
    """Estimate the rank of IN's marker matrix (the paper's estimate, unit-invariant)."""
    from .motion import check_coordinates
    from .rank import estimate_rank

    motion = _read(in_path, zero_is_missing)
    markers = _evidence_markers(motion)
    check_coordinates(motion, motion.fillable)
    matrix, observed = motion.matrix(markers)
    estimate = estimate_rank(matrix, observed, theta=theta)
    if as_json:
        click.echo(json.dumps({"rank": estimate.rank,
                               "singular_values": [float(s) for s in
                                                   estimate.singular_values]}))
    else:
        click.echo(f"rank: {estimate.rank}")


def _evidence_markers(motion):
    import numpy as np

    from .errors import NothingToRepair

    markers = np.flatnonzero(motion.fillable & motion.observed.any(axis=0))
    if markers.size == 0:
        raise NothingToRepair(f"{motion.path}: no marker has any observed sample")
    return markers


# ---------------------------------------------------------------- score


@main.command()
@click.argument("truth_path", metavar="TRUTH", type=_InputFile())
@click.argument("repaired_path", metavar="REPAIRED", type=_InputFile())
@click.option("--gapped", "gapped_path", type=_InputFile(), default=None,
              help="The gapped file that was repaired: its missing samples are scored. "
                   "Default: the samples that differ between TRUTH and REPAIRED by more "
                   "than the two files' storage precision (decimals, float32, C3D scale).")
@click.option("--json", "as_json", is_flag=True,
              help='Print {"rmse", "rmse_3d", "rmse_mm", "rmse_3d_mm", "missing_samples", '
                   '"unfilled_samples"}: the samples scored, and those to score that '
                   'REPAIRED still lacks (left out of the RMSE).')
@_zero_option
def score(truth_path: Path, repaired_path: Path, gapped_path, as_json: bool,
          zero_is_missing: str) -> None:
    """Error of REPAIRED against TRUTH on the missing samples.

    rmse is the paper's RMSE over missing coordinates; rmse_3d the RMS 3-D marker error;
    both in TRUTH's units and in mm. Files in different length units (a CMU AMC in
    in/0.45 and a C3D in mm) are compared in mm; a unit that is not a known length (a
    BVH's) must be the same in both files. No sample to score (none filled and observed in
    TRUTH) is an error (exit 123), not an RMSE of nan.
    """
    from .errors import MocapfillError
    from .metrics import score as compute

    truth = _read(truth_path, zero_is_missing)
    repaired = _read(repaired_path, zero_is_missing)
    gapped = None if gapped_path is None else _read(gapped_path, zero_is_missing)
    result = compute(truth, repaired, gapped)
    if result.missing_samples == 0:
        # An RMSE over no sample is no score: a swapped argument, the gapped file given as
        # TRUTH (its gaps are where the fills are), a repair that filled nothing.
        raise MocapfillError(_nothing_to_score(result, truth_path, repaired_path, gapped_path))
    if as_json:
        click.echo(json.dumps(result.as_dict()))
        return
    unit = truth.units
    mm = ("" if result.rmse_mm is None or unit.strip().lower() == "mm"
          else f" = {result.rmse_mm:.3f} mm (3-D {result.rmse_3d_mm:.3f} mm)")
    click.echo(f"RMSE {result.rmse:.6g} {unit} (3-D {result.rmse_3d:.6g} {unit}){mm} over "
               f"{result.missing_samples} missing samples"
               + (f"; {result.unfilled_samples} left unfilled" if result.unfilled_samples
                  else ""))


def _nothing_to_score(result, truth_path: Path, repaired_path: Path,
                      gapped_path: Path | None) -> str:
    if result.unfilled_samples:
        return (f"{repaired_path}: nothing to score: none of the {result.unfilled_samples} "
                f"samples to score is filled")
    if gapped_path is not None:
        return (f"{gapped_path}: nothing to score: no sample missing here is observed in "
                f"the truth {truth_path}")
    return (f"{repaired_path}: nothing to score: no filled sample is observed in the truth "
            f"{truth_path} (a sample counts as filled where it differs from the truth)")


# ---------------------------------------------------------------- info


@main.command()
@click.argument("in_path", metavar="IN", type=_InputFile())
@click.argument("repaired_path", metavar="[REPAIRED]", required=False,
                type=_InputFile())
@click.option("--json", "as_json", is_flag=True, help="Print the table as JSON.")
@click.option("--gaps-only", is_flag=True, help="List only the markers with missing samples.")
@_zero_option
def info(in_path: Path, repaired_path: Path | None, as_json: bool, gaps_only: bool,
         zero_is_missing: str) -> None:
    """Per-marker missing samples n/N (%), number of gaps, longest gap (frames, seconds).

    With REPAIRED, the table shows each marker before and after the repair.
    """
    from .report import check_same_clip, format_info, format_info_before_after, info_dict

    motion = _read(in_path, zero_is_missing)
    repaired = None if repaired_path is None else _read(repaired_path, zero_is_missing)
    if as_json:
        listed = motion if gaps_only else None
        payload = info_dict(motion, listed)
        if repaired is not None:
            check_same_clip(motion, repaired)     # as the table does
            payload = {"before": payload, "after": info_dict(repaired, listed)}
        click.echo(json.dumps(payload))
    elif repaired is not None:
        click.echo(format_info_before_after(motion, repaired, gaps_only=gaps_only))
    else:
        click.echo(format_info(motion, gaps_only=gaps_only))


# ---------------------------------------------------------------- plot


@main.command()
@click.argument("in_path", metavar="IN", type=_InputFile())
@click.argument("repaired_path", metavar="[REPAIRED]", required=False,
                type=_InputFile())
@click.option("-o", "--output", "out_path", required=True, type=_OutputFile(),
              help="Image to write: FILE.png, FILE.svg or FILE.html.")
@click.option("--markers", multiple=True, metavar="NAME|GLOB",
              help="Markers to draw (repeatable; globs). Default: up to 8 with the most "
                   "missing data.")
@_zero_option
def plot(in_path: Path, repaired_path: Path | None, out_path: Path, markers: tuple[str, ...],
         zero_is_missing: str) -> None:
    """Draw x/y/z trajectories over time (s; frames without a rate) in file units: gaps
    shaded, fills dashed.

    Needs matplotlib: pip install matplotlib (or '.[plot]' in mocapfill's checkout).
    """
    from .formats import check_output_folder
    from .plot import plot as draw

    check_output_folder(out_path)       # before reading, as repair and convert check OUT
    original = _read(in_path, zero_is_missing)
    repaired = None if repaired_path is None else _read(repaired_path, zero_is_missing)
    drawn = draw(original, repaired, out_path, markers=markers)
    click.echo(f"{out_path}: {len(drawn)} markers ({', '.join(drawn)})", err=True)


# ---------------------------------------------------------------- convert


@main.command()
@click.argument("in_path", metavar="IN", type=_InputFile())
@click.argument("out_path", metavar="OUT", type=_OutputFile())
@_zero_option
def convert(in_path: Path, out_path: Path, zero_is_missing: str) -> None:
    """Convert IN to OUT's format (by suffix), keeping gaps as gaps."""
    from . import formats

    formats.check_output(out_path, in_path)
    motion = _read(in_path, zero_is_missing)
    _write_noting(motion, out_path)
    # The markers OUT holds (a TRC leaves model outputs out): asked again here only, where
    # the summary counts them, not by every repair and simulate that writes a new file.
    written = formats.for_output(motion, out_path)[0]
    click.echo(f"{in_path} -> {out_path}: {written.n_markers} markers, {written.n_frames} "
               "frames", err=True)


def _write_noting(motion, out_path: Path,
                  read: tuple[Path, tuple[str, ...]] | None = None,
                  beside: tuple[Path, str] | None = None) -> None:
    """Write OUT, then show what its format could not hold as the clip had it (model
    outputs left out of a TRC, lengths converted to mm), after ``read``'s notes (IN and
    what its reader worked around), if given. Shown once OUT is written, so that a
    command that fails prints its one error line alone.

    ``beside`` (a path and its text, repair's ``--gaps-report``) is written to its
    temporary file before OUT and put in place after it: a run that fails on either
    leaves no new or changed OUT or report (but where the report's rename fails once OUT
    is in place, which a folder checked before the repair and already written in makes
    unlikely)."""
    from contextlib import nullcontext

    from . import formats

    with formats.text_pending(*beside) if beside is not None else nullcontext():
        written = formats.write(motion, out_path)
    for path, notes in ([read] if read else []) + [(out_path, written)]:
        for note in notes:
            click.echo(f"mocapfill: note: {path}: {note}", err=True)


# ---------------------------------------------------------------- bench


@main.group()
def bench() -> None:
    """Benchmarks: speed (make bench), accuracy, and the paper's experiments."""


@bench.command("speed")
@click.option("--runs", type=click.IntRange(1, 100), default=5, show_default=True,
              help="Runs per case (medians are reported).")
@click.option("--quick", is_flag=True,
              help="Skip the 30-minute and 300-marker synthetic clips.")
@click.option("--big-runs", type=click.IntRange(1, 100), default=1, show_default=True,
              help="Runs of the 30-minute and 300-marker clips (a minute or more each).")
@click.option("--no-compare", is_flag=True, help="Skip the trnn-paper and tsmc runs.")
@click.option("--json", "json_path", type=_OutputFile(), default=None,
              help="Also write the rows to FILE.json.")
def bench_speed(runs: int, quick: bool, big_runs: int, no_compare: bool,
                json_path: Path | None) -> None:
    """Wall time (s) of `mocapfill repair` per case, iterations, ms per iteration against
    the computed floor, peak memory (MB), and trnn-paper / tsmc side by side."""
    from .bench_speed import format_speed_table, rows_as_dicts, run_speed

    _check_written(json_path)
    rows = run_speed(runs=runs, quick=quick, compare=not no_compare, big_runs=big_runs)
    click.echo(format_speed_table(rows))
    if json_path is not None:
        from .formats import write_text_atomically

        write_text_atomically(json_path, json.dumps(rows_as_dicts(rows), indent=1))


def _check_written(*paths: Path | None) -> None:
    """Before a long run: each file it will write can be created (its folder exists, it is
    not a folder), not the temporary file's OSError once the run is over."""
    from .formats import check_output_folder

    for path in paths:
        if path is not None:
            check_output_folder(path)


@bench.command("accuracy")
@click.option("--quick", is_flag=True,
              help="WalkL_0001 and 85_02 (mr 0.4, ml 40), one seed, instead of all cases.")
@click.option("--methods", default=None, metavar="A,B,...",
              help="Comma-separated methods (default: all but svt, which takes minutes).")
@click.option("--json", "json_path", type=_OutputFile(), default=None,
              help="Also write the rows to FILE.json.")
@click.option("--plots", "plots_dir", type=_OutputFolder(), default=None,
              help="Write bar charts into DIR (needs matplotlib).")
def bench_accuracy(quick: bool, methods: str | None, json_path: Path | None,
                   plots_dir: Path | None) -> None:
    """Every method on the shared data with fixed seeds: the Gløersen-Federolf walking
    set (real gaps) and the paper's protocols on CMU clips. Prints a methods x cases
    table of error in mm and time in s: walkl lines the 3-D RMS marker error over the
    interior gap samples, cmu lines the paper's RMSE over missing coordinates (√3 times
    smaller for the same fills), mean over the seeds."""
    from .bench import format_table, run_accuracy

    _check_written(json_path)
    chosen = (["trnn", "trnn-lowrank", "trnn-paper", "pca", "gaussian", "spline", "pchip",
               "linear", "tsmc", "ialm", "psvt"] if methods is None
              else list(dict.fromkeys(m.strip() for m in methods.split(",") if m.strip())))
    unknown = sorted(set(chosen) - set(METHOD_NAMES))
    if unknown or not chosen:   # '' or ' , ' chose nothing: refuse it, not an empty table
        from .errors import ParameterError

        raise ParameterError(f"unknown method(s) {', '.join(unknown)}" if unknown
                             else f"--methods {methods!r} names no method")
    if plots_dir is not None:
        _require_matplotlib("--plots")      # now, not after the run
        plots_dir.mkdir(parents=True, exist_ok=True)
    rows = run_accuracy(quick, chosen, json_path=json_path, plots_dir=plots_dir)
    click.echo(format_table(rows))


def _require_matplotlib(option: str) -> None:
    from .errors import ParameterError

    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise ParameterError(f"{option} needs matplotlib: pip install matplotlib (or "
                             "'.[plot]' in mocapfill's checkout)") from None


@bench.command("paper")
@click.option("--plots", "plots_dir", type=_OutputFolder(), default=None,
              help="Write one PNG per figure into DIR (needs matplotlib).")
@click.option("--quick", is_flag=True,
              help="A small grid and one seed (about a minute) instead of the full run "
                   "(about 20 minutes on 2 cores).")
@click.option("--output", "markdown_path", type=_OutputFile(), default=None,
              help="Also write the markdown report to FILE.md.")
def bench_paper(plots_dir: Path | None, quick: bool, markdown_path: Path | None) -> None:
    """Reproduce the paper's figures 2-6: synthetic NRE/time against IALM and PSVT, rank
    estimate robustness, truncated-rank sweep, TrNN against TSMC over mr and ml (RMSE in
    mm). Prints a markdown report."""
    from .bench_paper import format_markdown, run_paper

    _check_written(markdown_path)
    if plots_dir is not None:
        plots_dir.mkdir(parents=True, exist_ok=True)
    report = format_markdown(run_paper(quick, plots_dir))
    click.echo(report)
    if markdown_path is not None:
        from .formats import write_text_atomically

        write_text_atomically(markdown_path, report)


def run() -> None:
    """The ``mocapfill`` command (``python -m mocapfill.cli``; the console script and
    ``python -m mocapfill`` load this module under a Ctrl-C handler first):
    :func:`main`, then an immediate exit.

    Python's finalisation after a command (its exit handlers, then the teardown of numpy,
    the solvers and every other module) took 28–38 ms of each one, a 30th of 85_02's
    repair, for nothing: outputs are written atomically and closed by then, and the
    solvers' child processes have ended. So once standard output and error are flushed,
    the process ends at once with the command's exit code. Where that is not certain
    (a thread of a Dask client still running, a flush that fails on a closed pipe), the
    exit is Python's usual one. Tests and other callers of :func:`main` are not affected.

    After Ctrl-C (or SIGTERM or SIGHUP, which stop the command the same way) it ends by
    that signal (see :mod:`mocapfill._interrupt`), at once even where threads run:
    finalising the interpreter while a solver thread is inside C++ code (pocketfft)
    aborted the process (SIGABRT, 6 of 16 interrupted repairs of 85_12).
    """
    import threading

    stop_on_signals()
    try:
        main()
        code = 0
    except SystemExit as exc:
        code = exc.code
    except KeyboardInterrupt:           # outside the command (click's parsing, say)
        say_interrupted()
        code = EXIT_INTERRUPTED
    try:
        # None where the command was started with that stream closed (``>&-``): Python
        # then has no sys.stdout, and flushing it was an AttributeError's traceback
        # (exit 1) after a repair that had succeeded.
        for stream in (sys.stdout, sys.stderr):
            if stream is not None:
                stream.flush()
    except (OSError, ValueError):
        if code != EXIT_INTERRUPTED:
            sys.exit(code)
    if code == EXIT_INTERRUPTED:
        die_interrupted()
    if not isinstance(code, (int, type(None))) or threading.active_count() > 1:
        sys.exit(code)
    os._exit(code or 0)


if __name__ == "__main__":  # pragma: no cover
    run()
