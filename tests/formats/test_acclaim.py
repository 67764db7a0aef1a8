"""ASF/AMC: the tolerant parser, canonical Acclaim FK, channel space and the patching writer."""
from __future__ import annotations

import errno
import os
import re
from pathlib import Path

import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import FormatError, ParameterError
from mocapfill.formats import acclaim, bvh
from mocapfill.motion import from_matrix
from tests.conftest import shared_file
from tests.formats.test_bvh import fill_by_interpolation
from tests.formats.test_csv import assert_every_cut_reads_as_a_prefix
from tests.helpers import peak_bytes
from tests.test_skeleton import rot

# Keywords deliberately out of the usual order, a comment, commas, wrapped limits, a bone
# without dof, dofs in a subset and a non-xyz order.
ASF = """# made by hand
:name tiny
:root
   axis XYZ
   order TX TY TZ RX RY RZ
   orientation 0 0 0
   position 0 0 0
:units
  length 0.5
  angle deg
  mass 1.0
:bonedata
  begin
     name arm
     id 1
     length 2
     direction 1, 0, 0
     axis 0 0 90  XYZ
    dof rx
    limits (-180.0 180.0)
  end
  begin
     id 2
     name hand
     direction 0 1 0
     length 1
     axis 0 0 0 XYZ
    dof rz ry
    limits (-180.0 180.0)
           (-180.0 180.0)
  end
  begin
     id 3
     name stub
     direction 0 0 1
     length 3
     axis 0 0 0 XYZ
  end
:hierarchy
  begin
    root arm stub
    arm hand
  end
"""


def write_pair(tmp_path: Path, frames: list[str], stem: str = "tiny_01",
               asf_name: str = "tiny_01.asf", header: str = ":FULLY-SPECIFIED\n:DEGREES\n"
               ) -> Path:
    (tmp_path / asf_name).write_text(ASF)
    amc = tmp_path / f"{stem}.amc"
    amc.write_text("#!OML:ASF tiny.asf\n" + header + "".join(frames))
    return amc


def frame(number: int, root: str = "0 0 0 0 0 0", arm: str | None = "0",
          hand: str | None = "0 0") -> str:
    lines = [f"{number}", f"root {root}"]
    lines += [] if arm is None else [f"arm {arm}"]
    lines += [] if hand is None else [f"hand {hand}"]
    return "".join(line + "\n" for line in lines)


def point(motion, label: str, frame_index: int = 0) -> np.ndarray:
    return motion.positions[frame_index, motion.labels.index(label)]


# ----------------------------------------------------------------------- ASF and FK

def test_points_are_the_root_and_every_bone_end(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1)]))
    assert motion.labels == ("root", "arm", "hand", "stub")


def test_rest_pose_puts_bone_ends_along_length_times_direction(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1, root="1 2 3 0 0 0")]))
    np.testing.assert_allclose(point(motion, "arm"), [3, 2, 3], atol=1e-12)
    np.testing.assert_allclose(point(motion, "hand"), [3, 3, 3], atol=1e-12)
    np.testing.assert_allclose(point(motion, "stub"), [1, 2, 6], atol=1e-12)


def test_root_rz_of_90_turns_every_bone_about_world_z(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1, root="0 0 0 0 0 90")]))
    np.testing.assert_allclose(point(motion, "arm"), [0, 2, 0], atol=1e-12)
    np.testing.assert_allclose(point(motion, "hand"), [-1, 2, 0], atol=1e-12)


def test_dof_rotation_is_about_the_bones_axis_frame(tmp_path):
    # arm: axis (0 0 90) makes its local x the world y; rx 90 turns the bone, which
    # points along world x, about world y: x -> -z.
    motion = acclaim.read(write_pair(tmp_path, [frame(1, arm="90")]))
    np.testing.assert_allclose(point(motion, "arm"), [0, 0, -2], atol=1e-12)


def test_dof_angles_rotate_about_fixed_axes_in_dof_order(tmp_path):
    # hand: dof "rz ry" -> M = Ry(b) @ Rz(a); its bone points along world y.
    motion = acclaim.read(write_pair(tmp_path, [frame(1, hand="30 40")]))
    expected = [2, 0, 0] + rot("Y", 40) @ rot("Z", 30) @ [0, 1, 0]
    np.testing.assert_allclose(point(motion, "hand"), expected, atol=1e-12)


def test_root_rotations_compose_about_fixed_axes_in_order(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1, root="0 0 0 30 40 50")]))
    expected = rot("Z", 50) @ rot("Y", 40) @ rot("X", 30) @ [0, 0, 3]
    np.testing.assert_allclose(point(motion, "stub"), expected, atol=1e-12)


def test_asf_with_radian_axes_matches_degrees(tmp_path):
    degrees = acclaim.read(write_pair(tmp_path, [frame(1, arm="90")]))
    (tmp_path / "tiny_01.asf").write_text(
        ASF.replace("angle deg", "angle rad").replace("axis 0 0 90", f"axis 0 0 {np.pi / 2!r}"))
    radians = acclaim.read(tmp_path / "tiny_01.amc")
    np.testing.assert_allclose(radians.positions, degrees.positions, atol=1e-12)


def test_amc_without_degrees_keyword_holds_radians(tmp_path):
    amc = write_pair(tmp_path, [frame(1, arm=repr(np.pi / 2))], header=":FULLY-SPECIFIED\n")
    motion = acclaim.read(amc)
    np.testing.assert_allclose(acclaim.channels(motion)[0][0, 6], 90.0)
    np.testing.assert_allclose(point(motion, "arm"), [0, 0, -2], atol=1e-12)


def test_translation_dofs_are_rejected_naming_the_bone(tmp_path):
    amc = write_pair(tmp_path, [frame(1)])
    (tmp_path / "tiny_01.asf").write_text(ASF.replace("dof rx\n", "dof rx tx\n"))
    with pytest.raises(FormatError, match=r"tiny_01\.asf: bad ASF: bone 'arm' has translation"):
        acclaim.read(amc)


def test_a_hierarchy_naming_an_undefined_bone_is_a_format_error(tmp_path):
    amc = write_pair(tmp_path, [frame(1)])
    (tmp_path / "tiny_01.asf").write_text(ASF.replace("arm hand", "arm hand finger"))
    with pytest.raises(FormatError, match="'finger' that :bonedata does not define"):
        acclaim.read(amc)


class _Name(str):
    """A bone name counting the comparisons made with it."""

    comparisons = 0

    def __eq__(self, other):
        _Name.comparisons += 1
        return str.__eq__(self, other)

    __hash__ = str.__hash__


def test_the_hierarchy_walk_compares_each_bone_a_few_times_not_with_every_bone_before():
    # Each bone was compared with every bone reached before it: 29 s of a 50,000-bone
    # chain (a 5.6 MB ASF).
    n = 2000
    bones = {_Name(f"b{k}"): acclaim._Bone(f"b{k}") for k in range(n)}
    children = {"root": [_Name("b0")]} | {_Name(f"b{k}"): [_Name(f"b{k + 1}")]
                                          for k in range(n - 1)}
    _Name.comparisons = 0
    order = acclaim._tree(acclaim._Asf(bones, children))
    assert [name for name, _ in order] == ["root"] + [f"b{k}" for k in range(n)]
    assert [parent for _, parent in order] == list(range(-1, n))
    assert _Name.comparisons < 10 * n


@pytest.mark.parametrize(("hierarchy", "words"), [
    ("root arm stub\n    arm hand stub", ":hierarchy reaches bone 'stub' twice"),
    ("root arm stub\n    arm hand\n    hand arm", ":hierarchy reaches bone 'arm' twice"),
    ("root arm\n    arm hand", "bones not in :hierarchy: stub"),
])
def test_a_hierarchy_reaching_a_bone_twice_or_not_at_all_is_a_format_error(tmp_path,
                                                                            hierarchy, words):
    amc = write_pair(tmp_path, [frame(1)])
    asf = tmp_path / "tiny_01.asf"
    asf.write_text(ASF.replace("root arm stub\n    arm hand", hierarchy))
    with pytest.raises(FormatError) as caught:
        formats.read(amc)
    assert str(caught.value) == f"{asf}: bad ASF: {words}"


ONE_BONE_ASF = """:units
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     name a
     direction 0 1 0
     length 1
     axis 0 0 0 XYZ
     dof rx
  end
:hierarchy
  begin
    root a
  end
"""


def test_frames_without_bone_lines_cost_a_few_hundred_bytes_each_to_read(tmp_path):
    # Each frame had a row of every channel and point made as it began, and forward
    # kinematics held every joint's rotations and its temporaries for the whole clip: a
    # 10 MB AMC of 5,000,000 such frames ("1\n") took 49 s and 5.5 GB.
    (tmp_path / "x.asf").write_text(ONE_BONE_ASF)
    (tmp_path / "x.amc").write_text(":DEGREES\n1\nroot 0 0 0 0 0 0\na 1\n")
    formats.read(tmp_path / "x.amc")           # the reader's modules, imported
    frames = 50_000
    (tmp_path / "x.amc").write_text(":DEGREES\n" + "1\n" * frames)
    peak = peak_bytes(lambda: formats.read(tmp_path / "x.amc"))
    motion = formats.read(tmp_path / "x.amc")
    assert (motion.n_frames, motion.n_markers, motion.observed.any()) == (frames, 2, False)
    assert peak < 500 * frames


def fan(tmp_path: Path, bones: int, frames: int, dof: str = "rx ry rz") -> Path:
    """An ASF of ``bones`` bones under the root and an AMC of ``frames`` frames, the first
    holding the root alone, the others no bone line ("1\\n", 2 bytes each)."""
    blocks = "".join(f"  begin\n     name b{k}\n     direction 0 1 0\n     length 1\n"
                     f"     axis 0 0 0 XYZ\n" + (f"     dof {dof}\n" if dof else "") + "  end\n"
                     for k in range(bones))
    hierarchy = " ".join(f"b{k}" for k in range(bones))
    (tmp_path / "x.asf").write_text(ONE_BONE_ASF.split(":bonedata")[0] + ":bonedata\n"
                                    + blocks + f":hierarchy\n  begin\n    root {hierarchy}\n"
                                    "  end\n")
    amc = tmp_path / "x.amc"
    amc.write_text(":DEGREES\n1\nroot 0 0 0 0 0 0\n" + "1\n" * (frames - 1))
    return amc


def test_a_clip_whose_points_would_take_more_than_4_gb_is_refused_before_it_is_built(
        tmp_path):
    # 100 KB of frames without bone lines against an ASF of 2,000 bones took more than
    # 4 GB: the channel matrix, then 9 floats of rotation a joint and frame in FK.
    amc = fan(tmp_path, 2000, 50_001)
    formats.read(write_pair(tmp_path, [frame(1)]))     # the reader's modules, imported
    caught = []

    def refused():
        with pytest.raises(FormatError) as raised:
            formats.read(amc)
        caught.append(raised)

    peak = peak_bytes(refused)
    assert str(caught[0].value) == (f"{amc}: 50001 frames of 2001 points (6006 channels) would "
                                 "take about 15.7 GB to read, more than the 4.0 GB a "
                                 "skeleton clip may take")
    assert peak < 64 << 20


@pytest.mark.parametrize(("bones", "dof"), [(100, "rx ry rz"), (100, ""), (200, "rx ry rz")])
def test_the_memory_a_read_is_refused_for_bounds_what_reading_takes(tmp_path, bones, dof):
    from mocapfill.skeleton import read_memory

    amc = fan(tmp_path, bones, 4000, dof)
    formats.read(write_pair(tmp_path, [frame(1)]))     # the reader's modules, imported
    peak = peak_bytes(lambda: formats.read(amc))
    motion = formats.read(amc)
    channels = 6 + bones * len(dof.split())
    assert motion.source.state.values.shape == (4000, channels)
    assert peak <= read_memory(4000, bones + 1, channels)


def test_a_bone_line_given_twice_in_a_frame_counts_as_its_last(tmp_path):
    amc = write_pair(tmp_path, [frame(1, arm="10"), frame(2, arm="20") + "arm 30\n",
                                frame(3, arm="40")])
    motion = formats.read(amc)
    once = formats.read(write_pair(tmp_path, [frame(1, arm="10"), frame(2, arm="30"),
                                              frame(3, arm="40")], stem="once"))
    np.testing.assert_array_equal(motion.positions, once.positions)
    lines = amc.read_text().splitlines()
    arm = motion.labels.index("arm")
    assert [lines[i] for i in motion.source.point_lines[:, arm]] == ["arm 10", "arm 30",
                                                                     "arm 40"]


def test_units_option_converts_positions_by_the_inch_convention(tmp_path):
    amc = write_pair(tmp_path, [frame(1)])
    plain, mm = acclaim.read(amc), acclaim.read(amc, units="mm")
    assert plain.units == "in/0.5" and mm.units == "mm"
    np.testing.assert_allclose(mm.positions, plain.positions * 25.4 / 0.5)


def test_an_unknown_units_option_is_a_parameter_error(tmp_path):
    with pytest.raises(ParameterError, match="units must be one of"):
        acclaim.read(write_pair(tmp_path, [frame(1)]), units="furlong")


# ----------------------------------------------------------------------- AMC

def test_bone_lines_may_come_in_any_order(tmp_path):
    shuffled = "1\nhand 30 40\nroot 1 2 3 0 0 0\narm 20\n"
    ordered = frame(1, root="1 2 3 0 0 0", arm="20", hand="30 40")
    a = acclaim.read(write_pair(tmp_path, [shuffled], stem="a"), asf=tmp_path / "tiny_01.asf")
    b = acclaim.read(write_pair(tmp_path, [ordered], stem="b"), asf=tmp_path / "tiny_01.asf")
    np.testing.assert_array_equal(a.positions, b.positions)


def test_rate_is_not_known_and_frame_numbers_start_where_the_file_does(tmp_path):
    # An AMC states no rate: 0 Hz, as a C3D without POINT:RATE (it was 120, CMU's, so a
    # --max-gap in seconds was read at a rate the file never stated).
    amc = write_pair(tmp_path, [frame(7), frame(8)])
    motion = acclaim.read(amc)
    assert motion.rate == 0.0 and motion.first_frame == 7 and motion.n_frames == 2
    assert acclaim.read(amc, rate=120).rate == 120.0
    assert formats.read(amc, rate=60).rate == 60.0


def test_frame_numbers_that_skip_are_noted_and_the_frames_read_in_file_order(tmp_path):
    # As TRC and CSV readers note a Frame column that skips; the AMC was renumbered silently.
    motion = acclaim.read(write_pair(tmp_path, [frame(1), frame(2), frame(4, arm="40"),
                                                frame(5), frame(7)]))
    assert motion.n_frames == 5 and motion.first_frame == 1
    assert acclaim.channels(motion)[0][2, 6] == 40          # frame 4 is the third frame
    assert motion.source.notes == (
        "the frame numbers are not consecutive (2 then 4 at line 12, and 1 more place(s)); "
        "frames are read in file order as consecutive frames numbered from 1",)


def test_a_repeated_frame_number_is_noted(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(3), frame(4), frame(4)]))
    assert motion.n_frames == 3 and motion.first_frame == 3
    assert motion.source.notes == (
        "the frame numbers are not consecutive (4 then 4 at line 12); frames are read in "
        "file order as consecutive frames numbered from 3",)


def test_consecutive_frame_numbers_are_not_noted(tmp_path):
    assert acclaim.read(write_pair(tmp_path, [frame(7), frame(8), frame(9)])).source.notes == ()


def test_nan_values_are_gaps(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1), frame(2, arm="nan")]))
    _, observed = acclaim.channels(motion)
    assert observed.sum() == observed.size - 1 and not observed[1, 6]


def test_a_bone_line_absent_from_a_frame_is_a_gap(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1), frame(2, hand=None)]))
    _, observed = acclaim.channels(motion)
    assert not observed[1, 7:9].any() and observed[0].all()


def test_a_gap_in_a_bone_hides_its_end_and_those_below_it(tmp_path):
    motion = acclaim.read(write_pair(tmp_path, [frame(1, arm="nan")]))
    np.testing.assert_array_equal(motion.observed[0], [True, False, False, True])


def test_a_bone_line_with_the_wrong_count_names_the_line(tmp_path):
    amc = write_pair(tmp_path, [frame(1, hand="1 2 3")])
    with pytest.raises(FormatError, match=r"line 7: hand has 3 values, its dof lists 2"):
        acclaim.read(amc)


def test_a_bone_unknown_to_the_asf_is_a_format_error(tmp_path):
    amc = write_pair(tmp_path, [frame(1) + "tail 3\n"])
    with pytest.raises(FormatError, match="bone 'tail' not in the ASF"):
        acclaim.read(amc)


def cut(amc: Path, n_bytes: int) -> Path:
    """Drop the last ``n_bytes`` of a file, as an interrupted copy does."""
    amc.write_bytes(amc.read_bytes()[:-n_bytes])
    return amc


# The values of this file are printed with two decimals, as a cut value is not.
TWO_DECIMALS = [frame(1, "1.00 2.00 3.00 4.00 5.00 6.00", "10.50", "20.25 30.75"),
                frame(2, "1.00 2.00 3.00 4.00 5.00 6.00", "11.50", "10.50 25.75")]


def test_an_amc_cut_inside_its_last_number_reads_that_value_as_missing(tmp_path):
    amc = cut(write_pair(tmp_path, TWO_DECIMALS), 2)  # "hand 10.50 25.7"
    motion = acclaim.read(amc)
    values, observed = acclaim.channels(motion)
    assert observed[1].tolist() == [True] * 8 + [False] and values[1, 7] == 10.5
    assert "looks cut short" in motion.source.notes[0]


@pytest.mark.parametrize("last", ["25.7", "25.", "25", "2", "2e", "-"])
def test_a_last_value_printed_less_precisely_than_its_dof_reads_as_missing(tmp_path, last):
    amc = write_pair(tmp_path, TWO_DECIMALS)
    amc.write_text(amc.read_text().removesuffix("25.75\n") + last)
    motion = acclaim.read(amc)
    assert acclaim.channels(motion)[1][1].tolist() == [True] * 8 + [False]
    assert motion.source.notes


def test_an_amc_cut_inside_its_last_line_reads_absent_values_as_missing(tmp_path):
    amc = cut(write_pair(tmp_path, [frame(1), frame(2, hand="10 25")]), 5)  # "hand 1"
    _, observed = acclaim.channels(acclaim.read(amc))
    assert observed[1].tolist() == [True] * 7 + [False, False]


def test_every_cut_of_an_amc_reads_as_a_prefix_of_its_values_or_fails(tmp_path):
    # Printed like a real AMC, each value with the same decimals (an integer "12" cut to
    # "1" would be as precise as the "6" above it: no reader can tell that cut).
    amc = write_pair(tmp_path, [
        frame(1, "1.500 2.250 3.000 4.000 5.000 6.000", "10.500", "20.250 30.125"),
        frame(2, "7.000 8.000 9.000 10.000 11.000 12.000", "nan", "-40.500 50.750")])
    assert_every_cut_reads_as_a_prefix(amc, acclaim.channels)


def test_every_cut_of_a_real_amcs_last_line_reads_its_last_value_as_missing(tmp_path):
    (tmp_path / "09.asf").write_bytes(shared_file("cmu/09.asf").read_bytes())
    data = shared_file("cmu/09_12.amc").read_bytes()
    assert data.endswith(b"\nltoes 8.94154\r\n")
    amc = tmp_path / "09_12.amc"
    for kept in ("ltoes 8.9415", "ltoes 8.941", "ltoes 8.9", "ltoes 8.", "ltoes 8"):
        amc.write_bytes(data.removesuffix(b"ltoes 8.94154\r\n") + kept.encode())
        motion = acclaim.read(amc)
        assert not motion.observed[-1, motion.labels.index("ltoes")], kept
        assert motion.source.notes, kept


@pytest.mark.parametrize("tail", ["3", "han"])
def test_an_amc_cut_inside_a_frame_number_or_bone_name_reads_the_frames_before(tmp_path,
                                                                                tail):
    amc = write_pair(tmp_path, [frame(1), frame(2), tail])
    motion = acclaim.read(amc)
    assert motion.n_frames == 2 and motion.observed.all()


# ----------------------------------------------------------------------- finding the ASF

def test_asf_with_the_same_stem_is_preferred(tmp_path):
    amc = write_pair(tmp_path, [frame(1)], stem="09_12", asf_name="09_12.asf")
    (tmp_path / "09.asf").write_text("not an asf")
    assert acclaim.read(amc).source.asf_path.name == "09_12.asf"


def test_asf_named_after_the_subject_prefix_is_found(tmp_path):
    amc = write_pair(tmp_path, [frame(1)], stem="09_12", asf_name="09.asf")
    (tmp_path / "other.asf").write_text("not an asf")
    assert acclaim.read(amc).source.asf_path.name == "09.asf"


def test_the_only_asf_in_the_folder_is_used(tmp_path):
    amc = write_pair(tmp_path, [frame(1)], stem="walk", asf_name="skeleton.asf")
    assert acclaim.read(amc).source.asf_path.name == "skeleton.asf"


def test_missing_asf_error_names_what_was_tried(tmp_path):
    amc = tmp_path / "09_12.amc"
    amc.write_text(frame(1))
    with pytest.raises(FormatError, match=r"09_12\.amc: .*tried 09_12\.asf and 09\.asf"):
        acclaim.read(amc)


@pytest.mark.parametrize("link_name", ["09_12.amc", "walk.amc"])
def test_an_amc_given_through_a_symlink_finds_the_skeleton_beside_its_target(tmp_path,
                                                                             link_name):
    # `ln -s ../in/09_12.amc links/; mocapfill repair links/09_12.amc out.amc` failed
    # (exit 123, "cannot find its skeleton ... in links") where the target itself read.
    (tmp_path / "in").mkdir()
    (tmp_path / "links").mkdir()
    write_pair(tmp_path / "in", [frame(1), frame(2, arm="10")], stem="09_12",
               asf_name="09.asf")
    (tmp_path / "in" / "10.asf").write_text("another subject's")
    link = tmp_path / "links" / link_name
    link.symlink_to(Path("..") / "in" / "09_12.amc")
    motion = formats.read(link)
    assert motion.source.asf_path == tmp_path / "in" / "09.asf"
    np.testing.assert_array_equal(motion.positions,
                                  formats.read(tmp_path / "in" / "09_12.amc").positions)
    (tmp_path / "out").mkdir()
    formats.write(motion, tmp_path / "out" / "09_12.amc")
    assert (tmp_path / "out" / "09.asf").read_text() == ASF


def test_a_symlinked_amc_without_a_skeleton_names_both_folders_looked_in(tmp_path):
    (tmp_path / "in").mkdir()
    (tmp_path / "links").mkdir()
    (tmp_path / "in" / "09_12.amc").write_text(frame(1))
    (tmp_path / "links" / "walk.amc").symlink_to(tmp_path / "in" / "09_12.amc")
    with pytest.raises(FormatError) as caught:
        formats.read(tmp_path / "links" / "walk.amc")
    assert str(caught.value) == (
        f"{tmp_path / 'links' / 'walk.amc'}: cannot find its skeleton: tried walk.asf in "
        f"{tmp_path / 'links'}, which holds no .asf file; tried 09_12.asf and 09.asf and "
        f"walk.asf in its target's folder {tmp_path / 'in'}, which holds no .asf file; put "
        "the skeleton beside it, named walk.asf")


# ----------------------------------------------------------------------- channel space

def test_channels_unwrap_and_with_channels_rewraps_only_filled_cells(tmp_path):
    frames = [frame(1, arm="170"), frame(2, arm="nan"), frame(3, arm="-172")]
    motion = acclaim.read(write_pair(tmp_path, frames))
    values, observed = acclaim.channels(motion)
    np.testing.assert_allclose(values[[0, 2], 6], [170, 188])
    values[1, 6] = 184.0
    filled = acclaim.with_channels(motion, values, np.ones_like(observed))
    np.testing.assert_allclose(filled.source.state.values[:, 6], [170, -176, -172])
    assert filled.observed.all()


# ----------------------------------------------------------------------- writing

def test_an_amc_with_a_byte_order_mark_reads_as_without(tmp_path):
    path = write_pair(tmp_path, [frame(1), frame(2, arm="30")])
    expected = acclaim.read(path)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    motion = acclaim.read(path)
    np.testing.assert_array_equal(motion.positions, expected.positions)


def test_filled_cell_is_written_in_place_with_six_significant_digits(tmp_path):
    amc = write_pair(tmp_path, [frame(1, arm="10"), frame(2, arm="nan"), frame(3, arm="20")])
    motion = acclaim.read(amc)
    values, observed = acclaim.channels(motion)
    values[1, 6] = 15.123456789
    out = tmp_path / "out.amc"
    acclaim.write(acclaim.with_channels(motion, values, np.ones_like(observed)), out)
    before, after = amc.read_text().splitlines(), out.read_text().splitlines()
    changed = [(a, b) for a, b in zip(before, after) if a != b]
    assert changed == [("arm nan", "arm 15.1235")] and len(after) == len(before)


def test_a_filled_dof_replaces_only_its_own_token_in_its_bone_line(tmp_path):
    # Observed dofs beside the gap, printed in several ways, spaced unevenly, must come back
    # as the file holds them: only the nan token is rewritten.
    root_gap = "root 1.5  -2.250 3.125000\tnan 20.0 -30.75 "
    hand_gap = "hand nan  -7.50"
    amc = write_pair(tmp_path, [
        frame(1, root="1.5 -2.25 3.125 10 20 -30.75", hand="10 -7.5"),
        frame(2, root=root_gap.removeprefix("root "), hand=hand_gap.removeprefix("hand ")),
        frame(3, root="1.5 -2.25 3.125 20 20 -30.75", hand="20 -7.5")])
    out = filled_everywhere(acclaim.read(amc), tmp_path / "out.amc")
    before, after = amc.read_text().splitlines(), out.read_text().splitlines()
    changed = [(a, b) for a, b in zip(before, after) if a != b]
    assert changed == [(root_gap, root_gap.replace("nan", "15")),
                       (hand_gap, hand_gap.replace("nan", "15"))]
    assert len(after) == len(before)


def test_filled_bone_absent_from_its_frame_gets_a_line_at_the_frames_end(tmp_path):
    amc = write_pair(tmp_path, [frame(1), frame(2, hand=None), frame(3)])
    motion = acclaim.read(amc)
    values, observed = acclaim.channels(motion)
    out = tmp_path / "out.amc"
    acclaim.write(acclaim.with_channels(motion, fill_by_interpolation(values, observed),
                                        np.ones_like(observed)), out)
    assert out.read_text() == amc.read_text().replace("arm 0\n3\n", "arm 0\nhand 0 0\n3\n")


def filled_everywhere(motion, out: Path) -> Path:
    """Write ``motion`` with every missing channel cell filled by interpolation."""
    values, observed = acclaim.channels(motion)
    acclaim.write(acclaim.with_channels(motion, fill_by_interpolation(values, observed),
                                        np.ones_like(observed)), out)
    return out


def test_a_repair_leaves_the_line_an_amc_was_cut_inside_as_it_was(tmp_path):
    amc = write_pair(tmp_path, TWO_DECIMALS[:1] + [TWO_DECIMALS[1].replace("10.50", "nan")])
    amc = cut(amc, 2)                                               # "hand nan 25.7"
    motion = acclaim.read(amc)
    out = filled_everywhere(motion, tmp_path / "out.amc")
    # The read nan is filled in place; "25.7", maybe cut short, is neither filled nor
    # completed, and no line ending is added.
    assert out.read_text() == amc.read_text().removesuffix("hand nan 25.7") + "hand 20.25 25.7"
    assert acclaim.channels(acclaim.read(out))[1][1].tolist() == [True] * 8 + [False]
    # The reader's note reaches reports (info, repair), as for TRC and CSV, each time.
    from mocapfill.report import reader_notes

    assert "looks cut short" in reader_notes(motion)[0]
    assert reader_notes(acclaim.read(out)) == reader_notes(motion)


def test_a_repair_leaves_the_absent_values_of_a_cut_line_absent(tmp_path):
    amc = cut(write_pair(tmp_path, TWO_DECIMALS), 6)                # "hand 10.50"
    out = filled_everywhere(acclaim.read(amc), tmp_path / "out.amc")
    assert out.read_bytes() == amc.read_bytes()


def test_with_channels_keeps_the_values_of_a_cut_line_it_did_not_read_missing(tmp_path):
    motion = acclaim.read(cut(write_pair(tmp_path, TWO_DECIMALS), 2))
    values, observed = acclaim.channels(motion)
    filled = acclaim.with_channels(motion, fill_by_interpolation(values, observed),
                                   np.ones_like(observed))
    assert motion.source.unread == (8,)
    assert filled.source.state.observed.sum() == observed.size - 1
    assert not filled.source.state.observed[1, 8]


# --------------------------------------------------------- no final line ending, not cut

def no_final_ending(tmp_path: Path, frames: list[str] = TWO_DECIMALS) -> Path:
    amc = write_pair(tmp_path, frames)
    amc.write_bytes(amc.read_bytes().removesuffix(b"\n"))
    return amc


def test_an_amc_without_a_final_line_ending_reads_its_last_value_as_data(tmp_path):
    motion = acclaim.read(no_final_ending(tmp_path))
    values, observed = acclaim.channels(motion)
    assert observed.all() and values[1, 8] == 25.75
    assert motion.source.notes == () and motion.source.cut_line == -1


def test_a_repair_keeps_the_last_line_of_an_amc_without_a_final_line_ending(tmp_path):
    amc = no_final_ending(tmp_path, [TWO_DECIMALS[0], TWO_DECIMALS[0].replace("1\n", "2\n")
                                     .replace("10.50", "nan"), TWO_DECIMALS[1]
                                     .replace("2\n", "3\n")])
    out = filled_everywhere(acclaim.read(amc), tmp_path / "out.amc")
    assert out.read_text() == amc.read_text().replace("arm nan", "arm 11")
    assert out.read_text().endswith("hand 10.50 25.75")           # no line ending added
    assert acclaim.read(out).observed.all()


def test_a_bone_line_filled_into_the_last_frame_goes_before_the_unterminated_last_line(
        tmp_path):
    amc = no_final_ending(tmp_path, [TWO_DECIMALS[0], frame(2, "1.00 2.00 3.00 4.00 5.00 6.00",
                                                            None, "10.50 25.75")])
    out = filled_everywhere(acclaim.read(amc), tmp_path / "out.amc")
    assert out.read_text() == amc.read_text().replace("hand 10.50 25.75",
                                                      "arm 10.5\nhand 10.50 25.75")
    assert acclaim.read(out).observed.all() and acclaim.read(out).source.notes == ()


@pytest.mark.parametrize("ends", ["hold", "extrapolate"])
def test_an_end_gap_repair_keeps_the_last_value_of_an_amc_without_a_final_ending(tmp_path,
                                                                                ends):
    from mocapfill.pipeline import RepairOptions, repair

    frames = [frame(f, "1.00 2.00 3.00 4.00 5.00 6.00", f"{10 + f}.50",
                    "10.50 nan" if 3 <= f < 6 else f"10.50 {20 + f}.25") for f in range(1, 7)]
    motion = acclaim.read(no_final_ending(tmp_path, frames))
    assert not motion.observed.all() and acclaim.channels(motion)[1][5].all()
    result = repair(motion, RepairOptions(space="channels", method="linear", ends=ends))
    out = tmp_path / "out.amc"
    acclaim.write(result.motion, out)
    assert out.read_text().endswith("hand 10.50 26.25")           # kept, no line ending
    assert acclaim.read(out).observed.all() and result.left == 0


def test_an_end_gap_repair_leaves_a_cut_last_value_and_counts_its_gap_left(tmp_path):
    from mocapfill.pipeline import LEFT_CUT, RepairOptions, repair

    frames = [frame(f, "1.00 2.00 3.00 4.00 5.00 6.00", f"{10 + f}.50",
                    f"10.50 {20 + f}.25") for f in range(1, 7)]
    amc = cut(write_pair(tmp_path, frames), 3)                      # "hand 10.50 26.2"
    result = repair(acclaim.read(amc), RepairOptions(space="channels", method="linear",
                                                      ends="hold"))
    out = tmp_path / "out.amc"
    acclaim.write(result.motion, out)
    assert out.read_bytes() == amc.read_bytes()
    assert [o.status for o in result.gaps] == [LEFT_CUT] and result.filled == 0


def test_cmu_09_12_without_its_final_line_ending_reads_its_last_value(tmp_path):
    (tmp_path / "09.asf").write_bytes(shared_file("cmu/09.asf").read_bytes())
    amc = tmp_path / "09_12.amc"
    amc.write_bytes(shared_file("cmu/09_12.amc").read_bytes().rstrip(b"\r\n"))
    motion = acclaim.read(amc)                                      # ends "ltoes 8.94154"
    assert motion.observed.all() and motion.source.notes == ()
    ltoes = motion.source.channel_names.index("ltoes.rx")
    assert acclaim.channels(motion)[0][-1, ltoes] == pytest.approx(8.94154)


def test_cmu_10_01_cut_before_its_final_line_ending_keeps_its_last_line(tmp_path):
    (tmp_path / "10.asf").write_bytes(shared_file("cmu/10.asf").read_bytes())
    amc = tmp_path / "10_01.amc"
    amc.write_bytes(shared_file("cmu/10_01.amc").read_bytes().rstrip(b"\r\n"))
    # "ltoes -6.5109": 5 significant digits where the file prints 6, as "-6.51093" cut
    # short would be: set aside, noted, and kept as it was.
    motion = acclaim.read(amc)
    assert motion.source.notes and not motion.observed[-1, motion.labels.index("ltoes")]
    out = filled_everywhere(motion, tmp_path / "out.amc")
    assert out.read_bytes() == amc.read_bytes()


def test_radian_amc_is_written_back_in_radians(tmp_path):
    amc = write_pair(tmp_path, [frame(1, arm="nan")], header=":FULLY-SPECIFIED\n")
    motion = acclaim.read(amc)
    values, observed = acclaim.channels(motion)
    values[0, 6] = 90.0
    out = tmp_path / "out.amc"
    acclaim.write(acclaim.with_channels(motion, values, np.ones_like(observed)), out)
    assert "arm 1.5708\n" in out.read_text()


def test_writing_a_motion_without_amc_source_explains_why_not(tmp_path):
    with pytest.raises(FormatError, match="AMC output needs an AMC input"):
        acclaim.write(from_matrix(np.zeros((6, 10))), tmp_path / "out.amc")


# ----------------------------------------------------------------------- real files

# cgspeed's BVH of a CMU clip: each BVH joint sits at the END of the ASF bone its BVH parent
# rotates (BVH point = bone start, AMC point = bone end). cgspeed dropped two lengths:
# ``Neck`` has a zero offset (no ``thorax`` length) and ``LeftFingerBase``/``LThumb`` (and
# right) have zero offsets (no ``lwrist`` length), so points above them differ in absolute
# position while every bone still turns the same way.
SAME_CHAIN = {  # BVH point -> AMC point, identical chains from the root
    "Hips": "root", "LeftUpLeg": "lhipjoint", "LeftLeg": "lfemur", "LeftFoot": "ltibia",
    "LeftToeBase": "lfoot", "LeftToeBase_End": "ltoes", "RightUpLeg": "rhipjoint",
    "RightLeg": "rfemur", "RightFoot": "rtibia", "RightToeBase": "rfoot",
    "RightToeBase_End": "rtoes", "Spine": "lowerback", "Spine1": "upperback",
}
SAME_BONE = {  # BVH point -> AMC bone whose vector (end minus parent's end) it reproduces
    **{k: v for k, v in SAME_CHAIN.items() if k != "Hips"},
    "Neck1": "lowerneck", "Head": "upperneck", "Head_End": "head",
    "LeftArm": "lclavicle", "LeftForeArm": "lhumerus", "LeftHand": "lradius",
    "LeftHandIndex1": "lhand", "LeftHandIndex1_End": "lfingers", "LThumb_End": "lthumb",
    "RightArm": "rclavicle", "RightForeArm": "rhumerus", "RightHand": "rradius",
    "RightHandIndex1": "rhand", "RightHandIndex1_End": "rfingers", "RThumb_End": "rthumb",
}


@pytest.fixture(scope="module")
def cmu_10_01():
    amc = acclaim.read(shared_file("cmu/10_01.amc"))
    from_bvh = bvh.read(shared_file("cmu/10_01.bvh"))
    return amc, from_bvh


def test_cmu_10_01_amc_reads_801_frames_of_31_points(cmu_10_01):
    amc, _ = cmu_10_01
    assert amc.positions.shape == (801, 31, 3) and amc.observed.all()
    assert amc.source.asf_path.name == "10.asf" and amc.units == "in/0.45"


def test_cmu_10_01_amc_and_bvh_points_on_the_same_chain_agree(cmu_10_01):
    amc, from_bvh = cmu_10_01
    bvh_points = from_bvh.positions[1:, [from_bvh.labels.index(k) for k in SAME_CHAIN]]
    amc_points = amc.positions[:, [amc.labels.index(v) for v in SAME_CHAIN.values()]]
    assert np.abs(bvh_points - amc_points).max() < 1e-3


def test_cmu_10_01_amc_and_bvh_bone_vectors_agree(cmu_10_01):
    amc, from_bvh = cmu_10_01
    bvh_skeleton = from_bvh.source.state.skeleton
    amc_skeleton = amc.source.state.skeleton
    for bvh_name, amc_name in SAME_BONE.items():
        j = from_bvh.labels.index(bvh_name)
        k = amc.labels.index(amc_name)
        bvh_vector = from_bvh.positions[1:, j] - from_bvh.positions[1:, bvh_skeleton.parents[j]]
        amc_vector = amc.positions[:, k] - amc.positions[:, amc_skeleton.parents[k]]
        assert np.abs(bvh_vector - amc_vector).max() < 1e-3, bvh_name


def test_patched_real_amc_differs_only_in_the_filled_cells(tmp_path):
    source = shared_file("cmu/10_01.amc")
    (tmp_path / "10.asf").write_bytes(shared_file("cmu/10.asf").read_bytes())
    lines = source.read_bytes().decode("latin-1").splitlines(keepends=True)
    punched = {}
    for index, line in enumerate(lines):
        if re.match(r"(lfemur|rhumerus|root) ", line) and 2000 < index < 2600:
            token = list(re.finditer(r"\S+", line))[2]
            punched[index] = line[:token.start()] + "nan" + line[token.end():]
    gapped = tmp_path / "10_01.amc"
    gapped.write_bytes("".join(punched.get(i, x) for i, x in enumerate(lines)).encode("latin-1"))
    motion = acclaim.read(gapped)
    values, observed = acclaim.channels(motion)
    assert (~observed).sum() == len(punched)
    filled = fill_by_interpolation(values, observed)
    out = tmp_path / "out.amc"
    acclaim.write(acclaim.with_channels(motion, filled, np.ones_like(observed)), out)

    before = source.read_bytes().splitlines(keepends=True)
    after = out.read_bytes().splitlines(keepends=True)
    assert len(after) == len(before)
    for index, (old, new) in enumerate(zip(before, after)):
        if index not in punched:
            assert new == old, f"line {index + 1} changed"
        else:
            old_tokens, new_tokens = old.split(), new.split()
            assert new_tokens[:2] == old_tokens[:2] and new_tokens[3:] == old_tokens[3:]
    back_values, back_observed = acclaim.channels(acclaim.read(out))
    assert back_observed.all()
    gap = ~observed
    np.testing.assert_allclose(back_values[gap], filled[gap], rtol=1e-5, atol=1e-9)


def test_writing_an_unchanged_amc_gives_the_same_bytes(tmp_path, cmu_10_01):
    amc, _ = cmu_10_01
    out = tmp_path / "same.amc"
    acclaim.write(amc, out)
    assert out.read_bytes() == shared_file("cmu/10_01.amc").read_bytes()


@pytest.mark.slow
def test_cmu_09_12_amc_reads_with_the_subject_asf():
    motion = acclaim.read(shared_file("cmu/09_12.amc"))
    assert motion.n_frames == 1918 and motion.observed.all()
    assert motion.source.asf_path.name == "09.asf"


# ----------------------------------------------------------------------- the skeleton beside

def test_an_amc_written_to_another_folder_gets_its_skeleton_and_reads_back(tmp_path):
    from mocapfill import formats

    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1), frame(2, arm="10")],
                                     asf_name="tiny.asf"))
    formats.write(motion, tmp_path / "out" / "copy_01.amc")
    # Named after the subject prefix, a name the reader tries before any other skeleton.
    assert (tmp_path / "out" / "copy.asf").read_bytes() == (tmp_path / "in" / "tiny.asf"
                                                            ).read_bytes()
    back = formats.read(tmp_path / "out" / "copy_01.amc")
    np.testing.assert_array_equal(back.positions, motion.positions)
    # A second trial of the subject there finds it: nothing is copied again or refused.
    formats.write(motion, tmp_path / "out" / "copy_02.amc")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "copy.asf", "copy_01.amc", "copy_02.amc"]


def test_amcs_of_two_subjects_written_to_one_folder_each_read_back_with_their_own(tmp_path):
    from mocapfill import formats

    (tmp_path / "out").mkdir()
    other_asf = ASF.replace("length 3", "length 4", 1)
    read = {}
    for subject, asf_text in (("09", ASF), ("10", other_asf)):
        folder = tmp_path / subject
        folder.mkdir()
        amc = write_pair(folder, [frame(1), frame(2, arm="10")], stem=f"{subject}_01",
                         asf_name=f"{subject}.asf")
        (folder / f"{subject}.asf").write_text(asf_text)
        read[subject] = acclaim.read(amc)
        formats.write(read[subject], tmp_path / "out" / f"{subject}_01.amc")
    for subject, motion in read.items():
        np.testing.assert_array_equal(
            formats.read(tmp_path / "out" / f"{subject}_01.amc").positions, motion.positions)
    assert not np.array_equal(read["09"].positions, read["10"].positions)


def test_a_different_skeleton_under_the_outputs_stem_is_refused_before_writing(tmp_path):
    from mocapfill import formats

    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1)], asf_name="tiny.asf"))
    (tmp_path / "out" / "copy_01.asf").write_text(ASF.replace("length 3", "length 4", 1))
    with pytest.raises(FormatError, match="differs from the input's skeleton"):
        formats.write(motion, tmp_path / "out" / "copy_01.amc")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["copy_01.asf"]


def test_an_amc_is_never_left_without_its_skeleton_when_the_copy_fails(tmp_path,
                                                                        monkeypatch):
    # The skeleton was copied after the AMC was written: a copy that failed (a full disk,
    # Ctrl-C) left an AMC that reads with no skeleton or another subject's, and that a
    # batch rerun skipped as up to date.
    from mocapfill import formats

    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1), frame(2, arm="10")],
                                     asf_name="tiny.asf"))
    write_bytes = Path.write_bytes

    def disk_full_for_the_skeleton(self, data):
        if self.name.startswith(".copy.asf."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))
        return write_bytes(self, data)

    monkeypatch.setattr(Path, "write_bytes", disk_full_for_the_skeleton)
    with pytest.raises(FormatError, match="No space left on device"):
        formats.write(motion, tmp_path / "out" / "copy_01.amc")
    assert list((tmp_path / "out").iterdir()) == []


@pytest.mark.skipif(os.name != "posix", reason="a umask is POSIX")
@pytest.mark.parametrize(("umask", "source_mode", "expected"),
                         [(0o022, 0o666, 0o644), (0o077, 0o644, 0o600), (0o022, 0o600, 0o600)])
@pytest.mark.parametrize("hard_links", [True, False])
def test_the_skeleton_copied_beside_an_amc_gets_its_mode_less_the_umask(
        tmp_path, monkeypatch, umask, source_mode, expected, hard_links):
    # Its mode was copied as it was: a 0666 skeleton came out world-writable under umask
    # 022, and under umask 077 the AMC was 0600 but its skeleton 0644.
    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1), frame(2, arm="10")],
                                     asf_name="tiny.asf"))
    (tmp_path / "in" / "tiny.asf").chmod(source_mode)
    if not hard_links:          # FAT, some network shares: written under its name
        def refused(*args, **kwargs):
            raise OSError(errno.EPERM, os.strerror(errno.EPERM))

        monkeypatch.setattr(os, "link", refused)
    previous = os.umask(umask)
    try:
        formats.write(motion, tmp_path / "out" / "copy_01.amc")
    finally:
        os.umask(previous)
    modes = {p.name: p.stat().st_mode & 0o7777 for p in (tmp_path / "out").iterdir()}
    assert modes == {"copy.asf": expected, "copy_01.amc": 0o666 & ~umask}


def test_a_skeleton_named_by_a_symlink_loop_beside_the_output_is_a_format_error(tmp_path):
    # Path.resolve() raised RuntimeError on the loop: a traceback, not a one-line error.
    from mocapfill import formats

    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1)], asf_name="tiny.asf"))
    (tmp_path / "out" / "copy.asf").symlink_to("copy.asf")
    with pytest.raises(FormatError, match="copy_01.amc: .*symbolic links"):
        formats.write(motion, tmp_path / "out" / "copy_01.amc")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["copy.asf"]


@pytest.mark.parametrize("other", ["tiny.asf", "copy.asf"])
def test_a_different_skeleton_the_reader_would_try_later_is_outranked_by_the_copy(tmp_path,
                                                                                  other):
    from mocapfill import formats

    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1), frame(2, arm="10")],
                                     asf_name="tiny.asf"))
    (tmp_path / "out" / other).write_text(ASF.replace("length 3", "length 4", 1))
    formats.write(motion, tmp_path / "out" / "copy_01.amc")
    np.testing.assert_array_equal(formats.read(tmp_path / "out" / "copy_01.amc").positions,
                                  motion.positions)


def test_the_copy_never_replaces_an_asf_and_takes_the_subject_prefix_instead(tmp_path):
    # Two skeletons in the input folder: an output there finds neither by name, and the
    # input's own tiny.asf must not be rewritten (even with the same bytes).
    from mocapfill import formats

    motion = acclaim.read(write_pair(tmp_path, [frame(1), frame(2, arm="10")],
                                     asf_name="tiny.asf"))
    (tmp_path / "other.asf").write_text(ASF.replace("length 3", "length 4", 1))
    before = (tmp_path / "tiny.asf").stat()
    formats.write(motion, tmp_path / "copy_02.amc")
    after = (tmp_path / "tiny.asf").stat()
    assert (after.st_ino, after.st_mtime_ns) == (before.st_ino, before.st_mtime_ns)
    assert (tmp_path / "copy.asf").read_bytes() == (tmp_path / "tiny.asf").read_bytes()
    np.testing.assert_array_equal(formats.read(tmp_path / "copy_02.amc").positions,
                                  motion.positions)


def test_a_skeleton_copied_there_meanwhile_is_not_replaced(tmp_path, monkeypatch):
    # Two AMCs of different subjects, their skeletons under one name, written into one
    # folder by two batch workers: both saw no 10.asf, and the second copy replaced the
    # first (os.replace), so the first AMC read back with the other subject's skeleton.
    from mocapfill import formats

    (tmp_path / "in").mkdir()
    (tmp_path / "out").mkdir()
    motion = acclaim.read(write_pair(tmp_path / "in", [frame(1), frame(2, arm="10")],
                                     stem="10_01", asf_name="10.asf"))
    other = ASF.replace("length 3", "length 4", 1)
    looked = acclaim.companions

    def the_other_worker_copies_first(motion, path):
        copy = looked(motion, path)
        if copy is not None and not (tmp_path / "out" / "10.asf").exists():
            def late_copy():
                (tmp_path / "out" / "10.asf").write_text(other)
                copy()
            return late_copy
        return copy

    monkeypatch.setattr(acclaim, "companions", the_other_worker_copies_first)
    formats.write(motion, tmp_path / "out" / "10_01.amc")
    assert (tmp_path / "out" / "10.asf").read_text() == other
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "10.asf", "10_01.amc", "10_01.asf"]
    np.testing.assert_array_equal(formats.read(tmp_path / "out" / "10_01.amc").positions,
                                  motion.positions)


# ----------------------------------------------------------------------- units of new files

@pytest.mark.parametrize("suffix", [".trc", ".csv", ".c3d"])
def test_a_position_file_written_from_an_amc_is_in_mm(tmp_path, suffix):
    # "in/0.5" is no unit a TRC or C3D reader knows: the lengths are converted, not labelled.
    amc = acclaim.read(write_pair(tmp_path, [frame(1), frame(2, hand="10 25")]))
    out = tmp_path / f"out{suffix}"
    notes = formats.write(amc, out)
    back = formats.read(out)
    assert back.units == "mm"
    np.testing.assert_allclose(back.positions, amc.positions * 25.4 / 0.5, rtol=1e-6)
    # A TRC or CSV states a rate, which an AMC does not give.
    assert notes == (("lengths in in/0.5 converted to mm (1 in/0.5 = 50.8 mm)",)
                     + (("the clip's frame rate is not known (0 Hz): written as 120 Hz",)
                        if suffix != ".c3d" else ()))


def test_an_npz_written_from_an_amc_keeps_its_unit(tmp_path):
    amc = acclaim.read(write_pair(tmp_path, [frame(1)]))
    assert formats.write(amc, tmp_path / "out.npz") == ()
    back = formats.read(tmp_path / "out.npz")
    assert back.units == "in/0.5"
    np.testing.assert_array_equal(back.positions, amc.positions)
