"""Forward kinematics and channel-space helpers shared by the skeleton formats (BVH, ASF/AMC).

A skeleton file stores a *channel matrix*: one row per frame, one column per channel (a
joint angle in degrees or a root translation). Marker-like positions are derived from it by
forward kinematics (FK), all frames at once.

One joint model covers both formats. For joint ``j`` with parent ``p``::

    L_j = C_j @ M_j @ C_j.T             M_j from the joint's rotation channels,
                                        C_j a fixed pre-rotation (identity in BVH)
    W_j = W_p @ L_j                     world rotation (W of the root's parent = I)
    p_j = p_p + F_j @ (offset_j + t_j)  F_j = W_p (BVH: the offset lives in the parent
                                        frame) or W_j (ASF: the bone vector turns with
                                        the bone); t_j = translation channels (else 0)

BVH: rotation channels are *intrinsic* in channel order (``Zrotation Xrotation
Yrotation`` -> R = Rz·Rx·Ry), the point is the joint (start of its bone). ASF/AMC: the dof
angles are rotations about *fixed* axes in dof order (``rx ry rz`` -> R = Rz·Ry·Rx), and
the point is the bone's end.

A point is observed in a frame when every channel that moves it is observed there: the
translation and rotation channels of its ancestors, its own translation channels and, when
its offset turns with its own frame (ASF bones), its own rotation channels.

Rotation channels are unwrapped along time before a repair (so that a completion method
sees continuous signals) and filled cells are wrapped back into the range the file used,
or, where the file stores a channel unwrapped, joined to the stored values beside them.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .motion import Motion

# How a rotation channel's stored values are wrapped. The number is the lower end of the
# 360-degree window; NaN means "the file stores continuous angles, do not wrap".
WRAP_SIGNED = -180.0      # (-180, 180]
WRAP_POSITIVE = 0.0       # [0, 360)


@dataclass(frozen=True, eq=False)
class Skeleton:
    """A kinematic tree whose joints are driven by columns of a channel matrix.

    Attributes
    ----------
    names
        Point names, parents before children.
    parents
        (joints,) int index of each joint's parent, -1 for a root.
    offsets
        (joints, 3) rest translation of each joint from its parent (see the module text for
        the frame it is expressed in).
    rotation_columns
        Per joint, the channel-matrix columns of its rotation channels, in channel order.
    rotation_axes
        Per joint, the axis letters of those channels ("ZXY"; "" when none).
    translation_columns
        Per joint, the columns of its translation channels (added to the offset).
    translation_axes
        Per joint, the axis letters of those channels ("XYZ"; "" when none).
    intrinsic
        True when rotation channels compose about moving axes (BVH), False for fixed axes
        (ASF/AMC).
    pre_rotations
        (joints, 3, 3) fixed frame ``C_j`` of each joint, or None for identity everywhere.
    offset_in_own_frame
        (joints,) bool; True where the offset turns with the joint's own rotation (ASF
        bones), False where it is expressed in the parent's frame (BVH, ASF root).
    n_channels
        Number of columns of the channel matrix.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    rotation_columns: tuple[tuple[int, ...], ...]
    rotation_axes: tuple[str, ...]
    translation_columns: tuple[tuple[int, ...], ...]
    translation_axes: tuple[str, ...]
    intrinsic: bool
    n_channels: int
    pre_rotations: np.ndarray | None = None
    offset_in_own_frame: np.ndarray | None = None

    def __post_init__(self) -> None:
        parents = np.asarray(self.parents, dtype=int)
        for j, parent in enumerate(parents):
            if parent >= j:
                raise ValueError(f"joint {self.names[j]!r} comes before its parent")
        own = (np.zeros(len(parents), bool) if self.offset_in_own_frame is None
               else np.asarray(self.offset_in_own_frame, bool))
        object.__setattr__(self, "parents", parents)
        object.__setattr__(self, "offsets", np.asarray(self.offsets, dtype=np.float64))
        object.__setattr__(self, "offset_in_own_frame", own)

    @property
    def n_joints(self) -> int:
        return len(self.names)

    @property
    def rotation_channel(self) -> np.ndarray:
        """(channels,) bool, True for rotation (angle) channels."""
        mask = np.zeros(self.n_channels, bool)
        for columns in self.rotation_columns:
            mask[list(columns)] = True
        return mask


# What reading a skeleton clip takes, per frame: READ_BYTES_PER_POINT for each point (its
# FK positions and their copies: NaN where missing, scaled, the Motion's own) and
# READ_BYTES_PER_CHANNEL for each channel (the channel matrix, its mask, the state's copy),
# above what tracemalloc measured of AMCs of 4,000 frames without bone lines: 101 points
# and 306 channels 58 MiB (estimated 65), 201 points and 606 channels 103 MiB (129), 101
# points and 6 channels 32 MiB (38). The file's lines are not counted: they grow with
# its size, not with its frames × points. (The pipeline counts its windows' bytes so:
# WINDOW_BYTES_PER_CELL.)
READ_BYTES_PER_POINT = 96
READ_BYTES_PER_CHANNEL = 24
# A clip that would take more is refused before its matrices are built: an AMC frame
# costs 2 bytes of file ("1\n", all its bones absent), and 100 KB of them against an ASF of
# 2,000 bones took more than 4 GB. A 30-minute CMU clip at 120 Hz (31 points, 62
# channels) takes 0.9 GB, a 60-fps iClone BVH of 141 points and 303 channels 57 minutes.
MAX_READ_MEMORY = 4 << 30


def read_memory(n_frames: int, n_points: int, n_channels: int) -> int:
    """About how many bytes reading a clip of these sizes takes (see
    :data:`READ_BYTES_PER_POINT`)."""
    return n_frames * (n_points * READ_BYTES_PER_POINT + n_channels * READ_BYTES_PER_CHANNEL)


def check_read_memory(path, n_frames: int, n_points: int, n_channels: int) -> None:
    """A FormatError naming ``path`` and the sizes where a clip of ``n_frames`` frames,
    ``n_points`` points and ``n_channels`` channels would take more than
    :data:`MAX_READ_MEMORY` to read (called by the readers before forward kinematics)."""
    from .errors import FormatError

    needed = read_memory(n_frames, n_points, n_channels)
    if needed > MAX_READ_MEMORY:
        raise FormatError(path, f"{n_frames} frames of {n_points} points ({n_channels} "
                                f"channels) would take about {_amount(needed)} to read, more "
                                f"than the {_amount(MAX_READ_MEMORY)} a skeleton clip may take")


def _amount(n_bytes: int) -> str:
    return (f"{n_bytes / 2**30:.1f} GB" if n_bytes >= 1 << 30
            else f"{n_bytes / 2**20:.1f} MB")


def euler_matrices(axes: str, angles: np.ndarray, intrinsic: bool, *,
                   degrees: bool = True) -> np.ndarray:
    """Rotation matrices of per-frame Euler angles.

    Parameters
    ----------
    axes
        Axis letters in the order the angles are given ("ZXY", "xz", ...); any case.
    angles
        (frames, len(axes)) angles, in degrees (radians with ``degrees=False``).
    intrinsic
        True: rotate about the moving axes (R = R_first · R_second · ...); False: about
        the fixed axes (R = ... · R_second · R_first).

    Returns
    -------
    numpy.ndarray
        (frames, 3, 3) matrices acting on column vectors.
    """
    angles = np.asarray(angles, dtype=np.float64)
    if not axes:
        return np.broadcast_to(np.eye(3), (angles.shape[0], 3, 3)).copy()
    if len(axes) > 3 or any(axis not in "xyzXYZ" for axis in axes):
        raise ValueError(f"Euler axes must be up to three of x, y, z, got {axes!r}")
    # Written out rather than through scipy.spatial.transform.Rotation, whose import (all
    # of scipy.spatial) took 0.35–0.41 s of every command reading a BVH or ASF/AMC file.
    radians = angles.reshape(-1, len(axes))
    if degrees:
        radians = np.radians(radians)
    matrices = _axis_rotations(axes[0], radians[:, 0])
    for k in range(1, len(axes)):
        turn = _axis_rotations(axes[k], radians[:, k])
        matrices = matrices @ turn if intrinsic else turn @ matrices
    return matrices


def _axis_rotations(axis: str, radians: np.ndarray) -> np.ndarray:
    """(frames, 3, 3) rotations by ``radians`` about the x, y or z axis (acting on column
    vectors, counter-clockwise seen from the axis's tip)."""
    i = "xyz".index(axis.lower())
    j, k = (i + 1) % 3, (i + 2) % 3
    cos, sin = np.cos(radians), np.sin(radians)
    out = np.zeros(radians.shape + (3, 3))
    out[:, i, i] = 1.0
    out[:, j, j] = cos
    out[:, j, k] = -sin
    out[:, k, j] = sin
    out[:, k, k] = cos
    return out


def forward_kinematics(skeleton: Skeleton, values: np.ndarray) -> np.ndarray:
    """World positions of every joint in every frame.

    Parameters
    ----------
    skeleton
        The kinematic tree.
    values
        (frames, channels) channel matrix, angles in degrees. Missing cells (NaN) are
        treated as 0; mask the result with :func:`observed_points`.

    Returns
    -------
    numpy.ndarray
        (frames, joints, 3) positions in the units of the offsets.
    """
    values = np.asarray(values, dtype=np.float64)
    n_frames = values.shape[0]
    positions = np.empty((n_frames, skeleton.n_joints, 3))
    # By blocks of frames: the world rotations of every joint (72 bytes a joint and frame)
    # and each joint's temporaries (some 400 bytes a frame) for the whole clip took a
    # 10 MB AMC of 5,000,000 frames to 5.5 GB.
    step = max(1, min(FK_BLOCK_FRAMES, FK_BLOCK_POINTS // max(1, skeleton.n_joints)))
    for start in range(0, n_frames, step):
        block = slice(start, start + step)
        _forward_block(skeleton, np.nan_to_num(values[block], nan=0.0), positions[block])
    return positions


# A block of :func:`forward_kinematics` holds up to FK_BLOCK_POINTS frames × joints (18 MB
# of world rotations) and FK_BLOCK_FRAMES frames (a joint's temporaries: 7 MB).
FK_BLOCK_POINTS = 1 << 18
FK_BLOCK_FRAMES = 1 << 14


def _forward_block(skeleton: Skeleton, values: np.ndarray, positions: np.ndarray) -> None:
    """:func:`forward_kinematics` of a block of frames (no NaN), into ``positions``."""
    n_frames = values.shape[0]
    world_rot = np.empty((n_frames, skeleton.n_joints, 3, 3))
    identity = np.broadcast_to(np.eye(3), (n_frames, 3, 3))
    for j, parent in enumerate(skeleton.parents):
        local = euler_matrices(skeleton.rotation_axes[j],
                               values[:, list(skeleton.rotation_columns[j])], skeleton.intrinsic)
        if skeleton.pre_rotations is not None:
            frame = skeleton.pre_rotations[j]
            local = frame @ local @ frame.T
        parent_rot = identity if parent < 0 else world_rot[:, parent]
        parent_pos = 0.0 if parent < 0 else positions[:, parent]
        world_rot[:, j] = parent_rot @ local
        translation = np.broadcast_to(skeleton.offsets[j], (n_frames, 3)).copy()
        for axis, column in zip(skeleton.translation_axes[j], skeleton.translation_columns[j]):
            translation[:, "XYZ".index(axis.upper())] += values[:, column]
        turn = world_rot[:, j] if skeleton.offset_in_own_frame[j] else parent_rot
        positions[:, j] = parent_pos + (turn @ translation[:, :, None])[:, :, 0]


def observed_points(skeleton: Skeleton, observed: np.ndarray) -> np.ndarray:
    """Which joint positions are known, given which channel cells are.

    Parameters
    ----------
    skeleton
        The kinematic tree.
    observed
        (frames, channels) bool, True where a channel cell is present.

    Returns
    -------
    numpy.ndarray
        (frames, joints) bool, True where every channel that moves the joint is observed.
    """
    observed = np.asarray(observed, bool)
    n_frames = observed.shape[0]
    frame_ok = np.empty((n_frames, skeleton.n_joints), bool)
    point_ok = np.empty((n_frames, skeleton.n_joints), bool)
    for j, parent in enumerate(skeleton.parents):
        parent_frame = np.ones(n_frames, bool) if parent < 0 else frame_ok[:, parent]
        parent_point = np.ones(n_frames, bool) if parent < 0 else point_ok[:, parent]
        rotation_ok = observed[:, list(skeleton.rotation_columns[j])].all(axis=1)
        translation_ok = observed[:, list(skeleton.translation_columns[j])].all(axis=1)
        frame_ok[:, j] = parent_frame & rotation_ok
        turn_ok = frame_ok[:, j] if skeleton.offset_in_own_frame[j] else parent_frame
        point_ok[:, j] = parent_point & translation_ok & turn_ok
    return point_ok


def moving_channels(skeleton: Skeleton, joint: int) -> np.ndarray:
    """The channel columns (sorted) that move ``joint``'s point: those whose missing cell
    hides it in :func:`observed_points`. They are the translation and rotation channels
    of its ancestors, its own translation channels and, where its offset turns with its
    own frame (ASF bones), its own rotation channels.

    Found by walking the joint's ancestors: ``~observed_points(skeleton, ~np.eye(channels))``
    gives the same for every joint at once, but as a channels × channels matrix and a
    channels × joints one (20,000 joints of 3 channels: 5.9 GB).
    """
    columns = list(skeleton.translation_columns[joint])
    if skeleton.offset_in_own_frame[joint]:
        columns += skeleton.rotation_columns[joint]
    ancestor = skeleton.parents[joint]
    while ancestor >= 0:
        columns += skeleton.rotation_columns[ancestor]
        columns += skeleton.translation_columns[ancestor]
        ancestor = skeleton.parents[ancestor]
    return np.unique(np.array(columns, dtype=np.intp))


def wrap_windows(values: np.ndarray, observed: np.ndarray,
                 rotation_channel: np.ndarray) -> np.ndarray:
    """The wrapping window each rotation channel's stored values use.

    Returns
    -------
    numpy.ndarray
        (channels,) lower end of the window: :data:`WRAP_SIGNED` when every observed value
        lies in [-180, 180], :data:`WRAP_POSITIVE` when they lie in [0, 360] but not the
        former, NaN for translation channels and for channels stored unwrapped.
    """
    windows = np.full(values.shape[1], np.nan)
    for c in np.flatnonzero(rotation_channel):
        column = values[observed[:, c], c]
        if column.size == 0 or (column.min() >= -180.0 and column.max() <= 180.0):
            windows[c] = WRAP_SIGNED
        elif column.min() >= 0.0 and column.max() <= 360.0:
            windows[c] = WRAP_POSITIVE
    return windows


def unwrap_rotations(values: np.ndarray, observed: np.ndarray,
                     rotation_channel: np.ndarray) -> np.ndarray:
    """Remove the 360-degree jumps of rotation channels along time.

    Each rotation column is unwrapped over its observed cells only (a jump across a gap is
    taken to be the shortest one); missing cells stay NaN, translation columns are copied.
    """
    result = np.where(observed, values, np.nan)
    for c in np.flatnonzero(rotation_channel):
        rows = np.flatnonzero(observed[:, c])
        if rows.size > 1:
            result[rows, c] = np.unwrap(values[rows, c], period=360.0)
    return result


def wrap_into(values: np.ndarray, windows: np.ndarray) -> np.ndarray:
    """Wrap each column into its window (see :func:`wrap_windows`); NaN windows pass."""
    values = np.array(values, dtype=np.float64)
    signed = windows == WRAP_SIGNED
    positive = windows == WRAP_POSITIVE
    values[:, signed] = 180.0 - np.mod(180.0 - values[:, signed], 360.0)
    values[:, positive] = np.mod(values[:, positive], 360.0)
    return values


@dataclass(frozen=True, eq=False)
class ChannelState:
    """The channel matrix of a clip, as read and as it is now.

    Attributes
    ----------
    skeleton
        The kinematic tree the channels drive.
    values
        (frames, channels) current channel values as stored (wrapped), NaN where missing.
    observed
        (frames, channels) bool, current mask.
    original_values
        The matrix as read from the file.
    original_observed
        The mask as read from the file (False at ``nan`` cells and absent lines).
    windows
        (channels,) wrapping window of each channel, from :func:`wrap_windows`.
    """

    skeleton: Skeleton
    values: np.ndarray
    observed: np.ndarray
    original_values: np.ndarray
    original_observed: np.ndarray
    windows: np.ndarray

    @classmethod
    def as_read(cls, skeleton: Skeleton, values: np.ndarray) -> ChannelState:
        """The state of a freshly read matrix; its NaN cells are the gaps."""
        values = np.asarray(values, dtype=np.float64)
        observed = np.isfinite(values)
        values = np.where(observed, values, np.nan)
        windows = wrap_windows(values, observed, skeleton.rotation_channel)
        return cls(skeleton, values, observed, values, observed, windows)

    def unwrapped(self) -> tuple[np.ndarray, np.ndarray]:
        """The current matrix with rotation channels unwrapped, and its mask (copies)."""
        return (unwrap_rotations(self.values, self.observed, self.skeleton.rotation_channel),
                self.observed.copy())

    def updated(self, values: np.ndarray, observed: np.ndarray) -> ChannelState:
        """A state holding new values where cells became observed.

        Cells observed now and before keep their stored value (a repair restores what was
        observed, and an unwrapped copy may differ from it by a multiple of 360); cells
        observed only now take ``values`` wrapped into their channel's window, or, in a
        channel the file stores unwrapped (no window), moved by the whole turns that
        separate ``values`` from the stored value at the cell observed before (after, at
        the start): an unwrapped copy of such a channel may be whole turns off the file
        from a step over 180 degrees on (a gap in a steep stretch), and its fills were
        written that far from their stored neighbours. Cells not observed become NaN.
        """
        values = np.asarray(values, dtype=np.float64)
        observed = np.asarray(observed, bool)
        if values.shape != self.values.shape or observed.shape != self.values.shape:
            raise ValueError(f"channel matrix must be {self.values.shape}, got "
                             f"{values.shape} values and {observed.shape} mask")
        observed = observed & np.isfinite(values)
        filled = wrap_into(values, self.windows)
        unwrapped = self.skeleton.rotation_channel & np.isnan(self.windows)
        rows = np.arange(values.shape[0])
        for c in np.flatnonzero(unwrapped & self.observed.any(axis=0)):
            seen = self.observed[:, c]
            before = np.maximum.accumulate(np.where(seen, rows, -1))
            after = np.minimum.accumulate(np.where(seen, rows, rows.size)[::-1])[::-1]
            reference = np.where(before >= 0, before, after)
            turns = np.round((self.values[reference, c] - values[reference, c]) / 360.0)
            filled[:, c] += 360.0 * np.nan_to_num(turns)
        new = np.where(self.observed, self.values, filled)
        return replace(self, values=np.where(observed, new, np.nan), observed=observed)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """FK positions (frames, joints, 3), NaN where missing, and their observed mask."""
        observed = observed_points(self.skeleton, self.observed)
        positions = forward_kinematics(self.skeleton, self.values)
        return np.where(observed[:, :, None], positions, np.nan), observed

    def changed_cells(self) -> np.ndarray:
        """(frames, channels) bool: cells whose observed state differs from the file's."""
        return self.observed != self.original_observed


def positions_edited(motion: Motion, state: ChannelState, scale: float = 1.0) -> int:
    """How many samples of ``motion`` disagree with its channel state (``scale``: the
    reader's factor from file lengths to positions): observed or not, or, observed in
    both, in value.

    A skeleton writer writes channels; a Motion whose positions were filled, blanked or
    moved (an offset, smoothing) without going through the channels would lose those
    edits silently. The positions are compared exactly: the reader and
    :func:`motion_with_channels` compute them from the channels as here.
    """
    positions, expected = state.points()
    if expected.shape != motion.observed.shape:
        return int(max(expected.size, motion.observed.size))
    differs = expected != motion.observed
    both = expected & motion.observed
    differs[both] |= (positions[both] * scale != motion.positions[both]).any(axis=1)
    return int(differs.sum())


_TOKEN = re.compile(r"\S+")


def patch_tokens(line: str, cells: dict[int, str]) -> str:
    """``line`` with its whitespace-separated tokens at the given indices replaced.

    Everything else (separators, trailing spaces, the line ending) is kept byte for byte.
    """
    pieces, last = [], 0
    for index, match in enumerate(_TOKEN.finditer(line)):
        if index in cells:
            pieces.append(line[last:match.start()])
            pieces.append(cells[index])
            last = match.end()
    pieces.append(line[last:])
    return "".join(pieces)


def motion_with_channels(motion: Motion, source, values: np.ndarray,
                         observed: np.ndarray) -> Motion:
    """A copy of ``motion`` driven by a new channel matrix (shared by BVH and AMC).

    ``source`` is the format's handle (it has ``state`` and ``scale``). Cells observed
    before keep their stored value; newly observed cells take ``values`` wrapped into the
    range their channel used; positions are recomputed by FK and the returned Motion's
    source carries the new matrix for the format's writer.
    """
    source = replace(source, state=source.state.updated(values, observed))
    positions, point_observed = source.state.points()
    return motion.with_positions(positions * source.scale, point_observed).replace(source=source)
