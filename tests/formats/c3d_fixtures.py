"""Build small C3D files byte by byte, in any processor format, for the C3D tests.

Written independently of ``mocapfill.formats.c3d`` so the reader is tested against a
second encoder, not against itself.
"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

PROCESSOR_CODES = {"intel": 84, "dec": 85, "mips": 86}


def encode_floats(values, processor: str) -> bytes:
    """float32 words in a processor's byte order (DEC: x4, 16-bit halves swapped)."""
    values = np.asarray(values, dtype=np.float64)
    if processor == "mips":
        return values.astype(">f4").tobytes()
    if processor == "intel":
        return values.astype("<f4").tobytes()
    raw = (values * 4).astype("<f4").view(np.uint8).reshape(-1, 4)
    return raw[:, [2, 3, 0, 1]].tobytes()


def encode_ints(values, processor: str) -> bytes:
    return np.asarray(values).astype(">i2" if processor == "mips" else "<i2").tobytes()


def _param(processor: str, group_id: int, name: str, value) -> bytes:
    int16 = ">h" if processor == "mips" else "<h"
    if isinstance(value, str):
        value = [value]
        single = True
    else:
        single = False
    if isinstance(value, (list, tuple)) and value and isinstance(value[0], str):
        width = max(len(s) for s in value) or 1
        data = b"".join(s.encode("latin-1").ljust(width) for s in value)
        type_code, dims = -1, (width,) if single else (width, len(value))
    elif isinstance(value, (list, tuple)) and not value:
        type_code, dims, data = -1, (0, 0), b""
    else:
        numbers = np.atleast_1d(np.asarray(value))
        dims = () if np.ndim(value) == 0 else numbers.shape
        if numbers.dtype.kind == "f":
            type_code, data = 4, encode_floats(numbers, processor)
        else:
            type_code, data = 2, encode_ints(numbers, processor)
    body = struct.pack("bB", type_code, len(dims)) + bytes(dims) + data + b"\x00"
    return (struct.pack("bb", len(name), group_id) + name.encode()
            + struct.pack(int16, 2 + len(body)) + body)


def c3d_bytes(positions, residuals=None, *, processor: str = "intel", scale: float = -0.1,
              rate: float = 100.0, labels=None, analog=None, units: str = "mm",
              first_frame: int = 1, groups: dict | None = None, point_used=None,
              analog_samples: int = 1) -> bytes:
    """A complete C3D file.

    Parameters
    ----------
    positions
        (frames, points, 3) coordinates; NaN is stored as NaN (float storage only).
    residuals
        (frames, points) fourth words (-1 for gaps, 65535 for the QTM zero signature);
        default 1.0 everywhere.
    scale
        POINT:SCALE; negative = float storage.
    labels
        POINT labels; more than 255 go to LABELS2; None = M1, M2, ...; fewer than points
        allowed.
    analog
        (frames, words) raw analog words per frame, or None.
    analog_samples
        Analog samples per frame; channels = words / analog_samples.
    groups
        Extra groups: {"MANUFACTURER": {"COMPANY": "Qualisys"}, "POINT": {"ANGLES": [...]}}.
    point_used
        POINT:USED to declare (default: the number of points).
    """
    positions = np.asarray(positions, dtype=np.float64)
    n_frames, n_points, _ = positions.shape
    residuals = np.ones((n_frames, n_points)) if residuals is None else np.asarray(residuals)
    analog = np.zeros((n_frames, 0)) if analog is None else np.asarray(analog)
    labels = [f"M{i + 1}" for i in range(n_points)] if labels is None else list(labels)
    is_float = scale < 0

    point: dict = {"USED": n_points if point_used is None else point_used,
                   "SCALE": float(scale), "RATE": float(rate), "DATA_START": 0,
                   "FRAMES": n_frames, "UNITS": units}
    for i in range(0, max(len(labels), 1), 255):
        point["LABELS" + ("" if i == 0 else str(i // 255 + 1))] = labels[i:i + 255]
    extra = {k: dict(v) for k, v in (groups or {}).items()}
    point.update(extra.pop("POINT", {}))
    channels = analog.shape[1] // analog_samples
    analog_group = {"USED": channels, "RATE": float(rate * analog_samples), "GEN_SCALE": 1.0}
    if channels:  # ezc3d 1.7 crashes on analog channels without these
        analog_group.update({"LABELS": [f"A{i + 1}" for i in range(channels)],
                             "SCALE": [1.0] * channels, "OFFSET": [0] * channels,
                             "UNITS": ["V"] * channels})
    all_groups = {"POINT": point, "ANALOG": analog_group, **extra}

    def section(data_block: int) -> bytes:
        point["DATA_START"] = data_block
        out = b""
        for gid, (gname, params) in enumerate(all_groups.items(), start=1):
            out += (struct.pack("bb", len(gname), -gid) + gname.encode()
                    + struct.pack(">h" if processor == "mips" else "<h", 3) + b"\x00")
            for name, value in params.items():
                out += _param(processor, gid, name, value)
        n_blocks = -(-(4 + len(out) + 2) // 512)
        head = bytes([1, 0x50, n_blocks, PROCESSOR_CODES[processor]])
        return (head + out).ljust(n_blocks * 512, b"\x00")

    n_blocks = len(section(0)) // 512
    params = section(2 + n_blocks)
    data_block = 2 + n_blocks

    header = (bytes([2, 0x50]) + encode_ints([n_points, analog.shape[1], first_frame,
                                              first_frame + n_frames - 1, 0], processor)
              + encode_floats([scale], processor)
              + encode_ints([data_block, analog_samples], processor)
              + encode_floats([rate], processor)).ljust(512, b"\x00")

    if is_float:
        words = np.concatenate([positions, residuals[:, :, None]], axis=2).reshape(n_frames, -1)
        frames = np.concatenate([words, analog], axis=1)
        body = encode_floats(frames, processor)
    else:
        raw = np.where(np.isfinite(positions), np.rint(positions / scale), 0)
        words = np.concatenate([raw, residuals[:, :, None]], axis=2).reshape(n_frames, -1)
        body = encode_ints(np.concatenate([words, analog], axis=1), processor)
    body += b"\x00" * (-len(body) % 512)
    return header + params + body


def write_c3d(path: Path, *args, **kwargs) -> Path:
    path.write_bytes(c3d_bytes(*args, **kwargs))
    return path
