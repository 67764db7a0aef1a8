"""ASF/AMC (Acclaim; the CMU Motion Capture Database): a skeleton file and a motion file.

The user passes the ``.amc``; its ``.asf`` is looked for beside it: the same stem
(``09_12.asf``), then the subject prefix before the first ``_`` (``09.asf``), then the only
``.asf`` in the folder. Option ``asf=`` names it explicitly.

Parsing is done here because both PyPI parsers fail on CMU files (they expect a fixed
keyword order, dof and limits on every bone, and one drops the last frame). The parser is
tolerant in the ways the Acclaim text allows: ``#`` comments, ``(``, ``)`` and ``,`` are
whitespace, ``:keyword`` sections in any order, keys in any order inside ``:root`` and a
bone block, bones without ``dof``, ``limits`` wrapped over lines. Bone dofs may be any
subset and order of ``rx ry rz``; translation dofs (``tx ty tz l``) are rejected. AMC
angles are degrees under ``:DEGREES`` and radians otherwise; the channel matrix always
holds degrees and the writer converts back.

Kinematics (canonical Acclaim, column vectors): for bone ``j`` with fixed frame
``C_j = Rot(axis_j)`` and dof rotation ``M_j`` (rotations about fixed axes in dof order,
``rx ry rz`` -> Rz·Ry·Rx), ``W_j = W_parent @ C_j @ M_j @ C_j.T`` and the bone's END point
is ``p_j = p_parent + length_j * W_j @ direction_j``. The root is at ``TX TY TZ`` plus its
``position``. Points of the Motion are ``root`` and the end point of every bone, labelled
with the bone name (so a BVH converted from the same ASF has the point of ``lfemur``'s end
at the joint *below* it, ``LeftLeg``).

AMC files declare no frame count: a bone line absent from a frame, or a ``nan`` value, is a
gap, not an error. A bone line with the wrong number of values is an error, except in the
line a file ends inside. A file that does not end with a line ending is read whole (many
tools end a file so) unless its last line shows that the file was cut short inside it
(``_looks_cut``): the bone line holds fewer values than its dofs, or its last value is not
a number or is printed less precisely than the same dof in the other frames and the
line's other values (``-17.3198`` cut to ``-17.3``; the test of CSV and TRC,
``_text.printed_whole``). Then the last value of that line is read as missing (unless
whitespace follows it), values absent from it are missing, and the source's notes say
so; a frame number or bone name the last line holds alone starts no frame and is not
read.

Units: the ASF's ``:units length`` is a divisor of the file's lengths; by the CMU
convention the unit before that division is the inch. By default positions stay in file
units, labelled ``"in/0.45"`` for CMU (``"in"`` when ``length`` is 1); ``units="mm"``,
``"cm"``, ``"m"`` or ``"in"`` converts positions (never the channels or the written file)
under that convention (CMU: 1 file unit = 0.0254 / 0.45 m = 56.444 mm); a TRC, CSV or
C3D written from file units gets them converted to mm (``formats.for_output``). The rate
is not in the files, so a clip reads as 0 Hz, "not known" (as a C3D without
``POINT:RATE``), unless option ``rate=`` gives it (CMU captured at 120 Hz): a
``--max-gap`` in seconds then fails rather than being read at a rate nobody stated.

Writing patches the AMC the Motion was read from: every line is echoed byte for byte
except the cells whose observed state changed (filled: a number with 6 significant digits,
like the CMU files; made missing: ``nan``). A filled cell whose bone line was absent from
its frame gets a new line at the end of that frame (before the file's last line when that
line has no line ending, so the output still ends without one). A patched file that ended
without a line ending still does, its last line patched in place like any other. If the
file was cut short inside its last line, that line's values the reader did not read (the
possibly cut last one, the absent ones) are never written: :func:`with_channels` keeps
them missing, a repair counts their gaps as ``left: cut short``, and the line keeps its
bytes from its last value read on.

An AMC holds joint angles only and is read with the ``.asf`` found beside it, so unless
the skeleton the reader would pick in the output's folder is already the input's, the
input's skeleton is copied there unchanged, under the output's subject prefix (``10.asf``
beside ``10_01.amc``, ``x.asf`` beside ``x.amc``), or under the output's stem where a
different skeleton holds the prefix's name: both are names the reader tries before a
folder's only ``.asf`` (no file is ever replaced; :func:`companions`). A repair or a batch
into another folder used to give AMC files that could not be read back. A different
``.asf`` named after the output's stem, the name the reader tries first, is refused
before anything is written: the output would be read with the wrong skeleton.
"""
from __future__ import annotations

import errno
import os
import stat
from array import array
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import FormatError, ParameterError
from ..motion import Motion
from ..skeleton import (
    ChannelState,
    Skeleton,
    check_read_memory,
    euler_matrices,
    motion_with_channels,
    patch_tokens,
    positions_edited,
)
from . import skeleton_input_needed
from ._patch import AsRead, as_read
from ._text import LATIN1_BOM, finite_number, frame_steps_notes, last_value_cut, latin1_label

INCH_IN = {"in": 1.0, "mm": 25.4, "cm": 2.54, "m": 0.0254}
NOT_DOF_CHANNELS = ("tx", "ty", "tz", "l")


# --------------------------------------------------------------------------- ASF

@dataclass
class _Bone:
    name: str
    direction: np.ndarray = field(default_factory=lambda: np.zeros(3))
    length: float = 0.0
    axis: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis_order: str = "XYZ"
    dof: tuple[str, ...] = ()


@dataclass
class _Asf:
    """The parts of an ASF the kinematics needs, lengths and angles as in the file."""

    bones: dict[str, _Bone]
    children: dict[str, list[str]]
    length_unit: float = 1.0
    angle_in_degrees: bool = True
    root_order: tuple[str, ...] = ("TX", "TY", "TZ", "RX", "RY", "RZ")
    root_axis: str = "XYZ"
    root_position: tuple[float, ...] = (0.0, 0.0, 0.0)
    root_orientation: tuple[float, ...] = (0.0, 0.0, 0.0)


def _clean(line: str) -> list[str]:
    """Tokens of a line: ``#`` starts a comment; parentheses and commas are whitespace."""
    text = line.split("#", 1)[0]
    return text.replace("(", " ").replace(")", " ").replace(",", " ").split()


def _sections(lines: list[str]) -> dict[str, list[list[str]]]:
    """Token lines grouped under their ``:keyword`` (inline values first)."""
    sections: dict[str, list[list[str]]] = {}
    current: list[list[str]] | None = None
    for line in lines:
        tokens = _clean(line)
        if not tokens:
            continue
        if tokens[0].startswith(":"):
            current = sections.setdefault(tokens[0][1:].lower(), [])
            if len(tokens) > 1:
                current.append(tokens[1:])
        elif current is not None:
            current.append(tokens)
    return sections


def _key_values(rows: list[list[str]]) -> dict[str, list[str]]:
    """``key value...`` rows; a row starting with a number continues the previous key."""
    values: dict[str, list[str]] = {}
    key = None
    for row in rows:
        if key is not None and _is_number(row[0]):
            values[key].extend(row)
        else:
            key = row[0].lower()
            values[key] = row[1:]
    return values


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _bone(block: list[list[str]]) -> _Bone:
    keys = _key_values(block)
    if "name" not in keys or not keys["name"]:
        raise ValueError("bone block without a name")
    bone = _Bone(keys["name"][0])
    if "direction" in keys:
        bone.direction = np.array([float(v) for v in keys["direction"][:3]])
    if "length" in keys:
        bone.length = float(keys["length"][0])
    if "axis" in keys:
        axis = keys["axis"]
        bone.axis = tuple(float(v) for v in axis[:3])
        bone.axis_order = axis[3].upper() if len(axis) > 3 else "XYZ"
    bone.dof = tuple(d.lower() for d in keys.get("dof", []))
    bad = [d for d in bone.dof if d not in ("rx", "ry", "rz")]
    if bad:
        what = "translation dofs" if set(bad) <= set(NOT_DOF_CHANNELS) else "unknown dofs"
        raise ValueError(f"bone {bone.name!r} has {what} {' '.join(bad)} (not supported)")
    return bone


def _blocks(rows: list[list[str]]) -> list[list[list[str]]]:
    """The rows between each ``begin`` and ``end``."""
    blocks, current = [], None
    for row in rows:
        word = row[0].lower()
        if word == "begin":
            current = []
        elif word == "end":
            if current is not None:
                blocks.append(current)
            current = None
        elif current is not None:
            current.append(row)
    return blocks


def parse_asf(text: str) -> _Asf:
    """Parse ASF text; raises ValueError naming what is wrong."""
    sections = _sections(text.splitlines())
    for needed in ("bonedata", "hierarchy"):
        if needed not in sections:
            raise ValueError(f"no :{needed} section")
    bones = {}
    for block in _blocks(sections["bonedata"]):
        bone = _bone(block)
        bones[bone.name] = bone
    children: dict[str, list[str]] = {}
    for block in _blocks(sections["hierarchy"]):
        for row in block:
            children.setdefault(row[0], []).extend(row[1:])
    asf = _Asf(bones, children)
    units = _key_values(sections.get("units", []))
    if "length" in units:
        asf.length_unit = float(units["length"][0])
    if "angle" in units:
        asf.angle_in_degrees = units["angle"][0].lower().startswith("deg")
    root = _key_values(sections.get("root", []))
    if "order" in root:
        asf.root_order = tuple(t.upper() for t in root["order"])
    if "axis" in root:
        asf.root_axis = root["axis"][0].upper()
    if "position" in root:
        asf.root_position = tuple(float(v) for v in root["position"][:3])
    if "orientation" in root:
        asf.root_orientation = tuple(float(v) for v in root["orientation"][:3])
    bad = [t for t in asf.root_order if t not in ("TX", "TY", "TZ", "RX", "RY", "RZ")]
    if bad:
        raise ValueError(f":root order has unknown channels {' '.join(bad)}")
    return asf


def _tree(asf: _Asf) -> list[tuple[str, int]]:
    """(bone, parent index) in depth-first order from ``root``; every bone must be reached."""
    order: list[tuple[str, int]] = [("root", -1)]
    # The bones reached, as a set: a scan of ``order`` for each took 29 s of a 50,000-bone
    # chain (a 5.6 MB ASF).
    seen = {"root"}
    stack = [(child, 0) for child in reversed(asf.children.get("root", []))]
    while stack:
        name, parent = stack.pop()
        if name not in asf.bones:
            raise ValueError(f":hierarchy names bone {name!r} that :bonedata does not define")
        if name in seen:
            raise ValueError(f":hierarchy reaches bone {name!r} twice")
        seen.add(name)
        order.append((name, parent))
        here = len(order) - 1
        stack.extend((child, here) for child in reversed(asf.children.get(name, [])))
    unreached = sorted(set(asf.bones) - seen)
    if unreached:
        raise ValueError(f"bones not in :hierarchy: {', '.join(unreached)}")
    return order


def _axis_frame(order: str, angles: tuple[float, ...], in_degrees: bool) -> np.ndarray:
    return euler_matrices(order, np.asarray(angles, dtype=np.float64)[None, :], intrinsic=False,
                          degrees=in_degrees)[0]


def build_skeleton(asf: _Asf) -> tuple[Skeleton, list[str], list[tuple[int, ...]]]:
    """The kinematic tree of an ASF and its channel layout.

    Returns
    -------
    skeleton
        Points ``root`` and every bone end, in depth-first order.
    channel_names
        ``"<bone>.<dof>"`` per column of the channel matrix (root in ``order``, then bones
        with dofs in point order).
    line_columns
        Per point, the channel columns of its AMC line in the line's value order (empty for
        bones without dofs).
    """
    tree = _tree(asf)
    rotation_columns, rotation_axes = [], []
    translation_columns, translation_axes = [], []
    channel_names: list[str] = []
    line_columns: list[tuple[int, ...]] = []
    offsets, frames, own = [], [], []
    for name, _parent in tree:
        rot_cols, rot_axes, tr_cols, tr_axes = [], "", [], ""
        dofs = asf.root_order if name == "root" else asf.bones[name].dof
        for dof in dofs:
            column = len(channel_names)
            channel_names.append(f"{name}.{dof}")
            if dof.upper().startswith("T"):
                tr_cols.append(column)
                tr_axes += dof[1].upper()
            else:
                rot_cols.append(column)
                rot_axes += dof[1].lower()
        line_columns.append(tuple(range(len(channel_names) - len(dofs), len(channel_names))))
        rotation_columns.append(tuple(rot_cols))
        rotation_axes.append(rot_axes)
        translation_columns.append(tuple(tr_cols))
        translation_axes.append(tr_axes)
        if name == "root":
            offsets.append(np.asarray(asf.root_position, float))
            frames.append(_axis_frame(asf.root_axis, asf.root_orientation, asf.angle_in_degrees))
            own.append(False)
        else:
            bone = asf.bones[name]
            offsets.append(bone.length * bone.direction)
            frames.append(_axis_frame(bone.axis_order, bone.axis, asf.angle_in_degrees))
            own.append(True)
    skeleton = Skeleton(tuple(name for name, _ in tree), np.array([p for _, p in tree]),
                        np.array(offsets), tuple(rotation_columns), tuple(rotation_axes),
                        tuple(translation_columns), tuple(translation_axes), intrinsic=False,
                        n_channels=len(channel_names), pre_rotations=np.array(frames),
                        offset_in_own_frame=np.array(own))
    return skeleton, channel_names, line_columns


def _asf_names(amc: Path) -> list[str]:
    """The skeleton names the reader tries first for an AMC: same stem, subject prefix."""
    return list(dict.fromkeys([f"{amc.stem}.asf", f"{amc.stem.split('_')[0]}.asf"]))


def _asf_files(folder: Path) -> dict[str, Path]:
    return {p.name.lower(): p for p in folder.iterdir() if p.suffix.lower() == ".asf"}


def find_asf(amc: Path) -> Path:
    """The ASF of an AMC: same stem, subject prefix, or the only .asf in the folder.

    An AMC given through a symbolic link whose folder holds none of these gets the one
    beside the link's target, found the same way (by the target's name first): a folder
    of links to trials (``links/09_12.amc -> ../in/09_12.amc``) failed with "cannot find
    its skeleton", where the target itself read.
    """
    folder = amc.parent if str(amc.parent) else Path(".")
    places = [(folder, _asf_names(amc), "")]
    # realpath, not Path.resolve(), which raises on a link loop (before Python 3.13).
    real = Path(os.path.realpath(amc))
    if real.parent != Path(os.path.realpath(folder)):
        places.append((real.parent, list(dict.fromkeys(_asf_names(real) + _asf_names(amc))),
                       "its target's folder "))
    looked = []
    for where, tried, which in places:
        asfs = _asf_files(where)
        for name in tried:
            if name.lower() in asfs:
                return asfs[name.lower()]
        if len(asfs) == 1:
            return next(iter(asfs.values()))
        found = f"{len(asfs)} .asf files" if asfs else "no .asf file"
        looked.append(f"tried {' and '.join(tried)} in {which}{where}, which holds {found}")
    raise FormatError(amc, f"cannot find its skeleton: {'; '.join(looked)}; put the skeleton "
                           f"beside it, named {amc.stem}.asf")


# --------------------------------------------------------------------------- AMC

@dataclass(frozen=True, eq=False)
class AmcSource:
    """What the AMC writer needs to patch the original file.

    Attributes
    ----------
    lines
        Every line of the AMC with its line ending (Latin-1, bytes round-trip exactly).
    asf_path
        The skeleton file used.
    channel_names
        ``"<bone>.<dof>"`` for every column of the channel matrix.
    line_columns
        Per point, the columns its AMC line holds, in value order.
    point_lines
        (frames, points) index into ``lines`` of each bone's line in each frame, -1 where
        the frame lacks that line.
    frame_ends
        Index of the last line of each frame.
    state
        The channel matrix (angles in degrees) as read and as it is now.
    angle_factor
        Degrees per AMC angle unit (1 under ``:DEGREES``, else 180/pi).
    scale
        Factor from file lengths to ``Motion.positions``.
    cut_line
        Index of the last line when the file may have been cut short inside it (see
        :func:`_looks_cut`), or -1: what it holds alone (a frame number, a bone name) is
        not read, nor are its bone's values after the last it reads.
    unread
        The channel columns of that bone line not read (the last value, possibly cut
        short, and the values absent from it): the last frame's cells there stay missing
        (:func:`with_channels`), so that the writer never completes that line.
    frame_notes
        A note when the frame numbers skip or repeat (frames are read in file order as
        consecutive frames, so reports and outputs number them otherwise).
    as_read
        The clip as read, in what a patch cannot change (``formats.write`` refuses to
        patch a clip that differs; the writer checks positions against the channels).
    """

    lines: tuple[str, ...]
    asf_path: Path
    channel_names: tuple[str, ...]
    line_columns: tuple[tuple[int, ...], ...]
    point_lines: np.ndarray
    frame_ends: np.ndarray
    state: ChannelState
    angle_factor: float
    scale: float = 1.0
    cut_line: int = -1
    unread: tuple[int, ...] = ()
    frame_notes: tuple[str, ...] = ()
    as_read: AsRead | None = None

    @property
    def notes(self) -> tuple[str, ...]:
        """What the reader worked around, for reports: frame numbers that skip or repeat
        (``frame_notes``), a file cut short inside a line."""
        if self.cut_line < 0:
            return self.frame_notes
        return self.frame_notes + ("the file ends inside its last line (no final line "
                                   "ending) and that line looks cut short: its last value "
                                   "is not read",)


@dataclass(frozen=True, eq=False)
class _Amc:
    """What :func:`_parse_amc` reads of an AMC.

    Attributes
    ----------
    values
        (frames, channels) values as written (angles in the file's unit), NaN where absent.
    point_lines
        (frames, points) line index of each bone's line in each frame, -1 where absent.
    first_frame
        The first frame's number.
    numbers, number_lines
        (frames,) each frame's number (float64) and the index of its line.
    ends
        (frames,) index of the last line of each frame.
    in_degrees
        Whether the file says ``:DEGREES``.
    cut_line, unread
        The line the file was cut short inside (-1 if none) and the channel columns of
        that line not read (see :class:`AmcSource`).
    """

    values: np.ndarray
    point_lines: np.ndarray
    first_frame: int
    numbers: np.ndarray
    number_lines: np.ndarray
    ends: np.ndarray
    in_degrees: bool
    cut_line: int
    unread: tuple[int, ...]


def _parse_amc(path: Path, lines: tuple[str, ...], skeleton: Skeleton,
               line_columns: list[tuple[int, ...]]) -> _Amc:
    """Channel values, line index of each (frame, point), each frame's number and the
    line index of that number, frame ends, whether angles are degrees, the line the file
    was cut short inside (-1 if none) and the channel columns of that line not read.

    Cells are collected in flat arrays of machine numbers and the matrices built once: a
    row of every channel and point per frame, made as each frame began, cost a 10 MB
    AMC of 5,000,000 frames without bone lines 49 s and 5.5 GB.
    """
    point_of = {name: j for j, name in enumerate(skeleton.names)}
    # The cells read: frame, channel column, value; the bone lines: frame, point, line.
    cell_frames, cell_columns, cell_values = array("q"), array("q"), array("d")
    line_frames, line_points, line_indices = array("q"), array("q"), array("q")
    numbers, number_lines, ends = array("d"), array("q"), array("q")
    first_frame = 0
    frame = -1
    in_frame: set[int] = set()      # the points whose line the current frame holds
    repeated = False                # a point's line twice in a frame: the last one counts
    in_degrees = False
    cut_line, unread = -1, ()
    for i, line in enumerate(lines):
        text = (line.removeprefix(LATIN1_BOM) if i == 0 else line).split("#", 1)[0]
        tokens = text.split()
        if not tokens:
            continue
        # The file ends inside this line (no line ending, no comment the cut fell in):
        # it may have been cut short anywhere, its last token too unless whitespace
        # follows it; a complete bone line is read whole all the same (_looks_cut).
        ends_inside = (i == len(lines) - 1 and not line.endswith(("\n", "\r"))
                       and "#" not in line)
        last_cut = ends_inside and not text[-1].isspace()
        if tokens[0].startswith(":"):
            in_degrees |= tokens[0].upper() == ":DEGREES"
            continue
        if len(tokens) == 1 and tokens[0].isdigit():
            if ends_inside:
                cut_line = i
                continue
            number = int(tokens[0])
            if frame < 0:
                first_frame = number
            frame += 1
            numbers.append(float(number))
            number_lines.append(i)
            ends.append(i)
            in_frame.clear()
            continue
        if frame < 0:
            raise FormatError(path, f"line {i + 1}: bone values before the first frame number")
        name = tokens[0]
        if name not in point_of or not line_columns[point_of[name]]:
            if last_cut and len(tokens) == 1:   # a bone name cut short
                cut_line = i
                continue
            what = "not in the ASF" if name not in point_of else "has no dof in the ASF"
            raise FormatError(path, f"line {i + 1}: bone {name!r} {what}")
        point = point_of[name]
        columns = line_columns[point]
        n_values = len(tokens) - 1
        if n_values > len(columns) or (n_values < len(columns) and not ends_inside):
            raise FormatError(path, f"line {i + 1}: {name} has {n_values} values, "
                                    f"its dof lists {len(columns)}")
        cut = ends_inside and _looks_cut(
            lines, tokens, last_cut, len(columns),
            _lines_of(point, frame, line_frames, line_points, line_indices))
        read = tokens[1:n_values] if cut and last_cut else tokens[1:]
        try:
            cell_values.extend([float(t) for t in read])
        except ValueError:
            raise FormatError(path, f"line {i + 1}: non-numeric value for {name}") from None
        cell_frames.extend([frame] * len(read))
        cell_columns.extend(columns[:len(read)])
        repeated |= point in in_frame
        in_frame.add(point)
        line_frames.append(frame)
        line_points.append(point)
        line_indices.append(i)
        ends[-1] = i
        if cut:
            cut_line, unread = i, columns[len(read):]
    if frame < 0:
        raise FormatError(path, "no frames (no line holding a frame number)")
    check_read_memory(path, frame + 1, skeleton.n_joints, skeleton.n_channels)
    values = _scattered((frame + 1, skeleton.n_channels), np.nan, cell_frames, cell_columns,
                        cell_values, repeated)
    if np.isinf(values).any():
        raise FormatError(path, "infinite value in the motion")
    point_lines = _scattered((frame + 1, skeleton.n_joints), -1, line_frames, line_points,
                             line_indices, repeated)
    return _Amc(values, point_lines, first_frame, np.frombuffer(numbers, np.float64),
                np.frombuffer(number_lines, np.int64), np.frombuffer(ends, np.int64),
                in_degrees, cut_line, unread)


def _scattered(shape: tuple[int, int], blank, rows: array, columns: array, values: array,
               repeated: bool) -> np.ndarray:
    """A ``shape`` matrix holding ``values`` at (``rows``, ``columns``), ``blank``
    elsewhere; where a cell is given twice (``repeated``), the last value given."""
    rows, columns = np.frombuffer(rows, np.int64), np.frombuffer(columns, np.int64)
    values = np.frombuffer(values, np.float64 if values.typecode == "d" else np.int64)
    matrix = np.full(shape, blank, dtype=values.dtype)
    if repeated:    # numpy leaves unsaid which of repeated indices' values is kept
        flat = rows * shape[1] + columns
        _, last = np.unique(flat[::-1], return_index=True)
        keep = flat.size - 1 - last
        rows, columns, values = rows[keep], columns[keep], values[keep]
    matrix[rows, columns] = values
    return matrix


def _lines_of(point: int, frames: int, line_frames: array, line_points: array,
              line_indices: array) -> list[int]:
    """The line index of ``point`` in each of the first ``frames`` frames, -1 where
    absent (the last line given in a frame)."""
    found = [-1] * frames
    for frame, other, index in zip(line_frames, line_points, line_indices):
        if other == point and frame < frames:
            found[frame] = index
    return found


def _looks_cut(lines: tuple[str, ...], tokens: list[str], last_cut: bool, n_columns: int,
               earlier: list[int]) -> bool:
    """Whether the bone line a file ends inside (without a line ending) may have been cut
    short inside it.

    Many tools end a file without a line ending, so such a line is read whole (its last
    value is data, which a patch keeps byte for byte) unless it shows a cut: it holds
    fewer values than its bone's dofs, or its last value (when no whitespace follows it)
    is not a number (``-17.``, ``1e``) or is printed less precisely than the same dof in
    the other frames and the line's other values (``-17.3198`` cut to ``-17.3``; see
    :func:`._text.printed_whole`). A dof no other frame holds a number for gives nothing
    to compare with: the value is taken as cut. As for CSV and TRC, doubt goes that way:
    a ``%g`` value that happens to end in zeros (``-6.5109`` for -6.51090, where the
    others print 6 significant digits) reads as cut and missing.

    Parameters
    ----------
    lines
        The file's lines.
    tokens
        The bone line's tokens: the bone's name and its values.
    last_cut
        Whether the line ends in its last token (no whitespace after it).
    n_columns
        The values a complete line of this bone holds.
    earlier
        The line index of this bone in each earlier frame, -1 where absent.
    """
    if len(tokens) - 1 < n_columns:
        return True
    if not last_cut:
        return False
    column = [t for t in (_value_token(lines[k], n_columns) for k in earlier if k >= 0)
              if t is not None]
    row = [t for t in tokens[1:-1] if finite_number(t)]
    return last_value_cut(tokens[-1], column, row)


def _value_token(line: str, k: int) -> str | None:
    """The ``k``-th token of a bone line (its name is token 0) when it is a finite number."""
    tokens = line.split("#", 1)[0].split()
    return tokens[k] if k < len(tokens) and finite_number(tokens[k]) else None


def _units(asf: _Asf, units: str | None) -> tuple[float, str]:
    if units is None:
        return 1.0, "in" if asf.length_unit == 1 else f"in/{asf.length_unit:g}"
    if units not in INCH_IN:
        raise ParameterError(f"units must be one of {', '.join(INCH_IN)}, got {units!r}")
    return INCH_IN[units] / asf.length_unit, units


def read(path: Path, *, asf: Path | str | None = None, rate: float | None = None,
         units: str | None = None) -> Motion:
    """Read an AMC motion and its ASF skeleton; points are root and bone ends from FK.

    Parameters
    ----------
    path
        The ``.amc`` file.
    asf
        The skeleton file; found beside the AMC when omitted.
    rate
        Frame rate in Hz (AMC files do not store it; CMU captured at 120 Hz). Default
        None: the clip reads as 0 Hz, not known.
    units
        None keeps file units; "mm", "cm", "m" or "in" converts positions assuming the
        ASF lengths are inches divided by ``:units length`` (the CMU convention).

    Returns
    -------
    Motion
        With ``source`` an :class:`AmcSource` for :func:`write`, :func:`channels` and
        :func:`with_channels`.
    """
    path = Path(path)
    asf_path = Path(asf) if asf is not None else find_asf(path)
    if not asf_path.is_file():
        raise FormatError(asf_path, "no such ASF file")
    try:
        skeleton_file = parse_asf(asf_path.read_bytes().decode("latin-1"))
        skeleton, channel_names, line_columns = build_skeleton(skeleton_file)
    except (ValueError, IndexError) as exc:
        raise FormatError(asf_path, f"bad ASF: {exc}") from None
    scale, label = _units(skeleton_file, units)
    lines = tuple(path.read_bytes().decode("latin-1").splitlines(keepends=True))
    amc = _parse_amc(path, lines, skeleton, line_columns)
    values, first_frame = amc.values, amc.first_frame
    angle_factor = 1.0 if amc.in_degrees else 180.0 / np.pi
    if angle_factor != 1.0:
        values[:, skeleton.rotation_channel] *= angle_factor
    frame_notes = frame_steps_notes(amc.numbers, amc.number_lines, "frame number",
                                    first_frame, subject="the frame numbers are",
                                    read_as="frames are read in file order as consecutive "
                                            "frames")
    state = ChannelState.as_read(skeleton, values)
    positions, observed = state.points()
    labels = tuple(latin1_label(n) for n in skeleton.names)
    source = AmcSource(lines, asf_path, tuple(channel_names), tuple(line_columns),
                       amc.point_lines, amc.ends, state, angle_factor, scale, amc.cut_line,
                       amc.unread, frame_notes,
                       as_read(labels, rate or 0.0, label, first_frame, None, positions))
    return Motion(positions * scale, observed, labels, rate or 0.0, label, source=source,
                  path=path, first_frame=first_frame)


# --------------------------------------------------------------------------- channel space

def _source(motion: Motion, path: Path | None = None) -> AmcSource:
    if not isinstance(motion.source, AmcSource):
        raise FormatError(path, skeleton_input_needed(".amc"))
    return motion.source


# What os.link raises on a file system without hard links (FAT, some network shares).
NO_HARD_LINKS = frozenset({errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS,
                           errno.EXDEV})


def companions(motion: Motion, path: Path):
    """Before an AMC is written to ``path``: check the skeleton it will be read with.

    Returns None when the ``.asf`` the reader finds beside ``path`` is the input's (same
    file or same bytes), else the function that copies the input's skeleton there before
    the AMC is written. Raises FormatError (naming ``path``) when a different skeleton there
    is named after the output's stem, the name the reader tries first.

    The copy bears a name the reader tries before falling back to a folder's only
    skeleton: the subject prefix (``10.asf`` beside ``10_01.amc``; trials of one subject
    share it), or the output's stem where a different skeleton holds that name. An AMC
    written beside the skeletons of other subjects (a batch of several into one folder)
    thus reads back with its own, whatever else is or will be copied there; an existing
    file is never replaced.
    """
    source = _source(motion, path)
    folder = path.parent if str(path.parent) else Path(".")
    asfs = _asf_files(folder)

    def same(found: Path) -> bool:
        # realpath, not Path.resolve(), which raises on a link loop (before Python 3.13).
        return (os.path.realpath(found) == os.path.realpath(source.asf_path)
                or found.read_bytes() == source.asf_path.read_bytes())

    tried = _asf_names(path)
    by_stem, by_prefix = tried[0], tried[-1]
    if by_stem.lower() in asfs:
        found = asfs[by_stem.lower()]
        if same(found):
            return None
        raise FormatError(path, f"its folder already holds {found.name}, which differs from "
                                f"the input's skeleton ({source.asf_path}) and would be read "
                                "with it; write to another folder")
    if by_prefix.lower() in asfs:
        if same(asfs[by_prefix.lower()]):
            return None
        name = by_stem                  # tried before the other subject's skeleton
    elif len(asfs) == 1 and same(next(iter(asfs.values()))):
        return None                     # the folder's only skeleton, the input's: read
    else:
        own = source.asf_path.name
        name = own if own.lower() == by_prefix.lower() else by_prefix
    target = folder / name

    def copy() -> None:
        from . import _discard, create_temp

        # Written whole beside it, then linked in under the name only where the name is
        # free: a parallel batch worker may have put another subject's skeleton there
        # since this one looked (two AMCs whose skeletons share a name, into one folder),
        # and renaming over it (os.replace) paired that worker's AMC with this skeleton.
        # Where the name was taken meanwhile, the choice is made again with what is there.
        # The source's mode less the umask (applied by the system as it creates the file),
        # as the AMC beside it gets: copied as it was (shutil.copymode), a 0666 skeleton
        # came out world-writable under umask 022, and a 0644 one readable to all beside a
        # 0600 AMC under umask 077.
        mode = stat.S_IMODE(os.stat(source.asf_path).st_mode) & 0o777
        tmp = create_temp(folder, target.name, ".tmp", mode)
        try:
            Path(tmp).write_bytes(source.asf_path.read_bytes())
            try:
                os.link(tmp, target)
            except FileExistsError:
                again = companions(motion, path)
                if again is not None:
                    again()
            except OSError as exc:
                if exc.errno not in NO_HARD_LINKS:
                    raise
                # Still never replaces a file.
                fd = os.open(target, os.O_WRONLY | os.O_CREAT | os.O_EXCL
                             | getattr(os, "O_BINARY", 0), mode)
                with open(fd, "wb") as out:
                    out.write(source.asf_path.read_bytes())
        finally:
            _discard(tmp)
    return copy


def channels(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """The clip's channel matrix (degrees, file lengths), rotations unwrapped along time.

    Returns
    -------
    tuple of numpy.ndarray
        (frames, channels) float64 values, NaN where missing, and the bool observed mask.
    """
    return _source(motion).state.unwrapped()


def with_channels(motion: Motion, values: np.ndarray, observed: np.ndarray) -> Motion:
    """A copy of ``motion`` driven by a new channel matrix.

    Cells observed before keep their stored value; newly observed cells take ``values``
    wrapped into the range their channel used; positions are recomputed by FK and the
    source carries the new matrix for :func:`write`. The cells of the bone line a file
    was cut short inside that the reader did not read (``AmcSource.unread``) stay as
    read, missing: the writer keeps that line byte for byte after its last value read,
    so a fill there could not be written, and a repair counts their gaps as left.
    """
    source = _source(motion)
    if source.unread:
        observed = np.array(observed, dtype=bool)   # a copy: the caller's mask is kept
        last, unread = len(source.frame_ends) - 1, list(source.unread)
        observed[last, unread] = source.state.original_observed[last, unread]
    return motion_with_channels(motion, source, values, observed)


# --------------------------------------------------------------------------- writing

def patches(motion: Motion) -> bool:
    """Whether :func:`write` can write ``motion``: as a patch of the AMC it was read from,
    the only way it writes."""
    return isinstance(motion.source, AmcSource)


def _cell_text(source: AmcSource, frame: int, column: int) -> str:
    state = source.state
    if not state.observed[frame, column]:
        return "nan"
    value = state.values[frame, column]
    if state.skeleton.rotation_channel[column]:
        value /= source.angle_factor
    return f"{value:.6g}"


def write(motion: Motion, path: Path, **_options) -> None:
    """Write a repaired AMC by patching the file the Motion was read from.

    Raises
    ------
    FormatError
        When the Motion did not come from AMC, or its positions were edited without going
        through :func:`with_channels` (or its channels were, in the values of a line the
        file was cut short inside that the reader did not read).
    """
    source = _source(motion, path)
    differing = positions_edited(motion, source.state, source.scale)
    if differing:
        raise FormatError(path, f"positions were changed outside channel space ({differing} "
                                "samples disagree with the channels); AMC stores joint "
                                "angles, which a repair fills with mocapfill.repair(motion, "
                                "RepairOptions(space='channels')), as the command line does")
    lines = list(source.lines)
    added: dict[int, list[str]] = {}
    changed = source.state.changed_cells()
    if changed[len(source.frame_ends) - 1, list(source.unread)].any():
        # with_channels keeps them missing; a value after the last one read could only
        # be written by completing a line that may hold a number cut short
        raise FormatError(path, "values the file was cut short before were changed; "
                                "AMC channels are changed through acclaim.with_channels")
    # The line ending new bone lines get: the file's, also where it ends without one.
    ending = next((line[len(line.rstrip("\r\n")):] for line in reversed(lines)
                   if line.endswith(("\n", "\r"))), "\n")
    for frame in np.flatnonzero(changed.any(axis=1)):
        for point, columns in enumerate(source.line_columns):
            touched = [k for k, c in enumerate(columns) if changed[frame, c]]
            if not touched:
                continue
            index = source.point_lines[frame, point]
            if index >= 0:
                cells = {k + 1: _cell_text(source, frame, columns[k]) for k in touched}
                lines[index] = patch_tokens(lines[index], cells)
            else:
                end = source.frame_ends[frame]
                newline = lines[end][len(lines[end].rstrip("\r\n")):] or ending
                texts = [_cell_text(source, frame, c) for c in columns]
                added.setdefault(end, []).append(
                    " ".join([source.state.skeleton.names[point], *texts]) + newline)
    out = []
    for i, line in enumerate(lines):
        new = added.get(i, [])
        if line.endswith(("\n", "\r")):
            out += [line, *new]
        else:
            # The file's last line, without a line ending: a frame's new bone lines go
            # before it, so that it stays last and keeps its lack of a final line ending.
            out += [*new, line]
    Path(path).write_bytes("".join(out).encode("latin-1"))
