"""Samples at exactly (0, 0, 0) as gaps in the text formats (``zero_is_missing="on"``).

QTM-derived text exports and the MoCap Toolbox store gaps as x = y = z = 0
(formats-and-conventions.md); a file read so must be repaired as the C3D reader's are:
only those samples' cells rewritten, every other line and cell kept.
"""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import ParameterError
from mocapfill.formats import csv as csvfmt
from mocapfill.formats import trc
from mocapfill.formats._text import read_lines, split_cells, split_ending
from tests.conftest import shared_file
from tests.formats.test_csv import fill_by_interp, write_text
from tests.formats.test_trc import trc_text
from tests.test_cli import run

# Marker A is at (0, 0, 0) in frames 2-3 (a gap written as zeros); B sits on the plane
# y = 0 in frame 2 (one zero coordinate, real data); C is blank in frame 4 (a gap as
# always).
PLAIN = ("Frame,Time,A_X,A_Y,A_Z,B_X,B_Y,B_Z,C_X,C_Y,C_Z\n"
         "1,0.00,1.000,2.000,3.000,5.0,5.0,5.0,7.25,8.25,9.25\n"
         "2,0.01,0.000,0.000,0.000,6.0,0,6.0,7.50,8.50,9.50\n"
         "3,0.02,0.000,0.000,0.000,7.0,7.0,7.0,7.75,8.75,9.75\n"
         "4,0.03,4.000,5.000,6.000,8.0,8.0,8.0,,,\n"
         "5,0.04,5.000,6.000,7.000,9.0,9.0,9.0,8.25,9.25,10.25\n")
VICON = ("Trajectories,,,,,,,,,,\n100,,,,,,,,,,\n"
         ",,S:A,,,S:B,,,S:C,,\nFrame,Sub Frame,X,Y,Z,X,Y,Z,X,Y,Z\n"
         ",,mm,mm,mm,mm,mm,mm,mm,mm,mm\n"
         + "".join(f"{k},0,{line.split(',', 2)[2]}\n"
                   for k, line in enumerate(PLAIN.splitlines()[1:], start=1)))
HEADERLESS = "".join(line.split(",", 2)[2] + "\n" for line in PLAIN.splitlines()[1:])
TRC = trc_text([line.replace(",", "\t") for line in PLAIN.splitlines()[1:]], frames=5,
               markers=3, names="A\t\t\tB\t\t\tC\t\t\t")
LAYOUTS = {"plain.csv": PLAIN, "vicon.csv": VICON, "headerless.csv": HEADERLESS,
           "clip.trc": TRC}
EXPECTED = np.array([[True, True, True], [False, True, True], [False, True, True],
                     [True, True, False], [True, True, True]])


@pytest.mark.parametrize("name", LAYOUTS)
def test_zero_samples_are_gaps_only_when_asked(tmp_path, name):
    path = write_text(tmp_path, LAYOUTS[name], name)
    on = formats.read(path, zero_is_missing="on")
    np.testing.assert_array_equal(on.observed, EXPECTED)
    assert np.isnan(on.positions[1:3, 0]).all()
    np.testing.assert_array_equal(on.positions[1, 1], [6, 0, 6])      # one zero: data
    assert "2 samples at exactly (0, 0, 0) read as missing (--zero-is-missing on)" \
        in on.source.notes
    for setting in ("auto", "off"):
        plain = formats.read(path, zero_is_missing=setting)
        np.testing.assert_array_equal(plain.observed[:, 0], True)
        np.testing.assert_array_equal(plain.positions[1, 0], [0, 0, 0])
        assert not any("(0, 0, 0)" in note for note in plain.source.notes)


@pytest.mark.parametrize("name", LAYOUTS)
def test_a_repair_rewrites_the_zero_samples_cells_and_nothing_else(tmp_path, name):
    path = write_text(tmp_path, LAYOUTS[name], name)
    original = formats.read(path, zero_is_missing="on")
    repaired = fill_by_interp(original)
    out = tmp_path / f"out_{name}"
    formats.write(repaired, out)
    source = original.source
    old_lines, new_lines = read_lines(path), read_lines(out)
    assert len(new_lines) == len(old_lines)
    filled = repaired.observed & ~original.observed
    cells_of = {int(source.row_lines[f]): set() for f in np.flatnonzero(filled.any(axis=1))}
    for f, m in zip(*np.nonzero(filled)):
        cells_of[int(source.row_lines[f])].update(source.columns[m].tolist())
    for i, (old, new) in enumerate(zip(old_lines, new_lines)):
        if i not in cells_of:
            assert new == old, f"line {i + 1} changed"
            continue
        old_cells = split_cells(split_ending(old)[0], source.delimiter)
        new_cells = split_cells(split_ending(new)[0], source.delimiter)
        changed = {c for c, (a, b) in enumerate(zip(old_cells, new_cells)) if a != b}
        assert changed == cells_of[i], f"line {i + 1}"
    back = formats.read(out, zero_is_missing="on")
    assert back.observed.all()
    np.testing.assert_allclose(back.positions, repaired.positions, atol=0.0051)
    # A (0, 0, 0) gap filled where the fill lies on it would be read as a gap again, so
    # the filled A of frames 2-3 (interpolated from frames 1 and 4) must not be 0, 0, 0.
    np.testing.assert_allclose(back.positions[1, 0], [2, 3, 4])


@pytest.mark.parametrize("name", ["plain.csv", "clip.trc"])
def test_samples_made_missing_are_written_as_zeros_in_a_zero_file(tmp_path, name):
    # simulate on a file whose gaps are zeros (and which has no blank or NaN cell to copy
    # the missing token from): the new gaps take the file's own form, 0 in the column's
    # precision, so the tools that wrote the file read them as gaps too.
    full = PLAIN.replace("8.0,8.0,8.0,,,", "8.0,8.0,8.0,8.00,9.00,10.00")  # C seen
    text = full if name.endswith(".csv") else trc_text(
        [line.replace(",", "\t") for line in full.splitlines()[1:]], frames=5, markers=3,
        names="A\t\t\tB\t\t\tC\t\t\t")
    path = write_text(tmp_path, text, name)
    motion = formats.read(path, zero_is_missing="on")
    observed = motion.observed.copy()
    observed[4, 1] = False                                         # B in frame 5
    positions = np.where(observed[:, :, None], motion.positions, np.nan)
    out = tmp_path / f"sim_{name}"
    formats.write(motion.with_positions(positions, observed), out)
    row = split_cells(split_ending(read_lines(out)[int(motion.source.row_lines[4])])[0],
                      motion.source.delimiter)
    assert [row[c] for c in motion.source.columns[1]] == ["0.0", "0.0", "0.0"]
    np.testing.assert_array_equal(formats.read(out, zero_is_missing="on").observed, observed)


@pytest.mark.parametrize("reader", [csvfmt.read, trc.read])
def test_an_unknown_zero_is_missing_value_is_refused(tmp_path, reader):
    path = write_text(tmp_path, TRC if reader is trc.read else PLAIN,
                      "a.trc" if reader is trc.read else "a.csv")
    with pytest.raises(ParameterError, match="zero_is_missing must be 'auto', 'on' or 'off'"):
        reader(path, zero_is_missing="yes")


def test_a_real_export_with_its_gaps_written_as_zeros_repairs_as_with_blanks(tmp_path):
    # The Vicon Nexus export (51 markers, gaps of up to 71 frames) with every gap's three
    # blank cells written as 0 instead, as a QTM-derived pipeline writes them: read
    # with --zero-is-missing on it has the same mask, and its repair the same fills.
    blank = shared_file("csv/vicon-nexus-markers.csv")
    motion = formats.read(blank)
    source = motion.source
    lines = list(source.lines)
    for f, m in zip(*np.nonzero(~motion.observed)):
        index = int(source.row_lines[f])
        body, ending = split_ending(lines[index])
        cells = split_cells(body, source.delimiter)
        for c in source.columns[m].tolist():
            cells[c] = "0"
        lines[index] = source.delimiter.join(cells) + ending
    zeros = tmp_path / "zeros.csv"
    zeros.write_bytes("".join(lines).encode())
    read = formats.read(zeros, zero_is_missing="on")
    np.testing.assert_array_equal(read.observed, motion.observed)
    outputs = []
    for path, zero_is_missing in ((blank, "off"), (zeros, "on")):
        out = tmp_path / f"out_{path.name}"
        result = run("repair", path, out, "--method", "spline",
                     "--zero-is-missing", zero_is_missing)
        assert result.exit_code == 0, result.output
        repaired = formats.read(out)
        assert repaired.observed.sum() > motion.observed.sum()      # gaps were filled
        outputs.append(repaired.positions)
    np.testing.assert_array_equal(outputs[1], outputs[0])
