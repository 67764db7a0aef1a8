import numpy as np
import pytest

import mocapfill

from .helpers import smooth_clip, with_gap


def test_rmse_refuses_a_mask_that_is_not_one_bool_per_sample():
    # A 0/1 mask indexed frames 0 and 1, and a (frames, markers, 3) one picked coordinates
    # (the 3-D error equal to the RMSE): wrong numbers, no error.
    rng = np.random.default_rng(0)
    truth = rng.normal(size=(20, 3, 3))
    estimate = truth + rng.normal(size=truth.shape)
    mask = np.zeros((20, 3), bool)
    mask[5:10, 1] = True
    diff = (estimate - truth)[mask]
    assert mocapfill.rmse(truth, estimate, mask) == (
        pytest.approx(np.sqrt((diff ** 2).mean())),
        pytest.approx(np.sqrt((diff ** 2).sum(axis=1).mean())))
    with pytest.raises(TypeError, match="rmse\\(\\) takes a bool mask, got int64"):
        mocapfill.rmse(truth, estimate, mask.astype(np.int64))
    with pytest.raises(ValueError, match=r"takes a \(frames, markers\) mask, \(20, 3\), got "
                                         r"\(20, 3, 3\)"):
        mocapfill.rmse(truth, estimate, np.repeat(mask[:, :, None], 3, axis=2))
    with pytest.raises(ValueError, match=r"got \(20, 3, 3\) and \(5, 3, 3\)"):
        mocapfill.rmse(truth, estimate[:5], mask)


def test_rmse_given_clips_points_to_score():
    clip = smooth_clip(20, 3)
    with pytest.raises(TypeError, match=r"got a Motion as truth: score\(\) takes clips"):
        mocapfill.rmse(clip, with_gap(clip, 0, 5, 9).positions, ~clip.observed)
