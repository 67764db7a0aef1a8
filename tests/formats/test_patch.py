"""A clip written to its own file's format is a patch of that file only while the patch
holds it: a clip that differs from the file in anything but the samples filled or removed
since reading is refused (``formats.write``), never written half as read."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import bvh
from mocapfill.gaps import simulate_gaps
from mocapfill.pipeline import RepairOptions, repair
from tests.formats.test_bvh import write_bvh
from tests.helpers import smooth_clip, with_gap

POSITION_SUFFIXES = (".csv", ".trc", ".c3d")


def gapped_file(tmp_path: Path, suffix: str) -> Path:
    """A clip with a gap, written as a new file of ``suffix`` (read back, it patches)."""
    path = tmp_path / f"gapped{suffix}"
    formats.write(with_gap(smooth_clip(60, 4, rate=100.0), 1, 20, 30), path)
    return path


def repaired(path: Path):
    return repair(formats.read(path), RepairOptions(method="linear")).motion


@pytest.mark.parametrize("suffix", POSITION_SUFFIXES)
def test_a_repaired_clip_converted_to_metres_is_refused_not_patched_in_mixed_units(
        tmp_path, suffix):
    # The patch kept the header's mm and the observed samples in mm, and wrote the filled
    # samples in m.
    clip = repaired(gapped_file(tmp_path, suffix))
    in_metres = clip.replace(positions=clip.positions / 1000, units="m")
    out = tmp_path / f"metres{suffix}"
    with pytest.raises(FormatError) as caught:
        formats.write(in_metres, out)
    message = str(caught.value)
    assert message.startswith(f"{out}: the clip differs from {tmp_path / f'gapped{suffix}'}")
    assert "its units (m, read as mm)" in message and "values of 230 samples" in message
    assert "motion.replace(source=None)" in message and "\n" not in message
    assert not out.exists()
    formats.write(in_metres.replace(source=None), out)       # as the message says
    back = formats.read(out)
    assert back.units == "m"
    np.testing.assert_allclose(back.positions, in_metres.positions, rtol=1e-6)


def one_coordinate(axis: int):
    """An edit of one coordinate of one observed sample (MK02, frame 4)."""
    def change(motion):
        positions = motion.positions.copy()
        positions[3, 2, axis] += 1.0
        return motion.with_positions(positions, motion.observed)
    return change


@pytest.mark.parametrize("suffix", POSITION_SUFFIXES)
@pytest.mark.parametrize("change, words", [
    # One coordinate alone: each of x, y and z must reach the check.
    *[pytest.param(one_coordinate(axis), "the values of 1 sample observed in the file "
                   "(first: MK02, frame 4)", id=f"only-{name}") for axis, name in enumerate("xyz")],
    (lambda m: m.with_positions(m.positions + 100.0, m.observed),
     "the values of 230 samples observed in the file (first: MK00, frame 1)"),
    (lambda m: m.with_positions(np.where(np.arange(60)[:, None, None] == 7,
                                         m.positions * 2, m.positions), m.observed),
     "the values of 4 samples observed in the file (first: MK00, frame 8)"),
    (lambda m: m.replace(rate=50.0), "its rate (50 Hz, read as 100 Hz)"),
    (lambda m: m.replace(first_frame=11), "its first frame (11, read as 1)"),
    (lambda m: m.replace(labels=("A",) + m.labels[1:]), "1 label(s) ('A', read as 'MK00')"),
    (lambda m: m.replace(positions=m.positions[:50], observed=m.observed[:50]),
     "its size (50 frames of 4 points, read as 60 of 4)"),
])
def test_a_clip_edited_beyond_its_gaps_is_refused_naming_the_change(tmp_path, suffix, change,
                                                                    words):
    # An edit of observed samples (smoothing, an offset) was dropped without a word.
    out = tmp_path / f"out{suffix}"
    with pytest.raises(FormatError, match="differs from") as caught:
        formats.write(change(repaired(gapped_file(tmp_path, suffix))), out)
    assert words in str(caught.value)
    assert not out.exists()


@pytest.mark.parametrize("suffix", POSITION_SUFFIXES)
def test_fills_and_simulated_gaps_still_patch(tmp_path, suffix):
    path = gapped_file(tmp_path, suffix)
    assert formats.write(repaired(path), tmp_path / f"filled{suffix}") == ()
    assert formats.read(tmp_path / f"filled{suffix}").observed.all()
    formats.write(simulate_gaps(formats.read(path), ml=5, seed=1), tmp_path / f"sim{suffix}")
    # -0.0 and 0.0 are the same value: an edit that only turns one into the other is none.
    clip = formats.read(path)
    zeroed = clip.with_positions(np.where(clip.observed[:, :, None], clip.positions * 0 - 0.0,
                                          np.nan), clip.observed)
    assert formats.write(zeroed.replace(source=None), tmp_path / f"zeros{suffix}") == ()
    zeros = formats.read(tmp_path / f"zeros{suffix}")
    assert np.signbit(zeros.positions[zeros.observed]).any()
    formats.write(zeros.with_positions(zeros.positions + 0.0, zeros.observed),
                  tmp_path / f"same{suffix}")


def test_bvh_positions_moved_outside_channel_space_are_refused(tmp_path):
    # The mask agreed with the channels, so the writer echoed the file unchanged.
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 0"]))
    moved = motion.with_positions(motion.positions + 100.0, motion.observed)
    with pytest.raises(FormatError, match=r"outside channel space \(6 samples"):
        formats.write(moved, tmp_path / "out.bvh")


def test_a_bvh_clip_given_another_rate_is_refused_without_suggesting_a_new_file(tmp_path):
    motion = bvh.read(write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 0"]))
    with pytest.raises(FormatError) as caught:
        formats.write(motion.replace(rate=50.0), tmp_path / "out.bvh")
    message = str(caught.value)
    assert "its rate (50 Hz, read as 100 Hz)" in message
    assert "BVH output is written only as a patch of BVH input" in message
    assert "source=None" not in message
