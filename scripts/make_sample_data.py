"""Generate the demo clip in ``sample_data/``: a synthetic walking trial and an occluded copy.

    python scripts/make_sample_data.py sample_data

writes ``walk_truth.csv`` (gap-free) and ``walk_gapped.csv`` (the same samples with
realistic occlusions) and prints one summary line to stderr. The output is deterministic
(fixed seed, no network), so the committed files can be checked against a fresh run.

The clip comes from a walking kinematic chain, not from a formula per marker: a pelvis
translating forward with lateral sway, thigh / shank / foot, thorax / head and upper arm /
forearm segments rotated by gait-like joint angles (left and right half a cycle apart,
trunk counter-rotating against the pelvis), and markers at fixed offsets on those rigid
segments. So markers on one segment keep their distances (up to the measurement noise),
which is what low-rank completion exploits. A slow speed change, a drifting heading, a
head turn and small stride-to-stride variability keep the clip from being exactly
periodic or exactly low-rank.

Coordinates: millimetres, Z up, X the initial walking direction, Y to the subject's left.
Joint angles in degrees; a segment's local frame has X anterior, Y left, Z up (proximal).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from mocapfill.formats import write
from mocapfill.motion import Motion

SEED = 2018
RATE_HZ = 120.0
N_FRAMES = 600
NOISE_MM = 0.3
DECIMALS = 3               # 0.001 mm, as motion-capture software exports
SUFFIX = ".csv"

STEPS_PER_S = 1.8          # cadence; a stride (gait cycle) is two steps
GROUND_CLEARANCE_MM = 14.0  # height of a marker centre resting on the floor

# Marker offsets in their segment's frame, written for the LEFT side (+Y lateral); the
# right side mirrors Y. Plug-in-Gait places the thigh, tibia and upper-arm markers at
# different heights left and right; the (left, right) pairs below keep that asymmetry.
PELVIS = {"ASI": (60.0, 120.0, 80.0), "PSI": (-100.0, 45.0, 80.0)}
HIP_JOINT = (0.0, 85.0, 0.0)                    # pelvis origin: midway between hip centres
LUMBAR_JOINT = (-40.0, 0.0, 110.0)              # thorax origin, in the pelvis frame
THIGH_LENGTH, SHANK_LENGTH = 420.0, 400.0
THIGH = {"THI": ((10.0, 70.0, -230.0), (10.0, 70.0, -190.0))}
SHANK = {"KNE": (0.0, 55.0, 0.0), "KNM": (0.0, -50.0, 0.0),   # on the knee flexion axis
         "TIB": ((15.0, 50.0, -200.0), (15.0, 50.0, -240.0)), "ANK": (0.0, 40.0, -SHANK_LENGTH)}
FOOT = {"HEE": (-70.0, 0.0, -40.0), "TOE": (135.0, -12.0, -35.0)}
THORAX = {"C7": (-80.0, 0.0, 470.0), "T10": (-120.0, 0.0, 230.0), "CLAV": (70.0, 0.0, 430.0),
          "STRN": (110.0, 0.0, 260.0), "RBAK": (-110.0, -90.0, 330.0)}
SHOULDER_MARKER = (-20.0, 180.0, 440.0)
SHOULDER_JOINT = (-20.0, 175.0, 400.0)
NECK_JOINT = (-40.0, 0.0, 490.0)
HEAD = {"FHD": (90.0, 55.0, 110.0), "BHD": (-80.0, 55.0, 100.0)}
UPPER_ARM_LENGTH, FOREARM_LENGTH = 290.0, 250.0
UPPER_ARM = {"UPA": ((-30.0, 45.0, -150.0), (-30.0, 45.0, -190.0)),
             "ELB": (0.0, 35.0, -UPPER_ARM_LENGTH)}    # lateral epicondyle, on the elbow axis
FOREARM = {"FRM": (-10.0, 35.0, -120.0), "WRA": (30.0, 5.0, -FOREARM_LENGTH),
           "WRB": (-30.0, -5.0, -FOREARM_LENGTH), "FIN": (15.0, 25.0, -FOREARM_LENGTH - 80.0)}

LABELS = ("LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "CLAV", "STRN", "RBAK",
          "LSHO", "LUPA", "LELB", "LFRM", "LWRA", "LWRB", "LFIN",
          "RSHO", "RUPA", "RELB", "RFRM", "RWRA", "RWRB", "RFIN",
          "LASI", "RASI", "LPSI", "RPSI",
          "LTHI", "LKNE", "LKNM", "LTIB", "LANK", "LHEE", "LTOE",
          "RTHI", "RKNE", "RKNM", "RTIB", "RANK", "RHEE", "RTOE")

# Occlusion: how many markers lose long runs, and how likely each marker is to be among
# them. Hands and wrists swing behind the body, ASIS markers hide under the arms and the
# belly, medial knee markers between the legs; head and back markers rarely drop.
N_OCCLUDED_MARKERS = 10
GAP_FRAMES = (20, 150)
N_FLICKERS = 6
FLICKER_FRAMES = (1, 5)
EDGE_MARGIN_FRAMES = 15    # every gap is interior: a solver has data on both sides
OCCLUSION_WEIGHT = {"WRA": 4.0, "WRB": 4.0, "FIN": 4.0, "ASI": 3.0, "KNM": 3.0, "FRM": 2.0,
                    "HEE": 1.5, "TOE": 1.5, "ANK": 1.5, "STRN": 1.5, "ELB": 1.5}


def _cardan(flexion_y=0.0, abduction_x=0.0, rotation_z=0.0) -> Rotation:
    """Per-frame rotations from angles in degrees (Y, then X, then Z; intrinsic)."""
    angles = np.broadcast_arrays(np.asarray(flexion_y, float), np.asarray(abduction_x, float),
                                 np.asarray(rotation_z, float), np.zeros(N_FRAMES))[:3]
    return Rotation.from_euler("YXZ", np.column_stack(angles), degrees=True)


def _wander(t: np.ndarray, rng: np.random.Generator, amplitude: float) -> np.ndarray:
    """Slow, smooth, non-periodic variation: a few sinusoids of incommensurate period."""
    freqs = rng.uniform(0.07, 0.5, size=4)
    phases = rng.uniform(0, 2 * np.pi, size=4)
    weights = rng.uniform(0.5, 1.0, size=4)
    wave = (weights[:, None] * np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None])).sum(0)
    return amplitude * wave / weights.sum()



def _periodic(knots: list[tuple[float, float]]) -> CubicSpline:
    """A smooth periodic curve over one gait cycle through (phase, degrees) knots."""
    phase, degrees = zip(*knots, (1.0, knots[0][1]))
    return CubicSpline(phase, degrees, bc_type="periodic")


# Sagittal angles of normal adult gait (degrees; heel strike at phase 0, toe-off at 0.6).
HIP_FLEXION = _periodic([(0.0, 33.0), (0.1, 31.0), (0.3, 10.0), (0.5, -15.0), (0.56, -13.0),
                         (0.65, 3.0), (0.75, 24.0), (0.87, 37.0), (0.95, 34.0)])
KNEE_FLEXION = _periodic([(0.0, 4.0), (0.12, 18.0), (0.22, 14.0), (0.4, 5.0), (0.5, 12.0),
                          (0.6, 38.0), (0.72, 62.0), (0.8, 54.0), (0.9, 30.0), (0.96, 10.0)])
# Pitch of the foot against the floor (+ toe down): heel strike toe-up, flat foot, heel
# rise, toe-off, swing. The ankle angle follows from it.
FOOT_PITCH = _periodic([(0.0, -12.0), (0.08, 0.0), (0.3, 0.0), (0.45, 12.0), (0.6, 50.0),
                        (0.7, 25.0), (0.8, 0.0), (0.9, -12.0)])


def _gait_angles(phase: np.ndarray, pelvic_tilt: np.ndarray) -> dict[str, np.ndarray]:
    """Sagittal joint angles (degrees) over the gait cycle; heel strike at phase 0.

    Hip and shoulder: + flexion (segment forward); knee and elbow: + flexion;
    ankle: + dorsiflexion. Shapes follow normal adult gait curves; the ankle is whatever
    keeps the foot at ``FOOT_PITCH`` (flat on the floor through mid-stance).
    """
    cycle = 2 * np.pi * phase
    hip, knee = HIP_FLEXION(phase % 1), KNEE_FLEXION(phase % 1)
    return {
        "hip": hip,
        "hip_adduction": 4 * np.sin(cycle + 0.3),
        "knee": knee,
        "ankle": pelvic_tilt - hip + knee - FOOT_PITCH(phase % 1),
        # Arms swing against the same-side leg.
        "shoulder": 4 - 16 * np.cos(cycle - 0.2),
        "elbow": 24 - 10 * np.cos(cycle - 0.2),
    }


def _on(position: np.ndarray, rotation: Rotation, offset) -> np.ndarray:
    """World coordinates of a point fixed at ``offset`` in a moving segment frame."""
    return position + rotation.apply(np.asarray(offset, float))


def _placed(segment: dict, side: str, sign: float, position: np.ndarray,
            rotation: Rotation) -> dict[str, np.ndarray]:
    """Trajectories of a segment's markers on one side (``sign`` -1 mirrors Y: right)."""
    mirror = np.array([1.0, sign, 1.0])
    placed = {}
    for name, offset in segment.items():
        if isinstance(offset[0], tuple):                    # (left, right) placements
            offset = offset[0] if sign > 0 else offset[1]
        placed[side + name] = _on(position, rotation, mirror * np.asarray(offset))
    return placed


def walk(rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Noise-free trajectories (frames, 3) of every marker of the walking clip, in mm."""
    t = np.arange(N_FRAMES) / RATE_HZ
    wander = {name: _wander(t, rng, amp) for name, amp in
              [("stride", 0.03), ("cadence", 0.03), ("heading", 4.0), ("trunk", 1.5),
               ("hip", 2.0), ("knee", 2.5), ("ankle", 1.5), ("shoulder", 3.0)]}
    # A slight slow-down halfway: shorter, slower strides.
    slow_down = 1 - 0.04 * (np.tanh((t - 2.6) / 0.7) + 1) / 2
    stride_hz = STEPS_PER_S / 2 * (1 + wander["cadence"]) * slow_down
    stride_scale = (1 + wander["stride"]) * slow_down
    phase = np.cumsum(stride_hz) / RATE_HZ + 0.1        # left gait-cycle phase, in cycles
    left, right = phase, phase + 0.5

    # The body is built in a frame moving with the pelvis (forward progression and heading
    # come later): lateral sway toward the stance leg, and the pelvis's list of the swing
    # side, forward rotation of the swinging hip and anterior tilt.
    pelvis = np.zeros((N_FRAMES, 3))
    pelvis[:, 1] = 22 * np.sin(2 * np.pi * (left - 0.05))
    pelvic_tilt = 10 + 2 * np.cos(4 * np.pi * left)
    pelvis_rot = _cardan(flexion_y=pelvic_tilt,
                         abduction_x=4 * np.sin(2 * np.pi * left),
                         rotation_z=-5 * np.cos(2 * np.pi * left))

    markers: dict[str, np.ndarray] = {}
    # Thorax counter-rotates against the pelvis; the head turns to look aside for a while.
    thorax = _on(pelvis, pelvis_rot, LUMBAR_JOINT)
    thorax_rot = _cardan(flexion_y=5 + 1.5 * np.cos(4 * np.pi * left) + wander["trunk"],
                         abduction_x=-1.5 * np.sin(2 * np.pi * left),
                         rotation_z=4 * np.cos(2 * np.pi * left))
    for name, offset in THORAX.items():
        markers[name] = _on(thorax, thorax_rot, offset)
    head_turn = 30 * (np.tanh((t - 1.8) / 0.35) - np.tanh((t - 3.4) / 0.45)) / 2
    head_rot = thorax_rot * _cardan(flexion_y=-5 + 3 * np.sin(2 * np.pi * 0.3 * t),
                                    rotation_z=head_turn)
    neck = _on(thorax, thorax_rot, NECK_JOINT)

    for side, sign, side_phase in (("L", 1.0, left), ("R", -1.0, right)):
        mirror = np.array([1.0, sign, 1.0])

        def place(segment: dict, position: np.ndarray, rotation: Rotation,
                  side: str = side, sign: float = sign) -> None:
            markers.update(_placed(segment, side, sign, position, rotation))

        angles = _gait_angles(side_phase, pelvic_tilt)
        for joint in ("hip", "knee", "ankle", "shoulder"):
            angles[joint] = angles[joint] * stride_scale + wander[joint]
        place(HEAD, neck, head_rot)
        place(PELVIS, pelvis, pelvis_rot)
        markers[side + "SHO"] = _on(thorax, thorax_rot, mirror * SHOULDER_MARKER)

        # Leg: flexion is a rotation about -Y (the distal end moves forward).
        hip = _on(pelvis, pelvis_rot, mirror * HIP_JOINT)
        thigh_rot = pelvis_rot * _cardan(flexion_y=-angles["hip"],
                                         abduction_x=-sign * angles["hip_adduction"])
        place(THIGH, hip, thigh_rot)
        knee = _on(hip, thigh_rot, (0.0, 0.0, -THIGH_LENGTH))
        shank_rot = thigh_rot * _cardan(flexion_y=angles["knee"])
        place(SHANK, knee, shank_rot)
        ankle = _on(knee, shank_rot, (0.0, 0.0, -SHANK_LENGTH))
        foot_rot = shank_rot * _cardan(flexion_y=-angles["ankle"], rotation_z=sign * 7.0)
        place(FOOT, ankle, foot_rot)

        # Arm: slightly abducted so the hand clears the hip.
        shoulder = _on(thorax, thorax_rot, mirror * SHOULDER_JOINT)
        upper_rot = thorax_rot * _cardan(flexion_y=-angles["shoulder"], abduction_x=sign * 9.0)
        place(UPPER_ARM, shoulder, upper_rot)
        elbow = _on(shoulder, upper_rot, (0.0, 0.0, -UPPER_ARM_LENGTH))
        forearm_rot = upper_rot * _cardan(flexion_y=-angles["elbow"],
                                          rotation_z=-sign * 10.0)
        place(FOREARM, elbow, forearm_rot)
    contact = {}
    for side, side_phase in (("L", left), ("R", right)):
        contact[side + "HEE"], contact[side + "TOE"] = _contact(side_phase)
    return _onto_floor(markers, contact, heading=wander["heading"] + 3.0 * t / t[-1])


def _contact(phase: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """How much a foot's heel and toe markers bear weight over the gait cycle.

    Stance runs from heel strike (phase 0) to toe-off (0.6); the load rolls from the heel
    to the toe over it.
    """
    p = (phase + 0.2) % 1 - 0.2                       # -0.2 .. 0.8, heel strike at 0

    def step(x: np.ndarray) -> np.ndarray:
        return 1 / (1 + np.exp(-x / 0.015))

    stance = step(p) * step(0.6 - p)
    roll = step(p - 0.3)
    return stance * (1 - roll), stance * roll


def _onto_floor(markers: dict[str, np.ndarray], contact: dict[str, np.ndarray],
                heading: np.ndarray) -> dict[str, np.ndarray]:
    """Move a body built in the pelvis's frame along the floor, its stance foot planted.

    The markers bearing weight (``contact``: weight per frame) stay put: their backward
    speed relative to the pelvis is the body's forward speed, and their height sets the
    body's vertical bob. ``heading`` (degrees per frame) bends the path gently.
    """
    weight = np.stack(list(contact.values()))
    weight /= weight.sum(axis=0)
    feet = np.stack([markers[name] for name in contact])                    # (n, F, 3)
    backward = -(np.gradient(feet[:, :, 0], axis=1) * weight).sum(axis=0)   # mm per frame
    speed = gaussian_filter1d(backward, sigma=3, mode="nearest")
    # No foot goes through the floor: where the swinging heel reaches lower than the
    # stance foot (late swing), the body rises onto the stance toes instead.
    lift = np.maximum(GROUND_CLEARANCE_MM - (feet[:, :, 2] * weight).sum(axis=0),
                      GROUND_CLEARANCE_MM - feet[:, :, 2].min(axis=0))
    lift = gaussian_filter1d(lift, sigma=3, mode="nearest")
    heading_rot = _cardan(rotation_z=heading)
    radians = np.radians(heading)
    path = np.column_stack([np.cumsum(speed * np.cos(radians)),
                            np.cumsum(speed * np.sin(radians)), lift])
    return {name: path + heading_rot.apply(xyz) for name, xyz in markers.items()}


def _runs(rng: np.random.Generator, taken: list[tuple[int, int]], count: int,
          lengths: tuple[int, int], spacing: int) -> list[tuple[int, int]]:
    """``count`` interior runs [start, stop) of random length, ``spacing`` frames apart from
    each other and from the runs already ``taken`` on the same marker."""
    runs: list[tuple[int, int]] = []
    while len(runs) < count:
        length = int(rng.integers(lengths[0], lengths[1] + 1))
        start = int(rng.integers(EDGE_MARGIN_FRAMES, N_FRAMES - EDGE_MARGIN_FRAMES - length))
        stop = start + length
        if all(stop + spacing <= a or b + spacing <= start for a, b in taken + runs):
            runs.append((start, stop))
    return runs


def occlude(rng: np.random.Generator, labels: tuple[str, ...]) -> np.ndarray:
    """The observed mask (frames, markers) of a realistically occluded copy of the clip."""
    weight = np.array([OCCLUSION_WEIGHT.get(label[1:] if label[0] in "LR" else label, 0.3)
                       for label in labels])
    observed = np.ones((N_FRAMES, len(labels)), bool)
    gaps: dict[int, list[tuple[int, int]]] = {j: [] for j in range(len(labels))}
    for j in rng.choice(len(labels), N_OCCLUDED_MARKERS, replace=False, p=weight / weight.sum()):
        n_runs = int(rng.choice([1, 2, 3], p=[0.45, 0.35, 0.2]))
        gaps[int(j)] += _runs(rng, gaps[int(j)], n_runs, GAP_FRAMES, spacing=20)
    for j in rng.choice(len(labels), N_FLICKERS, replace=True, p=weight / weight.sum()):
        gaps[int(j)] += _runs(rng, gaps[int(j)], 1, FLICKER_FRAMES, spacing=5)
    for j, runs in gaps.items():
        for start, stop in runs:
            observed[start:stop, j] = False
    return observed


def gap_lengths(observed: np.ndarray) -> list[int]:
    """Lengths of all runs of missing frames, over all markers."""
    padded = np.pad(~observed, ((1, 1), (0, 0))).astype(np.int8)
    edges = np.diff(padded, axis=0)
    starts = np.nonzero(edges.T == 1)
    stops = np.nonzero(edges.T == -1)
    return (stops[1] - starts[1]).tolist()


def make(out_dir: Path) -> str:
    """Write the truth and gapped clips into ``out_dir``; return the summary line."""
    rng = np.random.default_rng(SEED)
    markers = walk(rng)
    positions = np.stack([markers[label] for label in LABELS], axis=1)
    positions = np.round(positions + rng.normal(0.0, NOISE_MM, positions.shape), DECIMALS)
    observed = occlude(rng, LABELS)
    truth = Motion(positions, np.ones(observed.shape, bool), LABELS, RATE_HZ, "mm")
    write(truth, out_dir / f"walk_truth{SUFFIX}", decimals=DECIMALS)
    write(truth.with_positions(positions, observed), out_dir / f"walk_gapped{SUFFIX}",
          decimals=DECIMALS)
    lengths = gap_lengths(observed)
    long_gaps = [n for n in lengths if n >= GAP_FRAMES[0]]
    n_gapped = int((~observed).any(axis=0).sum())
    return (f"{out_dir}: {len(LABELS)} markers, {N_FRAMES} frames at {RATE_HZ:g} Hz; "
            f"walk_gapped{SUFFIX}: {100 * (~observed).mean():.1f}% missing, "
            f"{len(lengths)} gaps in {n_gapped} markers ({len(long_gaps)} of "
            f"{min(long_gaps)}-{max(long_gaps)} frames, {len(lengths) - len(long_gaps)} "
            f"flickers of {FLICKER_FRAMES[0]}-{FLICKER_FRAMES[1]})")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out_dir", type=Path, help="folder to write into (e.g. sample_data)")
    args = parser.parse_args(argv)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    print(make(args.out_dir), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
