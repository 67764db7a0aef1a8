"""Readers and writers, dispatched by file suffix.

Each format module exposes ``read(path, **options) -> Motion`` and
``write(motion, path, **options) -> None``. A writer given a Motion whose ``source`` came
from its own format patches a copy of the original file (only the samples whose observed
state changed: those filled since reading, and those a ``simulate`` made missing, written
as the format's gaps); otherwise it writes a new file. Since a patch echoes everything
else as read, ``write`` here refuses to patch a clip that differs from its file in
anything else (frames, points, labels, first frame, rate, units, the values of samples
observed in both: :func:`patch_problem`); ``motion.replace(source=None)`` writes a
position format's new file instead. ``write`` here
makes every output atomic: the module writes a temporary file beside the target, which is
renamed over it only when complete. Readers may return a clip of no frames (a BVH with
``Frames: 0``, an empty NPZ) so that ``info`` can report it; ``write`` refuses one.

A new file (not a patch) of a position format is written as other tools read that format
(:func:`for_output`): a TRC or CSV holds marker trajectories only, so points that are not
markers (C3D model outputs: angles, forces, moments, powers) are left out; a TRC, CSV or
C3D states a length unit, so a unit with a known length that is not a plain unit name
(``in/0.45``, CMU AMC lengths) is converted to mm. ``write`` returns one note per change,
and one for a unit it cannot convert (a BVH's ``unknown``), for the caller to show.

A skeleton format (BVH, ASF/AMC) may also expose ``channels(motion)`` and
``with_channels(motion, values, observed)`` so a repair can work in channel space and
write back into the original motion lines.
"""
from __future__ import annotations

import difflib
import errno
import importlib
import inspect
import math
import numbers
import os
import secrets
import shutil
import stat
import sys
import tempfile
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from types import ModuleType

import numpy as np

from ..errors import FormatError, ParameterError
from ..metrics import MM_PER_UNIT, mm_per_unit
from ..motion import Motion, require_motion
from ._patch import differences

# Suffix -> module. Plain dict, no global mutable plugin state.
FORMATS: dict[str, str] = {
    ".c3d": "mocapfill.formats.c3d",
    ".trc": "mocapfill.formats.trc",
    ".csv": "mocapfill.formats.csv",
    ".txt": "mocapfill.formats.csv",
    ".npz": "mocapfill.formats.npz",
    ".bvh": "mocapfill.formats.bvh",
    ".amc": "mocapfill.formats.acclaim",
}

# Formats whose readers take ``zero_is_missing`` (samples at exactly (0, 0, 0) as gaps).
ZERO_FORMATS = (".c3d", ".trc", ".csv", ".txt")

# Formats that store marker positions (valid targets of `convert`).
POSITION_FORMATS = (".c3d", ".trc", ".csv", ".txt", ".npz")

# Formats whose new files hold marker trajectories only (TRC for OpenSim, a marker CSV), and
# those whose new files state a length unit other tools read.
MARKER_ONLY_FORMATS = (".trc", ".csv", ".txt")
UNIT_FORMATS = (".c3d", ".trc", ".csv", ".txt")

# Known suffixes we do not read, with what to do instead.
WRONG_SUFFIXES: dict[str, str] = {
    ".asf": "an .asf holds only the skeleton; pass the .amc (its .asf is found beside it)",
    ".mat": "MATLAB files are not read; export the trajectories to CSV or C3D",
    ".tsv": "Qualisys TSV is not read; export C3D from QTM",
    ".fbx": "FBX is not read; export BVH or C3D",
    ".qtm": ".qtm project files are not read; export C3D from QTM",
    ".x2d": "Vicon raw camera data is not read; export C3D from Nexus",
    ".mot": "an OpenSim .mot holds coordinates or forces, not markers; pass the .trc",
}


# Skeleton formats whose writers patch joint channels (a repair into the same format works
# in channel space; anything else works on joint positions).
SKELETON_FORMATS = (".bvh", ".amc")


def same_skeleton_format(in_path: str | os.PathLike, out_path: str | os.PathLike) -> bool:
    """True when both files are BVH, or both AMC: repair and simulate in channel space."""
    suffix = Path(in_path).suffix.lower()
    return suffix in SKELETON_FORMATS and Path(out_path).suffix.lower() == suffix


def format_module(path: str | os.PathLike, *, output: bool = False) -> ModuleType:
    """The module that reads and writes files with this suffix (``output``: ``path`` is
    to be written, which a known suffix we do not handle gets its own message for:
    "pass the .amc" or "export C3D from QTM" is advice about inputs)."""
    suffix = Path(path).suffix.lower()
    if suffix in FORMATS:
        return importlib.import_module(FORMATS[suffix])
    if suffix in WRONG_SUFFIXES:
        if output:
            raise FormatError(path, f"{suffix} files are not written; name the output "
                              f"{', '.join(POSITION_FORMATS)} (or .bvh / .amc from an "
                              "input of that format)", exit_code=2)
        raise FormatError(path, WRONG_SUFFIXES[suffix], exit_code=2)
    known = ", ".join(sorted(FORMATS))
    raise FormatError(path, f"unknown file type {suffix or '(no suffix)'!r}; known: {known}",
                      exit_code=2)


def read(path: str | os.PathLike, **options) -> Motion:
    """Read a motion file of any known format.

    ``options`` are those of the format's reader: ``rate`` (Hz; every format, used only
    where the file states none: an AMC, a C3D with no rate in ``POINT:RATE`` or its
    header, a TRC or CSV
    without a rate or times, an NPZ without ``rate``; a BVH always states one),
    ``units`` (CSV, TRC: where the file states none; AMC: convert to it; BVH: its label),
    ``zero_is_missing`` (C3D, TRC, CSV), ``scale`` (BVH), ``asf`` (AMC).

    Raises
    ------
    TypeError
        An option the format's reader does not take (a misspelt one was ignored, or
        reported as the file's fault), before the file is opened.
    ParameterError
        ``rate`` that is not a positive, finite number, or a bad ``zero_is_missing``.
    FormatError
        Naming ``path``: no such file, a folder, an unknown suffix, or a file that cannot
        be read or parsed.
    """
    path = Path(path)
    if path.is_dir():   # before its suffix: a folder has none, or not a format's
        raise FormatError(path, "is a folder, not a file", exit_code=2)
    module = format_module(path)
    check_read_options(module, path.suffix.lower(), options)
    if not path.exists():
        raise FormatError(path, "no such file", exit_code=2)
    try:
        _check_readable(path)
        return module.read(path, **options)
    except (FormatError, ParameterError):
        raise
    except MemoryError:
        raise FormatError(path, "file declares more data than fits in memory") from None
    except OSError as exc:
        if exc.errno is None:       # numpy's "cannot interpret ... as a pickle" and such
            raise FormatError(path, f"cannot parse ({type(exc).__name__}: {exc})") from None
        # The system refused (permission denied, an I/O error): not the content's fault.
        # Named where it is another file (an AMC's skeleton).
        other = ("" if exc.filename is None or os.fspath(exc.filename) == str(path)
                 else f"{exc.filename}: ")
        raise FormatError(path, f"cannot read ({other}{exc.strerror})") from None
    except (ValueError, IndexError, KeyError, TypeError, OverflowError, UnicodeDecodeError,
            EOFError) as exc:
        # A parser tripping on a corrupt file: report it as the file's fault, one line.
        raise FormatError(path, f"cannot parse ({type(exc).__name__}: {exc})") from None


def check_read_options(module: ModuleType, suffix: str, options: dict) -> None:
    """Raise TypeError for an option ``module``'s reader does not take, naming it and the
    format, and ParameterError for a ``rate`` that is not a positive, finite number.

    Checked here, before the file is opened: the readers used to take any keyword and
    ignore it (``zero_is_mising="on"`` read zeros as data), or a TypeError raised inside
    one was reported as the file's fault ("85_02.c3d: cannot parse (TypeError: read()
    got an unexpected keyword argument 'rate')"). A misspelt option is a programming
    error, as Python's own TypeError for one is, not a problem with the file.
    """
    takes = [name for name, parameter in inspect.signature(module.read).parameters.items()
             if parameter.kind is inspect.Parameter.KEYWORD_ONLY]
    for name in options:
        if name not in takes:
            close = difflib.get_close_matches(name, takes, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise TypeError(f"read() got an unexpected keyword argument {name!r} for a "
                            f"{suffix} file (its reader takes {', '.join(takes)}){hint}")
    rate = options.get("rate")
    if rate is not None and not (isinstance(rate, numbers.Real) and not isinstance(rate, bool)
                                 and math.isfinite(rate) and rate > 0):
        # A reader took -1 or nan for the clip's rate (an AMC states none).
        raise ParameterError(f"rate must be a positive, finite number of Hz, got {rate!r}")


def _check_readable(path: Path) -> None:
    """Raise the OSError of opening a regular file ``path`` for reading (permission
    denied), which a reader could take for a file of the wrong kind (numpy's zip check
    returns False). A named pipe is not opened twice: its writer would see a reader go."""
    if stat.S_ISREG(os.stat(path).st_mode):
        with open(path, "rb"):
            pass


def check_output(path: str | os.PathLike, input_path: str | os.PathLike) -> None:
    """Before any work on ``input_path``: the checks :func:`write` makes on an output that
    need no clip (a known suffix, an existing folder, not the input, not a folder, a
    skeleton format only from the same format), so that a long repair is not thrown away
    for a mistyped OUT. Raises FormatError naming ``path``."""
    path, input_path = Path(path), Path(input_path)
    format_module(path, output=True)
    check_output_folder(path)
    if path.exists() and input_path.exists() and path.resolve() == input_path.resolve():
        raise FormatError(path, "refusing to overwrite the input file", exit_code=2)
    problem = skeleton_output_problem(path, input_path)
    if problem is not None:
        raise FormatError(path, problem, exit_code=2)


def check_output_folder(path: str | os.PathLike) -> None:
    """That ``path`` can be created as a file: its folder exists and it is not a folder
    itself (the checks of :func:`check_output` that hold for any output, a plot too).
    Raises FormatError naming ``path`` (exit 2), not the temporary file's OSError."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise FormatError(path, f"output folder {directory} does not exist", exit_code=2)
    if path.is_dir():
        raise FormatError(path, "is a folder; name the output file", exit_code=2)


def skeleton_output_problem(path: str | os.PathLike, input_path: str | os.PathLike
                            ) -> str | None:
    """Why ``path`` cannot be written from ``input_path`` (a BVH or AMC output holds joint
    angles, so it needs an input of its own format), or None."""
    suffix = Path(path).suffix.lower()
    if suffix in SKELETON_FORMATS and Path(input_path).suffix.lower() != suffix:
        return skeleton_input_needed(suffix)
    return None


def skeleton_input_needed(suffix: str) -> str:
    """The problem with writing positions to a skeleton format (``.bvh`` or ``.amc``)."""
    name, article = {".bvh": ("BVH", "a"), ".amc": ("AMC", "an")}[suffix]
    return (f"{name} output needs {article} {name} input (positions cannot be turned into "
            "joint angles); write .c3d/.trc/.csv instead")


def for_output(motion: Motion, path: str | os.PathLike) -> tuple[Motion, tuple[str, ...]]:
    """The clip as a new file of ``path``'s format holds it, and a note on each change.

    A writer that patches the clip's own source file gets it unchanged (a C3D keeps its
    model outputs, a TRC its header). A new TRC or CSV leaves out the points that are not
    marker trajectories (``fillable`` False: C3D model outputs): Vicon and OpenSim users
    read a TRC as markers only, and a later repair would fill those angles and moments and
    take them as evidence for the markers (a new C3D keeps them, listed in POINT:SCALARS).
    A new TRC, CSV or C3D file gets lengths in mm when the clip's unit has a known length
    but is not a plain unit name (``in/0.45``, the CMU AMC unit: a TRC ``Units`` or C3D
    ``POINT:UNITS`` no other tool reads); a unit with no known length (a BVH's
    ``unknown``) is kept, with a note saying so. A TRC or CSV of a clip without a frame
    rate (0 Hz) is written at 120 Hz, with a note. A new TRC writes marker names OpenSim
    accepts (``genou1_ NewMarker`` as ``genou1__NewMarker``) and a new CSV names on one
    line, none empty or repeated: the clip keeps its labels, and a note gives how many
    were renamed, with two examples. NPZ keeps all.

    Parameters
    ----------
    motion
        The clip to write.
    path
        The output file; its suffix picks the format.

    Returns
    -------
    motion, notes
        The clip to hand the format's writer, and readable notes (empty when unchanged).
    """
    suffix = Path(path).suffix.lower()
    module = format_module(path, output=True)
    if suffix not in UNIT_FORMATS or module.patches(motion):
        return motion, ()
    notes = []
    if suffix in MARKER_ONLY_FORMATS and not motion.fillable.all():
        keep = np.flatnonzero(motion.fillable)
        left_out = motion.n_markers - keep.size
        notes.append(f"{left_out} point(s) that are not marker trajectories (model outputs: "
                     f"angles, forces, moments, powers) left out; a {suffix} file holds "
                     "markers only (write .c3d or .npz to keep them)")
        motion = motion.replace(positions=motion.positions[:, keep],
                                observed=motion.observed[:, keep],
                                labels=tuple(motion.labels[j] for j in keep),
                                fillable=motion.fillable[keep])
    rename = getattr(module, "new_file_names", None)
    if rename is not None:
        # The writer renames; the clip keeps its labels (a note, not a change of data).
        changed = [(old, new) for old, new in zip(motion.labels, rename(motion.labels))
                   if old != new]
        if changed:
            shown = ", ".join(f"{old!r} -> {new!r}" for old, new in changed[:2])
            notes.append(f"{len(changed)} marker name(s) written as {module.NEW_FILE_NAMES}: "
                         f"{shown}{', ...' if len(changed) > 2 else ''}")
    units = motion.units.strip()
    factor = mm_per_unit(units)
    if factor is None:
        notes.append(f"length unit {units!r} is not known: positions written as they are, "
                     f"with the unit {units!r}, which other tools do not read as a length")
    elif units.lower() not in MM_PER_UNIT:
        notes.append(f"lengths in {units} converted to mm (1 {units} = {factor:.6g} mm)")
        motion = motion.replace(positions=motion.positions * factor, units="mm")
    if suffix in MARKER_ONLY_FORMATS and not (np.isfinite(motion.rate) and motion.rate > 0):
        # A TRC states a DataRate and a CSV a Time column: the writers fall back on
        # WRITTEN_RATE (_text.writable_rate), which the user should hear of, not find in
        # the file.
        from ._text import WRITTEN_RATE

        notes.append(f"the clip's frame rate is not known (0 Hz): written as {WRITTEN_RATE:g} Hz")
    if suffix == ".c3d" and not module.stores_first_frame(motion):
        notes.append(f"first frame {motion.first_frame} does not fit a C3D (0 to "
                     f"{0xFFFFFFFF - motion.n_frames}): frames numbered from 1")
    return motion, tuple(notes)


def write(motion: Motion, path: str | os.PathLike, *, final_path: Path | None = None,
          **options) -> tuple[str, ...]:
    """Write a motion file atomically; the suffix picks the format.

    ``final_path`` is where the file will end up when ``path`` is a temporary name the
    caller renames (an in-place repair): files it needs beside it (an AMC's skeleton) are
    checked and put there, not beside the temporary name.

    Returns
    -------
    tuple of str
        Notes on what a new file of this format could not hold as the clip had it (see
        :func:`for_output`), for the caller to show; empty when nothing changed.

    Raises
    ------
    FormatError
        Naming ``path``: the suffix is unknown, the output is the input file, its folder
        does not exist, the clip has no frames (TRC, CSV and AMC cannot hold one, and in
        any format an empty output would pass for a result), the clip was read from a
        file of ``path``'s format but differs from it in more than the samples filled or
        removed since reading (:func:`patch_problem`: its units, rate, first frame,
        frames, points or labels, or the values of samples observed in the file; for a
        new file of a position format, pass ``motion.replace(source=None)``), or the
        format's writer refuses the clip.
    """
    if isinstance(path, Motion):
        raise TypeError("write() takes the Motion first, then the path: write(motion, path)")
    require_motion(motion, "write")
    path = Path(path)
    module = format_module(path, output=True)
    if motion.path is not None and path.exists() and path.resolve() == motion.path.resolve():
        raise FormatError(path, "refusing to overwrite the input file", exit_code=2)
    if motion.n_frames == 0:
        raise FormatError(path, "refusing to write a clip with no frames")
    problem = patch_problem(motion, path)
    if problem is not None:
        raise FormatError(path, problem)
    motion, notes = for_output(motion, path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise FormatError(path, f"output folder {directory} does not exist")
    tmp = None
    try:
        # Files a written file needs beside it to be read back (an AMC's skeleton): put in
        # place first, so that the file never stands without them (a copy that failed
        # after it left an AMC that a batch rerun skipped as up to date). A write that
        # fails then leaves the companion, a complete file the next run finds and keeps.
        companions = getattr(module, "companions", None)
        before = (companions(motion, final_path or path) if companions is not None
                  else None)
        if before is not None:
            before()
        with atomic_output(path) as tmp:
            module.write(motion, Path(tmp), **{"target": final_path or path, **options})
    except FormatError as exc:
        # The module saw only the temporary name, or named no file at all.
        if exc.path is None or (tmp is not None and exc.path == tmp):
            raise FormatError(path, exc.problem, exit_code=exc.exit_code) from None
        raise
    except OSError as exc:
        if tmp is None:         # no temporary: a read-only or full folder
            raise FormatError(path, f"cannot write in {directory}: {exc.strerror or exc}") \
                from None
        # The error names the temporary file (".out.c3d.x1y2.tmp: Is a directory"); the
        # user knows the output's name.
        raise FormatError(path, exc.strerror or str(exc)) from None
    return notes


def patch_problem(motion: Motion, path: str | os.PathLike) -> str | None:
    """Why ``motion`` cannot be written to ``path`` as the patch of its own file that the
    format's writer makes of it (see :mod:`._patch`), or None (no patch, or one that holds
    the clip).

    A patch echoes all but the samples filled or made missing since reading, so a clip
    that differs from its file in anything else (converted to metres, resampled,
    relabelled, smoothed) would come out as something else: half in the old units, its
    edits dropped. It is refused rather than written as a new file instead, as the BVH
    and AMC writers refuse positions edited outside channel space: a new file drops what
    only the source holds (a C3D's analog data and parameters, a TRC's header), which the
    caller should choose to lose (``motion.replace(source=None)``) rather than find out.
    """
    module = format_module(path, output=True)
    patches = getattr(module, "patches", None)
    read = getattr(motion.source, "as_read", None)
    if patches is None or not patches(motion) or read is None:
        return None
    found = differences(motion, read)
    if not found:
        return None
    suffix = Path(path).suffix.lower()
    origin = f"{motion.path}, the file it was read from" if motion.path else "its source file"
    if suffix in SKELETON_FORMATS:
        name = suffix[1:].upper()
        how = (f"{name} output is written only as a patch of {name} input (positions cannot "
               "be turned into joint angles)")
    else:
        how = "write a new file with motion.replace(source=None)"
    listed = found[0] if len(found) == 1 else f"{', '.join(found[:-1])} and {found[-1]}"
    return (f"the clip differs from {origin}, in {listed}; a patch of that file changes "
            f"only the samples filled or removed since reading: {how}")


@contextmanager
def atomic_output(path: Path, suffix: str = ".tmp"):
    """A temporary name beside ``path`` to write to; it replaces ``path`` when the block
    ends normally and is removed when it raises, so ``path`` is never half-written.

    The result gets the mode a plain ``open()`` would give a new file (0666 less the
    umask). Where ``path`` is a regular file (or links to one), it gets that file's mode,
    and its owner and group where the process may set them (:func:`_keep_owner`), as
    ``cp`` or ``open()`` over it keep them: a 0600 output overwritten came out 0644.

    A ``path`` that is (or links to) a device, a named pipe or a socket is written through,
    as ``open()`` would: renaming a file over it replaced the node itself (``--json
    /dev/full`` left a JSON file in place of the device, ``--json /dev/stdout`` printed
    nothing). Atomicity means nothing there; a write that fails (``/dev/full``: no space
    left) raises as it happens.

    An OSError that names the temporary file, or no file (a write that failed), is raised
    naming ``path`` (:func:`_naming`).

    A ``path`` that is this process's own standard output or error, where that is a
    regular file (``--json /dev/stdout > out.txt``), gets the text after what the command
    printed there: renaming over ``/dev/stdout`` (a link to ``/proc/self/fd/1``) replaced
    the system's link with a regular file when run as root, and opening the file anew
    would overwrite what the command printed before.
    """
    stream = _own_stream(path)
    if stream is not None:
        tmp = None
        try:
            with tempfile.TemporaryDirectory(prefix="mocapfill-") as folder:
                tmp = os.path.join(folder, f"out{suffix}")
                yield tmp
                stream.flush()
                with open(tmp, "rb") as written, open(stream.fileno(), "wb",
                                                      closefd=False) as through:
                    shutil.copyfileobj(written, through)
        except OSError as exc:
            raise _naming(exc, path, tmp) from None
        return
    if _special_file(path):
        try:
            yield str(path)
        except OSError as exc:
            raise _naming(exc, path, None) from None
        return
    directory = path.parent if str(path.parent) else Path(".")
    try:
        replaced = os.stat(path)
    except OSError:         # absent (or a dangling link, a loop): a new file
        replaced = None
    try:
        # Only its owner reads the new file until it has the old one's mode.
        tmp = create_temp(directory, path.name, suffix, 0o666 if replaced is None else 0o600)
    except OSError as exc:
        raise _naming(exc, path, None) from None
    try:
        yield tmp
        if replaced is not None:
            _keep_owner(replaced, tmp)
            os.chmod(tmp, stat.S_IMODE(replaced.st_mode))
        os.replace(tmp, path)
    except OSError as exc:
        _discard(tmp)
        raise _naming(exc, path, tmp) from None
    except BaseException:
        _discard(tmp)
        raise


def _keep_owner(replaced: os.stat_result, tmp: str) -> None:
    """Give ``tmp`` the owner and group of the file it replaces (before its mode: a chown
    clears the set-user-ID bits). The file is replaced, not rewritten, and a repair run as
    root made every file root's: with mode 0600 its owner could no longer read it. Only
    root may give a file away, and a group only to a member of it: where the process may
    not, the file is its own, as any new file."""
    if not hasattr(os, "chown"):            # Windows
        return
    try:
        os.chown(tmp, replaced.st_uid, replaced.st_gid)
    except PermissionError:
        pass


def _naming(exc: OSError, path: Path, tmp: str | None) -> OSError:
    """``exc`` about ``path`` where it named the temporary file ``tmp`` (a full disk, a
    folder that takes no new file) or no file at all (a write that failed: ``/dev/full``,
    a full disk), else ``exc`` itself: the user knows the output's name, not
    ".out.json.x1y2.tmp", and "No space left on device" alone did not say which file of a
    command (a plot, a report) could not be written."""
    named = exc.filename is None or (tmp is not None and os.fspath(exc.filename) == tmp)
    if not named or exc.errno is None:      # another file's error, or not the system's
        return exc
    return OSError(exc.errno, exc.strerror, str(path))


# The longest name most file systems take (bytes), and the random part of a temporary name.
NAME_MAX = 255
_RANDOM_CHARS = 8


def create_temp(directory: str | os.PathLike, name: str, suffix: str = ".tmp",
                mode: int = 0o666) -> str:
    """Create an empty temporary file in ``directory`` for the file ``name`` (named as
    :func:`temp_prefix` says, then random characters and ``suffix``) and return its absolute
    path, as ``tempfile.mkstemp`` did.

    It gets ``mode`` less the umask, which the system applies as it creates the file, as
    for a plain ``open()`` (``mode`` 0o666). The umask was read instead, to set the mode of
    a file mkstemp had made 0600, and Python reads it only by setting it (``os.umask``):
    for that moment it was 0 for every thread of the process (measured: under umask 077, 6
    of the files a thread created while 3,000 reports were written were 0666, not 0600).
    """
    prefix = temp_prefix(name, suffix)
    for _ in range(tempfile.TMP_MAX):
        tmp = os.path.abspath(os.path.join(
            directory, f"{prefix}{secrets.token_hex(_RANDOM_CHARS // 2)}{suffix}"))
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0),
                         mode)
        except FileExistsError:
            continue
        os.close(fd)
        return tmp
    raise FileExistsError(errno.EEXIST, "No usable temporary file name found", str(directory))


# The token of the temporary names written in this context (:func:`temp_token`): a batch
# sets its own around each file it repairs (``batch.repair_file``).
TEMP_TOKEN: ContextVar[str | None] = ContextVar("mocapfill_temp_token", default=None)


def temp_token() -> str:
    """The token :func:`temp_prefix` puts in a temporary name: :data:`TEMP_TOKEN` where set,
    else this process's id. A batch stopped (Ctrl-C, a worker that died) removes the
    temporaries of its files (``batch.remove_temp_files``), found by name: matched by the
    output's name alone, they were those of any command writing the same output name in
    the same folder at that moment too, which then failed ("No such file or directory")."""
    return TEMP_TOKEN.get() or str(os.getpid())


def temp_prefix(name: str, suffix: str = ".tmp", token: str | None = None) -> str:
    """How :func:`atomic_output` starts the name of its temporary file for the file
    ``name``: ``.<name>.<token>.`` (``token``, by default :func:`temp_token`), the name cut
    short where ``.<name>.<token>.<random><suffix>`` would pass :data:`NAME_MAX` bytes (an
    output named with 255 bytes, which the file system takes, failed with "File name too
    long")."""
    token = temp_token() if token is None else token
    room = NAME_MAX - len(os.fsencode(suffix)) - _RANDOM_CHARS - len(os.fsencode(token)) - 3
    while len(os.fsencode(name)) > room:
        name = name[:-1]
    return f".{name}.{token}."


def _own_stream(path: Path):
    """``sys.stdout`` or ``sys.stderr`` where ``path`` is that stream's regular file
    (``/dev/stdout``, ``/proc/self/fd/2`` or the file's own name), else None."""
    try:
        target = os.stat(path)
    except OSError:
        return None
    if not stat.S_ISREG(target.st_mode):
        return None
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None and os.path.samestat(target, os.fstat(stream.fileno())):
                return stream
        except (OSError, ValueError, AttributeError):     # closed, or not a real file
            continue
    return None


def _special_file(path: Path) -> bool:
    """Whether ``path`` exists and is, after symbolic links, neither a regular file nor a
    folder: a device, a named pipe or a socket."""
    try:
        mode = os.stat(path).st_mode
    except OSError:         # absent (or a dangling link): a new file is made
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def write_text_atomically(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` through :func:`atomic_output`: reports, tables
    and pages are outputs too, and a write that fails (a full disk, Ctrl-C) must leave
    the previous file, not half of a new one."""
    with text_pending(path, text):
        pass


@contextmanager
def text_pending(path: str | os.PathLike, text: str):
    """Write ``text`` (UTF-8) to ``path``'s temporary file (:func:`atomic_output`) now, and
    put it in place when the block ends normally; the block raising removes it. For a
    file that stands or falls with another written in the block: a repair's gaps report
    that cannot be written (a full disk) then leaves no new or changed OUT, and a repair
    whose OUT cannot be written no new report."""
    with atomic_output(Path(path)) as tmp:
        Path(tmp).write_text(text, encoding="utf-8")
        yield


def _discard(tmp: str) -> None:
    if os.path.exists(tmp):
        os.unlink(tmp)
