"""TRC: tolerant reader, patch writer and OpenSim-layout new-file writer."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import trc
from mocapfill.motion import Motion
from tests.conftest import shared_file, shared_files
from tests.formats.test_csv import (
    assert_every_cut_reads_as_a_prefix,
    fill_by_interp,
    patch_round_trip,
    write_text,
)

KEYS = "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame" \
       "\tOrigNumFrames"


def trc_text(rows: list[str], *, frames: int = 3, markers: int = 2, units: str = "mm",
             names: str = "LASI\t\t\tR ASI\t\t\t", axes: bool = True, blank: bool = True,
             end: str = "\n") -> str:
    head = ["PathFileType\t4\t(X/Y/Z)\tclip.trc", KEYS,
            f"100\t100\t{frames}\t{markers}\t{units}\t100\t1\t{frames}",
            f"Frame#\tTime\t{names}"]
    if axes:
        head.append("\t\tX1\tY1\tZ1\tX2\tY2\tZ2")
    if blank:
        head.append("")
    return end.join(head + rows) + end


ROWS = ["1\t0.00\t1.500\t2.500\t3.500\t10.000\t20.000\t30.000",
        "2\t0.01\t1.600\t2.600\t3.600\t\t\t",
        "3\t0.02\t1.700\t2.700\t3.700\t11.000\t21.000\t31.000"]


def test_reads_labels_rate_units_and_first_frame(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS, units="m"), "a.trc"))
    assert motion.labels == ("LASI", "R ASI")
    assert (motion.rate, motion.units, motion.first_frame) == (100.0, "m", 1)
    np.testing.assert_array_equal(motion.positions[2, 1], [11, 21, 31])


def test_a_file_stating_no_rate_reads_as_0_hz_unless_the_rate_option_gives_one(tmp_path):
    # No DataRate value and no Time cells: 0 Hz, as a C3D without POINT:RATE (it was
    # 120, so a --max-gap in seconds was read at a rate the file never stated).
    def no_data_rate(rows: list[str]) -> str:
        return trc_text(rows).replace("100\t100\t3", "\t\t3").replace("mm\t100", "mm\t")

    untimed = ["\t".join(cell if k != 1 else "" for k, cell in enumerate(row.split("\t")))
               for row in ROWS]
    path = write_text(tmp_path, no_data_rate(untimed), "a.trc")
    assert "\t\t3\t2\tmm\t\t1\t3\n" in path.read_text()
    assert trc.read(path).rate == 0
    assert trc.read(path, rate=60).rate == 60
    # The Time column still gives the rate where the header states none.
    assert trc.read(write_text(tmp_path, no_data_rate(ROWS), "b.trc")).rate == 100


def test_blank_cells_are_missing(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS), "a.trc"))
    assert motion.observed.tolist() == [[True, True], [True, False], [True, True]]


def test_nan_cells_are_missing(tmp_path):
    rows = [ROWS[0], "2\t0.01\tnan\tNaN\tnan\t1\t2\t3", ROWS[2]]
    motion = trc.read(write_text(tmp_path, trc_text(rows), "a.trc"))
    assert motion.observed[:, 0].tolist() == [True, False, True]


def test_comma_delimited_file(tmp_path):
    text = trc_text(ROWS).replace("\t", ",")
    motion = trc.read(write_text(tmp_path, text, "a.trc"))
    assert motion.labels == ("LASI", "R ASI")
    assert motion.observed.tolist() == [[True, True], [True, False], [True, True]]


def test_a_quote_in_a_name_of_a_tab_delimited_file_is_part_of_that_name(tmp_path):
    # OpenSim splits on tabs alone; CSV quoting made R"KNE open a quoted cell that took
    # the names up to the next quote: 2 markers read of 4, exit 0.
    names = 'LKNE\t\t\tR"KNE\t\t\tLANK\t\t\tR"ANK"\t\t\t'
    rows = [row + "\t1\t2\t3\t4\t5\t6" for row in ROWS]
    motion = trc.read(write_text(tmp_path, trc_text(rows, markers=4, names=names), "a.trc"))
    assert motion.labels == ("LKNE", 'R"KNE', "LANK", 'R"ANK"')
    assert motion.source.notes == ()
    # A comma-delimited file (a spreadsheet's) keeps CSV quoting: a name may hold a comma.
    text = trc_text(ROWS).replace("\t", ",").replace("R ASI", '"R,ASI"')
    assert trc.read(write_text(tmp_path, text, "b.trc")).labels == ("LASI", "R,ASI")


def test_axis_line_and_blank_line_are_optional(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS, axes=False, blank=False), "a.trc"))
    assert motion.n_frames == 3 and motion.observed[0].all()


def test_first_frame_comes_from_the_first_frame_number(tmp_path):
    rows = [row.replace(f"{k + 1}\t", f"{k + 40}\t", 1) for k, row in enumerate(ROWS)]
    assert trc.read(write_text(tmp_path, trc_text(rows), "a.trc")).first_frame == 40


def test_frame_numbers_that_skip_are_noted(tmp_path):
    # Rows are frames one after the other (as OpenSim and BTK read them), so a gap report
    # would name frame 3 where the file says 7: the reader says so rather than stay silent.
    rows = [ROWS[0], ROWS[1], ROWS[2].replace("3\t", "7\t", 1)]
    motion = trc.read(write_text(tmp_path, trc_text(rows), "a.trc"))
    assert motion.n_frames == 3
    assert motion.source.notes == (
        "the Frame# column is not consecutive (2 then 7 at line 9); rows are read as "
        "consecutive frames numbered from 1",)


def test_consecutive_frame_numbers_are_not_noted(tmp_path):
    rows = [row.replace(f"{k + 1}\t", f"{k + 40}\t", 1) for k, row in enumerate(ROWS)]
    assert trc.read(write_text(tmp_path, trc_text(rows), "a.trc")).source.notes == ()


def test_marker_names_are_stripped_of_surrounding_blanks(tmp_path):
    text = trc_text(ROWS, names=" LASI \t\t\tR ASI \t\t\t")
    assert trc.read(write_text(tmp_path, text, "a.trc")).labels == ("LASI", "R ASI")


def test_padded_header_values_are_matched_to_their_keys(tmp_path):
    text = trc_text(ROWS).replace("100\t100\t3\t2\tmm\t100\t1\t3",
                                  "  100.0\t\t  100.0\t\t    3\t\t     2\t\t mm\t  100.0\t 1\t 3")
    motion = trc.read(write_text(tmp_path, text, "a.trc"))
    assert (motion.rate, motion.units) == (100.0, "mm")
    assert motion.source.notes == ()


def test_header_marker_count_disagreeing_with_the_names_is_noted(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS, markers=4), "a.trc"))
    assert motion.n_markers == 2
    assert motion.source.notes == ("header declares 4 markers, the names line has 2; 2 read",)


def test_fewer_rows_than_declared_frames_reads_the_rows_and_reports_truncation(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS, frames=10), "a.trc"))
    assert motion.n_frames == 3
    assert (motion.source.declared_frames, motion.source.truncated_rows_read) == (10, 3)
    assert motion.source.truncated
    assert "truncated: 3 of 10 declared frames read" in motion.source.notes


def test_complete_file_is_not_truncated(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS), "a.trc"))
    assert not motion.source.truncated and motion.source.truncated_rows_read is None


def test_file_cut_inside_its_last_row_reads_the_cut_cell_as_missing(tmp_path):
    text = trc_text(ROWS[:2] + ["3\t0.02\t1.700\t2.700\t3.700\t11.000\t21.0"], end="\n")
    path = write_text(tmp_path, text.rstrip("\n"), "a.trc")
    motion = trc.read(path)
    assert motion.observed[2].tolist() == [True, False]
    assert any("last row is shorter" in note for note in motion.source.notes)


def test_values_beyond_the_named_markers_are_ignored_and_noted(tmp_path):
    rows = [ROWS[0] + "\t7\t8\t9", ROWS[1], ROWS[2]]
    motion = trc.read(write_text(tmp_path, trc_text(rows), "a.trc"))
    assert motion.n_markers == 2
    assert any("1 rows hold values beyond" in note for note in motion.source.notes)


def test_file_cut_inside_its_last_number_reads_that_sample_as_missing(tmp_path):
    rows = ROWS[:2] + ["3\t0.02\t1.700\t2.700\t3.700\t11.000\t21.000\t31"]   # 31.000 cut
    motion = trc.read(write_text(tmp_path, trc_text(rows).removesuffix("\n"), "a.trc"))
    assert motion.observed[2].tolist() == [True, False]
    assert any("ends inside its last row" in note for note in motion.source.notes)


def test_file_without_a_final_line_ending_reads_its_last_value_as_data(tmp_path):
    motion = trc.read(write_text(tmp_path, trc_text(ROWS).removesuffix("\n"), "a.trc"))
    assert motion.observed[2].tolist() == [True, True]
    assert motion.positions[2, 1, 2] == 31
    assert not any("ends inside" in note for note in motion.source.notes)


@pytest.mark.parametrize("last_row", [ROWS[2], "3\t0.02\t\t\t\t11.000\t21.000\t31.000"],
                         ids=["observed", "gap in the last row"])
def test_repair_of_a_file_without_a_final_line_ending_keeps_its_last_values(tmp_path,
                                                                           last_row):
    text = trc_text(ROWS[:2] + [last_row]).removesuffix("\n")
    original = trc.read(write_text(tmp_path, text, "a.trc"))
    repaired = fill_by_interp(original)
    out = tmp_path / "out.trc"
    trc.write(repaired, out)
    last = out.read_text().rsplit("\n", 1)[1]              # still no final line ending
    assert last.endswith("\t11.000\t21.000\t31.000") and last.count("\t") == 7
    assert out.read_text().rsplit("\n", 1)[0] == text.rsplit("\n", 1)[0].replace(
        "3.600\t\t\t", "3.600\t10.500\t20.500\t30.500")
    assert trc.read(out).observed.all()


def test_every_cut_of_a_file_reads_as_a_prefix_of_its_samples_or_fails(tmp_path):
    assert_every_cut_reads_as_a_prefix(write_text(tmp_path, trc_text(ROWS), "a.trc"))


def test_a_short_row_is_a_format_error_naming_the_file_and_line(tmp_path):
    rows = [ROWS[0], "2\t0.01\t1.600\t2.600\t3.600", ROWS[2]]
    path = write_text(tmp_path, trc_text(rows), "a.trc")
    with pytest.raises(FormatError) as info:
        trc.read(path)
    assert str(info.value) == (f"{path}: line 8 holds 5 cells; Frame#, Time and 2 named "
                               "markers take 8")


def test_values_beyond_the_named_markers_that_are_not_whole_triplets_are_an_error(tmp_path):
    rows = [ROWS[0] + "\t7\t8", ROWS[1], ROWS[2]]
    path = write_text(tmp_path, trc_text(rows), "a.trc")
    with pytest.raises(FormatError) as info:
        trc.read(path)
    assert str(info.value) == (f"{path}: line 7 holds 10 cells; Frame#, Time and 2 named "
                               "markers take 8 (cells beyond those must be whole x, y, z "
                               "triplets)")


@pytest.mark.parametrize("stated", ["inf", "0", "-100", "nan", "abc"])
def test_a_data_rate_that_is_not_a_positive_finite_number_is_a_format_error(tmp_path,
                                                                             stated):
    text = trc_text(ROWS).replace("\n100\t100\t", f"\n{stated}\t100\t", 1)
    path = write_text(tmp_path, text, "a.trc")
    with pytest.raises(FormatError) as info:
        trc.read(path)
    assert str(info.value) == (f"{path}: DataRate is {stated!r}, not a frame rate (a "
                               "positive, finite number of Hz)")


def test_a_marker_named_twice_is_a_format_error(tmp_path):
    path = write_text(tmp_path, trc_text(ROWS, names="R.TETE\t\t\tR.TETE\t\t\t"), "a.trc")
    with pytest.raises(FormatError) as info:
        trc.read(path)
    assert str(info.value) == f"{path}: marker name 'R.TETE' appears twice in the Frame# line"


def test_the_first_name_repeated_is_the_one_named_among_many_names(tmp_path):
    # Each name was looked up in the slice of those before it: 50,000 names took 10.6 s,
    # 200,000 over a minute (n^2); this is minutes that way.
    names = [f"M{k}" for k in range(200_000)] + ["M7", "M3"]
    path = write_text(tmp_path, trc_text(ROWS, names="\t\t\t".join(names)), "a.trc")
    with pytest.raises(FormatError) as info:
        trc.read(path)
    assert str(info.value) == f"{path}: marker name 'M7' appears twice in the Frame# line"


def test_file_not_starting_with_path_file_type_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="not a TRC file"):
        trc.read(write_text(tmp_path, "Frame#\tTime\n1\t0\n", "a.trc"))


def test_file_without_rows_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="no data rows"):
        trc.read(write_text(tmp_path, trc_text([]), "a.trc"))


def test_unparsable_cell_error_names_row_and_column(tmp_path):
    rows = [ROWS[0], "2\t0.01\t1.6\tx1\t3.6\t\t\t", ROWS[2]]
    path = write_text(tmp_path, trc_text(rows), "a.trc")
    with pytest.raises(FormatError) as info:
        trc.read(path)
    assert str(info.value) == f"{path}: row 8, column Y1 (LASI): cannot parse 'x1'"


# ----------------------------------------------------------------------------- writers

def test_patch_changes_only_filled_cells(tmp_path):
    path = write_text(tmp_path, trc_text(ROWS, end="\r\n"), "a.trc")
    original = trc.read(path)
    repaired = fill_by_interp(original)
    out = tmp_path / "out.trc"
    trc.write(repaired, out)
    expected = path.read_bytes().replace(b"1.600\t2.600\t3.600\t\t\t",
                                         b"1.600\t2.600\t3.600\t10.500\t20.500\t30.500")
    assert out.read_bytes() == expected


def test_patch_keeps_the_observed_cells_of_a_partly_observed_sample(tmp_path):
    rows = [ROWS[0], ROWS[1].replace("3.600\t\t\t", "3.600\t\t20.125\t"), ROWS[2]]
    path = write_text(tmp_path, trc_text(rows, end="\r\n"), "a.trc")
    original = trc.read(path)
    assert original.observed[1].tolist() == [True, False]
    out = tmp_path / "out.trc"
    trc.write(fill_by_interp(original), out)
    expected = path.read_bytes().replace(b"3.600\t\t20.125\t\r",
                                         b"3.600\t10.500\t20.125\t30.500\r")
    assert out.read_bytes() == expected


def test_patch_pads_the_short_row_a_file_ends_inside(tmp_path):
    rows = [ROWS[0], ROWS[2].replace("3\t0.02", "2\t0.01"), "3\t0.02\t1.800\t2.800\t3.800\t"]
    original = trc.read(write_text(tmp_path, trc_text(rows).removesuffix("\n"), "a.trc"))
    assert original.observed[2].tolist() == [True, False]
    out = tmp_path / "out.trc"
    trc.write(fill_by_interp(original), out)       # R ASI held at 11, 21, 31
    last = "3\t0.02\t1.800\t2.800\t3.800\t11.000\t21.000\t31.000"    # no line ending still
    assert out.read_text().endswith("\n" + last)
    assert trc.read(out).observed.all()


def opensim_motion() -> Motion:
    positions = np.arange(3 * 2 * 3, dtype=float).reshape(3, 2, 3) / 7.0
    observed = np.array([[True, True], [True, False], [True, True]])
    return Motion(positions, observed, ("LASI", "R ASI*"), 60.0, "mm", first_frame=5)


def test_new_file_has_opensim_header_layout(tmp_path):
    out = tmp_path / "walk.trc"
    formats.write(opensim_motion(), out)       # through the atomic temp-file writer
    lines = out.read_text().split("\n")
    assert lines[:6] == ["PathFileType\t4\t(X/Y/Z)\twalk.trc",
                         KEYS,
                         "60\t60\t3\t2\tmm\t60\t5\t3",
                         "Frame#\tTime\tLASI\t\t\tR_ASI_\t\t\t",
                         "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\t",
                         ""]
    assert lines[7] == "6\t0.016666667\t0.8571428571428571\t1\t1.1428571428571428\t\t\t\t"


def test_new_file_reads_back_identically(tmp_path):
    motion = opensim_motion()
    out = tmp_path / "walk.trc"
    formats.write(motion, out)
    back = trc.read(out)
    assert back.labels == ("LASI", "R_ASI_")
    assert (back.rate, back.units, back.first_frame) == (60.0, "mm", 5)
    assert back.source.notes == ()
    np.testing.assert_array_equal(back.observed, motion.observed)
    np.testing.assert_array_equal(back.positions, motion.positions)


def test_motion_from_another_format_is_written_as_a_new_file(tmp_path):
    csv_path = write_text(tmp_path, "A_X,A_Y,A_Z\n1.5,2,3\n", "a.csv")
    out = tmp_path / "a.trc"
    formats.write(formats.read(csv_path), out)
    assert out.read_text().startswith("PathFileType\t4\t(X/Y/Z)\ta.trc\n")


def test_a_new_file_with_a_long_name_states_that_name_not_its_temporary_s(tmp_path):
    # The temporary file's name is cut short where the output's is long (255 bytes).
    csv_path = write_text(tmp_path, "A_X,A_Y,A_Z\n1.5,2,3\n", "a.csv")
    out = tmp_path / f"{'a' * 251}.trc"
    formats.write(formats.read(csv_path), out)
    assert out.read_text().startswith(f"PathFileType\t4\t(X/Y/Z)\t{out.name}\n")


@pytest.mark.parametrize("odd", ["\n", "\r", "\t", "\r\n", "\u2028"])
def test_a_new_file_named_with_a_line_break_or_tab_keeps_its_header_lines(tmp_path, odd):
    # The name went into the PathFileType line as it was: a line break there split the
    # header, and OpenSim read the file's own name as the header keys.
    csv_path = write_text(tmp_path, "A_X,A_Y,A_Z\n1.5,2,3\n", "a.csv")
    out = tmp_path / f"a{odd}b.trc"
    formats.write(formats.read(csv_path), out)
    lines = out.read_bytes().decode().split("\n")
    assert lines[0] == "PathFileType\t4\t(X/Y/Z)\ta_b.trc"
    assert lines[1].startswith("DataRate\t")


# ----------------------------------------------------------------------------- real files

def test_new_file_makes_names_that_opensim_renaming_makes_alike_unique(tmp_path):
    motion = opensim_motion().replace(labels=("R ASI", "R_ASI"))
    out = tmp_path / "out.trc"
    trc.write(motion, out)
    assert trc.read(out).labels == ("R_ASI", "R_ASI_2")




def test_btk_gait_trusts_the_names_line_over_num_markers(tmp_path):
    original, repaired, _ = patch_round_trip(shared_file("trc/btk-Gait.trc"), tmp_path)
    assert (original.n_frames, original.n_markers) == (487, 33)
    assert "header declares 66 markers, the names line has 33; 33 read" in original.source.notes
    assert 0.4 < (~original.observed).mean() < 0.5
    assert (repaired.observed & ~original.observed).sum() > 1000


def test_nimble_step_width_reads_its_501_rows_of_27107_declared():
    motion = trc.read(shared_file("trc/nimble-step_width.trc"))
    assert (motion.n_frames, motion.n_markers) == (501, 32)
    assert (motion.source.declared_frames, motion.source.truncated_rows_read) == (27107, 501)


def test_comma_truncated_trc_reads_93_of_652_declared_frames():
    motion = formats.read(shared_file("bad/pyomeca-markers-comma-truncated.trc"))
    assert (motion.n_frames, motion.n_markers) == (93, 51)
    assert (motion.source.declared_frames, motion.source.truncated_rows_read) == (652, 93)
    assert "truncated: 93 of 652 declared frames read" in motion.source.notes


def test_misaligned_header_of_nimble_motion_capture_walk():
    motion = trc.read(shared_file("trc/nimble-motion_capture_walk.trc"))
    assert (motion.n_frames, motion.n_markers, motion.rate, motion.units) == (238, 41, 100, "mm")


@pytest.mark.slow
@pytest.mark.parametrize("path", shared_files("trc", ".trc") + shared_files("bad", ".trc"),
                         ids=lambda p: p.name)
def test_every_shared_trc_reads_and_patches(path: Path, tmp_path):
    patch_round_trip(path, tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("path", shared_files("trc", ".trc"), ids=lambda p: p.name)
def test_every_shared_trc_converts_to_an_opensim_file_and_back(path: Path, tmp_path):
    motion = trc.read(path)
    out = tmp_path / "new.trc"
    trc.write(motion.replace(source=None), out)
    back = trc.read(out)
    assert back.labels == tuple(trc.opensim_name(s, j) for j, s in enumerate(motion.labels))
    np.testing.assert_array_equal(back.observed, motion.observed)
    np.testing.assert_array_equal(back.positions, motion.positions)
    assert back.rate == motion.rate


def test_a_new_trc_notes_the_names_it_changes(tmp_path):
    # OpenSim rejects whitespace, '/', '*', '+', '\\' in names: the writer replaces them,
    # and the user hears of it (the clip keeps its labels).
    from tests.helpers import smooth_clip

    clip = smooth_clip(30, 4).replace(labels=("genou1_ NewMarker", "A/B", "R*K", "C"))
    notes = formats.write(clip, tmp_path / "a.trc")
    assert notes == ("3 marker name(s) written as names OpenSim accepts: 'genou1_ NewMarker' "
                     "-> 'genou1__NewMarker', 'A/B' -> 'A_B', ...",)
    assert formats.read(tmp_path / "a.trc").labels == ("genou1__NewMarker", "A_B", "R_K", "C")
    assert clip.labels[0] == "genou1_ NewMarker"
    one = clip.replace(labels=("A", "B", "C D", "E"))
    assert formats.write(one, tmp_path / "b.trc") == (
        "1 marker name(s) written as names OpenSim accepts: 'C D' -> 'C_D'",)
    assert formats.write(one, tmp_path / "b.csv") == ()      # a CSV holds 'C D' as it is
    assert formats.write(clip.replace(labels=("A", "B", "C", "D")), tmp_path / "c.trc") == ()


def test_a_new_trc_replaces_a_quote_in_a_name_and_reads_back_every_marker(tmp_path):
    # R"KNE converted from a C3D read back as 2 markers of 4 (exit 0). OpenSim keeps the
    # quote, but CSV-minded readers of the tab-separated file (pandas) take it for one.
    from tests.helpers import smooth_clip

    clip = smooth_clip(30, 4).replace(labels=("LKNE", 'R"KNE', "LANK", "RANK"))
    formats.write(clip, tmp_path / "a.c3d")
    c3d = formats.read(tmp_path / "a.c3d")
    notes = formats.write(c3d, tmp_path / "a.trc")
    assert notes == ("1 marker name(s) written as names OpenSim accepts: 'R\"KNE' -> "
                     "'R_KNE'",)
    back = formats.read(tmp_path / "a.trc")
    assert back.labels == ("LKNE", "R_KNE", "LANK", "RANK")
    np.testing.assert_array_equal(back.positions, c3d.positions)


def test_a_new_csv_notes_the_names_it_changes(tmp_path):
    from tests.helpers import smooth_clip

    clip = smooth_clip(30, 2).replace(labels=("two\nlines", "B"))
    assert formats.write(clip, tmp_path / "a.csv") == (
        "1 marker name(s) written as names a CSV header holds: 'two\\nlines' -> 'two lines'",)
    assert formats.read(tmp_path / "a.csv").labels == ("two lines", "B")


@pytest.mark.parametrize("suffix", [".trc", ".csv"])
def test_a_clip_without_a_rate_is_written_at_120_hz_with_a_note(tmp_path, suffix):
    # A C3D without POINT:RATE reads as 0 Hz; a TRC's DataRate and a CSV's Time column
    # need one, and the user must hear that it was invented.
    from tests.helpers import smooth_clip

    clip = smooth_clip(30, 3)
    notes = formats.write(clip.replace(rate=0.0), tmp_path / f"a{suffix}")
    assert notes == ("the clip's frame rate is not known (0 Hz): written as 120 Hz",)
    assert formats.read(tmp_path / f"a{suffix}").rate == 120.0
    assert formats.write(clip, tmp_path / f"b{suffix}") == ()


def test_a_blank_first_frame_number_counts_back_from_the_next_one(tmp_path):
    # Rows are consecutive frames: with the first Frame# cell blank and the next row
    # numbered 41, the first row is frame 40 (41 made every reported frame one too high).
    rows = [row.replace(f"{k + 1}\t", f"{k + 40}\t", 1) for k, row in enumerate(ROWS)]
    rows[0] = "\t" + rows[0].split("\t", 1)[1]
    numbers = [int(row.split("\t")[0]) for row in rows[1:]]
    motion = trc.read(write_text(tmp_path, trc_text(rows), "a.trc"))
    assert motion.first_frame == numbers[0] - 1
    assert motion.source.notes == ()


def test_a_frame_number_beyond_64_bits_is_refused_naming_the_file(tmp_path):
    # Frame# 1e20 was read, and the repair to an NPZ crashed with an OverflowError.
    rows = [f"{frame}\t{row.split(chr(9), 1)[1]}" for frame, row in
            zip(("1e20", "1e20", "1e20"), ROWS)]
    path = write_text(tmp_path, trc_text(rows), "a.trc")
    with pytest.raises(FormatError) as caught:
        formats.read(path)
    assert str(caught.value).startswith(f"{path}: ")
    assert "first_frame must fit in 64 bits" in str(caught.value)
    assert str(caught.value).endswith("got 100000000000000000000)")
