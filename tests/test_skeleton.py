"""Forward kinematics and channel-space helpers shared by BVH and ASF/AMC."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mocapfill import formats, skeleton
from mocapfill.motion import Motion
from mocapfill.skeleton import (
    WRAP_POSITIVE,
    WRAP_SIGNED,
    ChannelState,
    Skeleton,
    euler_matrices,
    forward_kinematics,
    observed_points,
    patch_tokens,
    positions_edited,
    unwrap_rotations,
    wrap_into,
    wrap_windows,
)
from tests.conftest import shared_file


def rot(axis: str, degrees: float) -> np.ndarray:
    """Elementary rotation written out by hand (the oracle, independent of scipy)."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return {"X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]),
            "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def chain(*, own_frame: bool = False, pre_rotations: np.ndarray | None = None,
          axes: str = "Z") -> Skeleton:
    """Root with translation XYZ + rotations ``axes``, a child at offset (1, 0, 0) with one
    Z rotation, and a grandchild at (0, 2, 0)."""
    n_root = 3 + len(axes)
    return Skeleton(
        names=("root", "child", "tip"), parents=np.array([-1, 0, 1]),
        offsets=np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0]], float),
        rotation_columns=(tuple(range(3, n_root)), (n_root,), ()),
        rotation_axes=(axes, "Z", ""),
        translation_columns=((0, 1, 2), (), ()), translation_axes=("XYZ", "", ""),
        intrinsic=True, n_channels=n_root + 1, pre_rotations=pre_rotations,
        offset_in_own_frame=np.array([False, own_frame, own_frame]))


def test_intrinsic_euler_multiplies_in_channel_order():
    got = euler_matrices("ZXY", np.array([[30.0, 40.0, 50.0]]), intrinsic=True)[0]
    np.testing.assert_allclose(got, rot("Z", 30) @ rot("X", 40) @ rot("Y", 50), atol=1e-12)


def test_extrinsic_euler_multiplies_in_reverse_order():
    got = euler_matrices("xyz", np.array([[30.0, 40.0, 50.0]]), intrinsic=False)[0]
    np.testing.assert_allclose(got, rot("Z", 50) @ rot("Y", 40) @ rot("X", 30), atol=1e-12)


@pytest.mark.parametrize("intrinsic", [True, False])
def test_euler_matrices_are_scipys_rotations_for_every_sequence(intrinsic):
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(7)
    for axes in ["x", "y", "z", "zx", "yz", "xy", "zxy", "xyz", "yzx", "zyx", "xzy", "yxz",
                 "zxz", "xyx", "yzy"]:
        angles = rng.uniform(-400, 400, (20, len(axes)))
        expected = Rotation.from_euler(axes.upper() if intrinsic else axes, angles,
                                       degrees=True).as_matrix()
        np.testing.assert_allclose(euler_matrices(axes, angles, intrinsic), expected,
                                   rtol=0, atol=2e-15)
        np.testing.assert_allclose(euler_matrices(axes.upper(), np.radians(angles), intrinsic,
                                                  degrees=False), expected, rtol=0, atol=2e-15)


@pytest.mark.parametrize("axes", ["xw", "xyzx", "x-y"])
def test_euler_axes_other_than_up_to_three_of_xyz_are_refused(axes):
    with pytest.raises(ValueError, match="Euler axes"):
        euler_matrices(axes, np.zeros((1, len(axes))), True)


def test_reading_a_skeleton_file_does_not_import_scipy_spatial(tmp_path):
    # scipy.spatial's import took 0.35-0.41 s of every BVH / ASF-AMC command.
    import subprocess
    import sys

    bvh = tmp_path / "two.bvh"
    bvh.write_text("HIERARCHY\nROOT hip\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition "
                   "Zposition Zrotation Xrotation Yrotation\n End Site\n {\n  OFFSET 0 1 0\n }"
                   "\n}\nMOTION\nFrames: 2\nFrame Time: 0.01\n0 0 0 10 20 30\n1 0 0 10 20 30\n")
    script = ("import sys, mocapfill; m = mocapfill.read(sys.argv[1]); "
              "print(m.n_frames, 'scipy.spatial' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", script, str(bvh)], capture_output=True,
                          text=True, check=True)
    assert done.stdout.split() == ["2", "False"]


def test_euler_with_no_axes_is_identity_per_frame():
    got = euler_matrices("", np.zeros((4, 0)), intrinsic=True)
    np.testing.assert_array_equal(got, np.broadcast_to(np.eye(3), (4, 3, 3)))


def test_root_rotation_of_90_about_z_turns_the_child_offset():
    values = np.array([[5.0, 6.0, 7.0, 90.0, 0.0]])
    positions = forward_kinematics(chain(), values)[0]
    np.testing.assert_allclose(positions[0], [5, 6, 7], atol=1e-12)
    np.testing.assert_allclose(positions[1], [5, 7, 7], atol=1e-12)      # (1,0,0) -> (0,1,0)


def test_child_rotation_moves_only_points_below_it_in_parent_frame_convention():
    values = np.array([[0.0, 0.0, 0.0, 0.0, 90.0]])
    positions = forward_kinematics(chain(), values)[0]
    np.testing.assert_allclose(positions[1], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(positions[2], [1 - 2, 0, 0], atol=1e-12)  # (0,2,0) -> (-2,0,0)


def test_own_frame_offset_turns_with_the_joints_own_rotation():
    values = np.array([[0.0, 0.0, 0.0, 0.0, 90.0]])
    positions = forward_kinematics(chain(own_frame=True), values)[0]
    np.testing.assert_allclose(positions[1], [0, 1, 0], atol=1e-12)


def test_pre_rotation_conjugates_the_channel_rotation():
    # C = Rz(90): a rotation about the local X axis is one about world Y.
    frames = np.stack([np.eye(3), rot("Z", 90), np.eye(3)])
    skeleton = Skeleton(("root", "bone"), np.array([-1, 0]),
                        np.array([[0, 0, 0], [1, 0, 0]], float), ((), (0,)), ("", "x"),
                        ((), ()), ("", ""), intrinsic=False, n_channels=1,
                        pre_rotations=frames[:2], offset_in_own_frame=np.array([False, True]))
    positions = forward_kinematics(skeleton, np.array([[90.0]]))[0]
    np.testing.assert_allclose(positions[1], [0, 0, -1], atol=1e-12)


def test_forward_kinematics_is_vectorised_over_frames():
    angles = np.linspace(-170, 170, 7)
    values = np.zeros((7, 5))
    values[:, 3] = angles
    positions = forward_kinematics(chain(), values)
    expected = np.stack([np.cos(np.radians(angles)), np.sin(np.radians(angles)),
                         np.zeros(7)], axis=1)
    np.testing.assert_allclose(positions[:, 1], expected, atol=1e-12)


@pytest.mark.parametrize("relative", ["cmu/09_12.amc", "bvh/iclone-05_13-ccbase-60fps.bvh"])
def test_forward_kinematics_by_blocks_of_frames_gives_the_same_positions(relative,
                                                                        monkeypatch):
    # FK runs by blocks of frames so that its rotations and temporaries stay bounded;
    # a block is any run of frames, computed as the whole clip was.
    state = formats.read(shared_file(relative)).source.state
    monkeypatch.setattr(skeleton, "FK_BLOCK_FRAMES", 1 << 30)    # the clip in one block
    whole = forward_kinematics(state.skeleton, state.values)
    assert not np.isnan(whole).any()
    for frames, points in ((7, 1 << 18), (1 << 14, 100), (1 << 14, 1 << 18)):
        monkeypatch.setattr(skeleton, "FK_BLOCK_FRAMES", frames)
        monkeypatch.setattr(skeleton, "FK_BLOCK_POINTS", points)
        np.testing.assert_array_equal(forward_kinematics(state.skeleton, state.values), whole)


def test_missing_root_rotation_hides_descendants_but_not_the_root():
    observed = np.ones((1, 5), bool)
    observed[0, 3] = False
    np.testing.assert_array_equal(observed_points(chain(), observed)[0], [True, False, False])


def test_missing_joint_rotation_hides_its_children_not_the_joint():
    observed = np.ones((1, 5), bool)
    observed[0, 4] = False
    np.testing.assert_array_equal(observed_points(chain(), observed)[0], [True, True, False])


def test_missing_own_rotation_hides_an_own_frame_bone_end():
    observed = np.ones((1, 5), bool)
    observed[0, 4] = False
    got = observed_points(chain(own_frame=True), observed)[0]
    np.testing.assert_array_equal(got, [True, False, False])


def test_missing_root_translation_hides_every_point():
    observed = np.ones((1, 5), bool)
    observed[0, 1] = False
    np.testing.assert_array_equal(observed_points(chain(), observed)[0], [False] * 3)


def test_unwrap_removes_the_jump_across_180():
    values = np.array([[170.0], [179.0], [-172.0], [-160.0]])
    got = unwrap_rotations(values, np.ones((4, 1), bool), np.array([True]))
    np.testing.assert_allclose(got[:, 0], [170, 179, 188, 200])


def test_unwrap_skips_missing_cells_and_keeps_them_nan():
    values = np.array([[170.0], [np.nan], [-172.0]])
    observed = np.isfinite(values)
    got = unwrap_rotations(values, observed, np.array([True]))
    assert np.isnan(got[1, 0])
    np.testing.assert_allclose(got[[0, 2], 0], [170, 188])


def test_unwrap_leaves_translation_channels_alone():
    values = np.array([[170.0], [-172.0]])
    got = unwrap_rotations(values, np.ones((2, 1), bool), np.array([False]))
    np.testing.assert_array_equal(got, values)


def test_wrap_windows_tell_signed_positive_and_unwrapped_channels_apart():
    values = np.array([[-170.0, 10.0, 10.0, 5.0], [170.0, 350.0, 400.0, 5.0]])
    windows = wrap_windows(values, np.ones_like(values, bool),
                           np.array([True, True, True, False]))
    assert windows[0] == WRAP_SIGNED and windows[1] == WRAP_POSITIVE
    assert np.isnan(windows[2]) and np.isnan(windows[3])


def test_wrap_into_signed_window_gives_half_open_range():
    got = wrap_into(np.array([[190.0], [-180.0], [180.0], [540.0]]), np.array([WRAP_SIGNED]))
    np.testing.assert_allclose(got[:, 0], [-170, 180, 180, 180])


@given(st.lists(st.floats(-179.99, 180.0), min_size=2, max_size=40))
def test_wrapping_unwrapped_angles_gives_back_the_stored_ones(angles):
    values = np.array(angles)[:, None]
    unwrapped = unwrap_rotations(values, np.ones_like(values, bool), np.array([True]))
    wrapped = wrap_into(unwrapped, np.array([WRAP_SIGNED]))
    assert ((wrapped > -180.0 - 1e-9) & (wrapped <= 180.0)).all()
    # Same angle: -180 and 180 are one angle, and float rounding may pick either.
    difference = np.mod(wrapped - values + 180.0, 360.0) - 180.0
    np.testing.assert_allclose(difference, 0.0, atol=1e-9)


def test_updated_state_rewraps_only_filled_cells():
    skeleton = chain()
    values = np.zeros((3, 5))
    values[:, 3] = [170.0, np.nan, -175.0]
    state = ChannelState.as_read(skeleton, values)
    unwrapped, observed = state.unwrapped()
    unwrapped[1, 3] = 187.5                       # filled, between 170 and 185 (= -175)
    new = state.updated(unwrapped, np.ones_like(observed))
    np.testing.assert_allclose(new.values[:, 3], [170.0, -172.5, -175.0])


def test_a_fill_in_a_channel_stored_unwrapped_joins_its_stored_neighbour():
    # Stored beyond ±180 (iClone's -536 .. -717): the file's own continuous angles. A gap
    # that hides a sample of a steep stretch leaves a step over 180 between observed
    # cells, which unwrapping turns the short way, 360 away from every later stored
    # value; fills there were written so (-348.7 between -708.5 and -708.9).
    values = np.zeros((6, 5))
    values[:, 3] = [-536.0, np.nan, -717.0, -708.5, np.nan, -708.9]
    state = ChannelState.as_read(chain(), values)
    unwrapped, observed = state.unwrapped()
    np.testing.assert_allclose(unwrapped[:, 3], [-536, np.nan, -357, -348.5, np.nan, -348.9])
    unwrapped[[1, 4], 3] = [-446.5, -348.7]
    new = state.updated(unwrapped, np.ones_like(observed))
    np.testing.assert_allclose(new.values[:, 3], [-536, -446.5, -717, -708.5, -708.7, -708.9])


def test_a_fill_at_the_start_of_a_channel_stored_unwrapped_joins_the_cell_after_it():
    values = np.zeros((3, 5))
    values[:, 3] = [np.nan, -536.0, -717.0]
    state = ChannelState.as_read(chain(), values)
    unwrapped, observed = state.unwrapped()
    unwrapped[0, 3] = -535.0
    assert state.updated(unwrapped, np.ones_like(observed)).values[0, 3] == -535.0
    unwrapped[:, 3] += 720.0                  # values off the stored ones by whole turns
    assert state.updated(unwrapped, np.ones_like(observed)).values[0, 3] == -535.0


def test_updated_state_keeps_stored_value_of_cells_observed_before():
    state = ChannelState.as_read(chain(), np.array([[0, 0, 0, -175.0, 0]]))
    new = state.updated(np.array([[0, 0, 0, 185.0 + 360.0, 0]]), np.ones((1, 5), bool))
    assert new.values[0, 3] == -175.0


def test_updated_state_blanks_cells_no_longer_observed():
    state = ChannelState.as_read(chain(), np.ones((2, 5)))
    observed = np.ones((2, 5), bool)
    observed[1, 0] = False
    new = state.updated(state.values, observed)
    assert np.isnan(new.values[1, 0])
    assert new.changed_cells().sum() == 1


def test_patch_tokens_keeps_separators_and_line_ending():
    line = "1.0\t 2.0  3.0 \r\n"
    assert patch_tokens(line, {1: "nan"}) == "1.0\t nan  3.0 \r\n"


def test_positions_edited_counts_samples_the_channels_do_not_explain():
    state = ChannelState.as_read(chain(), np.zeros((2, 5)))
    positions, observed = state.points()
    motion = Motion(positions, observed, ("root", "child", "tip"), 120.0)
    assert positions_edited(motion, state) == 0
    observed = observed.copy()
    observed[0, 2] = False
    assert positions_edited(motion.with_positions(positions, observed), state) == 1


def test_skeleton_rejects_a_child_listed_before_its_parent():
    with pytest.raises(ValueError, match="before its parent"):
        Skeleton(("a", "b"), np.array([1, -1]), np.zeros((2, 3)), ((), ()), ("", ""),
                 ((), ()), ("", ""), intrinsic=True, n_channels=0)
