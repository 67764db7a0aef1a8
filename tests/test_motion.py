import re

import numpy as np
import pytest

import mocapfill
from mocapfill.motion import Motion, from_matrix

from .helpers import smooth_clip


def test_non_finite_coordinates_are_missing():
    positions = np.zeros((3, 2, 3))
    positions[1, 0, 2] = np.nan
    motion = Motion(positions, np.ones((3, 2), bool), ("A", "B"), 100.0)
    assert motion.observed.tolist() == [[True, True], [False, True], [True, True]]
    assert np.isnan(motion.positions[1, 0]).all()


def test_matrix_layout_is_xyz_rows_per_marker_and_frames_as_columns():
    motion = smooth_clip(n_frames=5, n_markers=2)
    matrix, mask = motion.matrix()
    assert matrix.shape == (6, 5) and mask.all()
    np.testing.assert_array_equal(matrix[3:6, 4], motion.positions[4, 1])


def test_matrix_of_a_long_clip_and_a_marker_subset_is_blockwise_the_same_layout():
    # The transposes go by blocks of frames: across block boundaries, for all markers and
    # for a subset, the matrix is x, y, z rows per marker and the way back puts each value
    # where it came from.
    from mocapfill.motion import _TRANSPOSE_FRAMES

    frames = 2 * _TRANSPOSE_FRAMES + 3
    rng = np.random.default_rng(1)
    motion = Motion(rng.standard_normal((frames, 4, 3)), rng.random((frames, 4)) > 0.2,
                    ("A", "B", "C", "D"), 100.0)
    for markers in (None, np.array([3, 1])):
        chosen = [0, 1, 2, 3] if markers is None else [3, 1]
        matrix, mask = motion.matrix(markers)
        assert matrix.shape == (3 * len(chosen), frames) and matrix.flags.c_contiguous
        for row, marker in enumerate(chosen):
            for axis in range(3):
                np.testing.assert_array_equal(matrix[3 * row + axis],
                                              motion.positions[:, marker, axis])
                np.testing.assert_array_equal(mask[3 * row + axis], motion.observed[:, marker])
        moved = motion.positions_from_matrix(matrix + 1.0, markers)
        np.testing.assert_array_equal(moved[:, chosen], motion.positions[:, chosen] + 1.0)
        others = [j for j in range(4) if j not in chosen]
        np.testing.assert_array_equal(moved[:, others], motion.positions[:, others])


def test_with_matrix_round_trips():
    motion = smooth_clip(n_frames=7, n_markers=3)
    matrix, mask = motion.matrix()
    again = motion.with_matrix(matrix, mask)
    np.testing.assert_array_equal(again.positions, motion.positions)


def test_from_matrix_marks_whole_samples_missing():
    data = np.arange(12.0).reshape(6, 2)
    data[4, 1] = np.nan
    motion = from_matrix(data)
    assert motion.observed.tolist() == [[True, True], [True, False]]


def test_shape_mismatch_is_rejected():
    with pytest.raises(ValueError):
        Motion(np.zeros((3, 2, 3)), np.ones((3, 3), bool), ("A", "B"), 100.0)


@pytest.mark.parametrize("call", [
    lambda clip: mocapfill.simulate_gaps("trial.c3d", mr=0.2),
    lambda clip: mocapfill.score(clip, "trial.c3d"),
    lambda clip: mocapfill.write("trial.c3d", "out.c3d"),
])
def test_public_functions_given_a_file_name_for_a_motion_say_to_read_it_first(call):
    with pytest.raises(TypeError, match=r"takes a Motion as \w+, got str: read the file "
                                        r"first, mocapfill.read\('trial.c3d'\)"):
        call(smooth_clip(20, 3))


def test_write_with_its_arguments_swapped_says_so(tmp_path):
    with pytest.raises(TypeError, match=r"write\(motion, path\)"):
        mocapfill.write(tmp_path / "out.npz", smooth_clip(20, 3))
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("rate", [-5.0, float("nan"), float("inf")])
def test_a_rate_that_is_not_a_frame_rate_is_refused(rate, tmp_path):
    # Such a clip was written to an NPZ that read then refused.
    clip = smooth_clip(20, 2)
    with pytest.raises(ValueError, match=r"rate must be a frame rate \(a positive, finite "
                                         r"number of Hz, or 0 when not known\), got"):
        Motion(clip.positions, clip.observed, clip.labels, rate)
    with pytest.raises(ValueError, match="rate must be a frame rate"):
        clip.replace(rate=rate)
    assert Motion(clip.positions, clip.observed, clip.labels, 0).rate == 0.0   # not known
    # A reader's rate= option is refused as the option it is, not as the file's fault.
    (tmp_path / "no-rate.csv").write_text("A_X,A_Y,A_Z\n1,2,3\n4,5,6\n")
    with pytest.raises(mocapfill.ParameterError, match="rate must be a positive, finite"):
        mocapfill.read(tmp_path / "no-rate.csv", rate=rate)


@pytest.mark.parametrize("first_frame", [2.5, float("nan"), True, "3", None])
def test_a_first_frame_that_is_not_a_whole_number_is_refused(first_frame):
    # 2.5 crashed the C3D writer with a TypeError.
    clip = smooth_clip(20, 2)
    with pytest.raises(ValueError, match=f"first_frame must be a whole number, got "
                                         f"{re.escape(repr(first_frame))}"):
        clip.replace(first_frame=first_frame)


def test_a_first_frame_given_as_a_numpy_integer_or_whole_float_is_that_int(tmp_path):
    clip = smooth_clip(20, 2)
    for given in (np.int64(3), 3.0):
        moved = clip.replace(first_frame=given)
        assert moved.first_frame == 3 and type(moved.first_frame) is int
    mocapfill.write(moved, tmp_path / "moved.c3d")
    assert mocapfill.read(tmp_path / "moved.c3d").first_frame == 3


@pytest.mark.parametrize("first_frame", [2**63 - 19, -2**63 - 1, 10**20, int(1e300)],
                         ids=["last-frame-over", "under", "1e20", "1e300"])
def test_a_first_frame_beyond_64_bits_is_refused(first_frame):
    # 1e20 (a TRC's Frame#) and 1e300 (an NPZ's first_frame) crashed the NPZ writer with
    # an OverflowError; the last frame of the clip's 20 must fit as well.
    clip = smooth_clip(20, 2)
    with pytest.raises(ValueError, match="first_frame must fit in 64 bits with the clip's "
                                         r"frames \(-2\*\*63 to 9223372036854775788\), got "):
        clip.replace(first_frame=first_frame)


def test_a_first_frame_at_the_64_bit_limits_is_kept_by_an_npz(tmp_path):
    for first_frame in (2**63 - 20, -2**63):
        clip = smooth_clip(20, 2).replace(first_frame=first_frame)
        mocapfill.write(clip, tmp_path / "clip.npz")
        assert mocapfill.read(tmp_path / "clip.npz").first_frame == first_frame


def test_a_motions_arrays_are_read_only_and_its_own():
    # A sample set to NaN in place stayed observed (a repair then failed with a misleading
    # SolverError); the flag is on the Motion's own arrays, never on the caller's.
    positions = np.zeros((4, 2, 3))
    observed = np.ones((4, 2), bool)
    fillable = np.ones(2, bool)
    clip = Motion(positions, observed, ("A", "B"), 100.0, fillable=fillable)
    for array in (clip.positions, clip.observed, clip.fillable):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0
    for array in (positions, observed, fillable):
        assert array.flags.writeable
        array[0] = 0
    assert clip.observed.all() and clip.fillable.all()
    edited = clip.positions.copy()      # an edit is a new clip
    edited[1, 0] = np.nan
    assert not clip.with_positions(edited, clip.observed).observed[1, 0]


def test_a_marker_name_is_matched_as_written_before_as_a_glob():
    # 'L[1]' as a glob is the set [1]: the marker so named matched nothing, and the error
    # listed it among the clip's markers.
    from mocapfill.motion import label_matches

    assert label_matches("L[1]", ["L[1]"]) and label_matches("Bob:L[1]", ["L[1]"])
    assert label_matches("L1", ["L[1]"])                    # still the glob too
    assert label_matches("LKNE", ["L*"]) and not label_matches("RKNE", ["L*"])
