"""C3D: read marker trajectories; write repairs as an in-place byte patch of the original.

Reading
-------
The 512-byte header and the parameter section are parsed here (all three processor
types: 84 Intel, 85 DEC, 86 MIPS/SGI), and the point block is read in one vectorised
``np.frombuffer`` over the data section, frame stride = (4 words per point + analog words
per frame). Every count taken from the header or parameters is checked against the file
size before anything is allocated, so a forged count gives a one-line ``FormatError``,
never a huge allocation.

A sample is missing when its fourth word (residual) is negative or any coordinate is not
finite. ``zero_is_missing`` adds exact (0, 0, 0) samples (all three coordinates, never
one): ``"on"``, ``"off"``, or ``"auto"`` (default), which turns it on for Qualisys files.
A file counts as Qualisys when MANUFACTURER:COMPANY contains "Qualisys", or when it
carries QTM's gap signature: at least one sample stored as exactly (0, 0, 0) whose fourth
word is 0x7FFF (all seven camera bits set, residual byte 255), a combination no measured
or computed sample has. QTM exports without a MANUFACTURER group (c3d.org Sample26) write
every gap that way.

Points listed in POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS or REACTIONS (model
outputs; matched by label, with or without a Vicon ``Subject:`` prefix) are read but get
``fillable=False``.

Writing
-------
A Motion read from a C3D file carries a :class:`C3DSource`. ``write`` then copies the
original bytes and overwrites, for each sample that was missing and is now observed, the
four words of that sample: x, y, z in the file's own processor format and storage, and
word 4 = 0 (residual 0 = "computed, not measured" per c3d.org). Header, parameters,
analog samples, events and every other sample stay byte-identical. Any other Motion is
written as a new Intel float C3D.
"""
from __future__ import annotations

import hashlib
import math
import re
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..motion import Motion

PROCESSORS = {84: "intel", 85: "dec", 86: "mips"}
# Parameters listing POINT entries that are model outputs, not marker trajectories.
MODEL_OUTPUT_LISTS = re.compile(r"(ANGLES|FORCES|MOMENTS|POWERS|SCALARS|REACTIONS)\d*")
QUALISYS_GAP_WORD = 0x7FFF
INT16_MAX = 32767
INT16_MIN = -32768


@dataclass(frozen=True)
class _Param:
    """One raw parameter: C3D type code (-1 char, 1 byte, 2 int16, 4 float), dims, bytes."""

    type: int
    dims: tuple[int, ...]
    data: bytes


@dataclass(frozen=True, eq=False)
class C3DSource:
    """What the patch writer needs to rewrite a sample of the original file in place.

    Attributes
    ----------
    path
        The file that was read.
    size, sha256
        Its size and digest when read; the writer refuses to patch a changed file.
    processor
        "intel", "dec" or "mips".
    is_float
        True for float storage (POINT:SCALE < 0), False for int16 storage.
    scale
        ``abs(POINT:SCALE)``; int16 words are coordinate / scale.
    data_start
        Byte offset of the first frame.
    frame_stride
        Bytes per frame (points and analog samples).
    n_points
        Points per frame in the file.
    point_index
        (markers,) int, the file point index of each Motion marker.
    observed
        (frames, markers) bool, the observed mask as read (the writer only patches samples
        that were False here).
    fillable
        (markers,) bool, False for model outputs; those points are never patched.
    """

    path: Path
    size: int
    sha256: str
    processor: str
    is_float: bool
    scale: float
    data_start: int
    frame_stride: int
    n_points: int
    point_index: np.ndarray
    observed: np.ndarray
    fillable: np.ndarray

    @property
    def word_size(self) -> int:
        return 4 if self.is_float else 2


# --------------------------------------------------------------------------- encoding


def _int_dtype(processor: str) -> np.dtype:
    return np.dtype(">i2" if processor == "mips" else "<i2")


def _decode_floats(raw: bytes | np.ndarray, processor: str) -> np.ndarray:
    """float32 values of 4-byte words (DEC: swap the 16-bit halves, IEEE, divide by 4)."""
    if processor == "mips":
        return np.frombuffer(raw, ">f4") if isinstance(raw, bytes) else raw.view(">f4")
    words = np.frombuffer(raw, "<u4") if isinstance(raw, bytes) else raw.view("<u4")
    if processor == "intel":
        return words.view("<f4")
    swapped = ((words >> np.uint32(16)) | (words << np.uint32(16))).astype("<u4")
    return swapped.view("<f4") / np.float32(4)


def _encode_floats(values: np.ndarray, processor: str) -> np.ndarray:
    """Inverse of :func:`_decode_floats`: uint8 bytes (..., 4·n) of float32 words."""
    if processor == "mips":
        return values.astype(">f4").view(np.uint8)
    words = values.astype("<f4")
    if processor == "dec":
        bits = (words * np.float32(4)).view("<u4")
        words = ((bits >> np.uint32(16)) | (bits << np.uint32(16))).astype("<u4")
    return words.view(np.uint8)


# --------------------------------------------------------------------------- parsing


def _parse_parameters(data: bytes, start: int, processor: str) -> dict[str, dict[str, _Param]]:
    """Group name -> parameter name -> raw parameter, from the parameter section."""
    int16 = ">h" if processor == "mips" else "<h"
    groups: dict[int, str] = {}
    raw: list[tuple[int, str, _Param]] = []
    pos = start + 4
    end = len(data)
    while pos + 2 <= end:
        n_chars, group_id = struct.unpack_from("bb", data, pos)
        n_chars = abs(n_chars)
        if n_chars == 0:
            break
        name = data[pos + 2:pos + 2 + n_chars].decode("latin-1").strip().upper()
        pos += 2 + n_chars
        if pos + 2 > end:
            break
        (offset,) = struct.unpack_from(int16, data, pos)
        body = pos + 2
        if group_id < 0:
            groups[-group_id] = name
        elif group_id > 0 and body + 2 <= end:
            type_code, n_dims = struct.unpack_from("bB", data, body)
            dims = tuple(data[body + 2:body + 2 + n_dims])
            size = abs(type_code) * math.prod(dims)
            first = body + 2 + n_dims
            if abs(type_code) in (1, 2, 4) and len(dims) == n_dims and first + size <= end:
                raw.append((group_id, name, _Param(type_code, dims, data[first:first + size])))
        if offset <= 0:
            break
        pos += offset
    params: dict[str, dict[str, _Param]] = {name: {} for name in groups.values()}
    for group_id, name, param in raw:
        params.setdefault(groups.get(group_id, f"GROUP{group_id}"), {})[name] = param
    return params


def _numbers(param: _Param | None, processor: str) -> np.ndarray:
    """Numeric values of a parameter, flattened (empty for a missing or char parameter)."""
    if param is None or param.type == -1:
        return np.zeros(0)
    if abs(param.type) == 1:
        return np.frombuffer(param.data, np.uint8).astype(float)
    if abs(param.type) == 2:
        return np.frombuffer(param.data, _int_dtype(processor)).astype(float)
    return _decode_floats(param.data, processor).astype(float)


def _strings(param: _Param | None) -> list[str]:
    """Strings of a char parameter (dims: length, count), stripped of padding."""
    if param is None or param.type != -1:
        return []
    text = param.data.decode("latin-1")
    width = param.dims[0] if param.dims else len(text)
    if width == 0:
        return []
    return [text[i:i + width].replace("\x00", " ").strip() for i in range(0, len(text), width)]


@dataclass(frozen=True)
class _Layout:
    processor: str
    params: dict[str, dict[str, _Param]]
    n_points: int
    n_frames: int
    is_float: bool
    scale: float
    data_start: int
    frame_stride: int
    rate: float
    first_frame: int


def _layout(path: Path, data: bytes) -> _Layout:
    """Header + parameters, with every count checked against the file size."""
    if len(data) == 0:
        raise FormatError(path, "empty file (0 bytes)")
    if len(data) < 512 or data[1] != 0x50:
        raise FormatError(path, "not a C3D file (no C3D header signature)")
    param_start = (data[0] - 1) * 512
    if data[0] < 1 or param_start + 4 > len(data):
        raise FormatError(path, f"not a C3D file (parameter block {data[0]} out of range)")
    proc_code = data[param_start + 3]
    if proc_code not in PROCESSORS:
        raise FormatError(path, f"not a C3D file (unknown processor type {proc_code})")
    processor = PROCESSORS[proc_code]
    params = _parse_parameters(data, param_start, processor)
    point = params.get("POINT", {})

    header = np.frombuffer(data[:24], _int_dtype(processor))
    uint = header.astype(np.int64) & 0xFFFF
    header_scale, header_rate = _decode_floats(data[12:16] + data[20:24], processor)

    def first(name: str, default: float) -> float:
        values = _numbers(point.get(name), processor)
        return float(values[0]) if values.size and np.isfinite(values[0]) else default

    n_points = int(first("USED", uint[1])) & 0xFFFF
    analog_words = int(uint[2])
    scale = first("SCALE", float(header_scale))
    if not np.isfinite(scale) or scale == 0:
        scale = -1.0 if not np.isfinite(header_scale) or header_scale <= 0 else header_scale
    rate = first("RATE", float(header_rate))
    is_float = scale < 0
    word = 4 if is_float else 2
    data_start = (int(uint[8]) - 1) * 512
    if data_start < 512 or data_start > len(data):
        start_block = int(first("DATA_START", 0)) & 0xFFFF
        data_start = (start_block - 1) * 512
    if data_start < 512 or data_start > len(data):
        raise FormatError(path, f"data section start {data_start} is outside the file")
    frame_stride = (4 * n_points + analog_words) * word
    n_frames = _frame_count(params, processor, uint)
    available = (len(data) - data_start) // frame_stride if frame_stride else n_frames
    if n_frames > available:
        raise FormatError(path, f"truncated: {available} of {n_frames} frames present")
    return _Layout(processor, params, n_points, n_frames, is_float, abs(scale), data_start,
                   frame_stride, rate if np.isfinite(rate) and rate > 0 else 0.0,
                   int(uint[3]))


def _frame_count(params: dict[str, dict[str, _Param]], processor: str,
                 header: np.ndarray) -> int:
    """Frames in the trial; past 65535 the header cannot say, so longer counts win."""
    count = max(int(header[4]) - int(header[3]) + 1, 0)
    point, trial = params.get("POINT", {}), params.get("TRIAL", {})
    frames = _numbers(point.get("FRAMES"), processor)
    if frames.size and frames[0] != 0:
        count = max(count, int(frames[0]) & 0xFFFF)
    long_frames = _numbers(point.get("LONG_FRAMES"), processor)
    if long_frames.size and np.isfinite(long_frames[0]) and long_frames[0] > 0:
        count = max(count, int(long_frames[0]))
    start = _numbers(trial.get("ACTUAL_START_FIELD"), processor).astype(np.int64) & 0xFFFF
    end = _numbers(trial.get("ACTUAL_END_FIELD"), processor).astype(np.int64) & 0xFFFF
    if start.size == 2 and end.size == 2:
        span = int(end[0] + (end[1] << 16)) - int(start[0] + (start[1] << 16)) + 1
        count = max(count, span)
    return count
