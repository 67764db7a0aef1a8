"""The demo clip in sample_data/: current, deterministic, and a plausible walking trial."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mocapfill.formats import read

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "make_sample_data.py"
SAMPLE = ROOT / "sample_data"
FILES = ("walk_truth.csv", "walk_gapped.csv")


@pytest.fixture(scope="module")
def truth():
    return read(SAMPLE / "walk_truth.csv")


@pytest.fixture(scope="module")
def gapped():
    return read(SAMPLE / "walk_gapped.csv")


def _runs_of_missing(observed: np.ndarray) -> list[int]:
    edges = np.diff(np.concatenate([[0], (~observed).astype(int), [0]]))
    return (np.nonzero(edges == -1)[0] - np.nonzero(edges == 1)[0]).tolist()


def _marker(motion, label: str) -> np.ndarray:
    return motion.positions[:, motion.labels.index(label)]


def test_script_regenerates_the_committed_files_byte_for_byte(tmp_path):
    result = subprocess.run([sys.executable, str(SCRIPT), str(tmp_path)],
                            capture_output=True, text=True, timeout=60, cwd=ROOT, check=False)
    assert result.returncode == 0, result.stderr
    assert result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1
    for name in FILES:
        assert (tmp_path / name).read_bytes() == (SAMPLE / name).read_bytes(), (
            f"sample_data/{name} is stale: run `python scripts/make_sample_data.py sample_data`")


def test_truth_is_a_gap_free_walk_of_about_40_markers_600_frames_120_hz_mm(truth):
    assert truth.observed.all()
    assert 36 <= truth.n_markers <= 44
    assert 550 <= truth.n_frames <= 650
    assert truth.rate == 120.0
    assert truth.units == "mm"


def test_gapped_clip_has_the_truth_labels_shape_rate_and_units(truth, gapped):
    assert gapped.labels == truth.labels
    assert gapped.positions.shape == truth.positions.shape
    assert (gapped.rate, gapped.units) == (truth.rate, truth.units)


def test_observed_samples_of_the_gapped_clip_equal_the_truth_exactly(truth, gapped):
    observed = gapped.observed
    assert not observed.all()
    np.testing.assert_array_equal(gapped.positions[observed], truth.positions[observed])


def test_at_least_six_markers_have_interior_gaps_of_20_to_150_frames(gapped):
    with_long_gaps = [label for j, label in enumerate(gapped.labels)
                      if any(20 <= n <= 150 for n in _runs_of_missing(gapped.observed[:, j]))]
    assert len(with_long_gaps) >= 6
    assert gapped.observed[0].all() and gapped.observed[-1].all(), "gaps must be interior"
    assert max(max(_runs_of_missing(gapped.observed[:, j]), default=0)
               for j in range(gapped.n_markers)) <= 150


@pytest.mark.parametrize("pair", [("LKNE", "LANK"), ("RKNE", "RANK"), ("LASI", "RPSI"),
                                  ("LFHD", "RBHD"), ("C7", "STRN"), ("LWRA", "LFIN"),
                                  ("LHEE", "LTOE")])
def test_markers_on_one_rigid_segment_keep_their_distance(truth, pair):
    distance = np.linalg.norm(_marker(truth, pair[0]) - _marker(truth, pair[1]), axis=1)
    assert distance.std() < 2.0


def test_joints_move_markers_on_adjacent_segments_relative_to_each_other(truth):
    thigh_to_ankle = np.linalg.norm(_marker(truth, "LTHI") - _marker(truth, "LANK"), axis=1)
    assert np.ptp(thigh_to_ankle) > 30.0                 # the knee flexes


def test_pelvis_walks_forward_more_than_a_metre(truth):
    pelvis = np.mean([_marker(truth, m) for m in ("LASI", "RASI", "LPSI", "RPSI")], axis=0)
    assert np.linalg.norm(pelvis[-1, :2] - pelvis[0, :2]) > 1000.0
    assert 700.0 < pelvis[:, 2].mean() < 1200.0          # pelvis height of a standing adult


def test_left_and_right_feet_alternate_half_a_cycle_apart(truth):
    left = _marker(truth, "LHEE")[:, 2] - _marker(truth, "LHEE")[:, 2].mean()
    right = _marker(truth, "RHEE")[:, 2] - _marker(truth, "RHEE")[:, 2].mean()
    assert np.corrcoef(left, right)[0, 1] < -0.3
