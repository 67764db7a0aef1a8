"""NumPy .npz: what a clip carries survives a round trip; clips of no frames read but are
not written; the rate must be usable; damaged or foreign archives are named as such."""
from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import FormatError
from mocapfill.formats import npz

from ..helpers import peak_bytes


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


def test_an_archive_without_rate_reads_as_0_hz_not_known(tmp_path):
    # As a CSV or TRC stating none: a --max-gap in seconds then fails instead of being
    # read at a rate nobody stated.
    path = tmp_path / "clip.npz"
    np.savez(path, positions=np.ones((3, 2, 3)))
    assert npz.read(path).rate == 0.0
    assert npz.read(save(tmp_path / "rated.npz", rate=250.0)).rate == 250.0


@pytest.mark.parametrize("rate", [np.inf, np.nan, -120.0])
def test_a_negative_or_non_finite_rate_is_a_format_error(tmp_path, rate):
    path = save(tmp_path / "clip.npz", rate=rate)
    with pytest.raises(FormatError) as caught:
        npz.read(path)
    assert str(caught.value).startswith(f"{path}: rate is {rate}, not a frame rate")


def test_complex_positions_are_a_format_error(tmp_path):
    # Read as float64 they lost their imaginary part without a word.
    path = tmp_path / "clip.npz"
    np.savez(path, positions=np.ones((3, 2, 3)) * (1 + 2j))
    with pytest.raises(FormatError) as caught:
        npz.read(path)
    assert str(caught.value) == f"{path}: positions must be real numbers, got complex ones"


def test_first_frame_and_model_outputs_survive_a_round_trip(tmp_path):
    motion = formats.read(save(tmp_path / "clip.npz"))
    motion = motion.replace(first_frame=244, fillable=np.array([True, False]))
    formats.write(motion, tmp_path / "out.npz")
    back = formats.read(tmp_path / "out.npz")
    assert back.first_frame == 244 and back.fillable.tolist() == [True, False]


def test_written_archive_is_what_numpy_reads_with_positions_stored_and_the_same_bytes_each_time(
        tmp_path):
    import zipfile

    rng = np.random.default_rng(0)
    positions = rng.normal(size=(50, 2, 3)) * 100
    observed = rng.random((50, 2)) > 0.2
    motion = formats.read(save(tmp_path / "clip.npz")).replace(positions=positions,
                                                                observed=observed)
    first, second = tmp_path / "a.npz", tmp_path / "b.npz"
    formats.write(motion, first)
    formats.write(motion, second)
    assert first.read_bytes() == second.read_bytes()
    with np.load(first) as data:        # numpy's own reader, not ours
        np.testing.assert_array_equal(data["positions"], motion.positions)
        np.testing.assert_array_equal(data["observed"], observed)
        assert data["labels"].tolist() == ["A", "B"] and float(data["rate"]) == 100.0
    kinds = {info.filename: info.compress_type for info in zipfile.ZipFile(first).infolist()}
    assert kinds.pop("positions.npy") == zipfile.ZIP_STORED
    assert set(kinds.values()) == {zipfile.ZIP_DEFLATED}


def test_labels_and_units_stored_as_bytes_and_a_one_element_rate_read(tmp_path):
    path = tmp_path / "bytes.npz"
    np.savez(path, positions=np.zeros((2, 2, 3)), labels=np.array([b"LASI", b"R\xc3\xa4"]),
             units=np.array(b"mm"), rate=np.array([240.0]))
    motion = npz.read(path)
    assert (motion.labels, motion.units, motion.rate) == (("LASI", "Rä"), "mm", 240.0)


@pytest.mark.parametrize(("content", "words"), [
    (b"\x02\x50" + bytes(510), "not an .npz archive (no zip signature)"),     # a C3D renamed
    (None, "unreadable array"),                                           # an object array
])
def test_a_foreign_or_unreadable_archive_is_named_as_such(tmp_path, content, words):
    path = tmp_path / "clip.npz"
    if content is None:
        np.savez(path, positions=np.array([[[1, 2, 3]], [[1, 2, "x"]]], dtype=object))
    else:
        path.write_bytes(content)
    with pytest.raises(FormatError) as caught:
        npz.read(path)
    assert str(caught.value).startswith(f"{path}: {words}")
    assert "allow_pickle" not in str(caught.value)


def npy_header(shape, descr="<f8") -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False,
                                                  "shape": shape})
    return buffer.getvalue()


def refused(path) -> str:
    with pytest.raises(FormatError) as caught:
        formats.read(path)
    return str(caught.value)


def test_a_zip_bomb_is_refused_from_its_headers_without_unpacking(tmp_path, monkeypatch):
    # 1.5 MB of deflated zeros declaring a (64M, 1, 3) clip took 12 s and 3.2 GB to read;
    # the limit is lowered here so that the archives stay small.
    monkeypatch.setattr(npz, "EXPANSION_FLOOR", 1 << 20)
    bomb = tmp_path / "bomb.npz"
    frames = 200_000                    # 4.8 MB of zeros, deflated to about 5 KB
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("positions.npy", npy_header((frames, 1, 3)) + bytes(frames * 24))
    peak = peak_bytes(lambda: refused(bomb))
    assert refused(bomb).startswith(f"{bomb}: its arrays unpack to 5 MB from ")
    assert "refused as a zip bomb (more than 100 to 1 above 1 MB" in refused(bomb)
    assert peak < 1 << 20
    # A clip of as many frames with coordinates in it reads, stored as this writer stores
    # it or deflated by numpy.
    rng = np.random.default_rng(0)
    clip = formats.read(save(tmp_path / "clip.npz")).replace(
        positions=rng.normal(size=(frames, 2, 3)), observed=np.ones((frames, 2), bool),
        labels=("A", "B"))
    formats.write(clip, tmp_path / "stored.npz")
    np.savez_compressed(tmp_path / "deflated.npz", positions=clip.positions)
    for name in ("stored.npz", "deflated.npz"):
        np.testing.assert_array_equal(formats.read(tmp_path / name).positions, clip.positions)


def test_a_member_declaring_more_stored_bytes_than_the_archive_holds_is_refused(tmp_path):
    # Its stored size is what the zip bomb check divides by: a lie there let a small
    # archive declare any clip.
    path = tmp_path / "lie.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("positions.npy", npy_header((200_000, 1, 3)) + bytes(4_800_000))
    data = bytearray(path.read_bytes())
    central = data.index(b"PK\x01\x02")
    data[central + 20:central + 24] = (10_000_000).to_bytes(4, "little")   # compress_size
    path.write_bytes(bytes(data))
    assert refused(path) == (f"{path}: positions.npy declares 10000000 bytes stored in an "
                             f"archive of {len(data)}: not a valid .npz archive")


@pytest.mark.parametrize("compression", [zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED],
                         ids=["stored", "deflated"])
def test_an_array_declaring_more_bytes_than_its_member_holds_is_refused_unallocated(
        tmp_path, compression):
    path = tmp_path / "cut.npz"
    with zipfile.ZipFile(path, "w", compression) as archive:
        archive.writestr("positions.npy", npy_header((10_000_000, 1, 3)) + bytes(64))
    peak = peak_bytes(lambda: refused(path))
    assert refused(path) == (f"{path}: positions.npy declares (10000000, 1, 3) float64 "
                             "(240000000 bytes) but holds 64 bytes: cut short or not "
                             "written by numpy")
    assert peak < 1 << 20


@pytest.mark.parametrize("key", ["rate", "first_frame"])
def test_a_rate_or_first_frame_of_many_numbers_is_refused_before_it_is_loaded(tmp_path, key):
    # A 200,000,000-element rate (1.5 MB deflated) used 1.5 GB before it was refused.
    path = tmp_path / "clip.npz"
    np.savez_compressed(path, positions=np.zeros((3, 2, 3)), **{key: np.zeros(1_000_000)})
    peak = peak_bytes(lambda: refused(path))
    assert refused(path) == f"{path}: {key} must hold one number, got 1000000"
    assert peak < 1 << 20


def test_arrays_whose_declared_shapes_disagree_are_refused_before_they_are_loaded(tmp_path):
    path = tmp_path / "clip.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("positions.npy", npy_header((3, 2, 3)) + bytes(144))
        archive.writestr("observed.npy", npy_header((5_000_000, 1), "|b1")
                         + bytes(5_000_000))
    peak = peak_bytes(lambda: refused(path))
    assert refused(path) == f"{path}: observed must be (3, 2), got (5000000, 1)"
    assert peak < 1 << 20


def test_an_oversized_header_is_named_as_such_not_as_python_objects(tmp_path):
    path = tmp_path / "clip.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("positions.npy", b"\x93NUMPY\x02\x00" + (100_000).to_bytes(4, "little")
                         + b"{" + b" " * 99_998 + b"\n")
    assert refused(path) == (f"{path}: positions.npy has a header of 100000 bytes, more than "
                             "the 10000 numpy reads: not an array numpy wrote")
