"""BVH: reading, forward kinematics, channel space and the patching writer."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import bvh
from mocapfill.motion import from_matrix
from tests.conftest import shared_file, shared_files
from tests.helpers import assert_only_nan_tokens_replaced
from tests.test_skeleton import rot

CHAIN = """HIERARCHY
ROOT Hips
{
  OFFSET 10 20 30
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Arm
  {
    OFFSET 1 0 0
    CHANNELS 3 {order}
    End Site
    {
      OFFSET 0 2 0
    }
  }
}
MOTION
Frames: {frames}
Frame Time: 0.01
"""


def write_bvh(tmp_path: Path, rows: list[str], order: str = "Zrotation Xrotation Yrotation",
              name: str = "chain.bvh", frames: int | None = None) -> Path:
    text = CHAIN.replace("{order}", order).replace(
        "{frames}", str(len(rows) if frames is None else frames))
    path = tmp_path / name
    path.write_text(text + "".join(row + "\n" for row in rows))
    return path


def point(motion, label: str, frame: int = 0) -> np.ndarray:
    return motion.positions[frame, motion.labels.index(label)]


# ----------------------------------------------------------------------- reading and FK

def test_labels_are_joints_then_end_sites_named_after_their_parent(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"]))
    assert motion.labels == ("Hips", "Arm", "Arm_End")


def _joint(name: str, body: str = "") -> str:
    return f"JOINT {name}\n{{\nOFFSET 0 0 0\n{body}}}\n"


_END_SITE = "End Site\n{\nOFFSET 0 0 0\n}\n"


def test_repeated_joint_and_end_site_names_get_the_first_free_suffix(tmp_path):
    # The names the reader has always given (they label the points): NAME_2, NAME_3 ...,
    # the first not taken, for End Sites too, a name taken later by a joint being skipped.
    path = tmp_path / "names.bvh"
    path.write_text(
        "HIERARCHY\nROOT J\n{\nOFFSET 0 0 0\nCHANNELS 3 Xposition Yposition Zposition\n"
        + _joint("J", _END_SITE) + _joint("J_2", _END_SITE) + _joint("J") + _joint("J_2_End")
        + _END_SITE * 2 + _joint("J_End_3") + _END_SITE + _joint("J")
        + "}\nMOTION\nFrames: 1\nFrame Time: 0.01\n0 0 0\n")
    assert bvh.read(path).labels == ("J", "J_2", "J_2_End", "J_2_2", "J_2_2_End", "J_3",
                                     "J_2_End_2", "J_End", "J_End_2", "J_End_3", "J_End_4",
                                     "J_4")


def _names_by_scanning(names: list[str]) -> list[str]:
    """The reader's names as it gave them by scanning the list of names so far."""
    given: list[str] = []
    for name in names:
        base, copy = name, 1
        while name in given:
            copy += 1
            name = f"{base}_{copy}"
        given.append(name)
    return given


@settings(max_examples=200, deadline=None)
@given(st.lists(st.sampled_from(["J", "J_2", "J_3", "J_2_2", "J_End", "J_End_2", "J_1",
                                 "J_02", "K"]), max_size=30))
def test_joint_names_are_those_of_scanning_the_names_so_far(names):
    tree = bvh._Hierarchy()
    for name in names:
        tree.add(name, -1)
    assert tree.names == _names_by_scanning(names)


def test_naming_many_joints_of_one_name_does_not_rescan_the_names():
    # Scanning a list of names for each candidate took 16-20 s for 2,000 sibling joints
    # named J and over a minute for 3,000 End Sites of one joint (n^3); this is minutes
    # that way and milliseconds with a set of names.
    tree = bvh._Hierarchy()
    for name in ["J"] * 10_000 + ["J_End"] * 10_000:
        tree.add(name, 0)
    assert tree.names[:3] == ["J", "J_2", "J_3"] and tree.names[9_999] == "J_10000"
    assert tree.names[10_000:10_002] == ["J_End", "J_End_2"]
    assert len(set(tree.names)) == 20_000


def test_rate_is_one_over_frame_time(tmp_path):
    assert bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"])).rate == 100.0


def test_root_position_channels_replace_the_root_offset(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["1 2 3 0 0 0 0 0 0"]))
    np.testing.assert_allclose(point(motion, "Hips"), [1, 2, 3])


def test_root_rotation_of_90_about_z_puts_the_child_on_the_y_axis(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["1 2 3 90 0 0 0 0 0"]))
    np.testing.assert_allclose(point(motion, "Arm"), [1, 3, 3], atol=1e-12)


def test_end_site_is_its_offset_turned_by_the_parent_joint(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 90 0 0"]))  # Arm: Z 90
    np.testing.assert_allclose(point(motion, "Arm_End"), [1 - 2, 0, 0], atol=1e-12)


@pytest.mark.parametrize("order", ["Zrotation Xrotation Yrotation",
                                   "Zrotation Yrotation Xrotation"])
def test_joint_rotation_composes_about_moving_axes_in_channel_order(tmp_path, order):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 30 40 50"], order=order))
    axes = [word[0] for word in order.split()]
    expected = rot(axes[0], 30) @ rot(axes[1], 40) @ rot(axes[2], 50) @ [0, 2, 0]
    np.testing.assert_allclose(point(motion, "Arm_End") - point(motion, "Arm"), expected,
                               atol=1e-12)


def test_zxy_and_zyx_orders_give_different_rotations(tmp_path):
    zxy = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 30 40 50"], name="a.bvh"))
    zyx = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 30 40 50"], name="b.bvh",
                             order="Zrotation Yrotation Xrotation"))
    assert np.abs(point(zxy, "Arm_End") - point(zyx, "Arm_End")).max() > 0.1


def test_nan_cells_are_gaps(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0", "0 0 0 0 0 0 nan 0 0"]))
    values, observed = bvh.channels(motion)
    assert not observed[1, 6] and observed.sum() == 17
    assert np.isnan(values[1, 6])


def test_a_gap_in_a_joint_rotation_hides_its_end_site_but_not_the_joint(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 nan 0 0"]))
    np.testing.assert_array_equal(motion.observed[0], [True, True, False])


def test_source_keeps_the_hierarchy_text_verbatim(tmp_path):
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"])
    head = path.read_text().split("0 0 0 0 0 0 0 0 0")[0]
    assert bvh.read(path).source.hierarchy == head


def test_a_line_with_the_wrong_number_of_values_names_the_line(tmp_path):
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0 0", "0 0 0 0 0 0 0 0 0"])
    with pytest.raises(FormatError, match=r"line 19 holds 10 values.*9 channels"):
        bvh.read(path)


def test_a_non_numeric_cell_is_a_format_error(tmp_path):
    with pytest.raises(FormatError, match="non-numeric"):
        bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 x 0 0"]))


def test_a_file_without_motion_section_is_a_format_error(tmp_path):
    path = tmp_path / "x.bvh"
    path.write_text("HIERARCHY\nROOT a\n{\nOFFSET 0 0 0\n}\n")
    with pytest.raises(FormatError, match="no MOTION"):
        bvh.read(path)


@pytest.mark.parametrize("channels, problem", [
    ("-2 Xposition", "-2 of joint 'Hips' is negative"),       # looped forever (i += 0)
    ("-5 Xposition Yposition Zposition", "-5 of joint 'Hips' is negative"),   # walked back
    ("5 Xposition Yposition Zposition", "5 of joint 'Hips' runs past the HIERARCHY "
                                        "(4 words follow it)"),
    ("three Xposition", "'three' of joint 'Hips' is not a whole number")])
def test_a_channels_count_that_is_not_the_channels_named_is_a_bad_hierarchy(tmp_path,
                                                                            channels,
                                                                            problem):
    path = tmp_path / "x.bvh"
    path.write_text(f"HIERARCHY\nROOT Hips\n{{\n OFFSET 0 0 0\n CHANNELS {channels}\n}}\n"
                    "MOTION\nFrames: 2\nFrame Time: 0.01\n0 0 0\n1 1 1\n")
    with pytest.raises(FormatError) as caught:
        bvh.read(path)
    assert str(caught.value) == f"{path}: bad HIERARCHY: CHANNELS count {problem}"


@pytest.mark.parametrize("hierarchy, problem", [
    ("OFFSET 0 0 0\nROOT Hips\n{\n}", "OFFSET outside any joint"),
    ("ROOT Hips\n{\n}\nCHANNELS 0", "CHANNELS outside any joint"),
    ("ROOT Hips\n{\nCHANNELS", "CHANNELS of joint 'Hips' without a count"),
    ("ROOT", "ROOT without a name")])
def test_a_hierarchy_word_without_its_joint_or_value_is_named(tmp_path, hierarchy, problem):
    # each was "bad HIERARCHY: list index out of range"
    path = tmp_path / "x.bvh"
    path.write_text(f"HIERARCHY\n{hierarchy}\nMOTION\nFrames: 0\nFrame Time: 0.01\n")
    with pytest.raises(FormatError) as caught:
        bvh.read(path)
    assert str(caught.value) == f"{path}: bad HIERARCHY: {problem}"


def test_fewer_frame_lines_than_declared_is_reported_as_truncated(tmp_path):
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"] * 3, frames=5)
    expected = r"chain\.bvh: truncated: 3 complete frames read, 5 declared$"
    with pytest.raises(FormatError, match=expected):
        bvh.read(path)


def without_final_ending(tmp_path: Path, rows: list[str]) -> Path:
    path = write_bvh(tmp_path, rows)
    path.write_bytes(path.read_bytes().removesuffix(b"\n"))
    return path


@pytest.mark.parametrize("last", ["-7.6", "-7.", "-7.6e"])
def test_a_bvh_cut_inside_its_last_value_is_reported_as_truncated(tmp_path, last):
    rows = ["1.5000 2.2500 3.1250 0.0000 0.0000 0.0000 10.1234 20.4321 30.5555",
            f"1.5000 2.2500 3.1250 0.0000 0.0000 0.0000 10.1234 20.4321 {last}"]
    path = without_final_ending(tmp_path, rows)
    expected = (r"chain\.bvh: truncated: 1 complete frames read, 2 declared "
                r"\(line 20 is cut short\)$")
    with pytest.raises(FormatError, match=expected):
        bvh.read(path)


@pytest.mark.parametrize("last", ["-7.6000", "-7.6000 "])
def test_a_bvh_without_a_final_line_ending_reads_its_last_value_as_data(tmp_path, last):
    rows = ["1.5000 2.2500 3.1250 0.0000 0.0000 0.0000 10.1234 20.4321 30.5555",
            f"1.5000 2.2500 3.1250 0.0000 0.0000 0.0000 10.1234 20.4321 {last}"]
    motion = bvh.read(without_final_ending(tmp_path, rows))
    assert motion.observed.all() and bvh.channels(motion)[0][1, 8] == -7.6


def test_a_one_frame_bvh_without_a_final_line_ending_reads_whole(tmp_path):
    # One frame gives nothing to compare the last value with: it is read as written.
    motion = bvh.read(without_final_ending(tmp_path, ["0 0 0 0 0 0 0 0 7.6"]))
    assert bvh.channels(motion)[0][0, 8] == 7.6


def test_real_file_cut_inside_its_last_value_is_reported_as_truncated(tmp_path):
    data = shared_file("cmu/10_01.bvh").read_bytes().rstrip(b"\r\n")   # ... -7.6754 8.9931
    cut = tmp_path / "cut.bvh"
    cut.write_bytes(data[:-2])                                          # ... -7.6754 8.99
    with pytest.raises(FormatError, match=r"truncated: 801 complete frames read, 802 "
                                          r"declared \(line \d+ is cut short\)$"):
        bvh.read(cut)
    whole = tmp_path / "whole.bvh"
    whole.write_bytes(data)
    assert bvh.read(whole).n_frames == 802


@pytest.mark.parametrize("frame_time", ["inf", "1e-320"])
def test_a_frame_time_that_is_not_a_positive_finite_number_is_a_format_error(tmp_path,
                                                                              frame_time):
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"])
    path.write_text(path.read_text().replace("Frame Time: 0.01", f"Frame Time: {frame_time}"))
    with pytest.raises(FormatError) as caught:
        bvh.read(path)
    assert str(caught.value) == (f"{path}: Frame Time is {frame_time!r}, not a frame time "
                                 "(a positive, finite number of seconds)")


@pytest.mark.parametrize("frames, frame_time", [
    ("Frames:", "Frame  Time:"), ("Frames:", "Frame\tTime:"), ("Frames :", "frame time :"),
    ("FRAMES:", " Frame \t Time:")])
def test_header_words_may_be_separated_by_any_whitespace(tmp_path, frames, frame_time):
    # The bvh package and other readers split on whitespace runs; "Frame  Time:" was a
    # bad MOTION header here.
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0", "1 0 0 0 0 0 0 0 0"])
    text = path.read_text().replace("Frames:", frames).replace("Frame Time:", frame_time)
    path.write_text(text)
    motion = bvh.read(path)
    assert (motion.n_frames, motion.rate) == (2, 100.0)


def test_a_header_word_run_together_is_still_a_bad_header(tmp_path):
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"])
    path.write_text(path.read_text().replace("Frame Time:", "FrameTime:"))
    with pytest.raises(FormatError, match="bad MOTION header: expected 'Frame Time:'"):
        bvh.read(path)


def test_a_negative_frames_count_is_a_bad_header(tmp_path):
    # was "too many frames: 0 complete frames read, -2 declared"
    path = write_bvh(tmp_path, [], frames=-2)
    with pytest.raises(FormatError) as caught:
        bvh.read(path)
    assert str(caught.value) == (f"{path}: bad MOTION header: 'Frames: -2' is not a number "
                                 "of frames")


def test_a_bvh_of_no_frames_reads_but_is_not_written(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, []))
    assert motion.n_frames == 0
    out = tmp_path / "out.bvh"
    with pytest.raises(FormatError) as caught:
        formats.write(motion, out)
    assert str(caught.value) == f"{out}: refusing to write a clip with no frames"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chain.bvh"]


def test_real_file_cut_mid_motion_names_the_file_and_the_frame_counts(tmp_path):
    data = shared_file("cmu/10_01.bvh").read_bytes()
    cut = tmp_path / "cut.bvh"
    cut.write_bytes(data[:len(data) // 2])
    with pytest.raises(FormatError) as caught:
        bvh.read(cut)
    message = str(caught.value)
    assert message.startswith(str(cut)) and "truncated" in message
    assert re.search(r"truncated: \d+ complete frames read, 802 declared", message)


# ----------------------------------------------------------------------- channel space

def test_channels_unwraps_a_rotation_crossing_180(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 170 0 0 0 0 0", "0 0 0 179 0 0 0 0 0",
                                           "0 0 0 -172 0 0 0 0 0"]))
    values, _ = bvh.channels(motion)
    np.testing.assert_allclose(values[:, 3], [170, 179, 188])


def test_with_channels_rewraps_filled_cells_into_the_files_range(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 170 0 0 0 0 0", "0 0 0 nan 0 0 0 0 0",
                                           "0 0 0 -172 0 0 0 0 0"]))
    values, observed = bvh.channels(motion)
    values[1, 3] = 184.0
    filled = bvh.with_channels(motion, values, np.ones_like(observed))
    np.testing.assert_allclose(filled.source.state.values[:, 3], [170, -176, -172])


def test_a_fill_in_a_channel_stored_unwrapped_joins_its_stored_neighbours(tmp_path):
    from mocapfill.pipeline import RepairOptions, repair

    turns = ["-536.0", "-717.0", "-708.5", "nan", "-708.9", "-709.2"]
    motion = bvh.read(write_bvh(tmp_path, [f"0 0 0 {z} 0 0 0 0 0" for z in turns]))
    result = repair(motion, RepairOptions(space="channels", method="linear"))
    out = tmp_path / "out.bvh"
    bvh.write(result.motion, out)
    assert out.read_text().splitlines()[-3].split()[3] == "-708.7000"


def test_with_channels_recomputes_positions_by_fk(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"]))
    values, observed = bvh.channels(motion)
    values[0, 3] = 90.0                     # was observed: keeps 0, nothing moves
    values[0, 0] = 5.0
    assert np.allclose(bvh.with_channels(motion, values, observed).positions,
                       motion.positions)


def test_with_channels_fills_positions_of_filled_joints(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 nan 0 0 0 0 0"]))
    assert not motion.observed[0, 1]
    values, observed = bvh.channels(motion)
    values[0, 3] = 90.0
    filled = bvh.with_channels(motion, values, np.ones_like(observed))
    assert filled.observed.all()
    np.testing.assert_allclose(point(filled, "Arm"), [0, 1, 0], atol=1e-12)


# ----------------------------------------------------------------------- writing

def punch_nan(source: Path, target: Path, cells: list[tuple[int, int]]) -> None:
    """Copy a BVH, replacing the given (frame, channel) tokens by ``nan``."""
    lines = source.read_bytes().decode("latin-1").splitlines(keepends=True)
    first = next(i for i, line in enumerate(lines) if line.lower().startswith("frame time"))
    for frame, column in cells:
        index = first + 1 + frame
        tokens = list(re.finditer(r"\S+", lines[index]))
        token = tokens[column]
        lines[index] = lines[index][:token.start()] + "nan" + lines[index][token.end():]
    target.write_bytes("".join(lines).encode("latin-1"))


def fill_by_interpolation(values: np.ndarray, observed: np.ndarray) -> np.ndarray:
    filled = values.copy()
    frames = np.arange(len(values))
    for c in range(values.shape[1]):
        gap = ~observed[:, c]
        if gap.any():
            filled[gap, c] = np.interp(frames[gap], frames[~gap], values[~gap, c])
    return filled


def test_patched_real_file_differs_only_in_the_filled_cells(tmp_path):
    original = shared_file("cmu/10_01.bvh")
    gapped = tmp_path / "gapped.bvh"
    cells = [(f, c) for f in range(300, 340) for c in (3, 10, 40)] + [(5, 0), (700, 95)]
    punch_nan(original, gapped, cells)
    motion = bvh.read(gapped)
    values, observed = bvh.channels(motion)
    filled = fill_by_interpolation(values, observed)
    out = tmp_path / "out.bvh"
    bvh.write(bvh.with_channels(motion, filled, np.ones_like(observed)), out)

    # Every token but the filled ones, every separator and line ending, as the file has it.
    assert assert_only_nan_tokens_replaced(gapped.read_bytes().decode("latin-1"),
                                           out.read_bytes().decode("latin-1")) == len(cells)
    assert out.read_bytes().startswith(motion.source.hierarchy.encode("latin-1"))
    back = bvh.read(out)
    back_values, back_observed = bvh.channels(back)
    assert back_observed.all()
    rows, cols = np.array(cells).T
    np.testing.assert_allclose(back_values[rows, cols], filled[rows, cols], atol=6e-5)


def test_a_filled_cell_replaces_only_its_own_token_in_its_line(tmp_path):
    # Observed values beside the gap, printed in several ways, spaced unevenly, must come
    # back as the file holds them: only the nan token is rewritten.
    gap_line = "1.5  -2.250 3.125000\t170.0 nan -0.5 10.1234 20.4321 30.5555 "
    rows = ["1.5 -2.25 3.125 170.0 10.0 -0.5 10.1234 20.4321 30.5555", gap_line,
            "1.5 -2.25 3.125 170.0 20.0 -0.5 10.1234 20.4321 30.5555"]
    path = write_bvh(tmp_path, rows)
    motion = bvh.read(path)
    values, observed = bvh.channels(motion)
    out = tmp_path / "out.bvh"
    bvh.write(bvh.with_channels(motion, fill_by_interpolation(values, observed),
                                np.ones_like(observed)), out)
    before, after = path.read_text().splitlines(), out.read_text().splitlines()
    assert after[-2] == gap_line.replace("nan", "15.000000")     # the file's 6 decimals
    assert after[:-2] + after[-1:] == before[:-2] + before[-1:]


def test_writing_an_unchanged_read_gives_the_same_bytes(tmp_path):
    original = shared_file("cmu/10_01.bvh")
    out = tmp_path / "same.bvh"
    bvh.write(bvh.read(original), out)
    assert out.read_bytes() == original.read_bytes()


def test_cells_made_missing_are_written_as_nan(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["1 2 3 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 0"]))
    values, observed = bvh.channels(motion)
    observed[1, 7] = False
    out = tmp_path / "gapped.bvh"
    bvh.write(bvh.with_channels(motion, values, observed), out)
    assert out.read_text().splitlines()[-1] == "1 2 3 0 0 0 0 nan 0"


def test_a_byte_order_mark_is_read_past_and_kept(tmp_path):
    plain = write_bvh(tmp_path, ["1 2 3 0 0 0 0 0 0", "nan 0 0 0 0 0 0 0 0"])
    path = tmp_path / "bom.bvh"
    path.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    motion = bvh.read(path)
    assert motion.labels == bvh.read(plain).labels
    values, observed = bvh.channels(motion)
    values[1, 0] = 1.0
    out = tmp_path / "filled.bvh"
    bvh.write(bvh.with_channels(motion, values, np.ones_like(observed)), out)
    assert out.read_bytes().splitlines()[:-1] == path.read_bytes().splitlines()[:-1]
    assert bvh.channels(bvh.read(out))[0][1, 0] == 1.0


def test_utf8_joint_names_read_as_written_and_the_patch_keeps_their_bytes(tmp_path):
    plain = write_bvh(tmp_path, ["1 2 3 0 0 0 0 0 0", "1 2 3 0 0 0 nan 0 0"])
    path = tmp_path / "hüfte.bvh"
    path.write_bytes(plain.read_bytes().replace(b"Hips", "Hüfte".encode()))
    motion = bvh.read(path)
    assert motion.labels[0] == "Hüfte"
    values, observed = bvh.channels(motion)
    values[1, 6] = 0.0
    out = tmp_path / "filled.bvh"
    bvh.write(bvh.with_channels(motion, values, np.ones_like(observed)), out)
    assert out.read_bytes().splitlines()[:-1] == path.read_bytes().splitlines()[:-1]


def test_filled_cells_use_the_files_decimals(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["1.123456 0 0 0 0 0 0 0 0",
                                           "nan 0 0 0 0 0 0 0 0"]))
    values, observed = bvh.channels(motion)
    values[1, 0] = 1.0 / 3.0
    out = tmp_path / "filled.bvh"
    bvh.write(bvh.with_channels(motion, values, np.ones_like(observed)), out)
    assert out.read_text().splitlines()[-1].split()[0] == "0.333333"


def test_writing_a_motion_without_bvh_source_explains_why_not(tmp_path):
    motion = from_matrix(np.zeros((6, 10)))
    with pytest.raises(FormatError, match="BVH output needs a BVH input"):
        bvh.write(motion, tmp_path / "out.bvh")


def test_writing_positions_filled_outside_channel_space_is_refused(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 nan 0 0 0 0 0"]))
    edited = motion.with_positions(np.zeros_like(motion.positions),
                                   np.ones_like(motion.observed))
    with pytest.raises(FormatError, match="outside channel space"):
        bvh.write(edited, tmp_path / "out.bvh")


# ----------------------------------------------------------------------- real files

def test_cmu_10_01_reads_with_its_skeleton_and_rate():
    motion = bvh.read(shared_file("cmu/10_01.bvh"))
    assert motion.positions.shape == (802, 38, 3)
    assert motion.rate == 120.0 and motion.units == "unknown"
    assert motion.observed.all()
    assert motion.labels[:3] == ("Hips", "LHipJoint", "LeftUpLeg")


def test_scale_and_units_options_apply_to_positions_only():
    path = shared_file("cmu/10_01.bvh")
    plain = bvh.read(path)
    scaled = bvh.read(path, scale=56.444, units="mm")
    assert scaled.units == "mm"
    np.testing.assert_allclose(scaled.positions, plain.positions * 56.444)
    np.testing.assert_array_equal(bvh.channels(scaled)[0], bvh.channels(plain)[0])


def test_joints_with_different_channel_orders_in_one_file_read():
    motion = bvh.read(shared_file("bvh/bvh_test1.bvh"))
    assert len(set(motion.source.state.skeleton.rotation_axes) - {""}) == 4
    assert motion.observed.all()


@pytest.mark.slow
@pytest.mark.parametrize("path", shared_files("bvh", ".bvh") + shared_files("cmu", ".bvh"),
                         ids=lambda p: p.name)
def test_every_shared_bvh_file_reads_and_writes_back_unchanged(path, tmp_path):
    motion = bvh.read(path)
    assert motion.n_frames > 0 and motion.observed.all()
    assert np.isfinite(motion.positions).all()
    out = tmp_path / path.name
    bvh.write(motion, out)
    assert out.read_bytes() == path.read_bytes()


@pytest.mark.parametrize("suffix", [".trc", ".c3d"])
def test_a_position_file_written_from_a_bvh_keeps_its_positions_and_notes_the_unit(tmp_path,
                                                                                  suffix):
    # BVH states no length unit: nothing to convert by, so the values are kept (a BVH ->
    # TRC -> NPZ round trip stays lossless) and the caller is told.
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 10 20 30", "1 2 3 0 0 0 10 20 30"]))
    out = tmp_path / f"out{suffix}"
    notes = formats.write(motion, out)
    assert len(notes) == 1 and "'unknown' is not known" in notes[0]
    back = formats.read(out)
    assert back.units == "unknown"
    np.testing.assert_allclose(back.positions, motion.positions, rtol=1e-6)


def test_a_clip_whose_points_would_take_more_than_the_limit_is_refused_naming_it(tmp_path,
                                                                                  monkeypatch):
    # As for an AMC (End Sites are points no channel costs a byte of file); the limit is
    # lowered here so that the file stays small: a frame of 3 points and 9 channels takes
    # about 504 bytes.
    from mocapfill import skeleton

    monkeypatch.setattr(skeleton, "MAX_READ_MEMORY", 1 << 20)
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0"] * 2100)
    with pytest.raises(FormatError) as caught:
        formats.read(path)
    assert str(caught.value) == (f"{path}: 2100 frames of 3 points (9 channels) would take "
                                 "about 1.0 MB to read, more than the 1.0 MB a skeleton clip "
                                 "may take")
    monkeypatch.setattr(skeleton, "MAX_READ_MEMORY", 2 << 20)
    assert formats.read(path).n_frames == 2100
