"""Marker CSV: plain, Vicon Nexus, headerless and Kinetics Toolkit layouts; patch writer."""
from __future__ import annotations

import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import csv as csvfmt
from mocapfill.formats._text import (
    cell_text,
    parse_number,
    printed_whole,
    read_lines,
    row_cells,
    split_cells,
    split_ending,
)
from mocapfill.motion import Motion
from tests.conftest import shared_file, shared_files


def write_text(tmp_path: Path, text: str, name: str = "clip.csv") -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode())
    return path


def fill_by_interp(motion: Motion) -> Motion:
    """Fill every gap of markers not missing for the whole clip by linear interpolation."""
    positions, observed = motion.positions.copy(), motion.observed.copy()
    t = np.arange(motion.n_frames)
    for j in range(motion.n_markers):
        seen = observed[:, j]
        if seen.any() and not seen.all():
            for axis in range(3):
                positions[~seen, j, axis] = np.interp(t[~seen], t[seen], positions[seen, j, axis])
            observed[:, j] = True
    return motion.with_positions(positions, observed)


def printed_resolution(text: str) -> float:
    """Half the last printed digit of a number cell: the rounding a reader may see."""
    text = text.strip().strip('"').lower()
    mantissa, _, exponent = text.partition("e")
    decimals = len(mantissa) - mantissa.find(".") - 1 if "." in mantissa else 0
    return 0.5 * 10.0 ** (int(exponent or 0) - decimals)


def assert_patch_invariant(original: Motion, repaired: Motion, out: Path) -> None:
    """Lines without a filled cell are identical; in the others only the missing cells of
    filled samples differ (the numbers of a partly observed sample stay); reading the
    output back gives the filled values to the precision they were printed."""
    source = original.source
    filled = repaired.observed & ~original.observed
    expected: dict[int, set[int]] = {}
    kept: dict[tuple[int, int], float] = {}         # (row, cell) -> the value it holds
    for f, m in zip(*np.nonzero(filled)):
        index = int(source.row_lines[f])
        readable = row_cells(source.lines, index, source.delimiter, source.cut_row)[0]
        cells = set()
        for c in source.columns[m].tolist():
            value = float(parse_number(cell_text(readable[c]))) if c < len(readable) else np.nan
            if np.isfinite(value):
                kept[index, c] = value
            else:
                cells.add(c)
        if source.w_columns is not None and source.w_columns[m] >= 0:
            cells.add(int(source.w_columns[m]))
        expected.setdefault(int(source.row_lines[f]), set()).update(cells)
    old_lines, new_lines = list(source.lines), read_lines(out)
    assert len(new_lines) == len(old_lines)
    for i, (old, new) in enumerate(zip(old_lines, new_lines)):
        if i not in expected:
            assert new == old, f"line {i + 1} changed"
            continue
        old_body, old_end = split_ending(old)
        new_body, new_end = split_ending(new)
        assert new_end == old_end
        old_cells = split_cells(old_body, source.delimiter)
        new_cells = split_cells(new_body, source.delimiter)
        old_cells += [""] * (len(new_cells) - len(old_cells))
        assert len(new_cells) == len(old_cells)
        changed = {c for c, (a, b) in enumerate(zip(old_cells, new_cells)) if a != b}
        assert changed <= expected[i], f"line {i + 1}: cells {changed - expected[i]} changed"
    back = formats.read(out)
    np.testing.assert_array_equal(back.observed, repaired.observed)
    frames, markers = np.nonzero(filled)
    rows: dict[int, list[str]] = {}
    for f, m in zip(frames, markers):
        index = int(source.row_lines[f])
        if index not in rows:
            rows[index] = split_cells(split_ending(new_lines[index])[0], source.delimiter)
        row = rows[index]
        for axis in range(3):
            c = int(source.columns[m, axis])
            if (index, c) in kept:
                assert back.positions[f, m, axis] == kept[index, c]
                continue
            text = row[c]
            value = repaired.positions[f, m, axis]
            error = abs(back.positions[f, m, axis] - value)
            assert error <= printed_resolution(text) + 8 * np.spacing(abs(value)), text


def assert_every_cut_reads_as_a_prefix(path: Path, samples=None) -> None:
    """Each copy of ``path`` cut short at any byte (an interrupted copy or download) is
    refused with a FormatError or reads as a prefix of the file's frames whose observed
    samples hold the file's values: a number cut short is never read as data.

    ``samples(motion)`` gives the (frames, ...) values and observed mask compared
    (positions by default). A cut that changes the labels (a headerless file cut inside its
    first row) is a different, valid file and is not compared.
    """
    samples = samples or (lambda motion: (motion.positions, motion.observed))
    whole = formats.read(path)
    values, observed = samples(whole)
    cut = path.with_name(f"{path.stem}_cut{path.suffix}")
    data = path.read_bytes()
    for size in range(1, len(data)):
        cut.write_bytes(data[:size])
        try:
            motion = formats.read(cut)
        except FormatError:
            continue
        if motion.labels != whole.labels:
            continue
        cut_values, cut_observed = samples(motion)
        n = len(cut_observed)
        assert n <= len(observed), size
        assert not (cut_observed & ~observed[:n]).any(), (size, data[size - 20:size])
        np.testing.assert_array_equal(cut_values[cut_observed], values[:n][cut_observed],
                                      err_msg=repr(data[size - 20:size]))


def patch_round_trip(path: Path, tmp_path: Path) -> tuple[Motion, Motion, Path]:
    original = formats.read(path)
    repaired = fill_by_interp(original)
    out = tmp_path / f"repaired{path.suffix}"
    formats.write(repaired, out)
    assert_patch_invariant(original, repaired, out)
    return original, repaired, out


# ----------------------------------------------------------------------------- plain CSV

PLAIN = ("Frame,Time,LASI_X,LASI_Y,LASI_Z,RASI_X,RASI_Y,RASI_Z\n"
         "1,0.00,1.5,2.5,3.5,10.25,20.25,30.25\n"
         "2,0.01,1.6,2.6,3.6,,,\n"
         "3,0.02,1.7,2.7,3.7,10.75,20.75,30.75\n")


def test_reads_name_underscore_axis_columns(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, PLAIN))
    assert motion.labels == ("LASI", "RASI")
    np.testing.assert_array_equal(motion.positions[0, 1], [10.25, 20.25, 30.25])


@pytest.mark.parametrize("header", ["A:X,A:Y,A:Z", "A.x,A.y,A.z", "A_x,A_Y,A_z", "A X,A Y,A Z"])
def test_reads_other_axis_separators(tmp_path, header):
    motion = csvfmt.read(write_text(tmp_path, f"{header}\n1,2,3\n"))
    assert motion.labels == ("A",)
    np.testing.assert_array_equal(motion.positions[0, 0], [1, 2, 3])


def test_axis_columns_may_come_in_any_order(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "A_Z,A_X,A_Y\n3,1,2\n"))
    np.testing.assert_array_equal(motion.positions[0, 0], [1, 2, 3])


def test_time_column_gives_rate_and_frame_column_first_frame(tmp_path):
    text = "Frame,Time (s),A_X,A_Y,A_Z\n11,0.000,1,2,3\n12,0.008,1,2,3\n13,0.017,1,2,3\n" \
           "14,0.025,1,2,3\n"
    motion = csvfmt.read(write_text(tmp_path, text))
    assert motion.rate == pytest.approx(120.0)      # not 125 from the rounded 0.008 step
    assert motion.first_frame == 11


def test_without_time_column_rate_option_is_used_else_the_rate_is_not_known(tmp_path):
    path = write_text(tmp_path, "A_X,A_Y,A_Z\n1,2,3\n1,2,3\n")
    assert csvfmt.read(path, rate=250).rate == 250
    # 0 Hz, as a C3D without POINT:RATE: it was 120, so --max-gap 0.5s meant 60 frames
    # of a rate the file never stated.
    assert csvfmt.read(path).rate == 0
    assert csvfmt.read(path).first_frame == 1


@pytest.mark.parametrize("text", [
    "Trajectories\n\n,,A,,\nFrame,Sub Frame,X,Y,Z\n,,mm,mm,mm\n1,0,1,2,3\n2,0,1,2,3\n",
    "Format Version,1.23,Length Units,Millimeters\n\n,Type,Marker,Marker,Marker\n"
    ",Name,A,A,A\n,ID,1,1,1\n,,Position,Position,Position\n"
    "Frame,Time (Seconds),X,Y,Z\n0,,1,2,3\n1,,1,2,3\n",
], ids=["vicon", "motive"])
def test_a_vicon_or_motive_export_stating_no_rate_reads_as_0_hz(tmp_path, text):
    path = write_text(tmp_path, text)
    assert csvfmt.read(path).rate == 0
    assert csvfmt.read(path, rate=250).rate == 250


def test_time_column_wins_over_rate_option(tmp_path):
    path = write_text(tmp_path, "time,A_X,A_Y,A_Z\n0,1,2,3\n0.01,1,2,3\n")
    assert csvfmt.read(path, rate=250).rate == pytest.approx(100)


def test_units_option_and_default(tmp_path):
    path = write_text(tmp_path, "A_X,A_Y,A_Z\n1,2,3\n")
    assert csvfmt.read(path).units == "mm"
    assert csvfmt.read(path, units="m").units == "m"


def test_comment_line_states_units_and_rate(tmp_path):
    path = write_text(tmp_path, "# units: m, rate: 200\nA_X,A_Y,A_Z\n1,2,3\n1,2,3\n")
    motion = csvfmt.read(path, units="mm", rate=50)
    assert (motion.units, motion.rate) == ("m", 200)


@pytest.mark.parametrize("line, items", [
    ("# units: mm, rate: 120", {"units": "mm", "rate": "120"}),
    ("#Units=m;RATE = 100 Hz", {"units": "m", "rate": "100 Hz"}),
    ("# made by: hand, rate: 50", {"by": "hand", "rate": "50"}),   # the word before ':'
    ("# : x: 1, k = v = w", {"x": "1", "k": "v = w"}),
    ("# a: , b:, c::d", {"a": "", "c": ":d"}),                     # b: nothing after ':'
    ("# no items here", {})])
def test_comment_items_are_key_separator_value(line, items):
    assert csvfmt._comment_items(line) == items


@settings(max_examples=300, deadline=None)
@given(st.text(alphabet="#aZ_1é٣ \t\u3000:=,;-.", max_size=30))
def test_comment_items_are_those_the_regular_expression_found(body):
    # The expression the reader used, fine on short lines (quadratic on a long word).
    found = re.findall(r"(\w+)\s*[:=]\s*([^,;]+)", body.lstrip("#"))
    assert csvfmt._comment_items(body) == {k.lower(): v.strip() for k, v in found}


def test_a_comment_line_of_one_long_word_is_read_past(tmp_path):
    # The regular expression backtracked over the word: 100,000 letters took over a minute.
    path = write_text(tmp_path, "# " + "a" * 100_000 + ", units: m, rate: 50\n"
                                "A_X,A_Y,A_Z\n1,2,3\n")
    motion = csvfmt.read(path)
    assert (motion.units, motion.rate, motion.n_frames) == ("m", 50, 1)


@pytest.mark.parametrize("token", ["", "NaN", "nan", "NA", " nan "])
def test_missing_tokens_make_the_sample_missing(tmp_path, token):
    path = write_text(tmp_path, f"A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1,2,3,{token},{token},{token}\n")
    motion = csvfmt.read(path)
    assert motion.observed.tolist() == [[True, False]]
    assert np.isnan(motion.positions[0, 1]).all()


def test_one_missing_cell_makes_the_whole_sample_missing(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "A_X,A_Y,A_Z\n1,,3\n"))
    assert not motion.observed[0, 0]


@pytest.mark.parametrize("delimiter", [";", "\t"])
def test_semicolon_and_tab_delimiters_are_sniffed(tmp_path, delimiter):
    text = PLAIN.replace(",", delimiter)
    motion = csvfmt.read(write_text(tmp_path, text))
    assert motion.labels == ("LASI", "RASI")
    assert motion.observed.tolist() == [[True, True], [True, False], [True, True]]


def test_quoted_header_and_cells_are_read(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, '"A,1_X","A,1_Y","A,1_Z"\n"1","2","3"\n'))
    assert motion.labels == ("A,1",)
    np.testing.assert_array_equal(motion.positions[0, 0], [1, 2, 3])


def test_unparsable_cell_error_names_file_row_and_column(tmp_path):
    path = write_text(tmp_path, "LASI_X,LASI_Y,LASI_Z\n1,2,3\n1,abc,3\n")
    with pytest.raises(FormatError) as info:
        csvfmt.read(path)
    assert str(info.value) == f"{path}: row 3, column LASI_Y: cannot parse 'abc'"


def test_header_only_file_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="no data rows"):
        csvfmt.read(write_text(tmp_path, "A_X,A_Y,A_Z\n"))


def test_file_without_marker_columns_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="no marker columns"):
        csvfmt.read(write_text(tmp_path, "Frame,Time,Force\n1,0,3\n"))


def test_empty_file_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="empty file"):
        csvfmt.read(write_text(tmp_path, "\n\n"))


def test_marker_without_all_three_axes_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="'A' has columns X, Y but no Z"):
        csvfmt.read(write_text(tmp_path, "A_X,A_Y\n1,2\n"))


def test_other_columns_are_ignored_and_noted(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "Frame,Sub Frame,A_X,A_Y,A_Z\n1,0,1,2,3\n"))
    assert motion.labels == ("A",)
    assert motion.source.notes == ("ignored columns: Sub Frame",)


# ----------------------------------------------------------------------------- writers

def test_patch_changes_only_filled_cells(tmp_path):
    original = csvfmt.read(write_text(tmp_path, PLAIN.replace("\n", "\r\n")))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    lines = out.read_bytes().decode().split("\r\n")
    assert lines[:2] + lines[3:] == PLAIN.split("\n")[:2] + PLAIN.split("\n")[3:]
    assert lines[2] == "2,0.01,1.6,2.6,3.6,10.50,20.50,30.50"   # the column's 2 decimals
    assert_patch_invariant(original, repaired, out)


def test_patch_keeps_the_observed_cells_of_a_partly_observed_sample(tmp_path):
    # A blank Y makes the sample missing, but X and Z are observations: only Y is filled.
    text = PLAIN.replace("1.6,2.6,3.6,,,", "1.6,2.6,3.6,10.9,,30.1")
    original = csvfmt.read(write_text(tmp_path, text))
    assert original.observed[1].tolist() == [True, False]
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_text() == text.replace(",10.9,,30.1", ",10.9,20.50,30.1")


def test_patch_rewrites_the_unread_cut_cell_of_a_partly_observed_sample(tmp_path):
    # The file ends inside its last row and "8" is printed with fewer decimals than its
    # column: it may be "8.25" cut short, so it is filled.
    path = write_text(tmp_path, "A_X,A_Y,A_Z\n1.00,2.00,3.00\n5.00,6.00,7.00\n7.00,,8")
    original = csvfmt.read(path)
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)           # held at 5, 6, 7
    assert out.read_text().endswith("\n7.00,6.00,7.00")   # no cell added, no line ending


def test_patch_keeps_the_last_cell_of_a_file_without_a_final_line_ending(tmp_path):
    # "8" is as precise as its column: the file merely lacks its final line ending.
    path = write_text(tmp_path, "A_X,A_Y,A_Z\n1,2,3\n5,6,7\n7,,8")
    original = csvfmt.read(path)
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)           # Y held at 6
    assert out.read_text() == "A_X,A_Y,A_Z\n1,2,3\n5,6,7\n7,6,8"


def test_patch_leaves_still_missing_samples_with_the_files_missing_token(tmp_path):
    text = "A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1,2,3,NaN,NaN,NaN\nNaN,NaN,NaN,NaN,NaN,NaN\n1,2,3,4,5,6\n"
    original = csvfmt.read(write_text(tmp_path, text))
    positions, observed = original.positions.copy(), original.observed.copy()
    positions[1, 0], observed[1, 0] = [1, 2, 3], True          # fill A only
    out = tmp_path / "out.csv"
    csvfmt.write(original.with_positions(positions, observed), out)
    assert out.read_text().splitlines()[2] == "1,2,3,NaN,NaN,NaN"


def test_patch_keeps_quoted_missing_cells_quoted(tmp_path):
    original = csvfmt.read(write_text(tmp_path, 'A_X,A_Y,A_Z\n"1.0","2.0","3.0"\n"","",""\n'
                                                '"1.0","2.0","3.0"\n'))
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_text().splitlines()[2] == '"1.0","2.0","3.0"'


def test_patch_never_rewrites_samples_the_file_holds(tmp_path):
    original = csvfmt.read(write_text(tmp_path, PLAIN))
    moved = original.with_positions(original.positions + 1.0, original.observed)
    out = tmp_path / "out.csv"
    csvfmt.write(moved, out)
    assert out.read_text() == PLAIN


def test_patch_of_exponent_columns_writes_exponent_notation(tmp_path):
    original = csvfmt.read(write_text(tmp_path, "A_X,A_Y,A_Z\n1.50e+02,2.0e+00,3.0e-01\n"
                                                ",,\n2.50e+02,4.0e+00,5.0e-01\n"))
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_text().splitlines()[2] == "2.00e+02,3.0e+00,4.0e-01"


def test_patch_keeps_a_byte_order_mark(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbfA_X,A_Y,A_Z\r\n1.0,2.0,3.0\r\n,,\r\n3.0,4.0,5.0\r\n")
    original = csvfmt.read(path)
    assert original.labels == ("A",)
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_bytes() == path.read_bytes().replace(b"\n,,\r", b"\n2.0,3.0,4.0\r")


def test_decimals_option_sets_the_precision_of_filled_cells(tmp_path):
    original = csvfmt.read(write_text(tmp_path, PLAIN))
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out, decimals=4)
    assert out.read_text().splitlines()[2] == "2,0.01,1.6,2.6,3.6,10.5000,20.5000,30.5000"


def new_motion() -> Motion:
    rng = np.random.default_rng(0)
    positions = rng.normal(scale=500, size=(5, 2, 3))
    observed = np.ones((5, 2), bool)
    observed[1:3, 1] = False
    return Motion(positions, observed, ("LASI", "R ASI"), 100.0, "m", first_frame=7)


def test_new_file_layout(tmp_path):
    out = tmp_path / "new.csv"
    formats.write(new_motion(), out)
    lines = out.read_text().splitlines()
    assert lines[0] == "# units: m, rate: 100"
    assert lines[1] == "Frame,Time,LASI_X,LASI_Y,LASI_Z,R ASI_X,R ASI_Y,R ASI_Z"
    assert lines[3].startswith("8,0.01,") and lines[3].endswith(",,,")


def test_new_file_round_trip_is_exact(tmp_path):
    motion = new_motion()
    out = tmp_path / "new.csv"
    formats.write(motion, out)
    back = formats.read(out)
    assert back.labels == motion.labels
    assert (back.rate, back.units, back.first_frame) == (100.0, "m", 7)
    np.testing.assert_array_equal(back.observed, motion.observed)
    np.testing.assert_array_equal(back.positions, motion.positions)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(allow_nan=True, allow_infinity=False, width=64), min_size=6,
                max_size=6 * 4))
def test_new_file_round_trip_reproduces_any_floats(values):
    n = len(values) // 6 * 6 or 6
    data = np.array((values * 2)[:n], dtype=float).reshape(-1, 2, 3)
    motion = Motion(data, np.isfinite(data).all(axis=2), ("A", "B"), 120.0)
    lines = csvfmt.new_file_lines(motion)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "x.csv"
        path.write_text("".join(lines))
        back = csvfmt.read(path)
    np.testing.assert_array_equal(back.observed, motion.observed)
    np.testing.assert_array_equal(back.positions, motion.positions)


def test_new_file_cells_hold_each_number_as_written_and_nothing_for_missing_samples():
    data = np.array([[[1.0, -0.5, 1e-7], [2.25, 3.0, 4.0]],
                     [[5.0, 6.0, 7.0], [0.1, 0.2, 0.3]]])
    observed = np.array([[True, False], [True, True]])
    motion = Motion(data, observed, ("A", "B"), 100.0)
    shortest = csvfmt.new_file_lines(motion)[2:]
    assert shortest == ["1,0,1,-0.5,1e-07,,,\n", "2,0.01,5,6,7,0.1,0.2,0.3\n"]
    fixed = csvfmt.new_file_lines(motion, decimals=2)[2:]
    assert fixed == ["1,0,1.00,-0.50,0.00,,,\n", "2,0.01,5.00,6.00,7.00,0.10,0.20,0.30\n"]


def test_motion_that_no_longer_fits_its_source_is_refused_and_written_new_on_request(
        tmp_path):
    # A patch cannot hold it; a new file is what the caller asks for (tests/formats/
    # test_patch.py: formats.write refuses it first, saying what differs).
    original = csvfmt.read(write_text(tmp_path, PLAIN))
    cut = original.replace(positions=original.positions[:2], observed=original.observed[:2])
    out = tmp_path / "out.csv"
    with pytest.raises(FormatError, match=r"write a new file with motion.replace\(source="):
        csvfmt.write(cut, out)
    csvfmt.write(cut.replace(source=None), out)
    assert out.read_text().splitlines()[1].startswith("Frame,Time,LASI_X")


# ----------------------------------------------------------------------------- Vicon Nexus

VICON = ("Trajectories,,,,,,,\r\n"
         "100,,,,,,,\r\n"
         ",,Sub:LASI,,,Sub:RASI,,\r\n"
         "Frame,Sub Frame,X,Y,Z,X,Y,Z\r\n"
         ",,mm,mm,mm,mm,mm,mm\r\n"
         "5,0,1.25,2.25,3.25,,,\r\n"
         "6,0,1.5,2.5,3.5,10.5,20.5,30.5\r\n"
         "7,0,,,,10.75,20.75,30.75\r\n"
         "\r\n"
         "Model Outputs,,,,,,,\r\n"
         "100,,,,,,,\r\n"
         ",,Sub:LKneeAngles,,,,,\r\n"
         "Frame,Sub Frame,X,Y,Z,,,\r\n"
         ",,deg,deg,deg,,,\r\n"
         "5,0,1,2,3,,,\r\n")


def test_vicon_export_reads_the_trajectories_section(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, VICON))
    assert motion.labels == ("Sub:LASI", "Sub:RASI")
    assert (motion.rate, motion.units, motion.first_frame) == (100.0, "mm", 5)
    assert motion.observed.tolist() == [[True, False], [True, True], [False, True]]
    np.testing.assert_array_equal(motion.positions[2, 1], [10.75, 20.75, 30.75])
    assert motion.source.notes == ("sections not read: Model Outputs",)


def test_vicon_trajectories_after_a_devices_section(tmp_path):
    devices = "Devices,,,,,,,\r\n1000,,,,,,,\r\n,,FP1,,,,,\r\nFrame,Sub Frame,Fx,Fy,Fz,,,\r\n" \
              ",,N,N,N,,,\r\n1,0,1,2,3,,,\r\n,,,,,,,\r\n"
    motion = csvfmt.read(write_text(tmp_path, devices + VICON))
    assert motion.labels == ("Sub:LASI", "Sub:RASI") and motion.n_frames == 3


def test_vicon_export_without_trajectories_is_a_format_error(tmp_path):
    text = VICON[VICON.index("Model Outputs"):]
    with pytest.raises(FormatError, match="without a Trajectories section"):
        csvfmt.read(write_text(tmp_path, text))


def test_vicon_patch_changes_only_filled_cells(tmp_path):
    original = csvfmt.read(write_text(tmp_path, VICON))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert_patch_invariant(original, repaired, out)
    assert out.read_bytes().split(b"\r\n")[5] == b"5,0,1.25,2.25,3.25,10.50,20.50,30.50"


def test_vicon_export_with_a_byte_order_mark_reads_and_keeps_it(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf" + VICON.encode())
    original = csvfmt.read(path)
    assert original.labels == csvfmt.read(write_text(tmp_path, VICON)).labels
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_bytes().startswith(b"\xef\xbb\xbfTrajectories")
    assert_patch_invariant(original, fill_by_interp(original), out)


# ----------------------------------------------------------------------------- OptiTrack Motive

# A Motive 1.25 export: a rigid body (rotation, position, error), its solved markers, a
# labelled marker, an unlabelled one, a TimeCode column; blank cells for occlusions; a
# quoted name holding the delimiter.
MOTIVE = ("Format Version,1.25,Take Name,Take 01,Take Notes,,Capture Frame Rate,240.000000,"
          "Export Frame Rate,120.000000,Capture Start Time,2024-01-01 01.00.00.000 PM,"
          "Total Frames in Take,4,Total Exported Frames,4,Rotation Type,Quaternion,"
          "Length Units,Meters,Coordinate Space,Global\n"
          "\n"
          ",Type,,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,Rigid Body,"
          "Rigid Body,Rigid Body,Rigid Body Marker,Rigid Body Marker,Rigid Body Marker,"
          "Rigid Body Marker,Marker,Marker,Marker,Marker,Marker,Marker\n"
          ",Name,,Wand,Wand,Wand,Wand,Wand,Wand,Wand,Wand,Wand:Marker1,Wand:Marker1,"
          "Wand:Marker1,Wand:Marker1,\"Sub, A:LASI\",\"Sub, A:LASI\",\"Sub, A:LASI\","
          "Unlabeled 1000,Unlabeled 1000,Unlabeled 1000\n"
          ",ID,,1,1,1,1,1,1,1,1,1:1,1:1,1:1,1:1,2,2,2,3,3,3\n"
          ",Parent,,,,,,,,,,Wand,Wand,Wand,Wand,,,,,,\n"
          ",,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,"
          "Mean Marker Error,Position,Position,Position,Marker Quality,Position,Position,"
          "Position,Position,Position,Position\n"
          "Frame,Time (Seconds),TimeCode,X,Y,Z,W,X,Y,Z,,X,Y,Z,,X,Y,Z,X,Y,Z\n"
          "0,0.000000,00:00:00:00,0,0,0,1,0.1,0.2,0.3,0.0001,0.11,0.21,0.31,1,"
          "0.512500,0.625000,0.750000,1.000000,2.000000,3.000000\n"
          "1,0.008333,00:00:00:01,0,0,0,1,0.1,0.2,0.3,0.0001,0.11,0.21,0.31,1,"
          ",,,1.100000,2.100000,3.100000\n"
          "2,0.016667,00:00:00:02,0,0,0,1,0.1,0.2,0.3,0.0001,0.11,0.21,0.31,1,"
          "0.537500,0.650000,0.775000,,,\n"
          "3,0.025000,00:00:00:03,0,0,0,1,0.1,0.2,0.3,0.0001,0.11,0.21,0.31,1,"
          "0.550000,0.662500,0.787500,1.300000,2.300000,3.300000\n")


def test_motive_export_reads_its_markers_rate_units_and_first_frame(tmp_path):
    # OptiTrack is one of the systems mocapfill's users record with: a Motive CSV export
    # was refused ("no marker columns").
    motion = csvfmt.read(write_text(tmp_path, MOTIVE))
    assert motion.labels == ("Sub, A:LASI", "Unlabeled 1000")
    assert (motion.rate, motion.units, motion.first_frame) == (120.0, "m", 0)
    assert motion.observed.tolist() == [[True, True], [False, True], [True, False],
                                        [True, True]]
    np.testing.assert_array_equal(motion.positions[0, 0], [0.5125, 0.625, 0.75])
    np.testing.assert_array_equal(motion.positions[3, 1], [1.3, 2.3, 3.3])
    assert motion.source.notes[0] == ("columns not read (not marker positions): "
                                      "8 Rigid Body, 4 Rigid Body Marker")


def test_motive_export_without_row_labels_reads_its_rows_in_motives_order(tmp_path):
    # Rows written ",,Marker,..." instead of ",Type,Marker,..." (as some tools that write
    # Motive's layout do): Type, Name and ID are taken in that order.
    lines = MOTIVE.splitlines(keepends=True)
    text = "".join(lines[:2] + [",," + line.split(",", 2)[2] for line in lines[2:5]]
                   + lines[6:])                     # no Parent row either
    motion = csvfmt.read(write_text(tmp_path, text))
    reference = csvfmt.read(write_text(tmp_path, MOTIVE, "reference.csv"))
    assert motion.labels == reference.labels
    np.testing.assert_array_equal(motion.positions, reference.positions)


def test_motive_patch_changes_only_filled_cells(tmp_path):
    original = csvfmt.read(write_text(tmp_path, MOTIVE))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert_patch_invariant(original, repaired, out)
    row = out.read_text().splitlines()[9]                  # frame 1
    assert row.endswith(",0.525000,0.637500,0.762500,1.100000,2.100000,3.100000")


def test_motive_export_of_rigid_bodies_only_is_a_format_error(tmp_path):
    lines = MOTIVE.splitlines(keepends=True)
    keep = 15                                       # frame, time, timecode, the rigid body
    text = "".join(lines[:2] + [",".join(line.split(",")[:keep]) + "\n" for line in lines[2:]])
    with pytest.raises(FormatError, match="no Marker position columns .*Rigid Body"):
        csvfmt.read(write_text(tmp_path, text))


def test_motive_export_without_its_axis_row_is_a_format_error(tmp_path):
    text = "".join(line for line in MOTIVE.splitlines(keepends=True)
                   if not line.startswith("Frame,"))
    with pytest.raises(FormatError, match="without its axis row"):
        csvfmt.read(write_text(tmp_path, text))


def test_every_cut_of_a_motive_export_reads_as_a_prefix_of_its_samples_or_fails(tmp_path):
    assert_every_cut_reads_as_a_prefix(write_text(tmp_path, MOTIVE))


# ----------------------------------------------------------------------------- headerless

def test_headerless_file_with_3k_columns_is_k_markers(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "1,2,3,4,5,6\n1.5,2.5,3.5,NaN,NaN,NaN\n"))
    assert motion.labels == ("M001", "M002")
    assert motion.observed.tolist() == [[True, True], [True, False]]
    assert motion.rate == 0                 # no time column: the file states no rate


def test_headerless_file_may_start_with_an_all_missing_frame(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "NaN,NaN,NaN\n1,2,3\n"))
    assert motion.observed.tolist() == [[False], [True]]


def test_headerless_leading_frame_column(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "3,1,2,3\n4,1,2,3\n"))
    assert (motion.labels, motion.first_frame) == (("M001",), 3)


def test_headerless_leading_time_column(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "0,1,2,3\n0.02,1,2,3\n0.04,1,2,3\n"))
    assert motion.rate == pytest.approx(50)


def test_headerless_leading_frame_and_time_columns(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "1,0,1,2,3\n2,0.005,1,2,3\n"))
    assert (motion.first_frame, motion.rate) == (1, pytest.approx(200))


@pytest.mark.parametrize("text", [
    "Frame,Time,A_X,A_Y,A_Z\n1,0,1,2,3\n2,0.01,1,2,3\n5,0.04,1,2,3\n",
    "1,1,2,3\n2,1,2,3\n5,1,2,3\n",
    "Trajectories\n100\n,,S:A,,\nFrame,Sub Frame,X,Y,Z\n,,mm,mm,mm\n"
    "1,0,1,2,3\n2,0,1,2,3\n5,0,1,2,3\n",
], ids=["plain", "headerless", "vicon"])
def test_frame_numbers_that_skip_are_noted(tmp_path, text):
    motion = csvfmt.read(write_text(tmp_path, text))
    assert motion.n_frames == 3
    assert any(note.startswith("the Frame column is not consecutive (2 then 5 at line ")
               for note in motion.source.notes)


@pytest.mark.parametrize("text", [
    "Frame,Time,A_X,A_Y,A_Z\n1,0,1,2,3\n2,0.01,,,\n3,0.02,1,2,3\n",
    "1,2,3\nNaN,NaN,NaN\n1,2,3\n",
], ids=["plain", "headerless"])
def test_rows_of_empty_cells_after_the_data_are_not_frames(tmp_path, text):
    # A spreadsheet saves rows it once formatted as ",,,,": padding, not frames whose
    # every sample is missing (the TRC and Vicon readers pass them over too).
    path = write_text(tmp_path, text + ",,,,\r\n, ,\n,,,,")
    motion = csvfmt.read(path)
    assert motion.n_frames == 3
    assert motion.observed[:, 0].tolist() == [True, False, True]
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(motion), out)
    assert out.read_bytes().endswith(b",,,,\r\n, ,\n,,,,")


def test_a_row_of_empty_cells_between_frames_is_a_frame(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, "1,2,3\n,,\n1,2,3\n"))
    assert motion.observed[:, 0].tolist() == [True, False, True]


def test_headerless_extra_column_that_is_not_a_counter_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="not a multiple of 3"):
        csvfmt.read(write_text(tmp_path, "5,1,2,3\n4,1,2,3\n"))


def test_headerless_patch_changes_only_filled_cells(tmp_path):
    original = csvfmt.read(write_text(tmp_path, "1.0,2.0,3.0\nNaN,NaN,NaN\n2.0,3.0,4.0\n"))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert out.read_text() == "1.0,2.0,3.0\n1.5,2.5,3.5\n2.0,3.0,4.0\n"


def test_headerless_file_with_a_byte_order_mark_reads_and_keeps_it(tmp_path):
    # Excel's "CSV UTF-8" save puts a BOM before the first number of a headerless file.
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbf1,1.0,2.0,3.0\n2,NaN,NaN,NaN\n3,2.0,3.0,4.0\n")
    original = csvfmt.read(path)
    assert (original.labels, original.first_frame) == (("M001",), 1)
    assert original.observed.tolist() == [[True], [False], [True]]
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_bytes() == path.read_bytes().replace(b"NaN,NaN,NaN", b"1.5,2.5,3.5")


def test_headerless_patch_of_a_first_cell_after_a_byte_order_mark_keeps_the_mark(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes(b"\xef\xbb\xbfNaN,2.0,3.0\n1.0,2.0,3.0\n2.0,3.0,4.0\n")
    original = csvfmt.read(path)
    assert original.observed.tolist() == [[False], [True], [True]]
    repaired = original.with_positions(np.nan_to_num(original.positions, nan=0.5),
                                       np.ones_like(original.observed))
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert out.read_bytes() == b"\xef\xbb\xbf0.5,2.0,3.0\n1.0,2.0,3.0\n2.0,3.0,4.0\n"


def test_patch_of_whole_number_columns_rounds_to_whole_numbers(tmp_path):
    original = csvfmt.read(write_text(tmp_path, "1,2,3\nNaN,NaN,NaN\n3,4,5\n"))
    out = tmp_path / "out.csv"
    csvfmt.write(fill_by_interp(original), out)
    assert out.read_text() == "1,2,3\n2,3,4\n3,4,5\n"


# ----------------------------------------------------------------------------- Kinetics Toolkit

KTK = ("Time,A[0],A[1],A[2],A[3],B[0],B[1],B[2],B[3]\r\n"
       "0,0.1,0.2,0.3,1,1.1,1.2,1.3,1\r\n"
       "0.02,0.2,0.3,0.4,1,nan,nan,nan,nan\r\n"
       "0.04,0.3,0.4,0.5,1,1.3,1.4,1.5,1")


def test_ktk_export_reads_points_in_metres(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, KTK))
    assert motion.labels == ("A", "B")
    assert (motion.units, motion.rate) == ("m", pytest.approx(50))
    assert motion.observed.tolist() == [[True, True], [True, False], [True, True]]


def test_ktk_patch_writes_the_homogeneous_coordinate(tmp_path):
    original = csvfmt.read(write_text(tmp_path, KTK))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert_patch_invariant(original, repaired, out)
    assert out.read_bytes().split(b"\r\n")[2] == b"0.02,0.2,0.3,0.4,1,1.2,1.3,1.4,1"


# ----------------------------------------------------------------------------- damaged files

# Layout -> (a file of two complete rows of markers A and B, ending in B's z = 6.75; how a
# row-length error names what sets the length).
DAMAGE = {
    "plain": ("A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1,2,3,4,5,6\n1.5,2.5,3.5,4.5,5.5,6.75\n",
              "the header row has 6"),
    "headerless": ("1,2,3,4,5,6\n1.5,2.5,3.5,4.5,5.5,6.75\n", "the first row has 6"),
    "vicon": ("Trajectories\n100\n,,S:A,,,S:B,,\nFrame,Sub Frame,X,Y,Z,X,Y,Z\n"
              ",,mm,mm,mm,mm,mm,mm\n1,0,1,2,3,4,5,6\n2,0,1.5,2.5,3.5,4.5,5.5,6.75\n",
              "the axis row has 8"),
}


@pytest.mark.parametrize("layout", DAMAGE)
def test_a_file_cut_inside_its_last_number_reads_that_sample_as_missing(tmp_path, layout):
    text = DAMAGE[layout][0].removesuffix(".75\n")           # 6.75 cut to 6
    motion = csvfmt.read(write_text(tmp_path, text))
    assert motion.observed.tolist() == [[True, True], [True, False]]
    np.testing.assert_array_equal(motion.positions[1, 0], [1.5, 2.5, 3.5])
    assert any("ends inside its last row" in note for note in motion.source.notes)


@pytest.mark.parametrize("text", [PLAIN, "1.5,2.25,3.125\n,,\n-1.75,20.5,300.25\n", VICON],
                         ids=["plain", "headerless", "vicon"])
def test_every_cut_of_a_file_reads_as_a_prefix_of_its_samples_or_fails(tmp_path, text):
    assert_every_cut_reads_as_a_prefix(write_text(tmp_path, text))


@pytest.mark.parametrize("layout", DAMAGE)
def test_a_short_row_is_a_format_error_naming_the_file_and_line(tmp_path, layout):
    text, width = DAMAGE[layout]
    lines = text.splitlines(keepends=True)
    lines[-1] = ",".join(lines[-1].split(",")[:4]) + "\n"
    path = write_text(tmp_path, "".join(lines))
    with pytest.raises(FormatError) as info:
        csvfmt.read(path)
    assert str(info.value) == f"{path}: line {len(lines)} holds 4 cells; {width}"


@pytest.mark.parametrize("layout", DAMAGE)
def test_a_row_with_a_value_beyond_the_header_is_a_format_error(tmp_path, layout):
    text, width = DAMAGE[layout]
    path = write_text(tmp_path, text.removesuffix("\n") + ",7\n")
    n_cells = int(width.split()[-1]) + 1
    with pytest.raises(FormatError) as info:
        csvfmt.read(path)
    assert str(info.value) == (f"{path}: line {len(text.splitlines())} holds {n_cells} "
                               f"cells; {width}")


@pytest.mark.parametrize("text", ["A_X,A_Y,A_Z\n1,2,3,\n4,5,6,\n",
                                  "A_X,A_Y,A_Z,\n1,2,3\n4,5,6,\n",
                                  "A_X;A_Y;A_Z\n1;2;3;;\n4;5;6\n"])
def test_empty_cells_beyond_the_header_are_accepted(tmp_path, text):
    # A guard: trailing delimiters and spreadsheet padding are not ragged rows.
    motion = csvfmt.read(write_text(tmp_path, text))
    assert motion.observed.tolist() == [[True], [True]]


def test_comment_rate_may_carry_its_unit(tmp_path):
    path = write_text(tmp_path, "# units: mm, rate: 100 Hz\nA_X,A_Y,A_Z\n1,2,3\n")
    assert csvfmt.read(path).rate == 100


@pytest.mark.parametrize("stated, rate", [("100 Hz", 100), ("100hz", 100), ("100 \t HZ", 100),
                                          ("100", 100), ("1e2 hZ", 100)])
def test_comment_rate_units_are_any_case_after_any_blanks(tmp_path, stated, rate):
    path = write_text(tmp_path, f"# units: mm, rate: {stated}\nA_X,A_Y,A_Z\n1,2,3\n")
    assert csvfmt.read(path).rate == rate


@pytest.mark.parametrize("stated", ["Hz", "100 Hz Hz", "100 H z"])
def test_a_comment_rate_of_hz_alone_or_twice_is_a_format_error(tmp_path, stated):
    path = write_text(tmp_path, f"# units: mm, rate: {stated}\nA_X,A_Y,A_Z\n1,2,3\n")
    with pytest.raises(FormatError, match="not a frame rate"):
        csvfmt.read(path)


def test_a_comment_rate_with_a_long_run_of_blanks_is_a_format_error(tmp_path):
    # "\s*hz$" was tried from every blank of the run: 200,000 blanks took over a minute.
    path = write_text(tmp_path, "# rate: 1" + " " * 200_000 + "x\nA_X,A_Y,A_Z\n1,2,3\n")
    with pytest.raises(FormatError, match=r"the rate in the '#' comment line is '1 +x', not"):
        csvfmt.read(path)


@pytest.mark.parametrize("stated", ["inf", "0", "-120", "nan", "abc"])
def test_a_comment_rate_that_is_not_a_positive_finite_number_is_a_format_error(tmp_path,
                                                                                stated):
    path = write_text(tmp_path, f"# units: mm, rate: {stated}\nA_X,A_Y,A_Z\n1,2,3\n")
    with pytest.raises(FormatError) as info:
        csvfmt.read(path, rate=100)
    assert str(info.value).startswith(f"{path}: ") and repr(stated) in str(info.value)


@pytest.mark.parametrize("stated", ["inf", "0", "-100"])
def test_a_vicon_rate_that_is_not_a_positive_finite_number_is_a_format_error(tmp_path,
                                                                              stated):
    path = write_text(tmp_path, VICON.replace("\r\n100,", f"\r\n{stated},", 1))
    with pytest.raises(FormatError) as info:
        csvfmt.read(path)
    assert str(info.value).startswith(f"{path}: ") and repr(stated) in str(info.value)


def test_patch_of_the_row_a_file_was_cut_inside_reads_back_as_written(tmp_path):
    head = "A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1.0,2.0,3.0,4.0,5.0,6.0\n"
    path = write_text(tmp_path, head + "1.0,2.0,3.0,,,\n1.0,2.0,3.0,5.0,6.0,7")
    original = csvfmt.read(path)
    repaired = fill_by_interp(original)                 # B held at 4, 5, 6 to the end
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert_patch_invariant(original, repaired, out)
    # B's 5.0 and 6.0 in the last row are observed cells, kept; its cut 7 is filled.
    assert out.read_text() == head + "1.0,2.0,3.0,4.0,5.0,6.0\n1.0,2.0,3.0,5.0,6.0,6.0"


def test_patch_of_the_row_a_file_was_cut_inside_blanks_its_unread_last_cell(tmp_path):
    path = write_text(tmp_path, "A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1.0,2.0,3.0,4.0,5.0,6.0\n,,,5.0,6.0,7")
    original = csvfmt.read(path)
    positions, observed = original.positions.copy(), original.observed.copy()
    positions[1, 0], observed[1, 0] = [1, 2, 3], True   # fill A only; B stays missing
    repaired = original.with_positions(positions, observed)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert out.read_text().endswith("\n1.0,2.0,3.0,5.0,6.0,")
    assert csvfmt.read(out).observed.tolist() == [[True, True], [True, False]]


def test_patch_of_a_short_cut_row_gives_it_the_cells_of_a_complete_row_and_no_more(tmp_path):
    path = write_text(tmp_path, "A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1.0,2.0,3.0,4.0,5.0,6.0\n1.0,2")
    original = csvfmt.read(path)
    assert original.observed.tolist() == [[True, True], [False, False]]
    positions, observed = original.positions.copy(), original.observed.copy()
    positions[1, 0], observed[1, 0] = [1, 2, 3], True   # fill A only; B stays missing
    out = tmp_path / "out.csv"
    csvfmt.write(original.with_positions(positions, observed), out)
    assert out.read_text().endswith("\n1.0,2.0,3.0,,,")       # A's observed 1.0 kept
    assert csvfmt.read(out).observed.tolist() == [[True, True], [True, False]]


# The sample file's last row ends "...,183.564,24.826": a complete row.
NO_FINAL_ENDING = ("A_X,A_Y,A_Z,B_X,B_Y,B_Z\n"
                   "1.500,2.500,3.500,4.500,5.500,6.750\n"
                   "1.600,2.600,3.600,,,\n"
                   "1.700,2.700,3.700,183.564,24.826,24.826")


def test_a_file_without_a_final_line_ending_reads_its_last_value_as_data(tmp_path):
    motion = csvfmt.read(write_text(tmp_path, NO_FINAL_ENDING))
    assert motion.observed.tolist() == [[True, True], [True, False], [True, True]]
    assert motion.positions[2, 1, 2] == 24.826
    assert not any("ends inside" in note for note in motion.source.notes)


@pytest.mark.parametrize("last_row", ["1.700,2.700,3.700,183.564,24.826,24.826",
                                      ",,,183.564,24.826,24.826"],
                         ids=["observed", "gap in the last row"])
def test_repair_of_a_file_without_a_final_line_ending_keeps_its_last_values(tmp_path,
                                                                           last_row):
    text = NO_FINAL_ENDING.rsplit("\n", 1)[0] + "\n" + last_row
    original = csvfmt.read(write_text(tmp_path, text))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.csv"
    csvfmt.write(repaired, out)
    assert_patch_invariant(original, repaired, out)
    last = out.read_text().rsplit("\n", 1)[1]              # still no final line ending
    assert last.endswith(",183.564,24.826,24.826") and last.count(",") == 5
    assert csvfmt.read(out).observed.all()


def test_a_clip_without_rate_is_written_at_the_rate_of_its_time_column(tmp_path):
    motion = Motion(np.ones((2, 1, 3)), np.ones((2, 1), bool), ("A",), 0.0)  # C3D, no RATE
    out = tmp_path / "out.csv"
    csvfmt.write(motion, out)
    assert out.read_text().splitlines()[0] == "# units: mm, rate: 120"
    assert csvfmt.read(out).rate == 120


def test_a_new_file_renames_repeated_labels_so_it_reads_back(tmp_path):
    motion = Motion(np.ones((2, 3, 3)), np.ones((2, 3), bool), ("A", "A", "B"), 100.0)
    out = tmp_path / "dup.csv"
    csvfmt.write(motion, out)
    assert csvfmt.read(out).labels == ("A", "A_2", "B")


@pytest.mark.parametrize("suffix", [".csv", ".trc"])
def test_a_clip_without_markers_is_not_written(tmp_path, suffix):
    # Neither text format can hold one: the file would be rejected when read back.
    out = tmp_path / f"out{suffix}"
    with pytest.raises(FormatError) as info:
        formats.write(Motion(np.zeros((3, 0, 3)), np.zeros((3, 0), bool), (), 100.0), out)
    assert str(info.value).startswith(f"{out}: ") and "no markers" in str(info.value)
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- real files

def test_vicon_nexus_csv_agrees_with_its_c3d():
    ezc3d = pytest.importorskip("ezc3d")
    motion = csvfmt.read(shared_file("csv/vicon-nexus-markers.csv"))
    c3d = ezc3d.c3d(str(shared_file("c3d/ezc3d-Vicon.c3d")))
    labels = list(c3d["parameters"]["POINT"]["LABELS"]["value"])

    def bare(label: str) -> str:
        return label.split(":", 1)[-1]

    assert [bare(s) for s in motion.labels] == [bare(s) for s in labels]
    points = c3d["data"]["points"][:3].transpose(2, 1, 0)        # (frames, markers, 3)
    np.testing.assert_array_equal(motion.observed, np.isfinite(points).all(axis=2))
    seen = motion.observed
    # Nexus prints 6 significant digits: relative error below 5e-6.
    np.testing.assert_allclose(motion.positions[seen], points[seen], rtol=5e-6, atol=1e-9)


def test_vicon_nexus_csv_patch_round_trip(tmp_path):
    original, repaired, _ = patch_round_trip(shared_file("csv/vicon-nexus-markers.csv"),
                                             tmp_path)
    assert (repaired.observed & ~original.observed).sum() > 0


def test_headerless_real_file_reads_13_markers_and_patches(tmp_path):
    original, repaired, _ = patch_round_trip(
        shared_file("csv/mogapfill-gait-raw-headerless.csv"), tmp_path)
    assert original.n_markers == 13 and original.source.kind == "headerless"
    assert (~original.observed).any() and (repaired.observed & ~original.observed).any()


def test_ktk_real_file_reads_39_points():
    motion = csvfmt.read(shared_file("csv/ktk-tennis_serve.csv"))
    assert (motion.n_markers, motion.units, motion.source.kind) == (39, "m", "ktk")
    assert motion.rate == pytest.approx(50)


@pytest.mark.parametrize(("text", "whole"), [("1.74931e-014", True), ("1.74931e-01", False),
                                             ("1.74931e-0", False), ("0.654321", True)])
def test_a_last_value_with_a_shorter_exponent_than_its_column_reads_as_cut(text, whole):
    # CMU prints near-zero angles with three-digit exponents, and others without one.
    assert printed_whole(text, ["6.07287e-014", "0.123456", "-3.84276e-014"], []) is whole


def test_ktk_real_file_without_a_final_line_ending_reads_its_last_row_whole():
    path = shared_file("csv/ktk-tennis_serve.csv")
    assert not path.read_bytes().endswith(b"\n")
    motion = csvfmt.read(path)
    assert motion.source.cut_row == -1 and motion.observed[-1].all()
    assert not any("ends inside" in note for note in motion.source.notes)


@pytest.mark.slow
@pytest.mark.parametrize("path", shared_files("csv", ".csv", ".txt"), ids=lambda p: p.name)
def test_every_shared_csv_reads_and_patches(path, tmp_path):
    patch_round_trip(path, tmp_path)
