"""What a patch of a clip's own file keeps as read, and whether a clip still agrees with it.

A writer given a Motion read from its own format patches a copy of that file: it writes
the samples whose observed state changed since reading (filled, or made missing by
``simulate``) and echoes everything else as the file holds it. The patch therefore holds
the clip only while the clip agrees with the file on everything else: its frames, its
points (labels, and which are markers), its first frame, rate and units, and the values
of the samples observed in both. A reader keeps those as an :class:`AsRead` in its source
handle; :func:`mocapfill.formats.write` refuses a patch of a clip that differs
(:func:`differences`) rather than write a file that says something else: a clip
converted to metres wrote a file whose header said mm, with the original samples in mm
and the filled ones in m, and an edit of observed samples (smoothing, an offset) was
dropped without a word.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..motion import Motion

# Odd multipliers (splitmix64's): a product by one is a bijection of the 64-bit words.
_MIX = (np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9),
        np.uint64(0x94D049BB133111EB))
# Samples per block of :func:`sample_digest` (1 MB of coordinates a block).
_DIGEST_SAMPLES = 1 << 15


@dataclass(frozen=True, eq=False)
class AsRead:
    """The clip as its reader made it, in what a patch of its file cannot change.

    Attributes
    ----------
    labels, rate, units, first_frame, fillable
        The Motion's fields as read.
    shape
        (frames, points) as read.
    observed
        (frames, points) mask as read, or None where ``digest`` is None.
    digest
        (frames, points) :func:`sample_digest` of the positions as read, or None for a
        skeleton format, whose writer checks the positions against the joint channels it
        writes (every sample, filled ones too: ``skeleton.positions_edited``).
    """

    labels: tuple[str, ...]
    rate: float
    units: str
    first_frame: int
    fillable: np.ndarray
    shape: tuple[int, int]
    observed: np.ndarray | None = None
    digest: np.ndarray | None = None


def as_read(labels: Sequence[str], rate: float, units: str, first_frame: int,
            fillable: np.ndarray | None, positions: np.ndarray,
            observed: np.ndarray | None = None) -> AsRead:
    """An :class:`AsRead` of the values a reader gives its Motion (normalised as the
    Motion normalises them); with ``observed``, the mask and a digest of the positions
    too. Built from the values rather than the Motion, so that a reader does not build
    its Motion twice (a long clip's check and copy take most of a second)."""
    shape = positions.shape[:2]
    fillable = (np.ones(shape[1], bool) if fillable is None
                else np.array(fillable, dtype=bool))
    digest = None if observed is None else sample_digest(positions)
    return AsRead(tuple(str(label) for label in labels), float(rate), units,
                  int(first_frame), fillable, shape, observed, digest)


def of_motion(motion: Motion, values: bool = True) -> AsRead:
    """An :class:`AsRead` of ``motion`` as a reader returns it (``values``: with the
    mask and digest of its positions)."""
    return as_read(motion.labels, motion.rate, motion.units, motion.first_frame,
                   motion.fillable, motion.positions, motion.observed if values else None)


def sample_digest(positions: np.ndarray) -> np.ndarray:
    """(frames, points) uint64: a digest of each sample's three coordinates.

    The bit patterns of x, y and z are mixed in turn (times an odd number, exclusive-or
    with the next), so a change of one coordinate always changes the digest, and of two or
    three with odds of 2**-64: a third of the memory of a copy of the positions, which a
    long clip would hold for its whole life (216,000 frames of 41 markers: 71 MB against
    212 MB). ``-0.0`` counts as ``0.0`` (the same value: ``x + 0`` turns one into the
    other).
    """
    frames, points = positions.shape[:2]
    flat = positions.reshape(-1, 3)
    digest = np.empty(frames * points, np.uint64)
    for start in range(0, flat.shape[0], _DIGEST_SAMPLES):   # by blocks: no full temporaries
        block = flat[start:start + _DIGEST_SAMPLES] + 0.0
        bits = block.view(np.uint64)
        mixed = bits[:, 0] * _MIX[0]
        mixed ^= bits[:, 1]
        mixed *= _MIX[1]
        mixed ^= bits[:, 2]
        mixed *= _MIX[2]
        digest[start:start + _DIGEST_SAMPLES] = mixed
    return digest.reshape(frames, points)


def differences(motion: Motion, read: AsRead) -> list[str]:
    """What of ``motion`` a patch of the file it was read from cannot hold: one phrase per
    difference from ``read`` (empty when it agrees)."""
    if motion.observed.shape != read.shape:
        frames, points = read.shape
        return [f"its size ({motion.n_frames} frames of {motion.n_markers} points, read as "
                f"{frames} of {points})"]
    found = []
    renamed = [j for j, (now, then) in enumerate(zip(motion.labels, read.labels))
               if now != then]
    if renamed:
        j = renamed[0]
        found.append(f"{len(renamed)} label(s) ({motion.labels[j]!r}, read as "
                     f"{read.labels[j]!r})")
    if not np.array_equal(motion.fillable, read.fillable):
        found.append("which points are markers (fillable)")
    if motion.first_frame != read.first_frame:
        found.append(f"its first frame ({motion.first_frame}, read as {read.first_frame})")
    if motion.rate != read.rate:            # (finite, as a Motion's rate must be)
        found.append(f"its rate ({motion.rate:g} Hz, read as {read.rate:g} Hz)")
    if motion.units != read.units:
        found.append(f"its units ({motion.units}, read as {read.units})")
    if read.digest is not None:
        changed = sample_digest(motion.positions) != read.digest
        changed &= motion.observed
        changed &= read.observed
        count = int(np.count_nonzero(changed))
        if count:
            frame, point = divmod(int(np.argmax(changed.reshape(-1))), read.shape[1])
            found.append(f"the values of {count} sample{'s' if count > 1 else ''} observed "
                         f"in the file (first: {motion.labels[point]}, frame "
                         f"{motion.first_frame + frame})")
    return found
