"""``formats.read``'s options: a keyword the format's reader does not take is a TypeError
(a programming error) before the file is opened; ``rate=`` is taken by every reader, used
only where the file states none, and must be a positive, finite number."""
from __future__ import annotations

import math

import pytest

from mocapfill import formats
from mocapfill.errors import FormatError, ParameterError
from tests.formats.c3d_fixtures import write_c3d
from tests.formats.test_bvh import write_bvh
from tests.helpers import smooth_clip

SUFFIXES = (".c3d", ".trc", ".csv", ".txt", ".bvh", ".amc", ".npz")


@pytest.mark.parametrize("suffix", SUFFIXES)
def test_a_misspelt_option_is_a_type_error_naming_it_and_the_format_not_the_file(tmp_path,
                                                                              suffix):
    # The CSV, TRC, BVH, AMC and NPZ readers ignored it (zero_is_mising="on" read zeros
    # as data); the C3D reader's TypeError was reported as the file's ("cannot parse").
    path = tmp_path / f"clip{suffix}"
    path.write_bytes(b"not a motion file")
    with pytest.raises(TypeError, match=rf"unexpected keyword argument 'zero_is_mising' for "
                                        rf"a \{suffix} file \(its reader takes .*rate"):
        formats.read(path, zero_is_mising="on")
    with pytest.raises(TypeError):      # before the file is opened: there is none
        formats.read(tmp_path / f"absent{suffix}", ratee=120)


@pytest.mark.parametrize(("suffix", "option"), [(".c3d", "units"), (".npz", "units"),
                                                (".bvh", "zero_is_missing"),
                                                (".amc", "zero_is_missing"),
                                                (".csv", "asf"), (".trc", "scale")])
def test_an_option_of_other_formats_is_refused_too(tmp_path, suffix, option):
    with pytest.raises(TypeError, match=f"'{option}' for a \\{suffix} file"):
        formats.read(tmp_path / f"absent{suffix}", **{option: "x"})


def test_a_c3d_takes_rate_where_it_states_none_and_keeps_its_own(tmp_path):
    clip = smooth_clip(20, 2).positions
    stated = formats.read(write_c3d(tmp_path / "stated.c3d", clip, rate=100.0), rate=60)
    assert stated.rate == 100.0
    none = write_c3d(tmp_path / "none.c3d", clip, rate=0.0)
    assert formats.read(none).rate == 0.0
    assert formats.read(none, rate=60).rate == 60.0


def test_an_npz_takes_rate_where_it_stores_none_and_a_bvh_keeps_its_frame_time(tmp_path):
    formats.write(smooth_clip(20, 2).replace(rate=0.0), tmp_path / "none.npz")
    assert formats.read(tmp_path / "none.npz", rate=50).rate == 50.0
    formats.write(smooth_clip(20, 2), tmp_path / "stated.npz")
    assert formats.read(tmp_path / "stated.npz", rate=50).rate == 120.0
    path = write_bvh(tmp_path, ["0 0 0 0 0 0 0 0 0", "1 2 3 0 0 0 0 0 0"])
    assert formats.read(path, rate=60).rate == 100.0


@pytest.mark.parametrize("rate", [-1, 0, math.nan, math.inf, "120", True])
@pytest.mark.parametrize("suffix", [".amc", ".csv", ".c3d"])
def test_a_rate_that_is_not_a_positive_finite_number_is_refused(tmp_path, rate, suffix):
    # An AMC read with rate=-1 or nan took it for the clip's rate.
    with pytest.raises(ParameterError, match=rf"rate must be a positive, finite number of "
                                             rf"Hz, got {rate!r}"):
        formats.read(tmp_path / f"absent{suffix}", rate=rate)
    with pytest.raises(FormatError, match="no such file"):     # None: not given
        formats.read(tmp_path / f"absent{suffix}", rate=None)
