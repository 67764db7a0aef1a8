"""Marker CSV files (``.csv``, ``.txt``): plain, Vicon Nexus, headerless and Kinetics Toolkit.

The layout is detected from the file itself.

Plain marker CSV
    Optional comment lines starting with ``#`` (``# units: mm, rate: 120`` is read), then
    a header row, then one row per frame. Optional ``Frame`` (``Frame#``, ``Frames``) and
    ``Time`` (``Time (s)``, ``time``, ``Time (Seconds)``) columns; each marker has three
    columns named ``NAME_X, NAME_Y, NAME_Z``, ``NAME:X ...`` or ``NAME.x ...`` (axis
    letter in any case, columns in any order). Other columns are ignored and listed in
    the source handle's notes. Cells are separated by ``,``, ``;`` or tab (the most
    frequent of the three in the header row); cells may be quoted.
Vicon Nexus export
    The first non-blank line names a section (``Trajectories``, ``Devices``, ``Joints``,
    ``Model Outputs``, ``Segments``). Each section has five header lines: its name, its
    sampling rate, the names row (``Subject:LASI`` above X, blanks above Y and Z), the
    axis row (``Frame, Sub Frame, X, Y, Z, ...``) and the units row; then its data rows up
    to a blank line. Only the ``Trajectories`` section is read; labels keep the
    ``Subject:`` prefix as Nexus writes it.
OptiTrack Motive export
    The first line holds the take's settings as name, value pairs (``Format Version``,
    ``Export Frame Rate``, ``Length Units`` ...); then the rows ``Type``, ``Name``, ``ID``
    (and ``Parent`` in newer versions), each with its label in the second cell (taken in
    that order where a file labels none), a row
    naming each column's quantity (``Position``, ``Rotation`` ...), and the axis row
    (``Frame, Time (Seconds)``, an optional ``TimeCode``, then ``X, Y, Z`` ...) above the
    data. Only the ``Position`` X, Y, Z columns of type ``Marker`` are read (labelled and
    unlabelled markers, named as Motive names them, ``Skeleton:LASI``, ``Unlabeled
    1000``); rigid bodies, bones and their solved markers (``Rigid Body Marker``, ``Bone
    Marker``: positions Motive computes from the solve, not measurements) and the
    quality columns are not, and the source handle's notes count them. The rate is the
    ``Export Frame Rate`` (else the ``Capture Frame Rate``), the unit the ``Length Units``
    (``Millimeters`` → mm, ``Centimeters`` → cm, ``Meters`` → m).
Headerless numeric CSV
    Every row is numeric, the first one too. With 3k columns they are k markers
    ``M001, M002, ...``; with 3k+1 the first column is a frame number (whole numbers) or
    a time in seconds, strictly increasing; with 3k+2 the first two are frame and time.
Kinetics Toolkit export (``ktk.TimeSeries`` written with pandas)
    A ``Time`` column, then four columns per point, ``NAME[0]`` .. ``NAME[3]``: x, y, z
    and the homogeneous coordinate (1 for a point). The fourth is not read; when a
    sample is filled and its fourth cell is missing it is written as ``1``.

Missing data: a sample is missing when any of its three cells is empty, ``NaN`` (any
case), ``NA`` or ``N/A``; with ``zero_is_missing="on"`` also when all three are exactly 0
(as QTM-derived exports and the MoCap Toolbox store gaps; ``_text.with_zero_gaps``).

Rows: every data row holds as many cells as the header row (the axis row in a Vicon
export, the first row in a headerless file); a row with fewer cells, or with values
beyond them, is a FormatError naming its line. Empty cells beyond them are accepted (a
trailing delimiter, spreadsheet padding), and lines of only empty cells after the last
row (``,,,,``, as a spreadsheet saves rows it once formatted) are not frames. A file
that does not end with a line ending is read whole (many tools end a file so) unless its
last row shows that the file was cut
short inside it (``_text.find_cut_row``): it holds fewer cells than a complete row, or
its last cell is not a number or is printed less precisely than the cells around it
(``956.933`` cut to ``956``). Then the last cell of that row is not read, the row may be
short, the samples of its absent or unread cells are missing, and the source handle's
notes say so.

Rate, first in this order: the ``# rate:`` comment; the Vicon rate line or the Motive
frame rate; the ``Time``
column (median step, or the mean step when all steps agree within rounding); the
``rate=`` option; else 0 Hz, "not known" (as a C3D without ``POINT:RATE``), so that a
``--max-gap`` in seconds fails rather than being read at a rate nobody stated. A rate
the file states (``120`` or ``120 Hz``) must be a
positive, finite number (``inf``, ``0``, ``-120``, ``nan`` or ``abc`` is a FormatError).
Units: the ``# units:`` comment; the Vicon units row or the Motive length units; the
``units=`` option; ``"mm"``
(``"m"`` for Kinetics Toolkit files, which are in SI units). Options only fill in what the
file does not state.

Writing: a Motion read from a CSV file (its ``source`` is this module's handle) is
written as a patched copy of that file (refused where the clip differs from the file in
anything else: ``formats.write``): only
the cells of samples that were missing and are now observed change, and of those only
the missing cells (a number beside a blank cell stays as it is); the cells of a sample
made missing since reading (``simulate``) are blanked with the file's own missing token.
A filled cell is
printed with the largest number of decimals that column's observed cells use (the file's
own precision; ``decimals=`` overrides), so read-back values agree with the Motion to that
precision. Any other Motion (``motion.replace(source=None)`` for one read from a CSV) is
written as a new plain CSV:
``# units: mm, rate: 120`` then ``Frame,Time,NAME_X,NAME_Y,NAME_Z,...``, empty cells for
missing samples, coordinates as the shortest text that reads back exactly; a clip without
a rate (0 Hz: a C3D with no ``POINT:RATE``, an AMC, a file stating none) is written at
120 Hz, and a clip without markers is refused. A patched file that ended without a line
ending still does, and its last row keeps its cells (an observed last value byte for
byte). If the file was cut
short inside that row and the row is patched, its unread last cell is blanked (unless
filled) and a short row gets the empty cells of a complete one, never more, so the output
reads back as written.
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
    is_blank,
    parse_column,
    parse_markers,
    parse_number,
    patched_lines,
    quote,
    rate_from_times,
    read_lines,
    read_zero_gaps,
    sniff_delimiter,
    split_cells,
    split_ending,
    writable_rate,
    write_lines,
)

DEFAULT_UNITS = "mm"
KINDS = ("csv", "vicon", "headerless", "ktk", "motive")

VICON_SECTIONS = ("trajectories", "devices", "joints", "model outputs", "segments")

# OptiTrack Motive's first cell, and its length units as the unit names mocapfill knows.
MOTIVE_FIRST_CELL = "format version"
MOTIVE_UNITS = {"millimeters": "mm", "centimeters": "cm", "meters": "m", "inches": "in",
                "feet": "ft"}

_FRAME = re.compile(r"^(frame|frames|frame#|frame ?number|frame_number)$", re.IGNORECASE)
_TIME = re.compile(r"^(time|time ?\((s|sec|secs|seconds)\)|time ?\[s\]|time_s)$",
                   re.IGNORECASE)
_AXIS = re.compile(r"^(?P<name>.+?)[_:. ](?P<axis>[xyz])$", re.IGNORECASE)
_KTK = re.compile(r"^(?P<name>.+)\[(?P<index>[0-3])\]$")
_KEY_ENDS = re.compile("[:=]")


def read(path: Path, *, rate: float | None = None, units: str | None = None,
         zero_is_missing: str = "auto") -> Motion:
    """Read a marker CSV file of any supported layout.

    Parameters
    ----------
    path
        The file.
    rate
        Frame rate in Hz, used only when the file states none (default None: such a file
        reads as 0 Hz, not known).
    units
        Length unit, used only when the file states none (default ``"mm"``; ``"m"`` for
        Kinetics Toolkit files).
    zero_is_missing
        ``"on"``: samples at exactly x = y = z = 0 are missing too; ``"auto"`` (no text
        file says it stores gaps so) and ``"off"`` read them as data.

    Returns
    -------
    Motion
        With ``source`` set to a handle the writer uses to patch this file.

    Raises
    ------
    FormatError
        Empty file, no data rows, no marker columns, a marker without all three axes, or
        a cell that is not a number (the message names the row and column).
    ParameterError
        ``zero_is_missing`` is not one of the three values.
    """
    return read_zero_gaps(_read_layout, path, rate, units, zero_is_missing)


def _read_layout(path: Path, rate: float | None, units: str | None) -> Motion:
    lines = read_lines(path)
    content = [i for i, line in enumerate(lines) if not is_blank(line)]
    if not content:
        raise FormatError(path, "empty file")
    comments: dict[str, str] = {}
    start = content[0]
    while start < len(lines) and (is_blank(lines[start]) or _body(lines, start).startswith("#")):
        if not is_blank(lines[start]):
            comments.update(_comment_items(_body(lines, start)))
        start += 1
    if start >= len(lines):
        raise FormatError(path, "no header row (only comment lines)")
    header = _body(lines, start)
    delimiter = sniff_delimiter(header)
    first = cell_text(split_cells(header, delimiter)[0]).lower()
    if first in VICON_SECTIONS:
        return _read_vicon(path, lines, delimiter, rate, units)
    if first == MOTIVE_FIRST_CELL:
        return _read_motive(path, lines, start, delimiter, rate, units)
    if _all_numeric(split_cells(header, delimiter)):
        return _read_headerless(path, lines, start, delimiter, comments, rate, units)
    return _read_plain(path, lines, start, delimiter, comments, rate, units)


def write(motion: Motion, path: Path, *, decimals: int | None = None,
          **_ignored: object) -> None:
    """Write a CSV: a patched copy of the source file when there is one, else a new file.

    Parameters
    ----------
    motion
        The clip.
    path
        Output file (``formats.write`` passes a temporary file it renames when done).
    decimals
        Decimals of written coordinates; None matches the source file's precision
        (patch) or writes the shortest exact text (new file).
    **_ignored
        Options meant for other formats.

    Raises
    ------
    FormatError
        The clip has no markers (a CSV without marker columns cannot be read back).
    """
    if patches(motion):
        write_lines(path, patched_lines(motion.source, motion, decimals))
    elif motion.n_markers == 0:
        raise FormatError(path, "the clip has no markers; a CSV file needs at least one")
    else:
        write_lines(path, new_file_lines(motion, decimals))


def patches(motion: Motion) -> bool:
    """Whether :func:`write` writes ``motion`` as a patched copy of the CSV it was read from."""
    source = motion.source
    return isinstance(source, TextSource) and source.kind in KINDS


def new_file_lines(motion: Motion, decimals: int | None = None) -> list[str]:
    """The lines of a new plain CSV holding ``motion`` (see the module docstring)."""
    names = new_file_names(motion.labels)
    header = ["Frame", "Time"] + [quote(f"{name}_{axis}", ",")
                                  for name in names for axis in "XYZ"]
    rate = writable_rate(motion.rate)
    lines = [f"# units: {motion.units}, rate: {format_float(rate)}\n",
             ",".join(header) + "\n"]
    lines.extend(",".join(cells) + "\n" for cells in frame_rows(
        motion, rate, decimals))
    return lines


# ----------------------------------------------------------------------------- layouts

def _read_plain(path: Path, lines: list[str], start: int, delimiter: str,
                comments: dict[str, str], rate: float | None,
                units: str | None) -> Motion:
    headers = [cell_text(c) for c in split_cells(_body(lines, start), delimiter)]
    frame_col = time_col = -1
    markers: dict[str, dict[int, int]] = {}
    w_cols: dict[str, int] = {}
    ignored: list[str] = []
    ktk = False
    for c, name in enumerate(headers):
        if frame_col < 0 and _FRAME.match(name):
            frame_col = c
        elif time_col < 0 and _TIME.match(name):
            time_col = c
        elif (match := _KTK.match(name)) is not None:
            ktk = True
            index = int(match["index"])
            if index == 3:
                w_cols[match["name"]] = c
            else:
                _add_axis(path, markers, match["name"], index, c, name)
        elif (match := _AXIS.match(name)) is not None:
            _add_axis(path, markers, match["name"], "xyz".index(match["axis"].lower()), c,
                      name)
        elif name:
            ignored.append(name)
    if not markers:
        raise FormatError(path, "no marker columns (expected NAME_X, NAME_Y, NAME_Z, "
                                "NAME:X ... or NAME.x ... in the header row)")
    for name, axes in markers.items():
        if len(axes) < 3:
            have = ", ".join("XYZ"[a] for a in sorted(axes))
            lack = ", ".join("XYZ"[a] for a in range(3) if a not in axes)
            raise FormatError(path, f"marker {name!r} has columns {have} but no {lack}")
    labels = tuple(markers)
    columns = np.array([[markers[n][a] for a in range(3)] for n in labels], dtype=int)
    row_lines = _data_rows(lines, start + 1, delimiter)
    if row_lines.size == 0:
        raise FormatError(path, "no data rows after the header")

    def column_name(marker: int, axis: int) -> str:
        return headers[columns[marker, axis]]

    width = RowWidth(_filled_width(headers), "the header row has")
    cut = find_cut_row(lines, row_lines, delimiter, width, columns)
    positions, observed = parse_markers(path, lines, row_lines, columns, delimiter,
                                        column_name, width, cut)
    frames = (parse_column(path, lines, row_lines, frame_col, delimiter, headers[frame_col],
                           cut) if frame_col >= 0 else np.array([]))
    times = (parse_column(path, lines, row_lines, time_col, delimiter, headers[time_col],
                          cut) if time_col >= 0 else np.array([]))
    first_frame = first_frame_from(frames)
    notes = (((f"ignored columns: {', '.join(ignored)}",) if ignored else ()) + _cut_note(cut)
             + (frame_steps_notes(frames, row_lines, headers[frame_col], first_frame)
                if frame_col >= 0 else ()))
    w_columns = (np.array([w_cols.get(n, -1) for n in labels], dtype=int) if ktk else None)
    source = TextSource("ktk" if ktk else "csv", tuple(lines), delimiter, row_lines,
                        columns, observed, labels, w_columns=w_columns, notes=notes,
                        cut_row=cut, width=width.cells)
    return Motion(positions, observed, labels,
                  _rate(path, comments, rate_from_times(times), rate),
                  comments.get("units") or units or ("m" if ktk else DEFAULT_UNITS),
                  source=source, path=path, first_frame=first_frame)


def _read_vicon(path: Path, lines: list[str], delimiter: str, rate: float | None,
                units: str | None) -> Motion:
    sections: dict[str, tuple[int, str]] = {}
    after_blank = True          # a section starts the file or follows an empty line
    for i in range(len(lines)):
        cells = [cell_text(c) for c in split_cells(_body(lines, i), delimiter)]
        if after_blank and cells[0].lower() in VICON_SECTIONS and not any(cells[1:]):
            sections.setdefault(cells[0].lower(), (i, cells[0]))
        after_blank = not any(cells)
    if "trajectories" not in sections:
        found = ", ".join(name for _, name in sections.values())
        raise FormatError(path, f"Vicon Nexus export without a Trajectories section "
                                f"(sections: {found}); only trajectories are read")
    top = sections["trajectories"][0]
    if top + 4 >= len(lines):
        raise FormatError(path, "Vicon Trajectories section ends inside its 5 header lines")
    head = [[cell_text(c) for c in split_cells(_body(lines, top + k), delimiter)]
            for k in range(5)]
    names_row, axes_row, units_row = head[2], head[3], head[4]
    blocks: dict[str, dict[int, int]] = {}
    current = ""
    for c, axis in enumerate(axes_row):
        if c < len(names_row) and names_row[c]:
            current = names_row[c]
        if c >= 2 and current and axis.upper() in ("X", "Y", "Z"):
            _add_axis(path, blocks, current, "XYZ".index(axis.upper()), c, f"{current} {axis}")
    complete = {name: axes for name, axes in blocks.items() if len(axes) == 3}
    if not complete:
        raise FormatError(path, "Vicon Trajectories section has no X, Y, Z marker columns")
    labels, columns, row_lines, width, cut, positions, observed = _marker_block(
        path, lines, delimiter, complete, axes_row, top + 5, "Vicon Trajectories section",
        "_", sectioned=True)
    frames = parse_column(path, lines, row_lines, 0, delimiter, "Frame", cut)
    unit_set = {units_row[c] for c in columns.reshape(-1)
                if c < len(units_row) and units_row[c]}
    if len(unit_set) > 1:
        raise FormatError(path, f"Vicon trajectories in mixed units: {sorted(unit_set)}")
    stated = head[1][0] if head[1] else ""
    file_rate = frame_rate(path, stated, "Trajectories rate") if stated else None
    others = [name for key, (_, name) in sections.items() if key != "trajectories"]
    first_frame = first_frame_from(frames)
    notes = (((f"sections not read: {', '.join(others)}",) if others else ()) + _cut_note(cut)
             + frame_steps_notes(frames, row_lines, "Frame", first_frame))
    source = TextSource("vicon", tuple(lines), delimiter, row_lines, columns, observed,
                        labels, notes=notes, cut_row=cut, width=width.cells)
    return Motion(positions, observed, labels, file_rate or rate or 0.0,
                  unit_set.pop() if unit_set else (units or DEFAULT_UNITS),
                  source=source, path=path, first_frame=first_frame)


def _read_motive(path: Path, lines: list[str], start: int, delimiter: str,
                 rate: float | None, units: str | None) -> Motion:
    settings = [cell_text(c) for c in split_cells(_body(lines, start), delimiter)]
    take = {settings[i].lower(): settings[i + 1] for i in range(0, len(settings) - 1, 2)}
    head: list[list[str]] = []       # the rows Type, Name, ID (Parent), then quantities
    axes_at = -1
    for i in range(start + 1, len(lines)):
        cells = [cell_text(c) for c in split_cells(_body(lines, i), delimiter)]
        if len(cells) > 1 and _FRAME.match(cells[0]) and _TIME.match(cells[1]):
            axes_at = i
            break
        if any(cells):
            head.append(cells)
    if axes_at < 0:
        raise FormatError(path, "OptiTrack Motive CSV without its axis row (Frame, "
                                "Time (Seconds), X, Y, Z ...)")
    # Each row's label is its second cell (``,Type,Marker,...``); where a file gives none,
    # the rows are taken in Motive's order. The quantities are the row above the axis row.
    labelled = {cells[1].lower(): cells for cells in head if len(cells) > 1 and not cells[0]}
    types = labelled.get("type", head[0] if len(head) >= 3 else None)
    names = labelled.get("name", head[1] if len(head) >= 3 else None)
    if types is None or names is None:
        raise FormatError(path, "OptiTrack Motive CSV without its Type, Name and quantity "
                                "(Position ...) rows above the axis row")
    quantities = head[-1]
    axes_row = [cell_text(c) for c in split_cells(_body(lines, axes_at), delimiter)]

    def cell(row: list[str], c: int) -> str:
        return row[c] if c < len(row) else ""

    blocks: dict[str, dict[int, int]] = {}
    ignored: dict[str, int] = {}
    for c in range(2, len(axes_row)):
        kind, name = cell(types, c), cell(names, c)
        axis = axes_row[c].upper()
        if (kind.lower() == "marker" and cell(quantities, c).lower() == "position"
                and name and axis in ("X", "Y", "Z")):
            _add_axis(path, blocks, name, "XYZ".index(axis), c, f"{name} {axis}")
        elif kind or name:
            ignored[kind or "untyped"] = ignored.get(kind or "untyped", 0) + 1
    complete = {name: axes for name, axes in blocks.items() if len(axes) == 3}
    if not complete:
        found = f" (it holds {', '.join(sorted(ignored))} columns)" if ignored else ""
        raise FormatError(path, f"OptiTrack Motive CSV has no Marker position columns "
                                f"(X, Y, Z){found}; export the markers too")
    labels, columns, row_lines, width, cut, positions, observed = _marker_block(
        path, lines, delimiter, complete, axes_row, axes_at + 1, "OptiTrack Motive CSV", " ")
    frames = parse_column(path, lines, row_lines, 0, delimiter, axes_row[0], cut)
    times = parse_column(path, lines, row_lines, 1, delimiter, axes_row[1], cut)
    stated = next(((key, take[key]) for key in ("export frame rate", "capture frame rate")
                   if take.get(key)), None)
    file_rate = (frame_rate(path, stated[1], stated[0].title()) if stated is not None
                 else rate_from_times(times))
    length_units = take.get("length units", "")
    first_frame = first_frame_from(frames)
    notes = ((("columns not read (not marker positions): " + ", ".join(
        f"{count} {kind}" for kind, count in ignored.items()),) if ignored else ())
        + _cut_note(cut) + frame_steps_notes(frames, row_lines, axes_row[0], first_frame))
    source = TextSource("motive", tuple(lines), delimiter, row_lines, columns, observed,
                        labels, notes=notes, cut_row=cut, width=width.cells)
    return Motion(positions, observed, labels, file_rate or rate or 0.0,
                  MOTIVE_UNITS.get(length_units.lower(), length_units.lower())
                  or units or DEFAULT_UNITS,
                  source=source, path=path, first_frame=first_frame)


def _marker_block(path: Path, lines: list[str], delimiter: str,
                  complete: dict[str, dict[int, int]], axes_row: list[str], start: int,
                  what: str, separator: str, *, sectioned: bool = False) -> tuple:
    """The markers ``complete`` (name → {axis: column}, all three axes) of a layout with an
    axis row (Vicon, Motive) and their samples in the data rows from line ``start``:
    (labels, columns, row_lines, width, cut_row, positions, observed). A column is named
    ``NAME{separator}X`` in an error message."""
    labels = tuple(complete)
    columns = np.array([[complete[n][a] for a in range(3)] for n in labels], dtype=int)
    row_lines = _data_rows(lines, start, delimiter, sectioned=sectioned)
    if row_lines.size == 0:
        raise FormatError(path, f"{what} has no data rows")

    def column_name(marker: int, axis: int) -> str:
        return f"{labels[marker]}{separator}{'XYZ'[axis]}"

    width = RowWidth(_filled_width(axes_row), "the axis row has")
    cut = find_cut_row(lines, row_lines, delimiter, width, columns)
    positions, observed = parse_markers(path, lines, row_lines, columns, delimiter,
                                        column_name, width, cut)
    return labels, columns, row_lines, width, cut, positions, observed


def _read_headerless(path: Path, lines: list[str], start: int, delimiter: str,
                     comments: dict[str, str], rate: float | None,
                     units: str | None) -> Motion:
    row_lines = _data_rows(lines, start, delimiter)
    n_cols = len(split_cells(_body(lines, start), delimiter))
    lead = n_cols % 3
    n_markers = n_cols // 3
    if n_markers == 0:
        raise FormatError(path, f"headerless CSV with {n_cols} columns holds no marker")
    labels = tuple(f"M{j + 1:03d}" for j in range(n_markers))
    columns = lead + np.arange(3 * n_markers, dtype=int).reshape(n_markers, 3)

    def column_name(marker: int, axis: int) -> str:
        return f"{columns[marker, axis] + 1} ({labels[marker]}_{'XYZ'[axis]})"

    width = RowWidth(n_cols, "the first row has")
    cut = find_cut_row(lines, row_lines, delimiter, width, columns)
    positions, observed = parse_markers(path, lines, row_lines, columns, delimiter,
                                        column_name, width, cut)
    leading = [parse_column(path, lines, row_lines, c, delimiter, str(c + 1), cut)
               for c in range(lead)]
    for values in leading:
        # a counter cut short in the row the file ends inside reads as missing
        counted = values[:-1] if cut >= 0 and np.isnan(values[-1]) else values
        if not (np.all(np.isfinite(counted)) and np.all(np.diff(counted) > 0)):
            raise FormatError(path, f"headerless CSV has {n_cols} columns, not a multiple "
                                    f"of 3, and its first {lead} column(s) are not an "
                                    "increasing frame/time counter")
    frames = times = np.array([])
    if lead == 2:
        frames, times = leading
    elif lead == 1:
        whole = np.all(np.mod(leading[0], 1) == 0)
        frames, times = (leading[0], times) if whole else (frames, leading[0])
    first_frame = first_frame_from(frames)
    notes = _cut_note(cut) + frame_steps_notes(frames, row_lines, "Frame", first_frame)
    source = TextSource("headerless", tuple(lines), delimiter, row_lines, columns,
                        observed, labels, notes=notes, cut_row=cut, width=width.cells)
    return Motion(positions, observed, labels,
                  _rate(path, comments, rate_from_times(times), rate),
                  comments.get("units") or units or DEFAULT_UNITS,
                  source=source, path=path, first_frame=first_frame)


# ----------------------------------------------------------------------------- helpers

def _body(lines: Sequence[str], index: int) -> str:
    body = split_ending(lines[index])[0]
    return body.lstrip("\ufeff") if index == 0 else body


def _comment_items(body: str) -> dict[str, str]:
    r"""The ``key: value`` (or ``key = value``) items of a ``#`` comment line, separated by
    ``,`` or ``;`` (``# units: mm, rate: 120``).

    In each item, the first ``:`` or ``=`` that follows a word (whitespace between them
    allowed) and has text after it ends the key, that word, lower-cased; the value is the
    rest of the item, stripped. These are the items ``re.findall(r"(\w+)\s*[:=]\s*
    ([^,;]+)")`` gave, found without it: that expression backtracked over a long word
    (``# aaa...``), in time growing with the square of its length.
    """
    items: dict[str, str] = {}
    for item in body.lstrip("#").replace(";", ",").split(","):
        start = 0               # where the text before the next ':' or '=' begins
        for at in (match.start() for match in _KEY_ENDS.finditer(item)):
            head = item[start:at].rstrip()
            key = len(head)
            while key and (head[key - 1].isalnum() or head[key - 1] == "_"):    # \w
                key -= 1
            if key < len(head) and at + 1 < len(item):
                items[head[key:].lower()] = item[at + 1:].strip()
                break
            start = at + 1
    return items


def _rate(path: Path, comments: dict[str, str], from_times: float | None,
          option: float | None) -> float:
    if "rate" in comments:
        stated = comments["rate"]
        if stated[-2:].lower() == "hz":         # "120 Hz" (no pattern: "\s*hz$" backtracked)
            stated = stated[:-2].rstrip()
        return frame_rate(path, stated, "the rate in the '#' comment line")
    for candidate in (from_times, option):
        if candidate is not None and candidate > 0:
            return float(candidate)
    return 0.0      # not known: see the module docstring


def _filled_width(headers: list[str]) -> int:
    """Cells up to the last non-empty header cell (a trailing delimiter adds an empty one)."""
    filled = [c for c, name in enumerate(headers) if name]
    return filled[-1] + 1 if filled else len(headers)


def _cut_note(cut_row: int) -> tuple[str, ...]:
    return (CUT_ROW_NOTE,) if cut_row >= 0 else ()


def _all_numeric(cells: list[str]) -> bool:
    """Whether a first row is data: every cell a number or a missing token, and not all
    of them empty (an all-``NaN`` first frame is data; an empty row is not)."""
    texts = [cell_text(raw) for raw in cells]
    try:
        for text in texts:
            parse_number(text)
    except ValueError:
        return False
    return any(texts)


def _add_axis(path: Path, markers: dict[str, dict[int, int]], name: str, axis: int,
              column: int, header: str) -> None:
    axes = markers.setdefault(name, {})
    if axis in axes:
        raise FormatError(path, f"column {header!r} appears twice")
    axes[axis] = column


def _data_rows(lines: Sequence[str], start: int, delimiter: str, *, sectioned: bool = False
               ) -> np.ndarray:
    """Indices of the data rows from ``start``: blank and ``#`` lines are skipped, and so
    are the lines of only empty cells after the last row (``,,,,``: rows a spreadsheet
    once formatted, not frames; between rows such a line is a frame with every sample
    missing).

    With ``sectioned`` (a sectioned Vicon file) a line with no text, or only empty cells,
    ends the section.
    """
    rows = []
    for i in range(start, len(lines)):
        body = split_ending(lines[i])[0]
        empty = not body.replace(delimiter, "").strip()
        if sectioned and empty:
            if rows:
                break
            continue
        if not body.strip():
            continue
        if body.lstrip().startswith("#"):
            continue
        rows.append((i, empty))
    while rows and rows[-1][1]:
        rows.pop()
    return np.array([i for i, _ in rows], dtype=int)


# What ``formats.for_output`` says of the names a new file gets, in its note on them.
NEW_FILE_NAMES = "names a CSV header holds"


def new_file_names(labels: Sequence[str]) -> list[str]:
    """The marker names of a new CSV: on one line, ``M001`` ... for an empty label, and
    unique (a repeated name would make its columns unreadable), like the TRC and C3D
    writers' names."""
    return unique_labels([_clean_label(label, j) for j, label in enumerate(labels)])


def _clean_label(label: str, index: int) -> str:
    label = " ".join(str(label).split("\n")).replace("\r", " ").strip()
    return label or f"M{index + 1:03d}"
