"""TRC marker files (Motion Analysis; OpenSim).

Layout::

    PathFileType 4 (X/Y/Z) walk.trc
    DataRate CameraRate NumFrames NumMarkers Units OrigDataRate OrigDataStartFrame OrigNumFrames
    60       60         900       41         mm    60           1                  900
    Frame#   Time       R.ASIS    (blank)    (blank) L.ASIS     ...
                        X1        Y1         Z1      X2         ...
    (blank line)
    1        0.000      ...

Reading is tolerant, because real files disagree with their own headers:

- cells are tab- or comma-separated (whichever the ``DataRate`` line uses); blanks
  around cells and around marker names are ignored;
- the marker names of a tab-delimited file are split on tabs alone, as OpenSim splits
  them: a ``"`` in a name is a character of it (``R"KNE``; CSV quoting made it open a
  quoted cell that swallowed the names up to the next ``"``). A comma-delimited file (a
  spreadsheet's) keeps CSV quoting, which a name holding a comma needs there;
- the ``X1 Y1 Z1`` line and the blank line are optional; key and value lines are matched
  on their non-empty cells when padding makes their cell counts differ;
- the marker names line and the rows are trusted over ``NumMarkers`` and ``NumFrames``:
  marker k takes cells 3k+2 .. 3k+4 of each row (as BTK and OpenSim read them), x, y, z
  triplets beyond the named markers (unnamed markers, as Motion Analysis Cortex writes
  them) are ignored, and a file with fewer rows than ``NumFrames`` (a truncated copy)
  gives the rows it holds. Each disagreement is described in the source handle's
  ``notes``; ``declared_frames`` and ``truncated_rows_read`` let a caller report "93 of
  652 declared frames read";
- a sample is missing when any of its cells is empty or ``NaN`` (any case); with
  ``zero_is_missing="on"`` also when all three are exactly 0 (``_text.with_zero_gaps``).

Strict where leniency would misread the file:

- every row holds the ``Frame#`` and ``Time`` cells and three per named marker; a row
  with fewer cells, or with cells beyond them that are neither empty (a trailing tab,
  as OpenSim writes after every cell) nor whole x, y, z triplets, is a FormatError
  naming its line;
- a file that does not end with a line ending is read whole unless its last row shows
  that the file was cut short inside it (``_text.find_cut_row``): fewer cells than a
  complete row, or a last cell that is not a number or is printed less precisely than
  the cells around it (``956.933`` cut to ``956``). Then the last cell of that row is not
  read, the row may be short, and the samples of its absent or unread cells are
  missing; the notes say so. A patched copy of a file without a final line ending has
  none either and keeps the cells of its last row; if the file was cut short and that
  row is patched, its unread last cell is blanked (unless filled) and a short row gets
  the empty cells of a complete one, so the output reads back as written;
- a marker name given twice in the ``Frame#`` line, and a ``DataRate`` that is not a
  positive, finite number (``inf``, ``0``, ``nan``), are FormatErrors.

Rate: ``DataRate``, else the ``Time`` column, else the ``rate=`` option, else 0 Hz, "not
known" (as a C3D without ``POINT:RATE``), so that a ``--max-gap`` in seconds fails rather
than being read at a rate nobody stated.
Units: ``Units``, else the ``units=`` option, else mm. ``first_frame``: the first
``Frame#`` value, else ``OrigDataStartFrame``, else 1.

Writing: a Motion read from a TRC file is written as a patched copy (refused where the
clip differs from the file in anything else: ``formats.write``): only the missing cells
of samples that were missing and are now observed change (a number beside a blank cell
stays as it is), printed with the largest number of decimals that column's observed
cells use (``decimals=`` overrides); the cells of a sample made missing since reading
(``simulate``) are blanked with the file's own missing token.
Any other Motion (``motion.replace(source=None)`` for one read from a TRC) is written in
exactly the layout OpenSim's ``TRCFileAdapter`` writes: tab-delimited,
``PathFileType\\t4\\t(X/Y/Z)\\t<name>``, the 8 header keys and their values, each marker
name followed by three tabs, ``X1 Y1 Z1`` ... numbered from 1, a
blank line, then rows whose cells are each followed by a tab; ``Frame#`` counts from
``first_frame`` (= ``OrigDataStartFrame``), time from 0, missing samples are empty
cells, coordinates the shortest text that reads back exactly. A clip without a rate (0
Hz: a C3D with no ``POINT:RATE``, an AMC, a file stating none) is written at 120 Hz,
with a note; a clip without markers is refused.

Marker names in a new file have the characters OpenSim rejects in component names
(whitespace, ``\\``, ``/``, ``*``, ``+``) replaced by ``_``: a TRC is written for OpenSim,
and a name it rejects makes the whole file unusable there, whereas the renamed marker
is still recognisable. ``"`` is replaced too: OpenSim keeps it as a character of the
name, but readers that split tab-separated text as CSV (pandas' ``read_csv``,
spreadsheets) take it for a quote and merge the names after it. Names that two labels
become alike get ``_2``, ``_3`` ... (``formats.write`` notes the renaming). A patched
file keeps its names as they are.
"""
from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..motion import Motion, unique_labels
from ._text import (
    CUT_ROW_NOTE,
    RowWidth,
    TextSource,
    cell_text,
    find_cut_row,
    first_frame_from,
    format_float,
    frame_rate,
    frame_rows,
    frame_steps_notes,
    parse_column,
    parse_markers,
    patched_lines,
    rate_from_times,
    read_lines,
    read_zero_gaps,
    split_cells,
    split_ending,
    writable_rate,
    write_lines,
)

DEFAULT_UNITS = "mm"
HEADER_KEYS = ("DataRate", "CameraRate", "NumFrames", "NumMarkers", "Units",
               "OrigDataRate", "OrigDataStartFrame", "OrigNumFrames")

_AXIS_LABEL = re.compile(r"^[XYZ]\d+$", re.IGNORECASE)
# What a new file's marker names do not hold: the characters OpenSim rejects in a
# component name, and a double quote (see the module docstring).
_NOT_IN_NAMES = re.compile(r'[\s\\/*+"]')
# What would split the PathFileType line into lines (str.splitlines') or cells (a tab).
_HEADER_BREAKS = re.compile("[\t\n\v\f\r\x1c-\x1e\x85\u2028\u2029]+")


def read(path: Path, *, rate: float | None = None, units: str | None = None,
         zero_is_missing: str = "auto") -> Motion:
    """Read a TRC file.

    Parameters
    ----------
    path
        The file.
    rate
        Frame rate in Hz, used only when the file states none (default None: such a file
        reads as 0 Hz, not known).
    units
        Length unit, used only when the header has no ``Units`` (default ``"mm"``).
    zero_is_missing
        ``"on"``: samples at exactly x = y = z = 0 are missing too (blank or ``NaN``
        cells always are); ``"auto"`` and ``"off"`` read them as data.

    Returns
    -------
    Motion
        With ``source`` set to a :class:`~mocapfill.formats._text.TextSource` that the
        writer uses to patch this file and that carries the reader's ``notes``.

    Raises
    ------
    FormatError
        Not a TRC file, a header line missing, no marker names, no data rows, or a cell
        that is not a number (the message names the row and column).
    ParameterError
        ``zero_is_missing`` is not one of the three values.
    """
    return read_zero_gaps(_read, path, rate, units, zero_is_missing)


def _read(path: Path, rate: float | None, units: str | None) -> Motion:
    lines = read_lines(path)
    if not lines or not _body(lines, 0).startswith("PathFileType"):
        raise FormatError(path, "not a TRC file (first line does not start with "
                                "PathFileType)")
    keys_at = _find(lines, 1, 6, lambda body: body.strip().startswith("DataRate"))
    if keys_at < 0 or keys_at + 1 >= len(lines):
        raise FormatError(path, "TRC header has no DataRate ... line with its values")
    keys_body = _body(lines, keys_at)
    delimiter = "\t" if "\t" in keys_body else "," if "," in keys_body else ""
    if not delimiter:
        raise FormatError(path, "TRC header is neither tab- nor comma-delimited")
    header = _header(keys_body, _body(lines, keys_at + 1), delimiter)
    names_at = _find(lines, keys_at + 2, keys_at + 5,
                     lambda body: body.strip().startswith("Frame#"))
    if names_at < 0:
        raise FormatError(path, "TRC header has no Frame# Time <marker names> line")
    labels = tuple(name for name in (cell_text(c) for c in
                                     _name_cells(_body(lines, names_at), delimiter)[2:])
                   if name)
    if not labels:
        raise FormatError(path, "TRC file names no markers")
    seen: set[str] = set()
    for name in labels:
        if name in seen:
            raise FormatError(path, f"marker name {name!r} appears twice in the Frame# line")
        seen.add(name)
    start = names_at + 1
    if start < len(lines) and _is_axis_line(_body(lines, start), delimiter):
        start += 1
    row_lines = np.array([i for i in range(start, len(lines))
                          if _body(lines, i).replace(delimiter, "").strip()], dtype=int)
    if row_lines.size == 0:
        raise FormatError(path, "TRC file has no data rows")

    n_markers = len(labels)
    columns = 2 + np.arange(3 * n_markers, dtype=int).reshape(n_markers, 3)
    width = RowWidth(2 + 3 * n_markers, f"Frame#, Time and {n_markers} named markers take",
                     triplets=True)
    cut = find_cut_row(lines, row_lines, delimiter, width, columns)
    last_short = (cut >= 0
                  and len(split_cells(split_ending(lines[cut])[0], delimiter)) < width.cells)

    def column_name(marker: int, axis: int) -> str:
        return f"{'XYZ'[axis]}{marker + 1} ({labels[marker]})"

    positions, observed = parse_markers(path, lines, row_lines, columns, delimiter,
                                        column_name, width, cut)
    frames = parse_column(path, lines, row_lines, 0, delimiter, "Frame#", cut)
    times = parse_column(path, lines, row_lines, 1, delimiter, "Time", cut)

    declared_frames = _int(header.get("NumFrames"))
    notes = _notes(lines, row_lines, delimiter, header, n_markers, declared_frames,
                   cut >= 0, last_short)
    truncated = (len(row_lines) if declared_frames is not None
                 and len(row_lines) < declared_frames else None)
    stated = header.get("DataRate")
    file_rate = frame_rate(path, stated, "DataRate") if stated else rate_from_times(times)
    start_frame = _int(header.get("OrigDataStartFrame"))
    first_frame = first_frame_from(frames, 1 if start_frame is None else start_frame)
    notes += frame_steps_notes(frames, row_lines, "Frame#", first_frame)
    source = TextSource("trc", tuple(lines), delimiter, row_lines, columns, observed,
                        labels, declared_frames=declared_frames,
                        truncated_rows_read=truncated, notes=tuple(notes), cut_row=cut,
                        width=width.cells)
    return Motion(positions, observed, labels, file_rate or rate or 0.0,
                  header.get("Units") or units or DEFAULT_UNITS, source=source, path=path,
                  first_frame=first_frame)


def write(motion: Motion, path: Path, *, decimals: int | None = None,
          target: Path | None = None, **_ignored: object) -> None:
    """Write a TRC: a patched copy of the source file when there is one, else a new file.

    Parameters
    ----------
    motion
        The clip.
    path
        Output file (``formats.write`` passes a temporary file it renames when done).
    target
        The file ``path`` becomes, whose name the ``PathFileType`` line states (default:
        ``path``; the temporary's name is cut short where the target's is long).
    decimals
        Decimals of written coordinates; None matches the source file's precision
        (patch) or writes the shortest exact text (new file).
    **_ignored
        Options meant for other formats.

    Raises
    ------
    FormatError
        The clip has no markers (a TRC naming none cannot be read back).
    """
    if patches(motion):
        write_lines(path, patched_lines(motion.source, motion, decimals))
    elif motion.n_markers == 0:
        raise FormatError(path, "the clip has no markers; a TRC file needs at least one")
    else:
        write_lines(path, new_file_lines(motion, Path(target or path).name, decimals))


def patches(motion: Motion) -> bool:
    """Whether :func:`write` writes ``motion`` as a patched copy of the TRC it was read from."""
    source = motion.source
    return isinstance(source, TextSource) and source.kind == "trc"


def new_file_lines(motion: Motion, name: str, decimals: int | None = None) -> list[str]:
    """The lines of a new TRC file in OpenSim's layout (see the module docstring)."""
    rate = writable_rate(motion.rate)
    n_frames, n_markers = motion.n_frames, motion.n_markers
    values = (format_float(rate), format_float(rate), str(n_frames), str(n_markers),
              motion.units, format_float(rate), str(motion.first_frame), str(n_frames))
    lines = [f"PathFileType\t4\t(X/Y/Z)\t{_HEADER_BREAKS.sub('_', name)}\n",
             "\t".join(HEADER_KEYS) + "\n",
             "\t".join(values) + "\n",
             "Frame#\tTime\t" + "".join(f"{name}\t\t\t"
                                        for name in opensim_names(motion.labels)) + "\n",
             "\t\t" + "".join(f"X{k}\tY{k}\tZ{k}\t" for k in range(1, n_markers + 1)) + "\n",
             "\n"]
    # Every cell, the last included, is followed by a tab.
    lines.extend("\t".join(cells) + "\t\n" for cells in frame_rows(
        motion, rate, decimals))
    return lines


def opensim_name(label: str, index: int) -> str:
    """``label`` with the characters OpenSim rejects, and ``"``, replaced by ``_``
    (``M001`` if empty)."""
    name = _NOT_IN_NAMES.sub("_", str(label).strip())
    return name or f"M{index + 1:03d}"


def opensim_names(labels: Sequence[str]) -> list[str]:
    """:func:`opensim_name` of each label, made unique as the C3D reader makes repeated
    labels unique (``R ASI`` and ``R_ASI`` become ``R_ASI``, ``R_ASI_2``): a TRC naming a
    marker twice is not read."""
    return unique_labels([opensim_name(label, j) for j, label in enumerate(labels)])


# What ``formats.for_output`` says of the names a new file gets, in its note on them.
NEW_FILE_NAMES = "names OpenSim accepts"
new_file_names = opensim_names


# ----------------------------------------------------------------------------- helpers

def _body(lines: Sequence[str], index: int) -> str:
    body = split_ending(lines[index])[0]
    return body.lstrip("\ufeff") if index == 0 else body


def _find(lines: Sequence[str], start: int, stop: int, test) -> int:
    for i in range(start, min(stop, len(lines))):
        if test(_body(lines, i)):
            return i
    return -1


def _name_cells(body: str, delimiter: str) -> list[str]:
    """The raw cells of the ``Frame#`` line: split on tabs alone in a tab-delimited file,
    as OpenSim splits it, so that a ``"`` in a name stays in that name (see the module
    docstring); with CSV quoting in a comma-delimited one."""
    return body.split(delimiter) if delimiter == "\t" else split_cells(body, delimiter)


def _header(keys_body: str, values_body: str, delimiter: str) -> dict[str, str]:
    """Header keys and values; padded value lines are matched on their non-empty cells."""
    keys = [cell_text(c) for c in split_cells(keys_body, delimiter)]
    values = [cell_text(c) for c in split_cells(values_body, delimiter)]
    named = [k for k in keys if k]
    filled = [v for v in values if v]
    if len(named) == len(filled) and len(keys) != len(values):
        return dict(zip(named, filled))
    return {k: v for k, v in zip(keys, values) if k}


def _is_axis_line(body: str, delimiter: str) -> bool:
    cells = [cell_text(c) for c in split_cells(body, delimiter)]
    filled = [c for c in cells if c]
    return bool(filled) and all(_AXIS_LABEL.match(c) for c in filled)


def _notes(lines: Sequence[str], row_lines: np.ndarray, delimiter: str,
           header: dict[str, str], n_markers: int, declared_frames: int | None,
           cut: bool, last_short: bool) -> list[str]:
    notes = []
    declared_markers = _int(header.get("NumMarkers"))
    if declared_markers is not None and declared_markers != n_markers:
        notes.append(f"header declares {declared_markers} markers, the names line has "
                     f"{n_markers}; {n_markers} read")
    n_rows = len(row_lines)
    if declared_frames is not None and n_rows < declared_frames:
        notes.append(f"truncated: {n_rows} of {declared_frames} declared frames read")
    elif declared_frames is not None and n_rows > declared_frames:
        notes.append(f"header declares {declared_frames} frames; {n_rows} rows read")
    width = 2 + 3 * n_markers
    overlong = sum(1 for i in row_lines
                   if any(c.strip() for c in
                          split_cells(split_ending(lines[i])[0], delimiter)[width:]))
    if overlong:
        notes.append(f"{overlong} rows hold values beyond the {n_markers} named markers' "
                     "columns; ignored")
    if cut:
        notes.append(CUT_ROW_NOTE)
    if last_short:
        notes.append("the last row is shorter than the header implies; its absent cells "
                     "read as missing")
    return notes


def _int(text: str | None) -> int | None:
    value = _float(text)
    return int(value) if value is not None and value.is_integer() else None


def _float(text: str | None) -> float | None:
    try:
        return float(text) if text else None
    except ValueError:
        return None
