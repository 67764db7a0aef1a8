"""NumPy ``.npz``: arrays ``positions`` (frames, markers, 3), ``observed``, ``labels``,
``rate``, ``units``. Missing samples are stored as NaN and as False in ``observed``.

``rate`` 0 means "not known", as for a C3D without ``POINT:RATE``; a negative or
non-finite rate is a FormatError."""
from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..motion import Motion


def read(path: Path, **_options) -> Motion:
    try:
        with np.load(path, allow_pickle=False) as data:
            positions = np.asarray(data["positions"], dtype=np.float64)
            observed = (np.asarray(data["observed"], bool) if "observed" in data
                        else np.isfinite(positions).all(axis=2))
            labels = [str(s) for s in data["labels"]] if "labels" in data else None
            rate = float(data["rate"]) if "rate" in data else 120.0
            units = str(data["units"]) if "units" in data else "mm"
    except (zipfile.BadZipFile, OSError) as exc:
        raise FormatError(path, f"not a valid .npz archive ({exc})") from None
    except KeyError as exc:
        raise FormatError(path, f"missing array {exc}") from None
    if positions.ndim != 3 or positions.shape[2] != 3:
        raise FormatError(path, f"positions must be (frames, markers, 3), got {positions.shape}")
    if not (np.isfinite(rate) and rate >= 0):
        raise FormatError(path, f"rate is {rate}, not a frame rate (a positive, finite number "
                                "of Hz, or 0 when not known)")
    if labels is None:
        labels = [f"M{j + 1:03d}" for j in range(positions.shape[1])]
    return Motion(positions, observed, tuple(labels), rate, units, path=path)


def write(motion: Motion, path: Path, **_options) -> None:
    with open(path, "wb") as fh:
        np.savez_compressed(fh, positions=motion.positions, observed=motion.observed,
                            labels=np.array(motion.labels, dtype=str),
                            rate=np.float64(motion.rate), units=np.array(motion.units))
