"""Skeleton clips repaired in channel space and written back into their own format."""
import numpy as np
import pytest

from mocapfill import formats
from mocapfill.errors import FormatError, ParameterError
from mocapfill.formats.bvh import channels as bvh_channels
from mocapfill.gaps import find_gaps, simulate_channel_gaps
from mocapfill.pipeline import RepairOptions, repair

from .conftest import shared_file
from .helpers import assert_only_nan_tokens_replaced


@pytest.mark.parametrize("name", ["cmu/10_01.bvh", "cmu/10_01.amc"])
def test_simulated_channel_gaps_repair_and_patch_only_gap_lines(tmp_path, name):
    source = shared_file(name)
    if source.suffix == ".amc":
        (tmp_path / "10.asf").write_bytes(shared_file("cmu/10.asf").read_bytes())
    truth = formats.read(source)
    gapped = simulate_channel_gaps(truth, ml=30, markers=4, seed=2)
    gapped_path = tmp_path / f"gapped{source.suffix}"
    formats.write(gapped, gapped_path)
    assert b"nan" in gapped_path.read_bytes()

    reread = formats.read(gapped_path)
    assert (~reread.observed).any()
    result = repair(reread, RepairOptions(space="channels", method="linear"))
    out = tmp_path / f"repaired{source.suffix}"
    formats.write(result.motion, out)

    gapped_text = gapped_path.read_bytes().decode("latin-1")
    out_text = out.read_bytes().decode("latin-1")
    # Only the nan tokens change; the observed tokens of their lines stay as written.
    replaced = assert_only_nan_tokens_replaced(gapped_text, out_text)
    assert replaced == gapped_text.split().count("nan")
    assert "nan" not in out_text

    repaired = formats.read(out)
    missing = ~reread.observed
    error = np.sqrt(np.mean((repaired.positions - truth.positions)[missing] ** 2))
    spread = np.nanstd(truth.positions)
    assert error < 0.1 * spread
    assert all(o.status == "filled" for o in result.gaps)


def test_channel_repair_with_the_default_method_fills_every_gap(tmp_path):
    truth = formats.read(shared_file("cmu/10_01.bvh"))
    gapped = simulate_channel_gaps(truth, ml=20, markers=3, seed=5)
    result = repair(gapped, RepairOptions(space="channels"))
    assert result.motion.observed.all()
    np.testing.assert_array_equal(result.motion.positions[gapped.observed],
                                  gapped.positions[gapped.observed])


def _chain_with_a_gap(tmp_path, column):
    from .formats.test_bvh import write_bvh

    rows = []
    for f in range(40):
        cells = [f"{f:.4f}", "0", "0", "0", "0", "0", f"{3 * f:.4f}", f"{f:.4f}", "0"]
        cells[3] = f"{2 * f:.4f}"
        if 15 <= f < 25:
            cells[column] = "nan"
        rows.append(" ".join(cells))
    return formats.read(write_bvh(tmp_path, rows))


@pytest.mark.parametrize(("column", "points"), [(6, ["Arm_End"]),        # the arm's own turn
                                                (3, ["Arm", "Arm_End"])])  # the hips' turn
def test_channel_repair_applies_the_jump_check_to_the_points_it_moves(tmp_path, column,
                                                                      points):
    gapped = _chain_with_a_gap(tmp_path, column)
    assert [g.label for g in find_gaps(gapped)] == points
    filled = repair(gapped, RepairOptions(space="channels", method="linear"))
    assert {o.status for o in filled.gaps} == {"filled"} and filled.motion.observed.all()
    # A tolerance below any fill's deviation from the constant-velocity prediction.
    strict = repair(gapped, RepairOptions(space="channels", method="linear",
                                          max_jump_mm=1e-9))
    assert [o.status for o in strict.gaps] == ["rejected: jump"] * len(points)
    np.testing.assert_array_equal(strict.motion.observed, gapped.observed)
    values, observed = bvh_channels(strict.motion)
    assert np.isnan(values[15:25, column]).all() and not observed[15:25, column].any()


def test_a_rank_above_the_channels_is_refused_in_terms_of_channels(tmp_path):
    # The channel-space matrix has a row per channel (9 here: root 6 + arm 3), not
    # 3 × markers; the refusal must name what actually bounds the rank.
    gapped = _chain_with_a_gap(tmp_path, 6)
    options = RepairOptions(space="channels", method="trnn-lowrank",
                            solver_options={"rank": 10})
    with pytest.raises(ParameterError) as refused:
        repair(gapped, options)
    message = str(refused.value)
    assert "--rank 10 is larger than this clip allows (9: the smaller of the 9 channels " \
           "and frames)" in message
    assert "markers" not in message


def _chain_with_gaps(tmp_path, runs):
    """The chain of :func:`_chain_with_a_gap`, ``nan`` in each (column, start, stop)."""
    from .formats.test_bvh import write_bvh

    rows = []
    for f in range(40):
        cells = [f"{f:.4f}", "0", "0", f"{2 * f:.4f}", "0", "0", f"{3 * f:.4f}", f"{f:.4f}",
                 "0"]
        for column, start, stop in runs:
            if start <= f < stop:
                cells[column] = "nan"
        rows.append(" ".join(cells))
    return formats.read(write_bvh(tmp_path, rows))


@pytest.mark.parametrize(("runs", "options"), [
    # The hips' turn missing from the start, the arm's turn from inside that gap on: the
    # arm's end is missing from frame 0 (an end gap, left) though the arm's run is inside.
    ([(3, 0, 6), (6, 3, 11)], {}),
    # Every channel moving the arm's end missing somewhere: missing through the whole clip.
    ([(0, 0, 2), (3, 2, 20), (6, 15, 40)], {}),
    # A run too long for --max-gap beside a short one: the arm's end would be filled where
    # only the short run crosses its gap.
    ([(3, 10, 16), (6, 14, 26)], {"max_gap_frames": 8}),
])
def test_a_point_whose_gap_is_left_gets_no_fill_from_its_channels(tmp_path, runs, options):
    gapped = _chain_with_gaps(tmp_path, runs)
    result = repair(gapped, RepairOptions(space="channels", method="linear", **options))
    assert any(o.status != "filled" for o in result.gaps)
    for outcome in result.gaps:
        gap = outcome.gap
        filled = result.motion.observed[gap.start:gap.stop, gap.marker]
        assert filled.all() if outcome.status == "filled" else not filled.any(), outcome


@pytest.mark.parametrize("name", ["cmu/10_01.bvh", "cmu/10_01.amc"])
def test_a_position_repair_written_to_its_skeleton_format_names_the_public_way(tmp_path,
                                                                               name):
    # The README's recipe, write(repair(read(x.bvh)).motion, y.bvh), pointed at
    # bvh.with_channels, an internal function.
    source = shared_file(name)
    if source.suffix == ".amc":
        (tmp_path / "10.asf").write_bytes(shared_file("cmu/10.asf").read_bytes())
    gapped_path = tmp_path / f"gapped{source.suffix}"
    formats.write(simulate_channel_gaps(formats.read(source), ml=30, markers=4, seed=2),
                  gapped_path)
    gapped = formats.read(gapped_path)
    out = tmp_path / f"out{source.suffix}"
    with pytest.raises(FormatError) as caught:
        formats.write(repair(gapped, RepairOptions(method="linear")).motion, out)
    message = str(caught.value)
    assert "mocapfill.repair(motion, RepairOptions(space='channels'))" in message
    assert "with_channels" not in message and "\n" not in message
    formats.write(repair(gapped, RepairOptions(method="linear", space="channels")).motion,
                  out)
    assert formats.read(out).observed.all()


@pytest.mark.parametrize("name", ["cmu/10_01.amc", "cmu/10_01.bvh",
                                  "bvh/iclone-05_13-ccbase-60fps.bvh"])
def test_the_channels_moving_each_joint_are_those_of_the_dense_computation(name):
    from mocapfill.skeleton import moving_channels, observed_points

    skeleton = formats.read(shared_file(name)).source.state.skeleton
    # moves[c, j]: a missing cell of channel c alone hides joint j (what the repair used)
    moves = ~observed_points(skeleton, ~np.eye(skeleton.n_channels, dtype=bool))
    for joint in range(skeleton.n_joints):
        np.testing.assert_array_equal(moving_channels(skeleton, joint),
                                      np.flatnonzero(moves[:, joint]))
    assert any(moving_channels(skeleton, joint).size for joint in range(skeleton.n_joints))


def test_a_channel_repair_of_a_wide_skeleton_allocates_no_channels_by_channels_matrix(
        tmp_path):
    # Which joints each channel moves was a channels × channels and a channels × joints
    # matrix: 20,000 joints of 3 channels, 3 frames, took 5.9 GB and 74 s. Here 2,000
    # joints under the root, each with an End Site its rotation hides when missing.
    import tracemalloc

    n = 2000
    joints = "".join(f"  JOINT J{k}\n  {{\n    OFFSET 0 0 1\n    CHANNELS 3 Zrotation "
                     f"Xrotation Yrotation\n    End Site\n    {{\n      OFFSET 0 1 0\n    }}\n"
                     "  }\n" for k in range(n))
    rows = []
    for f in range(6):
        row = [str(f)] * 3 + [str(f + k % 7) for k in range(3 * n)]
        if f == 2:
            row[3 + 3 * 5] = "nan"                   # J5's Zrotation: J5_End's gap
        rows.append(" ".join(row))
    path = tmp_path / "fan.bvh"
    path.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition "
                    "Yposition Zposition\n" + joints + "}\nMOTION\nFrames: 6\nFrame Time: "
                    "0.01\n" + "\n".join(rows) + "\n")
    motion = formats.read(path)
    options = RepairOptions(space="channels", method="linear")
    repair(motion, options)                            # the methods' modules, imported
    tracemalloc.start()
    try:
        result = repair(motion, options)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert [(o.gap.label, o.status) for o in result.gaps] == [("J5_End", "filled")]
    assert result.motion.observed.all()
    assert peak < 16 << 20           # was 81 MB: (6003 × 6003) and (6003 × 4001) bools
