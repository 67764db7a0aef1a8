"""C3D: read marker trajectories; write repairs as an in-place byte patch of the original.

Why not the ``c3d`` package: py-c3d 0.6 fails on real files of the shared set
(btk-sample15__FP1, btk-sample24) and offers no way to rewrite single samples in place,
which the writer below needs; this parser reads every shared C3D file or rejects it with
a reason.

Reading
-------
The 512-byte header and the parameter section are parsed here (all three processor
types: 84 Intel, 85 DEC, 86 MIPS/SGI), and the point block is read in one vectorised
``np.frombuffer`` over the data section, frame stride = (4 words per point + analog words
per frame). Every count taken from the header or parameters is checked against the file
size before anything is allocated, so a forged count gives a one-line ``FormatError``,
never a huge allocation. Frames are counted from the header's first and last frame
words; where the last is 65535 (the most 16 bits hold: a clip longer than that, or one
numbered past it), POINT:LONG_FRAMES or TRIAL:ACTUAL_START_FIELD/ACTUAL_END_FIELD (32-bit
frame numbers) count them, as Vicon writes them, and TRIAL's start gives a first frame
past 65535.

A sample is missing when its fourth word (residual) is negative or any coordinate is not
finite. ``zero_is_missing`` adds exact (0, 0, 0) samples (all three coordinates, never
one): ``"on"``, ``"off"``, or ``"auto"`` (default), which turns it on for Qualisys files.
A file counts as Qualisys when MANUFACTURER:COMPANY contains "Qualisys", or when it
carries QTM's gap signature: a float file with at least one sample stored as exactly
(0, 0, 0) whose fourth word is 65535.0 (all 16 bits set, i.e. -1 read as unsigned, so
"valid" by the sign rule), a combination no measured or computed sample has. QTM exports
without a MANUFACTURER group (c3d.org Sample26) write every gap that way. Zero samples of
model outputs (an angle or a power may be exactly 0) are never made missing.

Points listed in POINT:ANGLES, FORCES, MOMENTS, POWERS, SCALARS or REACTIONS, or in another
list the file declares in POINT:TYPE_GROUPS (Vicon's MODELED_MARKERS: joint centres) (model
outputs; matched by label as stored, with or without a Vicon ``Subject:`` prefix) are read
but get ``fillable=False``.

Writing
-------
A Motion read from a C3D file carries a :class:`C3DSource`. ``write`` then copies the
original bytes and overwrites, for each sample that was missing and is now observed, the
four words of that sample: x, y, z in the file's own processor format and storage, and
word 4 = 0 (residual 0 = "computed, not measured" per c3d.org); a sample made missing
since reading (``simulate``) gets x = y = z = 0 and word 4 = -1, a C3D gap. Header, parameters,
analog samples, events and every other sample stay byte-identical. Any other Motion is
written as a new Intel float C3D, its frame numbers in TRIAL:ACTUAL_START_FIELD and
ACTUAL_END_FIELD too (the header's words hold 65535 for a frame number past it), and
its points that are not marker trajectories (``fillable`` False, model outputs) listed
in POINT:SCALARS (SCALARS2 ... past 255 of them), so they read back as model outputs:
a clip does not record whether a point was an angle, a force or a power, and SCALARS is
the one list that claims no kind.
"""
from __future__ import annotations

import math
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..motion import Motion, unique_labels
from ._patch import AsRead, as_read
from ._text import check_zero_setting, utf8_or_latin1

PROCESSORS = {84: "intel", 85: "dec", 86: "mips"}
# Parameters listing POINT entries that are model outputs, not marker trajectories.
MODEL_OUTPUT_LISTS = re.compile(r"(ANGLES|FORCES|MOMENTS|POWERS|SCALARS|REACTIONS)\d*")
QUALISYS_GAP_WORD = 0xFFFF  # a float fourth word of 65535: 16 bits all set
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
    size, crc32
        Its size and CRC-32 when read; the writer refuses to patch a changed file.
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
    zeros_are_gaps
        Whether exact (0, 0, 0) samples were read as missing (``zero_is_missing``).
    data
        The bytes read, kept only when ``path`` is not a regular file (a FIFO, a device):
        such a file cannot be read a second time, so the writer patches these instead.
        None for a regular file, which the writer re-reads rather than holding a large
        file's bytes for the life of the clip.
    as_read
        The clip as read, in what a patch cannot change (``formats.write`` refuses to
        patch a clip that differs).
    """

    path: Path
    size: int
    crc32: int
    processor: str
    is_float: bool
    scale: float
    data_start: int
    frame_stride: int
    n_points: int
    point_index: np.ndarray
    observed: np.ndarray
    fillable: np.ndarray
    zeros_are_gaps: bool = False
    data: bytes | None = None
    as_read: AsRead | None = None

    @property
    def word_size(self) -> int:
        return 4 if self.is_float else 2

    @property
    def value_range(self) -> tuple[float, float] | None:
        """The coordinates an int16 word can hold at this scale (None for float storage):
        a repair keeps its fills within it (``pipeline.repair``)."""
        if self.is_float:
            return None
        return INT16_MIN * self.scale, INT16_MAX * self.scale


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
    end = min(len(data), start + 255 * 512)       # the block count is one byte
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
    data = param.data
    width = param.dims[0] if param.dims else len(data)
    if width == 0:
        return []
    # The format declares no encoding: most writers store ASCII, some Latin-1, and names
    # outside Latin-1 can only have been stored as UTF-8 (ours are, see :func:`_encode`).
    return [utf8_or_latin1(data[i:i + width]).replace("\x00", " ").strip()
            for i in range(0, len(data), width)]


def _encode(text: str) -> bytes:
    """A string for a C3D char parameter: Latin-1 where it fits (ASCII labels stay as
    every reader expects), else UTF-8 — never a lossy '?' in place of a character."""
    try:
        return text.encode("latin-1")
    except UnicodeEncodeError:
        return text.encode("utf-8")


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

    def point_value(name: str, default: float) -> float:
        values = _numbers(point.get(name), processor)
        return float(values[0]) if values.size and np.isfinite(values[0]) else default

    n_points = int(point_value("USED", uint[1])) & 0xFFFF
    scale = point_value("SCALE", float(header_scale))
    if not np.isfinite(scale) or scale == 0:
        scale = -1.0 if not np.isfinite(header_scale) or header_scale <= 0 else header_scale
    rate = point_value("RATE", float(header_rate))
    if not (np.isfinite(rate) and rate > 0):    # as SCALE: the header's, where it has one
        rate = float(header_rate) if np.isfinite(header_rate) and header_rate > 0 else 0.0
    word = 4 if scale < 0 else 2
    data_start = (int(uint[8]) - 1) * 512
    if not 512 <= data_start <= len(data):
        data_start = ((int(point_value("DATA_START", 0)) & 0xFFFF) - 1) * 512
    if not 512 <= data_start <= len(data):
        raise FormatError(path, "data section start is outside the file")
    data_bytes = len(data) - data_start
    n_frames = _frame_count(params, processor, uint)
    if n_frames is None:  # no usable count anywhere: whatever whole frames the file holds
        n_frames = data_bytes // ((4 * n_points + int(uint[2])) * word or 1)
    # Header word 3 should be analog channels x samples per frame; some writers store the
    # channel count only, so the candidate that fills the data section most snugly wins.
    strides = [(4 * n_points + analog) * word for analog in _analog_words(params, processor, uint,
                                                                         rate)]
    fitting = [s for s in strides if n_frames * s <= data_bytes]
    if not fitting:
        available = data_bytes // strides[0] if strides[0] else 0
        raise FormatError(path, f"truncated: {available} of {n_frames} frames present")
    frame_stride = max(fitting)
    return _Layout(processor, params, n_points, n_frames, scale < 0, abs(scale), data_start,
                   frame_stride, rate, _first_frame(params, processor, uint))


def _analog_words(params: dict[str, dict[str, _Param]], processor: str, header: np.ndarray,
                  rate: float) -> list[int]:
    """Candidate analog words per frame, the header's first."""
    analog = params.get("ANALOG", {})
    used = _numbers(analog.get("USED"), processor)
    candidates = [int(header[2])]
    if used.size:
        channels = int(used[0]) & 0xFFFF
        candidates.append(channels * int(header[9]))
        analog_rate = _numbers(analog.get("RATE"), processor)
        if analog_rate.size and rate > 0 and np.isfinite(analog_rate[0]):
            candidates.append(channels * round(float(analog_rate[0]) / rate))
    return candidates


def _trial_field(trial: dict[str, _Param], name: str, processor: str) -> int | None:
    """TRIAL:ACTUAL_START_FIELD or ACTUAL_END_FIELD: a frame number as two 16-bit words."""
    words = _numbers(trial.get(name), processor)
    if words.size != 2 or not np.isfinite(words).all():
        return None
    low, high = (words.astype(np.int64) & 0xFFFF).tolist()
    return low + (high << 16)


def _frame_count(params: dict[str, dict[str, _Param]], processor: str,
                 header: np.ndarray) -> int | None:
    """Frames in the trial: the header's count, or the parameters' where the header's last
    frame word is full (0xFFFF: a clip longer than 65535 frames, or one numbered past
    frame 65535) and they count more."""
    count = int(header[4]) - int(header[3]) + 1
    point, trial = params.get("POINT", {}), params.get("TRIAL", {})
    counts = [float(n) for n in _numbers(point.get("LONG_FRAMES"), processor)[:1]]
    start = _trial_field(trial, "ACTUAL_START_FIELD", processor)
    end = _trial_field(trial, "ACTUAL_END_FIELD", processor)
    if start is not None and end is not None:
        counts.append(end - start + 1)
    counts = [int(n) for n in counts if np.isfinite(n) and n > 0]
    if header[4] == 0xFFFF and counts and max(counts) > count:
        return max(counts)
    if count <= 0:
        longer = [n for n in counts if n > 65535]
        if longer:
            return max(longer)
        # POINT:FRAMES = 0 with a header of no frames is a clip of none, whatever padding
        # fills the data block's last 512 bytes (read as frames of zeros before).
        frames = _numbers(point.get("FRAMES"), processor)
        return int(frames[0]) & 0xFFFF if frames.size and np.isfinite(frames[0]) else None
    return count


def _first_frame(params: dict[str, dict[str, _Param]], processor: str,
                 header: np.ndarray) -> int:
    """The first frame's number: the header's, or TRIAL:ACTUAL_START_FIELD's past 65535."""
    start = _trial_field(params.get("TRIAL", {}), "ACTUAL_START_FIELD", processor)
    return start if start is not None and start > 0xFFFF else int(header[3])


def _stored_labels(point: dict[str, _Param], n_points: int) -> list[str]:
    """POINT:LABELS + LABELS2, LABELS3..., as stored (empty where none), one per point."""
    names = _strings(point.get("LABELS"))
    extra = 2
    while f"LABELS{extra}" in point:
        names += _strings(point[f"LABELS{extra}"])
        extra += 1
    return names[:n_points] + [""] * max(n_points - len(names), 0)


def _model_outputs(point: dict[str, _Param], labels: list[str], n_points: int) -> np.ndarray:
    """(points,) bool, True for points named in POINT:ANGLES, FORCES, ... (model outputs).

    ``labels`` as stored (:func:`_stored_labels`), not as read: a label given twice is
    read ``LKneeAngles_2`` the second time, which no list names, and that copy of a model
    output was filled. Also the lists of the other point types a file declares in
    POINT:TYPE_GROUPS (pairs of list and type names: Vicon's ``MODELED_MARKERS``, the joint
    centres a model computes, beside ``ANGLES`` ...), except a list of markers.
    """
    declared = {name.upper() for name in _strings(point.get("TYPE_GROUPS"))} & set(point)
    declared -= {"LABELS", "DESCRIPTIONS", "UNITS", "MARKERS"}
    listed: set[str] = set()
    for name, param in point.items():
        if MODEL_OUTPUT_LISTS.fullmatch(name) or name in declared:
            listed.update(s for s in _strings(param) if s)
    listed |= {s.rsplit(":", 1)[-1] for s in listed}
    return np.array([lab in listed or lab.rsplit(":", 1)[-1] in listed
                     for lab in labels[:n_points]], dtype=bool)


def _units(point: dict[str, _Param]) -> str:
    """POINT:UNITS normalised ("mete", "meters" -> "m"); "mm" when absent."""
    raw = next(iter(_strings(point.get("UNITS"))), "").strip().lower()
    if raw and not raw.isalpha():
        return raw          # a compound unit ("in/0.45", the CMU AMC length): kept whole
    if not raw or raw.startswith(("mm", "milli")):
        return "mm"
    if raw.startswith(("cm", "centi")):
        return "cm"
    if raw == "m" or raw.startswith("met"):
        return "m"
    if raw.startswith("in"):
        return "in"
    return raw


def read(path: Path, *, zero_is_missing: str = "auto", rate: float | None = None) -> Motion:
    """Read the marker trajectories of a C3D file.

    Parameters
    ----------
    path
        The C3D file.
    zero_is_missing
        ``"on"``: samples stored as exactly (0, 0, 0) are also missing; ``"off"``: never;
        ``"auto"``: on for Qualisys files (see the module docstring).
    rate
        Frame rate in Hz, used only when the file states none (``POINT:RATE`` and the
        header's rate 0 or absent; default None: such a file reads as 0 Hz, not known).

    Returns
    -------
    Motion
        Positions in the file's POINT:UNITS, with a :class:`C3DSource` for patching.

    Raises
    ------
    FormatError
        Empty, not C3D, truncated, or inconsistent counts.
    ParameterError
        ``zero_is_missing`` is not one of the three values.
    """
    check_zero_setting(zero_is_missing)
    path = Path(path)
    data = path.read_bytes()
    layout = _layout(path, data)
    n_frames, n_points = layout.n_frames, layout.n_points
    word = 4 if layout.is_float else 2
    block = np.frombuffer(data, np.uint8, count=n_frames * layout.frame_stride,
                          offset=layout.data_start)
    records = block.reshape(n_frames, layout.frame_stride)[:, :4 * word * n_points]
    if layout.is_float:
        words = _decode_floats(np.ascontiguousarray(records), layout.processor)
    else:
        words = np.ascontiguousarray(records).view(_int_dtype(layout.processor))
    words = words.reshape(n_frames, n_points, 4)
    coords, fourth = words[:, :, :3], words[:, :, 3]
    observed = fourth >= 0
    if layout.is_float:
        observed &= np.isfinite(coords).all(axis=2)

    point = layout.params.get("POINT", {})
    stored = _stored_labels(point, n_points)
    labels = _named(stored)
    fillable = ~_model_outputs(point, stored, n_points)
    if zero_is_missing == "auto":
        company = " ".join(_strings(layout.params.get("MANUFACTURER", {}).get("COMPANY")))
        # Cheap test first; zeros only if needed. An int16 word cannot hold 65535, and
        # numpy 2.0-2.2.1 crash (SIGSEGV) comparing a strided int16 array with it.
        signature = (fourth == QUALISYS_GAP_WORD if layout.is_float
                     else np.zeros(fourth.shape, bool))
        qtm_gaps = signature.any() and (signature & (coords == 0).all(axis=2)).any()
        zero_is_missing = "on" if "qualisys" in company.lower() or qtm_gaps else "off"
    if zero_is_missing == "on":  # model outputs (an angle, a power) may well be exactly 0
        observed &= ~((coords == 0).all(axis=2) & fillable)
    positions = coords.astype(np.float64)
    if not layout.is_float:
        positions *= layout.scale
    positions[~observed] = np.nan
    point_index = np.arange(n_points)
    for frozen in (observed, point_index):
        frozen.setflags(write=False)
    units = _units(point)
    rate = layout.rate or rate or 0.0       # the option only where the file states none
    source = C3DSource(path=path, size=len(data), crc32=zlib.crc32(data),
                       processor=layout.processor, is_float=layout.is_float,
                       scale=layout.scale, data_start=layout.data_start,
                       frame_stride=layout.frame_stride, n_points=n_points,
                       point_index=point_index, observed=observed,
                       fillable=np.array(fillable), zeros_are_gaps=zero_is_missing == "on",
                       data=None if path.is_file() else data,
                       as_read=as_read(labels, rate, units, layout.first_frame,
                                       fillable, positions, observed))
    return Motion(positions, observed.copy(), tuple(labels), rate, units,
                  fillable=fillable, source=source, path=path, first_frame=layout.first_frame)


# --------------------------------------------------------------------------- writing


def write(motion: Motion, path: Path, **_options) -> None:
    """Write ``motion`` as C3D: a byte patch of its source file, or a new Intel float file.

    Parameters
    ----------
    motion
        The clip. When its ``source`` is a :class:`C3DSource`, only samples whose observed
        state changed are written (fillable points only): newly observed ones with word 4 =
        0 (computed), newly missing ones (simulated gaps) as x = y = z = 0 with word 4 = -1;
        everything else in the output is a byte copy of the original.
    path
        Output file.

    Raises
    ------
    FormatError
        The source file changed since it was read, the motion no longer matches it, or a
        filled value does not fit the file's int16 storage.
    """
    path = Path(path)
    if patches(motion):
        path.write_bytes(_patched(motion, motion.source, path))
        return
    try:
        path.write_bytes(_new_file(motion))
    except FormatError as exc:
        raise FormatError(path, exc.problem) from None


def patches(motion: Motion) -> bool:
    """Whether :func:`write` writes ``motion`` as a byte patch of the C3D it was read from."""
    return isinstance(motion.source, C3DSource)


def _patched(motion: Motion, source: C3DSource, out: Path) -> bytes:
    """The source file's bytes with the newly observed samples written in."""
    if source.data is not None:     # a FIFO or the like: a second read would block or differ
        return _patch(motion, source, out, source.data)
    try:
        original = source.path.read_bytes()
    except OSError as exc:
        raise FormatError(source.path, f"cannot re-read the original to patch it ({exc})") from None
    if len(original) != source.size or zlib.crc32(original) != source.crc32:
        raise FormatError(source.path, "changed since it was read; read it again before writing")
    return _patch(motion, source, out, original)


def _patch(motion: Motion, source: C3DSource, out: Path, original: bytes) -> bytes:
    """``original`` (the source file's bytes, as read) with the changed samples written in."""
    if motion.observed.shape != source.observed.shape:
        raise FormatError(out, f"motion is {motion.observed.shape} (frames, markers) but its "
                               f"source C3D holds {source.observed.shape}; cannot patch")
    editable = (source.fillable & motion.fillable)[None, :]
    fill = motion.observed & ~source.observed & editable
    # Samples removed (e.g. by `simulate`) become C3D gaps: x = y = z = 0, word 4 = -1.
    erase = ~motion.observed & source.observed & editable
    frames, markers = np.nonzero(fill | erase)
    if frames.size == 0:
        return original
    erased = erase[frames, markers]
    values = np.where(erased[:, None], 0.0, motion.positions[frames, markers])  # finite
    word4 = np.where(erased, -1.0, 0.0)
    if source.is_float:
        if not np.isfinite(values.astype(np.float32) * np.float32(4)).all():
            raise FormatError(out, "a filled value overflows the float32 range of this C3D")
        encoded = _encode_floats(np.column_stack([values, word4]), source.processor)
    else:
        raw = np.rint(values / source.scale)
        if raw.max() > INT16_MAX or raw.min() < INT16_MIN:
            worst = float(np.abs(values).max())
            raise FormatError(out, f"a filled value ({worst:g}) would overflow the int16 range "
                                   f"of this integer C3D (scale {source.scale:g}, limit "
                                   f"{INT16_MAX * source.scale:g}); write a float C3D instead")
        words = np.column_stack([raw, word4]).astype(_int_dtype(source.processor))
        encoded = words.view(np.uint8)
    record = 4 * source.word_size
    offsets = (source.data_start + frames * source.frame_stride
               + source.point_index[markers] * record)
    patched = np.frombuffer(bytearray(original), np.uint8)
    patched[offsets[:, None] + np.arange(record)] = encoded.reshape(len(offsets), record)
    return patched.tobytes()


def _param_entry(group_id: int, name: str, type_code: int, dims: tuple[int, ...],
                 data: bytes) -> bytes:
    body = struct.pack("<bB", type_code, len(dims)) + bytes(dims) + data + b"\x00"
    return (struct.pack("<bb", len(name), group_id) + name.encode()
            + struct.pack("<h", 2 + len(body)) + body)


def _group_entry(group_id: int, name: str) -> bytes:
    return struct.pack("<bb", len(name), -group_id) + name.encode() + struct.pack("<hB", 3, 0)


def _char_param(group_id: int, name: str, strings: list[str] | str) -> bytes:
    """A char parameter: one string (1-D) or a list of strings (2-D, width x count)."""
    single = isinstance(strings, str)
    encoded = [_encode(s) for s in ([strings] if single else strings)]
    too_long = next((s for s in encoded if len(s) > 255), None)
    if too_long is not None:
        # The dimension is one byte: a longer string would have to be cut, and cut labels
        # can collide. Refused rather than written with other names than the clip's.
        shown = utf8_or_latin1(too_long)
        shown = shown if len(shown) <= 40 else shown[:40] + "..."
        raise FormatError(None, f"POINT:{name} {shown!r} is {len(too_long)} bytes long; a "
                                "C3D file holds at most 255 per entry")
    width = max((len(s) for s in encoded), default=0) or 1
    data = b"".join(s.ljust(width) for s in encoded)
    return _param_entry(group_id, name, -1, (width,) if single else (width, len(encoded)), data)


def _number_param(group_id: int, name: str, values: list[float], floating: bool) -> bytes:
    data = np.asarray(values, "<f4" if floating else "<u2").tobytes()
    dims = () if len(values) == 1 else (len(values),)
    return _param_entry(group_id, name, 4 if floating else 2, dims, data)


# Bytes of one char parameter's strings: its entry's offset to the next is a 16-bit word.
_MAX_PARAM_DATA = 32_000


def _label_chunks(labels: list[str]) -> list[list[str]]:
    """Labels split into LABELS, LABELS2, ... entries: at most 255 strings each (a one-byte
    count) and at most ``_MAX_PARAM_DATA`` bytes once padded to the entry's longest."""
    chunks: list[list[str]] = [[]]
    width = 0
    for label in labels:
        size = len(_encode(label))
        chunk = chunks[-1]
        if chunk and (len(chunk) == 255 or max(width, size) * (len(chunk) + 1)
                      > _MAX_PARAM_DATA):
            chunks.append([])
            chunk, width = chunks[-1], 0
        chunk.append(label)
        width = max(width, size)
    return chunks


NEW_FILE_NAMES = "names a C3D reads back"


def new_file_names(labels: list[str] | tuple[str, ...]) -> list[str]:
    """The POINT:LABELS of a new C3D: the names :func:`read` gives back (padding spaces
    stripped, ``POINT{n}`` for an empty label, repeats numbered), so a clip written and
    read again keeps the names, and a note tells of any change."""
    return _named([str(label).replace("\x00", " ").strip() for label in labels])


def _named(names: list[str]) -> list[str]:
    """Empty names as ``POINT{n}``, repeats numbered (what :func:`read` gives)."""
    return unique_labels([name or f"POINT{i + 1}" for i, name in enumerate(names)])


def stores_first_frame(motion: Motion) -> bool:
    """Whether a new C3D can hold the clip's first frame number (TRIAL:ACTUAL_START_FIELD
    and ACTUAL_END_FIELD: unsigned 32-bit frame numbers); one that cannot is written as 1."""
    return 0 <= motion.first_frame <= 0xFFFFFFFF - motion.n_frames


def _new_file(motion: Motion) -> bytes:
    """A new Intel float C3D: header, POINT/ANALOG/TRIAL parameters, float32 frames.

    Points whose ``fillable`` is False are listed in POINT:SCALARS (see the module
    docstring). Missing samples are stored as (0, 0, 0) with residual -1; observed samples with
    residual 0, since no residual is known (c3d.org reads that as "computed").
    """
    n_frames, n_markers = motion.observed.shape
    if n_markers > 0xFFFF:
        raise FormatError(None, f"{n_markers} markers do not fit one C3D file (65535 at most)")
    finite = np.abs(motion.positions[motion.observed])
    if finite.size and finite.max() > np.finfo(np.float32).max:
        # float32 would store inf, which every reader takes as a gap: refused, not lost
        raise FormatError(None, f"a value ({float(finite.max()):g}) overflows the float32 "
                                "range of a C3D file (3.4e38 at most)")
    scale = -(float(finite.max()) / 32000 if finite.size and finite.max() > 0 else 1.0)
    # Frame numbers past 65535 live in TRIAL:ACTUAL_START_FIELD / ACTUAL_END_FIELD (two
    # 16-bit words each); the header's 16-bit words then hold 65535.
    first_frame = motion.first_frame if stores_first_frame(motion) else 1
    last_frame = first_frame + n_frames - 1
    labels = new_file_names(motion.labels)
    chunks = _label_chunks(labels)

    params = [_group_entry(1, "POINT"),
              _number_param(1, "USED", [n_markers], False),
              _number_param(1, "FRAMES", [min(n_frames, 0xFFFF)], False),
              _number_param(1, "SCALE", [scale], True),
              _number_param(1, "RATE", [motion.rate], True),
              _number_param(1, "DATA_START", [0], False),          # set below
              _char_param(1, "UNITS", motion.units)]
    for i, chunk in enumerate(chunks):
        suffix = "" if i == 0 else str(i + 1)
        params += [_char_param(1, f"LABELS{suffix}", chunk),
                   _char_param(1, f"DESCRIPTIONS{suffix}", [""] * len(chunk))]
    # Model outputs (fillable False) in POINT:SCALARS: see the module docstring.
    outputs = [label for label, ok in zip(labels, motion.fillable) if not ok]
    if outputs:
        for i, chunk in enumerate(_label_chunks(outputs)):
            params.append(_char_param(1, "SCALARS" + ("" if i == 0 else str(i + 1)), chunk))
    if n_frames > 0xFFFF:
        params.append(_number_param(1, "LONG_FRAMES", [n_frames], True))
    params += [_group_entry(2, "ANALOG"),
               _number_param(2, "USED", [0], False),
               _number_param(2, "RATE", [motion.rate], True),
               _number_param(2, "GEN_SCALE", [1.0], True),
               _group_entry(3, "TRIAL"),
               _number_param(3, "ACTUAL_START_FIELD", [first_frame & 0xFFFF,
                                                        first_frame >> 16], False),
               _number_param(3, "ACTUAL_END_FIELD", [last_frame & 0xFFFF, last_frame >> 16],
                             False)]
    section_size = 4 + sum(len(p) for p in params) + 2
    n_blocks = -(-section_size // 512)
    if n_blocks > 0xFF:     # the parameter section's block count is one byte
        raise FormatError(None, f"the labels of {n_markers} markers need a {n_blocks}-block "
                                "parameter section, and a C3D file holds 255 blocks at most; "
                                "write .trc or .csv, or shorten the labels")
    data_block = 2 + n_blocks
    params[5] = _number_param(1, "DATA_START", [data_block], False)
    section = (bytes([1, 0x50, n_blocks, 84]) + b"".join(params)).ljust(n_blocks * 512, b"\0")

    header = bytearray(512)
    struct.pack_into("<BBHHHHHfHHf", header, 0, 2, 0x50, n_markers, 0,
                     min(first_frame, 0xFFFF), min(last_frame, 0xFFFF), 0, scale, data_block,
                     # analog samples per frame: ANALOG:RATE / POINT:RATE, 0 for a 0 Hz clip
                     # (py-c3d refuses a file where they disagree)
                     1 if motion.rate > 0 else 0, motion.rate)
    struct.pack_into("<H", header, 298, 0x3039)                  # 4-character event labels

    frames = np.zeros((n_frames, n_markers, 4), "<f4")
    frames[:, :, :3] = np.where(motion.observed[:, :, None], motion.positions, 0.0)
    frames[:, :, 3] = np.where(motion.observed, 0.0, -1.0)
    body = frames.tobytes()
    if n_frames < 0xFFFF:
        body += b"\0" * (-len(body) % 512)
    # else no padding: POINT:FRAMES then holds 65535 (-1 as the int16 it is), which ezc3d
    # takes as "count to the end of the file", so padding would read as frames at (0, 0, 0)
    return bytes(header) + section + body

