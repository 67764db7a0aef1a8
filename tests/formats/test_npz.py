"""NumPy .npz: clips of no frames read but are not written; the rate must be usable."""
from __future__ import annotations

import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import npz


def save(path, n_frames: int = 3, rate: float = 100.0):
    positions = np.arange(n_frames * 2 * 3, dtype=float).reshape(n_frames, 2, 3)
    np.savez(path, positions=positions, observed=np.ones((n_frames, 2), bool),
             labels=np.array(["A", "B"]), rate=np.float64(rate), units=np.array("mm"))
    return path


@pytest.mark.parametrize("suffix", [".trc", ".csv", ".c3d", ".npz"])
def test_a_clip_of_no_frames_reads_but_converting_it_is_refused(tmp_path, suffix):
    motion = formats.read(save(tmp_path / "empty.npz", n_frames=0))
    assert (motion.n_frames, motion.n_markers) == (0, 2)
    out = tmp_path / f"out{suffix}"
    with pytest.raises(FormatError) as caught:
        formats.write(motion, out)
    assert str(caught.value) == f"{out}: refusing to write a clip with no frames"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["empty.npz"]


@pytest.mark.parametrize("rate", [np.inf, np.nan, -120.0])
def test_a_negative_or_non_finite_rate_is_a_format_error(tmp_path, rate):
    path = save(tmp_path / "clip.npz", rate=rate)
    with pytest.raises(FormatError) as caught:
        npz.read(path)
    assert str(caught.value).startswith(f"{path}: rate is {rate}, not a frame rate")
