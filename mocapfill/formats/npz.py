"""NumPy ``.npz``: arrays ``positions`` (frames, markers, 3), ``observed``, ``labels``,
``rate``, ``units``, ``first_frame`` and ``fillable`` (False for points that are not
markers: C3D model outputs). Missing samples are stored as NaN and as False in
``observed``. Only ``positions`` is required; labels and units may be stored as bytes.

``rate`` 0 means "not known", as for a C3D without ``POINT:RATE``, and so does an archive
without ``rate`` (as a CSV or TRC stating none): the ``rate=`` option is used then; a
negative or non-finite rate is a FormatError.

Nothing is loaded before every array's .npy header is read and checked (:func:`_members`):
a small archive declaring a large clip (deflated zeros, a header over a cut member) was
unpacked or allocated whole before it was refused, or read as that clip."""
from __future__ import annotations

import io
import math
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..motion import Motion
from ._text import utf8_or_latin1


def _text(value) -> str:
    """A label or unit as stored: str, or bytes (UTF-8 where it decodes, else Latin-1)."""
    return utf8_or_latin1(value) if isinstance(value, bytes) else str(value)


# Longest .npy header read: numpy's own bound (np.load's ``max_header_size``); the arrays
# numpy writes have headers of one or two hundred bytes.
MAX_HEADER = 10_000
# An archive whose arrays unpack to more than MAX_EXPANSION times the bytes it stores them
# in is refused once they pass EXPANSION_FLOOR bytes: deflate packs zeros about 1000 to 1,
# and 1.5 MB of them declared a (64M, 1, 3) clip that took 12 s and 3.2 GB to read. Real
# coordinates deflate about 1.1 to 1 (this writer stores them, see STORED) and a mask of
# one value about 1000 to 1, but a mask holds a 24th of its positions' bytes: a clip
# passes 100 to 1 only when more than 99 % of its samples are missing (97.5 %: 36 to 1).
MAX_EXPANSION = 100
EXPANSION_FLOOR = 64 << 20
# The arrays read, each from member ``key``, else ``key.npy`` (as np.load finds them).
ARRAYS = ("positions", "observed", "labels", "rate", "units", "first_frame", "fillable")


@dataclass(frozen=True)
class _Member:
    """An array of the archive as its .npy header declares it (nothing of it loaded)."""

    info: zipfile.ZipInfo
    shape: tuple[int, ...]
    dtype: np.dtype

    @property
    def size(self) -> int:
        return math.prod(self.shape)


def _header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, path: Path) -> _Member:
    """The shape and dtype an archive member declares, read from its header alone, and
    checked against the bytes the member holds (so that loading it allocates only data
    that is there)."""
    name = info.filename
    with archive.open(info) as member:
        head = member.read(12)      # magic (6), version (2), header length (2 or 4)
        try:
            version = np.lib.format.read_magic(io.BytesIO(head))
        except ValueError:
            raise FormatError(path, f"{name} is not a NumPy array (no .npy signature)") from None
        if version not in ((1, 0), (2, 0)):     # 3.0: headers numpy cannot write in Latin-1
            raise FormatError(path, f"{name} is a .npy file of version "
                                    f"{version[0]}.{version[1]}, not read (1.0 or 2.0)")
        start = 10 if version == (1, 0) else 12
        if len(head) < start:
            raise FormatError(path, f"{name} is cut short inside its header")
        length = int.from_bytes(head[8:start], "little")
        if length > MAX_HEADER:
            raise FormatError(path, f"{name} has a header of {length} bytes, more than the "
                                    f"{MAX_HEADER} numpy reads: not an array numpy wrote")
        text = head + member.read(start + length - len(head))
    read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                   else np.lib.format.read_array_header_2_0)
    try:
        shape, _fortran, dtype = read_header(io.BytesIO(text[8:]))
    except ValueError as exc:        # cut short, not a dictionary, an unknown dtype
        raise FormatError(path, f"unreadable array {name} ({' '.join(str(exc).split())})"
                          ) from None
    if dtype.hasobject:
        raise FormatError(path, f"unreadable array {name} (it holds Python objects, which "
                                "are never loaded)")
    if any(n < 0 for n in shape):
        raise FormatError(path, f"unreadable array {name} (shape {shape})")
    declared = math.prod(shape) * dtype.itemsize
    held = info.file_size - len(text)
    if declared > held:
        raise FormatError(path, f"{name} declares {shape} {dtype} ({declared} bytes) but "
                                f"holds {max(held, 0)} bytes: cut short or not written by numpy")
    return _Member(info, tuple(shape), dtype)


def _members(archive: zipfile.ZipFile, path: Path) -> dict[str, _Member]:
    """The arrays of :data:`ARRAYS` the archive holds, declared shapes checked against each
    other and the bytes they unpack to against those they are stored in."""
    names = set(archive.namelist())
    size = path.stat().st_size
    members = {}
    for key in ARRAYS:
        name = key if key in names else f"{key}.npy"
        if name in names:
            info = archive.getinfo(name)
            if info.compress_size > size:       # the zip bomb check's denominator
                raise FormatError(path, f"{name} declares {info.compress_size} bytes stored "
                                        f"in an archive of {size}: not a valid .npz archive")
            members[key] = _header(archive, info, path)
    if "positions" not in members:
        raise FormatError(path, "missing array 'positions'")
    shape = members["positions"].shape
    if len(shape) != 3 or shape[2] != 3:
        raise FormatError(path, f"positions must be (frames, markers, 3), got {shape}")
    if members["positions"].dtype.kind == "c":   # float64 would drop the imaginary part
        raise FormatError(path, "positions must be real numbers, got complex ones")
    if "observed" in members and members["observed"].shape != shape[:2]:
        raise FormatError(path, f"observed must be {shape[:2]}, got {members['observed'].shape}")
    if "labels" in members and members["labels"].size != shape[1]:
        raise FormatError(path, f"{members['labels'].size} labels for {shape[1]} markers")
    if "fillable" in members and members["fillable"].size != shape[1]:
        raise FormatError(path, "fillable must hold one entry per marker, got "
                                f"{members['fillable'].size}")
    for key in ("rate", "first_frame"):
        if key in members and members[key].size != 1:
            raise FormatError(path, f"{key} must hold one number, got {members[key].size}")
    if "units" in members and members["units"].size < 1:
        raise FormatError(path, "units must hold one text, got none")
    unpacked = sum(m.info.file_size for m in members.values())
    stored = sum(m.info.compress_size for m in members.values())
    if unpacked > EXPANSION_FLOOR and unpacked > MAX_EXPANSION * stored:
        raise FormatError(path, f"its arrays unpack to {unpacked / 2**20:.0f} MB from "
                                f"{stored / 2**20:.2g} MB ({unpacked / max(stored, 1):.0f} to "
                                f"1): refused as a zip bomb (more than {MAX_EXPANSION} to 1 "
                                f"above {EXPANSION_FLOOR >> 20} MB; motion data deflates "
                                "far less)")
    return members


def read(path: Path, *, rate: float | None = None) -> Motion:
    """Read an archive; ``rate`` (Hz) is used only when it stores none (or 0, not known).

    Each array's .npy header is read and checked first (shapes that agree, one number for
    ``rate`` and ``first_frame``, the bytes declared present in the archive, no zip bomb:
    :func:`_members`), so that a small file never has numpy allocate a large clip."""
    if not zipfile.is_zipfile(path):
        raise FormatError(path, "not an .npz archive (no zip signature)")
    try:
        with zipfile.ZipFile(path) as archive:
            members = _members(archive, path)

            def load(key: str) -> np.ndarray:
                with archive.open(members[key].info) as member:
                    return np.lib.format.read_array(member, allow_pickle=False)

            positions = np.asarray(load("positions"), dtype=np.float64)
            observed = (np.asarray(load("observed"), bool) if "observed" in members
                        else np.isfinite(positions).all(axis=2))
            labels = ([_text(s) for s in load("labels").reshape(-1)]
                      if "labels" in members else None)
            stored = float(load("rate").reshape(-1)[0]) if "rate" in members else 0.0
            units = _text(load("units").reshape(-1)[0]) if "units" in members else "mm"
            first_frame = (int(load("first_frame").reshape(-1)[0]) if "first_frame" in members
                           else 1)
            fillable = (np.asarray(load("fillable"), bool).reshape(-1)
                        if "fillable" in members else None)
    except (zipfile.BadZipFile, OSError, EOFError, NotImplementedError) as exc:
        raise FormatError(path, f"not a valid .npz archive ({exc})") from None
    except (ValueError, TypeError) as exc:     # text where numbers belong
        raise FormatError(path, f"unreadable array ({exc})") from None
    if not (np.isfinite(stored) and stored >= 0):
        raise FormatError(path, f"rate is {stored}, not a frame rate (a positive, finite number "
                                "of Hz, or 0 when not known)")
    rate = stored or rate or 0.0
    if labels is None:
        labels = [f"M{j + 1:03d}" for j in range(positions.shape[1])]
    return Motion(positions, observed, tuple(labels), rate, units, fillable=fillable,
                  path=path, first_frame=first_frame)


# Deflate gains about 8 % on float64 coordinates (a 216,000 × 41 clip: 193 MB against 211
# MB) at 18 times the cost (7.9 s against 0.4 s), so positions are stored; the mask and
# the small arrays compress to almost nothing and stay deflated. np.load reads both.
STORED = ("positions",)


def write(motion: Motion, path: Path, **_options) -> None:
    arrays = {"positions": motion.positions, "observed": motion.observed,
              "labels": np.array(motion.labels, dtype=str),
              "rate": np.float64(motion.rate), "units": np.array(motion.units),
              "first_frame": np.int64(motion.first_frame), "fillable": motion.fillable}
    with open(path, "wb") as fh, zipfile.ZipFile(fh, "w", allowZip64=True) as archive:
        for name, array in arrays.items():
            # A fixed date: the same repair writes the same bytes.
            info = zipfile.ZipInfo(f"{name}.npy", (1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_STORED if name in STORED else zipfile.ZIP_DEFLATED
            with archive.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(array),
                                          allow_pickle=False)
