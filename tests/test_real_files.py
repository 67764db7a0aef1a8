"""End-to-end on real files through the command line: every format in, position formats
out, gaps kept as gaps, same-format repairs that patch only the holes, bad files refused."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from mocapfill import formats
from mocapfill.cli import main
from mocapfill.metrics import mm_per_unit

from .conftest import shared_file
from .helpers import assert_only_nan_tokens_replaced


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


@pytest.mark.parametrize("source, target", [
    ("c3d/ezc3d-Vicon.c3d", ".csv"),
    ("c3d/btk-sample02__DEC_INT.C3D", ".trc"),
    ("trc/btk-Gait.trc", ".c3d"),
    ("csv/vicon-nexus-markers.csv", ".trc"),
    ("cmu/10_01.bvh", ".trc"),
    ("cmu/10_01.amc", ".c3d"),
])
def test_convert_keeps_positions_and_gaps(tmp_path, source, target):
    path = shared_file(source)
    out = tmp_path / f"converted{target}"
    result = run("convert", path, out)
    assert result.exit_code == 0, result.output
    before, after = formats.read(path), formats.read(out)
    assert after.n_frames == before.n_frames and after.n_markers == before.n_markers
    np.testing.assert_array_equal(after.observed, before.observed)
    # A unit no other tool reads (in/0.45, CMU AMC) is written as mm; others are kept.
    scale = 1.0
    if after.units != before.units:
        assert after.units == "mm"
        scale = mm_per_unit(before.units)
    np.testing.assert_allclose(after.positions[after.observed],
                               scale * before.positions[before.observed], rtol=1e-5,
                               atol=1e-3)


def test_c3d_repair_through_the_cli_changes_only_filled_samples(tmp_path):
    path = shared_file("c3d/ezc3d-Vicon.c3d")
    out = tmp_path / "out.c3d"
    result = run("repair", path, out, "--method", "linear")
    assert result.exit_code == 0, result.output
    before, after = path.read_bytes(), out.read_bytes()
    assert len(before) == len(after)
    source = formats.read(path).source
    repaired = formats.read(out)
    filled = repaired.observed & ~formats.read(path).observed
    assert filled.any()
    # Every differing byte lies inside the four words of a filled (frame, point) sample.
    diff = np.flatnonzero(np.frombuffer(before, np.uint8) != np.frombuffer(after, np.uint8))
    offset = diff - source.data_start
    frame, within = np.divmod(offset, source.frame_stride)
    point = within // (4 * source.word_size)
    marker_of_point = {p: j for j, p in enumerate(source.point_index)}
    assert all(filled[f, marker_of_point[p]] for f, p in zip(frame, point))


def test_simulate_repair_score_on_a_cmu_clip_beats_linear(tmp_path):
    clip = shared_file("cmu/85_02.c3d")
    gapped = tmp_path / "gapped.c3d"
    assert run("simulate", clip, gapped, "--ml", "40", "--seed", "1").exit_code == 0
    scores = {}
    for method in ("trnn", "linear"):
        out = tmp_path / f"{method}.c3d"
        assert run("repair", gapped, out, "--method", method).exit_code == 0
        result = run("score", clip, out, "--gapped", gapped, "--json")
        scores[method] = __import__("json").loads(result.stdout)["rmse_mm"]
    assert scores["trnn"] < scores["linear"]


def test_a_cmu_amc_scores_its_converted_and_repaired_c3d_as_the_c3d_does(tmp_path):
    # convert writes AMC positions in mm: score refused the AMC (in/0.45) as the truth.
    amc = shared_file("cmu/10_01.amc")
    converted, gapped, repaired = (tmp_path / f"{n}.c3d" for n in ("c", "g", "r"))
    assert run("convert", amc, converted).exit_code == 0
    assert run("simulate", converted, gapped, "--ml", "30", "--seed", "1").exit_code == 0
    assert run("repair", gapped, repaired, "--method", "linear").exit_code == 0
    from_amc = run("score", amc, repaired, "--json")
    assert from_amc.exit_code == 0, from_amc.output
    from_c3d = json.loads(run("score", converted, repaired, "--json").stdout)
    scored = json.loads(from_amc.stdout)
    assert scored["missing_samples"] == from_c3d["missing_samples"] == 300
    assert scored["rmse_mm"] == pytest.approx(from_c3d["rmse_mm"], rel=1e-6)
    assert scored["rmse"] == pytest.approx(from_c3d["rmse_mm"] / mm_per_unit("in/0.45"),
                                           rel=1e-6)


@pytest.mark.parametrize("bad, words", [
    ("bad/gait-raw-csv-text.c3d", "not a C3D file"),
    ("c3d/ezc3d-Optotrak.c3d", "truncated"),
])
def test_bad_files_are_refused_in_one_line_and_nothing_is_written(tmp_path, bad, words):
    out = tmp_path / "out.c3d"
    result = run("repair", shared_file(bad), out)
    assert result.exit_code == 123
    assert words in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_truncated_trc_reads_what_is_there(tmp_path):
    result = run("info", shared_file("bad/pyomeca-markers-comma-truncated.trc"), "--json")
    assert result.exit_code == 0
    assert __import__("json").loads(result.stdout)["frames"] == 93


def test_every_format_reports_info_rank_and_simulates(tmp_path):
    for name in ("c3d/c3dorg-Sample26__Capture0002.c3d", "trc/btk-Res16bits.trc",
                 "csv/mogapfill-gait-raw-headerless.csv", "cmu/12_01.bvh"):
        path = shared_file(name)
        assert run("info", path).exit_code == 0, name
        assert run("rank", path, "--json").exit_code == 0, name
        sim = tmp_path / f"sim{path.suffix}"
        result = run("simulate", path, sim, "--mr", "0.2", "--seed", "3")
        assert result.exit_code == 0, (name, result.output)
        assert (~formats.read(sim).observed).sum() > (~formats.read(path).observed).sum()


def test_bvh_simulate_and_repair_through_the_cli_patch_only_gap_cells(tmp_path):
    clip = shared_file("cmu/10_01.bvh")
    gapped, out = tmp_path / "gapped.bvh", tmp_path / "out.bvh"
    assert run("simulate", clip, gapped, "--ml", "20", "--markers", "3", "--seed", "4"
               ).exit_code == 0
    result = run("repair", gapped, out, "--method", "spline")
    assert result.exit_code == 0, result.output
    before, after = gapped.read_bytes().decode("latin-1"), out.read_bytes().decode("latin-1")
    assert assert_only_nan_tokens_replaced(before, after) == before.split().count("nan") > 0
    assert "nan" not in after


def test_max_jump_option_rejects_fills_and_reports_them(tmp_path):
    report = tmp_path / "gaps.json"
    result = run("repair", shared_file("c3d/ezc3d-Vicon.c3d"), tmp_path / "o.c3d",
                 "--method", "linear", "--max-jump", "0.001", "--gaps-report", report)
    assert result.exit_code == 0, result.output
    statuses = {row["status"] for row in __import__("json").loads(report.read_text())["gaps"]}
    assert "rejected: jump" in statuses
