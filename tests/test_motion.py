import numpy as np
import pytest

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
