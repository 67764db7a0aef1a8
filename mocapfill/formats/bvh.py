"""BVH (Biovision hierarchy): a joint tree with per-frame channel values.

Reading
    The file is parsed here rather than with the ``bvh`` package: a patching writer needs
    the line of every frame, the End Sites and the channel columns of every joint, which
    ``bvh`` 0.3 does not expose (it has no End-Site accessor and keeps no line positions),
    and its character-by-character tokenizer is slower than splitting lines.

    * ``CHANNELS`` orders are per joint and may differ within a file. Rotation channels
      compose about moving axes in channel order (``Zrotation Xrotation Yrotation`` ->
      R = Rz·Rx·Ry), the convention of bvhio and bvhtoolbox.
    * Position channels *replace* the joint's OFFSET (the root's OFFSET is ignored when the
      root has position channels), as bvhio and bvhtoolbox do.
    * End Sites give a position but no channels; they are labelled ``<parent>_End``.
    * ``nan`` tokens in MOTION lines are gaps (missing channel cells); any other token that
      is not a number is an error.
    * A file with fewer complete frame lines than ``Frames:`` declares (a truncated file) or
      more is rejected with a FormatError giving both counts: a patching writer must not
      echo a damaged file, and the user should know the clip is incomplete. A last frame
      line the file ends inside (no line ending, no whitespace after its last value) is
      not complete when its last value looks cut short: not a number (``-7.``, ``1e``) or
      printed less precisely than the same channel in the other frames and its joint's
      other channels (``8.9931`` cut to ``8.99``; the test of CSV, TRC and AMC,
      ``_text.printed_whole``). Many tools end a file without a line ending, so a last
      value printed like the others is read as data.
    * A ``Frame Time`` that is not a positive, finite number of seconds (``inf``, ``0``,
      ``nan``) is rejected too. ``Frames: 0`` reads as a clip of no frames (``info`` can
      report it); :func:`mocapfill.formats.write` refuses to write a clip of no frames.

The Motion
    Points are the joints in file order, each followed by its End Site, at their FK world
    positions. BVH states no length unit: ``units`` is ``"unknown"`` unless the caller says
    (option ``units=``); option ``scale=`` multiplies positions (the channel values and the
    written file are never scaled). CMU BVH files (cgspeed) use the lengths of the CMU ASF
    files, so ``read(path, scale=56.444, units="mm")`` gives millimetres. The rate is
    ``1 / Frame Time``, rounded to the nearest integer when within 0.01 % of it (files
    write ``.0083333`` for 120 Hz).

Writing
    Only a Motion read from BVH can be written (positions cannot be turned back into
    joint angles). The HIERARCHY block and every frame line are echoed byte for byte,
    except the cells whose observed state changed since reading: a cell filled since then
    gets a number with the file's own number of decimals (at least 4), a cell made
    missing gets ``nan``. Repairs therefore go through :func:`with_channels`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..motion import Motion
from ..skeleton import (
    ChannelState,
    Skeleton,
    check_read_memory,
    motion_with_channels,
    patch_tokens,
    positions_edited,
)
from . import skeleton_input_needed
from ._patch import AsRead, as_read
from ._text import LATIN1_BOM, finite_number, last_value_cut, latin1_label

_TOKEN = re.compile(r"\S+")
_DECIMALS = re.compile(r"\.(\d+)")


@dataclass(frozen=True, eq=False)
class BvhSource:
    """What the BVH writer needs to patch the original file.

    Attributes
    ----------
    lines
        Every line of the file with its own line ending (decoded as Latin-1, so the bytes
        round-trip exactly).
    frame_lines
        Index into ``lines`` of each frame's line.
    channel_names
        ``"<joint>.<channel>"`` for every column of the channel matrix.
    state
        The channel matrix as read and as it is now, with the skeleton.
    decimals
        Decimals written for a filled cell.
    scale
        Factor from file lengths to ``Motion.positions``.
    as_read
        The clip as read, in what a patch cannot change (``formats.write`` refuses to
        patch a clip that differs; the writer checks positions against the channels).
    """

    lines: tuple[str, ...]
    frame_lines: tuple[int, ...]
    channel_names: tuple[str, ...]
    state: ChannelState
    decimals: int
    scale: float = 1.0
    as_read: AsRead | None = None

    @property
    def hierarchy(self) -> str:
        """The text before the first frame line (HIERARCHY block and MOTION header)."""
        return "".join(self.lines[:self.frame_lines[0]] if self.frame_lines else self.lines)


# --------------------------------------------------------------------------- reading

class _Hierarchy:
    """Accumulates joints while walking the HIERARCHY tokens."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self.parents: list[int] = []
        self.offsets: list[list[float]] = []
        self.rotation_columns: list[tuple[int, ...]] = []
        self.rotation_axes: list[str] = []
        self.translation_columns: list[tuple[int, ...]] = []
        self.translation_axes: list[str] = []
        self.channel_names: list[str] = []
        self._taken: set[str] = set()       # the names, for a lookup that is not a scan
        self._copies: dict[str, int] = {}   # name -> the last n of a NAME_n given for it

    def add(self, name: str, parent: int) -> int:
        """Add a joint; a name already taken becomes ``NAME_2``, ``NAME_3`` ..., the first
        of those not taken (labels must be unique: two End Sites of one joint, ...). Names
        only accumulate, so every ``NAME_n`` up to the last one given for NAME is taken and
        the search goes on from there."""
        if name in self._taken:
            base, copy = name, self._copies.get(name, 1)
            while name in self._taken:
                copy += 1
                name = f"{base}_{copy}"
            self._copies[base] = copy
        self._taken.add(name)
        self.names.append(name)
        self.parents.append(parent)
        self.offsets.append([0.0, 0.0, 0.0])
        for per_joint in (self.rotation_columns, self.translation_columns):
            per_joint.append(())
        for per_joint in (self.rotation_axes, self.translation_axes):
            per_joint.append("")
        return len(self.names) - 1

    def set_channels(self, joint: int, channels: list[str]) -> None:
        for channel in channels:
            kind = channel[1:].lower()
            axis = channel[0].upper()
            if axis not in "XYZ" or kind not in ("rotation", "position"):
                raise ValueError(f"unknown channel {channel!r} of joint {self.names[joint]!r}")
            column = (len(self.channel_names),)
            if kind == "rotation":
                self.rotation_columns[joint] += column
                self.rotation_axes[joint] += axis
            else:
                self.translation_columns[joint] += column
                self.translation_axes[joint] += axis
            self.channel_names.append(f"{self.names[joint]}.{channel}")

    def skeleton(self) -> Skeleton:
        offsets = np.array(self.offsets, dtype=np.float64).reshape(-1, 3)
        for j, axes in enumerate(self.translation_axes):
            for axis in axes:                  # position channels replace the OFFSET
                offsets[j, "XYZ".index(axis)] = 0.0
        return Skeleton(tuple(self.names), np.array(self.parents, int), offsets,
                        tuple(self.rotation_columns), tuple(self.rotation_axes),
                        tuple(self.translation_columns), tuple(self.translation_axes),
                        intrinsic=True, n_channels=len(self.channel_names))


def _parse_hierarchy(tokens: list[str]) -> _Hierarchy:
    """Walk ROOT/JOINT/End Site blocks; raises ValueError on a malformed block."""
    tree = _Hierarchy()
    stack: list[int] = []
    pending: int | None = None
    i = 0
    while i < len(tokens):
        word = tokens[i]
        upper = word.upper()
        if upper in ("ROOT", "JOINT"):
            if upper == "JOINT" and not stack:
                raise ValueError("JOINT outside any ROOT")
            if i + 1 == len(tokens):
                raise ValueError(f"{word} without a name")
            pending = tree.add(tokens[i + 1], stack[-1] if stack else -1)
            i += 2
        elif upper == "END":
            if not stack:
                raise ValueError("End Site outside any joint")
            parent_name = tree.names[stack[-1]]
            pending = tree.add(f"{parent_name}_End", stack[-1])
            i += 2
        elif word == "{":
            if pending is None:
                raise ValueError("'{' without a joint")
            stack.append(pending)
            pending = None
            i += 1
        elif word == "}":
            if not stack:
                raise ValueError("unbalanced '}'")
            stack.pop()
            i += 1
        elif upper in ("OFFSET", "CHANNELS") and not stack:
            raise ValueError(f"{word} outside any joint")
        elif upper == "OFFSET":
            tree.offsets[stack[-1]] = [float(t) for t in tokens[i + 1:i + 4]]
            i += 4
        elif upper == "CHANNELS":
            count = _channel_count(tokens, i, tree.names[stack[-1]])
            tree.set_channels(stack[-1], tokens[i + 2:i + 2 + count])
            i += 2 + count
        elif upper == "HIERARCHY":
            i += 1
        else:
            raise ValueError(f"unexpected word {word!r} in HIERARCHY")
    if stack:
        raise ValueError("HIERARCHY ends inside a joint block (missing '}')")
    if not tree.names:
        raise ValueError("HIERARCHY holds no ROOT")
    return tree


def _channel_count(tokens: list[str], at: int, joint: str) -> int:
    """The count of the ``CHANNELS`` word at ``tokens[at]``: a whole number, not negative,
    and not more than the words after it (a negative count would walk the tokens backwards
    or not at all)."""
    if at + 1 == len(tokens):
        raise ValueError(f"CHANNELS of joint {joint!r} without a count")
    text = tokens[at + 1]
    try:
        count = int(text)
    except ValueError:
        raise ValueError(f"CHANNELS count {text!r} of joint {joint!r} is not a whole "
                         "number") from None
    if count < 0:
        raise ValueError(f"CHANNELS count {count} of joint {joint!r} is negative")
    left = len(tokens) - at - 2
    if count > left:
        raise ValueError(f"CHANNELS count {count} of joint {joint!r} runs past the HIERARCHY "
                         f"({left} words follow it)")
    return count


def _header_value(line: str, key: str) -> str:
    """The value of a MOTION header line ``Key: value``; the key's words may be separated
    by any whitespace (``Frame  Time:``, a tab), as the bvh package and others read them."""
    head, _, value = line.partition(":")
    if " ".join(head.split()).lower() != key:
        raise ValueError(f"expected '{key.title()}:' but found {line.strip()!r}")
    return value.strip()


def _rate(frame_time: float) -> float:
    rate = 1.0 / frame_time
    nearest = round(rate)
    return float(nearest) if nearest and abs(rate - nearest) <= 1e-4 * rate else rate


def _file_decimals(frame_text: list[str]) -> int:
    """Most decimals a number has in the first frame lines, kept within [4, 10]."""
    found = max((len(m) for line in frame_text[:50] for m in _DECIMALS.findall(line)),
                default=0)
    return min(max(found, 4), 10)


def _last_value_cut(lines: tuple[str, ...], frame_lines: list[int], rows: list[list[str]],
                    tree: _Hierarchy) -> bool:
    """Whether the file ends inside the last value of its last frame line and that value
    looks cut short (see the module text); ``rows`` hold every frame's tokens, complete."""
    index = frame_lines[-1]
    line = lines[index]
    if index != len(lines) - 1 or line.endswith(("\n", "\r")) or line[-1].isspace():
        return False
    last = len(rows[-1]) - 1
    column = [row[last] for row in rows[:-1] if finite_number(row[last])]
    joint = next(rotation + translation for rotation, translation
                 in zip(tree.rotation_columns, tree.translation_columns)
                 if last in rotation + translation)
    row = [rows[-1][c] for c in joint if c != last and finite_number(rows[-1][c])]
    # With nothing to compare it with (one frame), a number is read as written.
    return last_value_cut(rows[-1][-1], column, row, alone=False)


def _read_source(path: Path, scale: float) -> tuple[BvhSource, float]:
    lines = tuple(path.read_bytes().decode("latin-1").splitlines(keepends=True))
    starts = [i for i, line in enumerate(lines) if line.strip().upper() == "MOTION"]
    if not starts:
        raise FormatError(path, "no MOTION section (is this a BVH file?)")
    motion_at = starts[0]
    try:
        tree = _parse_hierarchy(_TOKEN.findall("".join(lines[:motion_at])
                                               .removeprefix(LATIN1_BOM)))
    except (ValueError, IndexError) as exc:
        raise FormatError(path, f"bad HIERARCHY: {exc}") from None
    rest = [i for i in range(motion_at + 1, len(lines)) if lines[i].strip()]
    if len(rest) < 2:
        raise FormatError(path, "MOTION section lacks 'Frames:' and 'Frame Time:'")
    try:
        declared = int(_header_value(lines[rest[0]], "frames"))
        if declared < 0:
            raise ValueError(f"'Frames: {declared}' is not a number of frames")
        frame_time_text = _header_value(lines[rest[1]], "frame time")
        frame_time = float(frame_time_text)
    except ValueError as exc:
        raise FormatError(path, f"bad MOTION header: {exc}") from None
    if not (np.isfinite(frame_time) and frame_time > 0 and np.isfinite(1.0 / frame_time)):
        raise FormatError(path, f"Frame Time is {frame_time_text!r}, not a frame time (a "
                                "positive, finite number of seconds)")
    frame_lines = rest[2:]
    n_channels = len(tree.channel_names)
    rows = [lines[i].split() for i in frame_lines]
    cut_short = ""
    for number, (i, row) in enumerate(zip(frame_lines, rows)):
        if len(row) != n_channels:
            if number == len(rows) - 1 and len(row) < n_channels and number < declared:
                cut_short = f" (line {i + 1} is cut short)"
                rows.pop()
                break
            raise FormatError(path, f"line {i + 1} holds {len(row)} values, "
                                    f"the HIERARCHY declares {n_channels} channels")
    if not cut_short and rows and _last_value_cut(lines, frame_lines[:len(rows)], rows, tree):
        cut_short = f" (line {frame_lines[len(rows) - 1] + 1} is cut short)"
        rows.pop()
    if len(rows) != declared:
        what = "truncated" if len(rows) < declared else "too many frames"
        raise FormatError(path, f"{what}: {len(rows)} complete frames read, {declared} "
                                f"declared{cut_short}")
    check_read_memory(path, len(rows), len(tree.names), n_channels)
    try:
        values = np.array(rows, dtype=np.float64).reshape(len(rows), n_channels)
    except ValueError as exc:
        raise FormatError(path, f"non-numeric value in MOTION ({exc})") from None
    if np.isinf(values).any():
        raise FormatError(path, "infinite value in MOTION")
    state = ChannelState.as_read(tree.skeleton(), values)
    source = BvhSource(lines, tuple(frame_lines), tuple(tree.channel_names), state,
                       _file_decimals([lines[i] for i in frame_lines]), scale)
    return source, _rate(frame_time)


def _motion(source: BvhSource, rate: float, units: str, path: Path | None) -> Motion:
    positions, observed = source.state.points()
    labels = tuple(latin1_label(name) for name in source.state.skeleton.names)
    source = replace(source, as_read=as_read(labels, rate, units, 1, None, positions))
    return Motion(positions * source.scale, observed, labels, rate, units, source=source,
                  path=path)


def read(path: Path, *, units: str = "unknown", scale: float = 1.0,
         rate: float | None = None) -> Motion:
    """Read a BVH file; points are joint and End Site positions from FK.

    Parameters
    ----------
    path
        The ``.bvh`` file.
    units
        Label of the length unit (BVH files do not state one).
    scale
        Factor applied to positions (not to the channels or the written file).
    rate
        Not used: a BVH states its rate (``Frame Time``; a file whose ``Frame Time`` is
        not a positive number is refused). Taken, as every reader takes it, so that one
        call reads a clip in any format (``rate=120`` for CMU clips, whose AMCs state
        none).

    Returns
    -------
    Motion
        With ``source`` a :class:`BvhSource` for :func:`write`, :func:`channels` and
        :func:`with_channels`.
    """
    source, rate = _read_source(Path(path), float(scale))
    return _motion(source, rate, units, Path(path))


# --------------------------------------------------------------------------- channel space

def _source(motion: Motion, path: Path | None = None) -> BvhSource:
    if not isinstance(motion.source, BvhSource):
        raise FormatError(path, skeleton_input_needed(".bvh"))
    return motion.source


def channels(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The clip's channel matrix, rotation channels unwrapped along time.

    Returns
    -------
    tuple of numpy.ndarray
        (frames, channels) float64 values in degrees / file lengths, NaN where missing, and
        the (frames, channels) bool observed mask.
    """
    return _source(motion).state.unwrapped()


def with_channels(motion: Motion, values: np.ndarray, observed: np.ndarray) -> Motion:
    """A copy of ``motion`` driven by a new channel matrix.

    Parameters
    ----------
    motion
        A Motion read from BVH.
    values
        (frames, channels) new values (rotation channels may be unwrapped).
    observed
        (frames, channels) bool, True where ``values`` hold data.

    Returns
    -------
    Motion
        Cells observed before keep their stored value, newly observed cells take
        ``values`` wrapped into the range their channel used; positions are recomputed by
        FK and the source carries the new matrix for :func:`write`.
    """
    return motion_with_channels(motion, _source(motion), values, observed)


# --------------------------------------------------------------------------- writing

def patches(motion: Motion) -> bool:
    """Whether :func:`write` can write ``motion``: as a patch of the BVH it was read from,
    the only way it writes."""
    return isinstance(motion.source, BvhSource)


def write(motion: Motion, path: Path, **_options) -> None:
    """Write a repaired BVH by patching the file the Motion was read from.

    Raises
    ------
    FormatError
        When the Motion did not come from BVH, or its positions were edited without going
        through :func:`with_channels`.
    """
    source = _source(motion, path)
    state = source.state
    differing = positions_edited(motion, state, source.scale)
    if differing:
        raise FormatError(path, f"positions were changed outside channel space ({differing} "
                                "samples disagree with the channels); BVH stores joint "
                                "angles, which a repair fills with mocapfill.repair(motion, "
                                "RepairOptions(space='channels')), as the command line does")
    lines = list(source.lines)
    changed = state.changed_cells()
    for frame in np.flatnonzero(changed.any(axis=1)):
        cells = {int(c): (f"{state.values[frame, c]:.{source.decimals}f}"
                          if state.observed[frame, c] else "nan")
                 for c in np.flatnonzero(changed[frame])}
        index = source.frame_lines[frame]
        lines[index] = patch_tokens(lines[index], cells)
    Path(path).write_bytes("".join(lines).encode("latin-1"))
