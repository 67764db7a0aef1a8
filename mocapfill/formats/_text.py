"""Shared machinery of the delimited text formats (CSV and TRC).

Both formats keep the original text in a :class:`TextSource` handle so that a writer can
patch it: only the cells of samples whose observed state changed are rewritten (filled
since reading, or made missing by ``simulate``: blanked with the file's own missing token,
:func:`patched_lines`); every
other byte of the file (header, delimiters, quoting, line endings, the cells of untouched
samples) is written back as it was read.

Files are decoded as UTF-8 with ``surrogateescape``, so bytes that are not UTF-8 (a
Latin-1 path in a TRC header, say) survive the round trip unchanged.
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import FormatError, ParameterError
from ..motion import Motion
from ._patch import AsRead, of_motion

ENCODING = "utf-8"
ERRORS = "surrogateescape"

#: Cell texts (case-insensitive, after stripping blanks and quotes) that mean "missing".
# A UTF-8 byte order mark (Excel's and Notepad's "UTF-8" saves) as Latin-1 decodes it.
LATIN1_BOM = "\xef\xbb\xbf"
BOM = "\ufeff"
MISSING_TOKENS = frozenset({"", "nan", "-nan", "+nan", "na", "n/a"})

_LINE = re.compile(r"[^\r\n]*(?:\r\n|\r|\n)|[^\r\n]+$")


@dataclass(frozen=True, eq=False)
class TextSource:
    """Everything a writer needs to patch the text file a Motion was read from.

    Attributes
    ----------
    kind
        Layout that was read: ``"csv"``, ``"vicon"``, ``"headerless"``, ``"ktk"``, ``"trc"``.
    lines
        The original lines, each with its own line ending.
    delimiter
        Cell separator of the data rows.
    row_lines
        (frames,) index into ``lines`` of the row that holds each frame.
    columns
        (markers, 3) cell index of x, y and z of each marker within a row.
    observed
        (frames, markers) mask as read; the writer fills only samples False here.
    labels
        Marker labels as read; a Motion with other labels cannot be patched.
    w_columns
        (markers,) cell index of a homogeneous coordinate written as ``1`` when the sample
        is filled and the cell is missing (Kinetics Toolkit ``NAME[3]``), or -1.
    declared_frames
        Frame count the header declares (TRC ``NumFrames``), None when it declares none.
    truncated_rows_read
        Rows read from a file holding fewer frames than it declares; None when complete.
    cut_row
        Index into ``lines`` of the data row the file ends inside when that row looks cut
        short (see :func:`find_cut_row`): its last cell is not read. -1 when there is none.
    width
        Cells a complete data row holds (:class:`RowWidth`); 0 when unknown.
    zeros_are_gaps
        Whether samples at exactly x = y = z = 0 were read as missing
        (:func:`with_zero_gaps`): a repair rewrites all three of their cells.
    notes
        Readable remarks on what the reader tolerated (header counts that disagree with
        the data, ignored columns, a truncated file), for a report to show.
    as_read
        The clip as read, in what a patch cannot change (``formats.write`` refuses to
        patch a clip that differs); set by :func:`read_zero_gaps`.
    """

    kind: str
    lines: tuple[str, ...]
    delimiter: str
    row_lines: np.ndarray
    columns: np.ndarray
    observed: np.ndarray
    labels: tuple[str, ...]
    w_columns: np.ndarray | None = None
    declared_frames: int | None = None
    truncated_rows_read: int | None = None
    notes: tuple[str, ...] = ()
    cut_row: int = -1
    width: int = 0
    zeros_are_gaps: bool = False
    as_read: AsRead | None = None

    @property
    def truncated(self) -> bool:
        """True when the file holds fewer frames than its header declares."""
        return self.truncated_rows_read is not None

    def fits(self, motion: Motion) -> bool:
        """Whether ``motion`` still has the shape and labels of the file (can be patched)."""
        return (motion.positions.shape[:2] == self.observed.shape
                and tuple(motion.labels) == self.labels)


def check_zero_setting(zero_is_missing: str) -> None:
    """Raise ParameterError unless ``zero_is_missing`` is ``"auto"``, ``"on"`` or ``"off"``
    (the readers that take it: C3D, TRC, CSV)."""
    if zero_is_missing not in ("auto", "on", "off"):
        raise ParameterError(f"zero_is_missing must be 'auto', 'on' or 'off', "
                             f"not {zero_is_missing!r}")


def read_zero_gaps(read: Callable[[Path, float | None, str | None], Motion], path: Path,
                   rate: float | None, units: str | None, zero_is_missing: str) -> Motion:
    """``read(path, rate, units)`` (a format's reader), its samples at exactly (0, 0, 0)
    as gaps with ``zero_is_missing="on"`` (the setting checked first). ``"auto"`` reads
    them as data: unlike a QTM C3D file, a text file carries no sign of the exporter that
    wrote its gaps so (formats-and-conventions.md: QTM-derived TSV pipelines, the MoCap
    Toolbox)."""
    check_zero_setting(zero_is_missing)
    motion = read(Path(path), rate, units)
    if zero_is_missing == "on":
        motion = with_zero_gaps(motion)
    # The handle gets the clip as read (after its zeros became gaps) here, once, for the
    # layouts that each build their Motion: one more Motion built, a few per cent of the
    # time spent parsing the text.
    return replace(motion, source=replace(motion.source, as_read=of_motion(motion)))


def with_zero_gaps(motion: Motion) -> Motion:
    """``motion``, read from a text file, with its samples at exactly x = y = z = 0 as gaps
    (all three coordinates, never one: a marker may sit on an axis plane). The source
    handle's mask takes them too, so a repair rewrites their cells (:func:`patched_lines`),
    and its notes say how many there were."""
    zero = (motion.positions == 0).all(axis=2)       # NaN is not 0: gaps stay gaps
    if not zero.any():
        return motion
    positions = motion.positions.copy()
    positions[zero] = np.nan
    observed = motion.observed & ~zero
    source = motion.source
    count = int(zero.sum())
    note = (f"{count} sample{'s' if count > 1 else ''} at exactly (0, 0, 0) read as missing "
            "(--zero-is-missing on)")
    source = replace(source, observed=observed.copy(), zeros_are_gaps=True,
                     notes=tuple(source.notes) + (note,))
    return replace(motion, positions=positions, observed=observed, source=source)


# ----------------------------------------------------------------------------- text I/O

def read_lines(path: Path) -> list[str]:
    """The lines of a text file, each keeping its line ending (``\\r\\n``, ``\\n``, ``\\r``)."""
    text = Path(path).read_bytes().decode(ENCODING, ERRORS)
    return _LINE.findall(text)


def write_lines(path: Path, lines: Sequence[str]) -> None:
    """Write lines (with their endings) back byte for byte."""
    Path(path).write_bytes("".join(lines).encode(ENCODING, ERRORS))


def split_ending(line: str) -> tuple[str, str]:
    """``(body, ending)`` of a line."""
    if line.endswith("\r\n"):
        return line[:-2], "\r\n"
    if line.endswith(("\n", "\r")):
        return line[:-1], line[-1]
    return line, ""


def split_cells(body: str, delimiter: str) -> list[str]:
    """Raw cells of a line body; joining them with ``delimiter`` gives the body back.

    A cell in double quotes may hold the delimiter (CSV quoting, ``""`` for a quote).
    """
    if '"' not in body:
        return body.split(delimiter)
    cells, start, quoted = [], 0, False
    for i, char in enumerate(body):
        if char == '"':
            quoted = not quoted
        elif char == delimiter and not quoted:
            cells.append(body[start:i])
            start = i + 1
    cells.append(body[start:])
    return cells


def cell_text(raw: str) -> str:
    """The value of a raw cell: blanks around it, a byte order mark before it (the first
    cell of a file saved as Excel's "CSV UTF-8") and enclosing quotes removed.

    Bytes that were not UTF-8 (kept as surrogates so a patch writes them back) are
    decoded as Latin-1 here, so labels and units are printable strings.
    """
    text = raw.strip().lstrip(BOM).strip()
    if len(text) >= 2 and text[0] == '"' and text[-1] == '"':
        text = text[1:-1].replace('""', '"').strip()
    if not text.isascii():
        text = printable(text)
    return text


def printable(text: str) -> str:
    """``text`` with the undecodable bytes ``read_lines`` kept as surrogates decoded as
    Latin-1 (a lone surrogate cannot be printed or encoded)."""
    return utf8_or_latin1(text.encode(ENCODING, ERRORS))


def utf8_or_latin1(data: bytes) -> str:
    """Bytes as UTF-8 where they are valid UTF-8 (plain ASCII is), else as Latin-1 (a lone
    byte ≥ 0x80 is not valid UTF-8, so Latin-1 text reads as Latin-1)."""
    try:
        return data.decode(ENCODING)
    except UnicodeDecodeError:
        return data.decode("latin-1")


def latin1_label(name: str) -> str:
    """A name read from a file decoded as Latin-1 (BVH, AMC, ASF keep their bytes so), as a
    readable label: re-read as UTF-8 where its bytes are valid UTF-8 (``Hüfte``, not
    ``HÃ¼fte``)."""
    return utf8_or_latin1(name.encode("latin-1"))


def quote(text: str, delimiter: str) -> str:
    """``text`` as a cell, in quotes only when it holds the delimiter, a quote or a newline."""
    if delimiter in text or '"' in text or "\n" in text or "\r" in text:
        return '"' + text.replace('"', '""') + '"'
    return text


def is_blank(line: str) -> bool:
    return not line.strip()


def sniff_delimiter(line: str, candidates: str = ",;\t") -> str:
    """The candidate that occurs most often in ``line`` (ties: earlier candidate wins)."""
    counts = [line.count(c) for c in candidates]
    return candidates[int(np.argmax(counts))] if max(counts) else candidates[0]


# ----------------------------------------------------------------------------- numbers

def parse_number(text: str) -> float:
    """A cell value as float; NaN for a missing token; ValueError when unparsable."""
    if text.lower() in MISSING_TOKENS:
        return float("nan")
    return float(text)


def row_cells(lines: Sequence[str], index: int, delimiter: str,
              cut_row: int = -1) -> tuple[list[str], bool]:
    """Raw cells of a data row, and whether it is the row ``cut_row`` the file may have
    been cut short inside (see :func:`find_cut_row`).

    The last cell of the cut row is left out of the returned cells: it may be a number cut
    short (``956.933`` cut to ``956``), so readers take it as missing, and may accept the
    row holding fewer cells than a complete one.
    """
    body = split_ending(lines[index])[0]
    cells = split_cells(body, delimiter)
    cut = index == cut_row
    return (cells[:-1] if cut else cells), cut


def ends_inside_row(lines: Sequence[str], row_lines: np.ndarray) -> bool:
    """Whether the file ends inside its last data row (no line ending after it)."""
    return (row_lines.size > 0 and int(row_lines[-1]) == len(lines) - 1
            and not split_ending(lines[-1])[1])


def find_cut_row(lines: Sequence[str], row_lines: np.ndarray, delimiter: str,
                 width: RowWidth, columns: np.ndarray) -> int:
    """The line index of the last data row when the file may have been cut short inside
    it, else -1.

    Many tools end a file without a line ending, so a last row without one is read whole
    (its last cell is data, which a patch keeps byte for byte) unless it shows a cut: it
    holds fewer cells than a complete row, or its last cell is not a number (``1.5e``,
    ``-``), or the cell is printed less precisely than the same column in the other rows
    and the other coordinates of its marker in the row (``31.000`` cut to ``31``).

    "As precisely" has two readings, and a whole cell passes either: as many decimals as
    any of those cells (files printed with fixed decimals), or as many significant digits
    as any cell of its column and as the fewest of its marker's other coordinates, with
    no fewer decimals than the fewest of its column (files printed with ``%g``, whose
    decimals follow the magnitude; the same value cut short loses digits both ways). A
    column no other row holds a number in gives nothing to compare with: the cell is
    taken as cut. Reading a cut number as data would put a wrong value among the
    observations, so doubt goes that way: a ``%g`` value that happens to end in zeros
    (``954.3`` for 954.300) reads as cut and missing.

    Parameters
    ----------
    lines, row_lines, delimiter, columns
        As in :class:`TextSource`.
    width
        The cells a complete row holds.
    """
    if not ends_inside_row(lines, row_lines):
        return -1
    index = int(row_lines[-1])
    cells = split_cells(split_ending(lines[index])[0], delimiter)
    if len(cells) < width.cells:
        return index
    last = len(cells) - 1
    text = cell_text(cells[last])
    try:
        parse_number(text)
    except ValueError:
        return index
    if text.lower() in MISSING_TOKENS:
        return -1           # missing whether cut or not
    column = [cell_text(other[last])
              for other in (split_cells(split_ending(lines[int(i)])[0], delimiter)
                            for i in row_lines[:-1])
              if _holds_value(other, last)]
    marker = next((m for m in columns.tolist() if last in m), [])
    row = [cell_text(cells[c]) for c in marker if c != last and _holds_value(cells, c)]
    return -1 if printed_whole(text, column, row) else index


def finite_number(token: str) -> bool:
    """Whether a token reads as a finite number."""
    try:
        return bool(np.isfinite(float(token)))
    except ValueError:
        return False


def last_value_cut(text: str, column: Sequence[str], row: Sequence[str], *,
                   alone: bool = True) -> bool:
    """Whether ``text``, a value a file ends right after (an AMC's or a BVH's last), looks
    cut short: not a number (``1e``), or a finite one not :func:`printed_whole` beside
    ``column`` and ``row``. ``nan`` is missing whether cut or not, and ``inf`` is refused
    by the readers anyway: neither looks cut. ``alone`` is the answer for a finite number
    with an empty ``column`` (nothing to compare it with)."""
    try:
        value = float(text)
    except ValueError:
        return True
    if not np.isfinite(value):
        return False
    if not column:
        return alone
    return not printed_whole(text, column, row)


def printed_whole(text: str, column: Sequence[str], row: Sequence[str]) -> bool:
    """Whether ``text``, a number a file ends right after, is printed as precisely as the
    numbers around it, so that it reads as whole rather than as cut short.

    The two readings of "as precisely" are those of :func:`find_cut_row`: as many decimals
    as any of ``column`` and ``row`` (fixed decimals), or as many significant digits as
    any of ``column`` and the fewest of ``row``, with no fewer decimals than the fewest
    of ``column`` (``%g``); an exponent has no fewer digits than the fewest of ``column``
    (``1.74931e-014`` cut to ``1.74931e-01``). A cut just before the exponent
    (``1.74931``) reads as whole where the column prints some values without one.

    Parameters
    ----------
    text
        The number, as printed.
    column
        The same value in the file's other rows or frames (a column, a bone's dof), as
        printed; finite numbers only. When empty, nothing to compare with: False.
    row
        The values printed beside it (its marker's other coordinates, its bone's other
        dofs); finite numbers only.
    """
    if not column:
        return False
    column_precision = [_precision(t) for t in column]
    row_precision = [_precision(t) for t in row]
    decimals, digits, exponent = _precision(text)
    if exponent < min(e for _, _, e in column_precision) or 0 <= exponent < min(
            (e for _, _, e in column_precision if e >= 0), default=0):
        return False        # no exponent, or a shorter one, where the column prints one
    fixed = decimals >= max(d for d, _, _ in column_precision + row_precision)
    general = (digits >= max(g for _, g, _ in column_precision)
               and digits >= min((g for _, g, _ in row_precision), default=0)
               and decimals >= min(d for d, _, _ in column_precision))
    return fixed or general


def _precision(text: str) -> tuple[int, int, int]:
    """Decimals and significant digits of a number's mantissa, and digits of its exponent
    (-1 without one)."""
    mantissa, e, exponent = text.lower().partition("e")
    dot = mantissa.find(".")
    decimals = 0 if dot < 0 else len(mantissa) - dot - 1
    digits = len("".join(ch for ch in mantissa if ch.isdigit()).lstrip("0"))
    return decimals, digits, (len(exponent.lstrip("+-")) if e else -1)


#: Note a reader adds when the file ends inside its last data row and that row looks cut.
CUT_ROW_NOTE = ("the file ends inside its last row (no final line ending) and that row looks "
                "cut short: its last cell is not read")


@dataclass(frozen=True)
class RowWidth:
    """How many cells a complete data row holds, and what sets that number.

    A row may hold fewer cells only when the file ends inside it (see :func:`find_cut_row`).
    Cells beyond ``cells`` are accepted when they are blank (a trailing delimiter, as
    OpenSim writes after every cell, or padding a spreadsheet adds); with ``triplets``
    (TRC) they may also be whole x, y, z triplets of markers the names line does not name,
    as Motion Analysis Cortex exports write them.
    """

    cells: int
    set_by: str         # ends "line N holds M cells; ...": "the header row has", ...
    triplets: bool = False

    def check(self, path: Path, cells: Sequence[str], index: int, cut: bool) -> None:
        """Raise FormatError naming the line when ``cells`` is not a complete row."""
        n_cells = len(cells)
        if n_cells == self.cells or (n_cells < self.cells and cut):
            return
        if n_cells > self.cells:
            if all(not cell_text(c) for c in cells[self.cells:]):
                return
            written = n_cells - (0 if cell_text(cells[-1]) else 1)    # less a trailing one
            if self.triplets and (cut or (written - self.cells) % 3 == 0):
                return
        extra = (" (cells beyond those must be whole x, y, z triplets)"
                 if self.triplets and n_cells > self.cells else "")
        raise FormatError(path, f"line {index + 1} holds {n_cells} cells; {self.set_by} "
                                f"{self.cells}{extra}")


def parse_markers(path: Path, lines: Sequence[str], row_lines: np.ndarray,
                  columns: np.ndarray, delimiter: str,
                  column_name: Callable[[int, int], str],
                  width: RowWidth, cut_row: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Positions and observed mask of the marker cells of the given rows.

    Parameters
    ----------
    path
        File name for error messages.
    lines, row_lines, columns, delimiter
        As in :class:`TextSource`.
    column_name
        ``column_name(marker, axis)`` names a column in an error message.
    width
        The cells a complete row holds; a row holding another number is an error.
    cut_row
        The row the file may have been cut short inside (:func:`find_cut_row`), or -1.

    Returns
    -------
    positions, observed
        (frames, markers, 3) with NaN at missing samples, and (frames, markers) bool.
        A sample is missing when any of its cells is missing, or absent or cut short in a
        row the file was cut short inside (see :func:`row_cells`); a repair fills its missing cells
        and keeps the others (:func:`patched_lines`).
    """
    n_frames, n_markers = len(row_lines), len(columns)
    flat = columns.reshape(-1).tolist()
    values = np.full((n_frames, len(flat)), np.nan)
    for f, index in enumerate(row_lines):
        cells, cut = row_cells(lines, index, delimiter, cut_row)
        if len(cells) != width.cells:
            width.check(path, cells, index, cut)
        try:        # fast path: every cell a plain number
            values[f] = [float(cells[c]) for c in flat]
            continue
        except (ValueError, IndexError):
            pass
        n_cells = len(cells)
        row = values[f]
        for k, c in enumerate(flat):
            if c >= n_cells:
                continue
            text = cell_text(cells[c])
            try:
                row[k] = parse_number(text)
            except ValueError:
                name = column_name(k // 3, k % 3)
                raise FormatError(path, f"row {index + 1}, column {name}: "
                                        f"cannot parse {text!r}") from None
    positions = values.reshape(n_frames, n_markers, 3)
    observed = np.isfinite(positions).all(axis=2)
    positions[~observed] = np.nan
    return positions, observed


def parse_column(path: Path, lines: Sequence[str], row_lines: np.ndarray, column: int,
                 delimiter: str, name: str, cut_row: int = -1) -> np.ndarray:
    """One column (Frame, Time) of the data rows as floats, NaN where empty, absent or
    the unread last cell of ``cut_row`` (see :func:`row_cells`)."""
    out = np.full(len(row_lines), np.nan)
    for f, index in enumerate(row_lines):
        cells = row_cells(lines, index, delimiter, cut_row)[0]
        if column < len(cells):
            text = cell_text(cells[column])
            try:
                out[f] = parse_number(text)
            except ValueError:
                raise FormatError(path, f"row {index + 1}, column {name}: "
                                        f"cannot parse {text!r}") from None
    return out


def frame_rate(path: Path, text: str, what: str) -> float:
    """A frame rate the file states, in Hz; FormatError unless a positive finite number.

    A file stating an absurd rate (``inf``, ``0``, ``-120``, ``nan``, ``abc``) is damaged or
    mis-edited: reading it as some default rate would silently rescale every time and
    every ``--max-gap`` in seconds.
    """
    try:
        rate = float(text)
    except ValueError:
        rate = float("nan")
    if not (np.isfinite(rate) and rate > 0):
        raise FormatError(path, f"{what} is {text!r}, not a frame rate (a positive, finite "
                                "number of Hz)")
    return rate


# The rate a new TRC or CSV file states for a clip without one (formats.write notes it). A
# file that states none is read as 0 Hz, not as this.
WRITTEN_RATE = 120.0


def writable_rate(rate: float) -> float:
    """The rate a new file states: WRITTEN_RATE for a clip without one (0 Hz: a C3D with no
    ``POINT:RATE``, an AMC, a file stating none), which is also the rate its Time column
    is written at."""
    return rate if np.isfinite(rate) and rate > 0 else WRITTEN_RATE


def rate_from_times(times: np.ndarray) -> float | None:
    """Frame rate implied by a time column, or None when it implies none.

    The median step is robust to a dropped row; when every step agrees with the mean step
    to within the rounding of printed times, the mean step over the whole span is used
    instead (times printed to 3 decimals at 120 Hz would otherwise give 125 Hz).
    """
    t = times[np.isfinite(times)]
    if t.size < 2:
        return None
    steps = np.diff(t)
    median = float(np.median(steps))
    if median <= 0:
        return None
    mean = float(t[-1] - t[0]) / (t.size - 1)
    step = mean if np.all(np.abs(steps - mean) <= 0.5 * mean) else median
    return round(1.0 / step, 6)


def first_frame_from(frames: np.ndarray, default: int = 1) -> int:
    """The number of the first row: the first Frame value when it is a whole number, less
    the rows before it whose Frame cell is empty, else ``default``.

    Rows are consecutive frames, so a blank first cell (then ``101``) numbers the first
    row 100; taking 101 put every frame number of a gap report one too high.
    """
    seen = np.flatnonzero(np.isfinite(frames))
    if seen.size and float(frames[seen[0]]).is_integer():
        return int(frames[seen[0]]) - int(seen[0])
    return default


def frame_steps_notes(frames: np.ndarray, row_lines: np.ndarray, name: str,
                      first_frame: int, *, subject: str | None = None,
                      read_as: str = "rows are read as consecutive frames"
                      ) -> tuple[str, ...]:
    """A note when a frame-number column does not count up by one per row.

    Readers take rows as consecutive frames (as OpenSim and BTK read a TRC), so the frame
    numbers of reports and outputs count rows from ``first_frame``; where the file's own
    numbers skip (rows deleted) or repeat, they differ from those, and the note says so.
    Empty cells (NaN) are passed over. ``subject`` (default "the NAME column is") and
    ``read_as`` word the note for a format without columns (an AMC's frame numbers).
    """
    seen = np.flatnonzero(np.isfinite(frames))
    values = frames[seen]
    wrong = np.flatnonzero(np.diff(values) != np.diff(seen))
    if wrong.size == 0:
        return ()
    k = int(wrong[0])
    more = f", and {wrong.size - 1} more place(s)" if wrong.size > 1 else ""
    subject = subject or f"the {name} column is"
    return (f"{subject} not consecutive "
            f"({format_float(values[k])} then {format_float(values[k + 1])} at line "
            f"{int(row_lines[seen[k + 1]]) + 1}{more}); {read_as} numbered from "
            f"{first_frame}",)


def format_float(value: float) -> str:
    """Shortest text that reads back as exactly ``value`` (``1.0`` written ``1``)."""
    text = repr(float(value))
    return text.removesuffix(".0")


def frame_rows(motion: Motion, rate: float, decimals: int | None) -> Iterator[list[str]]:
    """Each frame's cells for a new text file: its frame number and time (``rate`` Hz),
    then x, y, z of every marker (:func:`format_float`, or ``decimals`` fixed decimals),
    empty where the sample is missing.

    The numbers are formatted all at once from one list of the clip's floats rather than
    one function call each (an 85_12-sized clip, 550,000 numbers: a TRC or CSV took about
    1 s to write before); the text is the same.
    """
    n_frames, n_markers = motion.observed.shape
    missing = ~motion.observed
    for f, values in enumerate(motion.positions.reshape(n_frames, 3 * n_markers).tolist()):
        if decimals is None:
            cells = [text[:-2] if text.endswith(".0") else text for text in map(repr, values)]
        else:
            cells = [f"{value:.{decimals}f}" for value in values]
        for m in np.flatnonzero(missing[f]).tolist():
            cells[3 * m:3 * m + 3] = ("", "", "")
        yield [str(motion.first_frame + f), format_time(f / rate)] + cells


def format_time(seconds: float) -> str:
    """A time to 9 decimals without trailing zeros (``0``, ``0.008333333``, ``0.025``)."""
    text = f"{seconds:.9f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


# ----------------------------------------------------------------------------- patching

@dataclass(frozen=True)
class NumberStyle:
    """How a column prints its numbers: fixed decimals, or exponent notation."""

    decimals: int | None          # None: shortest exact text (format_float)
    exponent: bool = False

    def format(self, value: float) -> str:
        if self.decimals is None:
            return format_float(value)
        if self.exponent:
            return f"{value:.{self.decimals}e}"
        return f"{value:.{self.decimals}f}"


def _decimals(text: str) -> tuple[int, bool]:
    """Digits after the decimal point of a number cell (of its mantissa), and whether it
    is written with an exponent."""
    exponent = "e" in text or "E" in text
    if exponent:
        text = text.lower().split("e", 1)[0]
    dot = text.find(".")
    return (0 if dot < 0 else len(text) - dot - 1), exponent


def column_styles(source: TextSource, cells_needed: set[int]) -> dict[int, NumberStyle]:
    """The number style of each needed column, from the observed cells it already holds.

    A column prints with the largest number of decimals its observed cells use (files
    written with ``%g`` use fewer decimals for larger numbers; the most precise one is
    kept), in exponent notation when any of them does. A column with no observed cell
    takes the most precise style of the other needed columns; with none at all, the
    shortest exact text.
    """
    needed = sorted(cells_needed)
    decimals = dict.fromkeys(needed, -1)
    exponent: set[int] = set()
    for index in source.row_lines:
        cells = row_cells(source.lines, index, source.delimiter, source.cut_row)[0]
        n_cells = len(cells)
        for c in needed:
            if c >= n_cells:
                continue
            text = (cell_text(cells[c]) if '"' in cells[c] or BOM in cells[c]
                    else cells[c].strip())
            if text.lower() in MISSING_TOKENS:
                continue
            places, in_exponent = _decimals(text)
            if in_exponent:
                exponent.add(c)
            decimals[c] = max(decimals[c], places)
    best = {c: NumberStyle(d, c in exponent) for c, d in decimals.items() if d >= 0}
    fallback = (max(best.values(), key=lambda s: (s.decimals, s.exponent)) if best
                else NumberStyle(None))
    return {c: best.get(c, fallback) for c in cells_needed}


def patched_lines(source: TextSource, motion: Motion,
                  decimals: int | None = None) -> list[str]:
    """The original lines with the cells of samples whose observed state changed.

    Samples missing in the file and observed in ``motion`` are written with the column's
    own precision, their missing cells only: a coordinate the file holds for a partly
    observed sample (a blank Y beside a number in X) is never rewritten. Samples the
    file holds but the Motion marks missing (gaps added by ``simulate``) are blanked with
    the file's own missing token (the first one found in its rows, else an empty cell;
    in a file whose gaps were read from zeros and that has no such token, ``0`` in the
    column's precision). A filled sample read as a gap from zeros
    (:attr:`TextSource.zeros_are_gaps`) has all three cells rewritten. The values of
    samples observed in both are never rewritten.

    Parameters
    ----------
    source
        Handle of the file ``motion`` was read from (``source.fits(motion)`` must hold).
    motion
        The repaired clip.
    decimals
        Decimals for the filled cells; None matches each column's own precision.
    """
    if not source.fits(motion):     # formats.write says how; a direct call is refused too
        raise FormatError(None, "the clip no longer has the frames and markers of the file "
                                "it was read from, so it cannot be written as a patch of it: "
                                "write a new file with motion.replace(source=None)")
    filled = motion.observed & ~source.observed
    erased = source.observed & ~motion.observed
    frames, markers = np.nonzero(filled | erased)
    if frames.size == 0:
        return list(source.lines)
    token = missing_token(source) if erased.any() else ""
    zero_token = source.zeros_are_gaps and not token
    needed = {int(c) for c in np.unique(source.columns[markers].reshape(-1))}
    styles = (column_styles(source, needed) if decimals is None
              else dict.fromkeys(needed, NumberStyle(int(decimals))))
    lines = list(source.lines)
    cut_row = source.cut_row
    by_frame: dict[int, list[int]] = {}
    for f, m in zip(frames.tolist(), markers.tolist()):
        by_frame.setdefault(f, []).append(m)
    for f, marker_list in by_frame.items():
        index = int(source.row_lines[f])
        body, ending = split_ending(lines[index])
        cells = split_cells(body, source.delimiter)
        cut_cell = len(cells) - 1
        for m in marker_list:
            if erased[f, m]:
                for axis in range(3):
                    c = int(source.columns[m, axis])
                    _set_cell(cells, c, styles[c].format(0.0) if zero_token else token)
                continue
            zeros = source.zeros_are_gaps and all(
                _cell_value(cells, int(c)) == 0 for c in source.columns[m])
            for axis in range(3):
                c = int(source.columns[m, axis])
                if (not (index == cut_row and c == cut_cell) and not zeros
                        and _holds_value(cells, c)):
                    continue    # an observed cell of a partly observed sample: kept
                _set_cell(cells, c, styles[c].format(motion.positions[f, m, axis]))
            if source.w_columns is not None and source.w_columns[m] >= 0:
                w = int(source.w_columns[m])
                if w >= len(cells) or cell_text(cells[w]).lower() in MISSING_TOKENS:
                    _set_cell(cells, w, "1")
        if index == cut_row:
            # The file was cut short inside this row, so a reader sets its last cell aside:
            # blank the cut text unless a fill replaced it (a homogeneous ``1`` cannot be
            # cut), and give a short row back the cells of a complete one, empty, so that
            # the output reads back as written (a complete row whose last cell is empty or
            # printed in its column's precision is read whole). Never more cells than a
            # complete row: the output keeps the file's columns.
            kept = {int(c) for m in marker_list if filled[f, m] for c in source.columns[m]}
            if source.w_columns is not None:
                kept.update(source.w_columns.tolist())
            if cut_cell not in kept:
                cells[cut_cell] = ""
            cells.extend([""] * (source.width - len(cells)))
        lines[index] = source.delimiter.join(cells) + ending
    return lines


def missing_token(source: TextSource) -> str:
    """How this file writes a missing cell: the first missing token in its marker cells."""
    marker_cells = np.unique(source.columns.reshape(-1))
    for f in np.flatnonzero((~source.observed).any(axis=1)):
        cells = split_cells(split_ending(source.lines[int(source.row_lines[f])])[0],
                            source.delimiter)
        for c in marker_cells:
            if c < len(cells):
                text = cells[c].strip().lstrip(BOM)
                if text.lower() in MISSING_TOKENS:
                    return text
    return ""


def _cell_value(cells: list[str], index: int) -> float:
    """A row's cell as a number; NaN where it is missing, absent or not a number."""
    if index >= len(cells):
        return math.nan
    try:
        return parse_number(cell_text(cells[index]))
    except ValueError:
        return math.nan


def _holds_value(cells: list[str], index: int) -> bool:
    """Whether a row's cell holds a finite number (an observed coordinate)."""
    return math.isfinite(_cell_value(cells, index))


def _set_cell(cells: list[str], index: int, text: str) -> None:
    """Replace a cell's text, keeping its quotes and a byte order mark before it (the
    first cell of a headerless file); pad a short row with empty cells."""
    if index >= len(cells):
        cells.extend([""] * (index + 1 - len(cells)))
    mark = BOM if cells[index].startswith(BOM) else ""
    if cells[index].lstrip(BOM).strip().startswith('"'):
        text = f'"{text}"'
    cells[index] = mark + text
