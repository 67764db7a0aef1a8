"""The command line: exit codes, one-line errors, atomic outputs, JSON shapes."""
import errno
import json
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mocapfill import formats
from mocapfill.cli import main
from mocapfill.motion import Motion

from .helpers import smooth_clip, with_gap


@pytest.fixture
def clip_files(tmp_path):
    truth = smooth_clip(300, 10)
    gapped = with_gap(with_gap(truth, 1, 50, 110), 4, 150, 190)
    formats.write(truth, tmp_path / "truth.npz")
    formats.write(gapped, tmp_path / "gapped.npz")
    return tmp_path


def run(*args):
    result = CliRunner().invoke(main, [str(a) for a in args])
    return result


def test_repair_writes_a_complete_file_and_a_summary(clip_files):
    result = run("repair", clip_files / "gapped.npz", clip_files / "out.npz")
    assert result.exit_code == 0, result.output
    assert "2 gaps filled" in result.stderr
    assert formats.read(clip_files / "out.npz").observed.all()


@pytest.mark.parametrize(("asked", "noted"), [(500, True), (10, False), (4, False)])
def test_simulate_notes_when_ml_cannot_hit_as_many_markers_as_asked(clip_files, asked,
                                                                    noted):
    # The 10-marker clip: --markers 500 used to hit all 10 without a word.
    result = run("simulate", clip_files / "truth.npz", clip_files / "s.npz", "--ml", "20",
                 "--markers", asked, "--seed", "1")
    assert result.exit_code == 0, result.output
    note = (f"mocapfill: note: {clip_files / 'truth.npz'}: --markers {asked} but the clip has "
            "10 markers with data; --ml hit all 10")
    assert (note in result.stderr) == noted
    assert ("note:" in result.stderr) == noted
    hit = (~formats.read(clip_files / "s.npz").observed).any(axis=0).sum()
    assert hit == min(asked, 10)


def test_simulate_notes_the_markers_without_room_for_an_ml_run(clip_files):
    # Markers 0–3 of the 10 are gapped every 15 frames: no 22 frames seen in a row for a
    # run of 20, so --ml hits the 6 others, and the note says why.
    motion = formats.read(clip_files / "truth.npz")
    observed = motion.observed.copy()
    observed[::15, :4] = False
    formats.write(motion.with_positions(motion.positions, observed), clip_files / "g.npz")
    result = run("simulate", clip_files / "g.npz", clip_files / "s.npz", "--ml", "20",
                 "--markers", "8", "--seed", "1")
    assert result.exit_code == 0, result.output
    assert (f"mocapfill: note: {clip_files / 'g.npz'}: --markers 8 but the clip has 6 markers "
            "with data and 22 frames seen in a row; --ml hit all 6") in result.stderr
    new = observed & ~formats.read(clip_files / "s.npz").observed
    assert new.any(axis=0).tolist() == [False] * 4 + [True] * 6


def test_simulate_repair_score_chain_beats_linear_interpolation(clip_files):
    d = clip_files
    assert run("simulate", d / "truth.npz", d / "sim.npz", "--ml", "40", "--seed", "1",
               "--markers", "5").exit_code == 0
    errors = {}
    for method in ("trnn", "linear"):
        assert run("repair", d / "sim.npz", d / f"{method}.npz", "--method", method
                   ).exit_code == 0
        scored = run("score", d / "truth.npz", d / f"{method}.npz", "--gapped", d / "sim.npz",
                     "--json")
        errors[method] = json.loads(scored.stdout)
    assert errors["trnn"]["missing_samples"] == 5 * 40
    assert errors["trnn"]["rmse_mm"] < errors["linear"]["rmse_mm"]
    assert errors["trnn"]["rmse_3d"] == pytest.approx(errors["trnn"]["rmse"] * np.sqrt(3))


def test_rank_json_has_rank_and_singular_values(clip_files):
    result = run("rank", clip_files / "gapped.npz", "--json")
    payload = json.loads(result.stdout)
    assert set(payload) == {"rank", "singular_values"}
    assert 1 <= payload["rank"] <= 30 and len(payload["singular_values"]) == 30


def test_info_reports_per_marker_gaps(clip_files):
    result = run("info", clip_files / "gapped.npz", "--json")
    rows = {r["marker"]: r for r in json.loads(result.stdout)["per_marker"]}
    assert rows["MK01"]["missing"] == 60 and rows["MK01"]["longest_gap_frames"] == 60
    assert rows["MK04"]["longest_gap_s"] == pytest.approx(40 / 120, abs=1e-4)
    text = run("info", clip_files / "gapped.npz").stdout
    assert "MK01" in text and "60/300" in text


def test_info_json_of_a_clip_without_rate_is_valid_json(clip_files):
    formats.write(formats.read(clip_files / "gapped.npz").replace(rate=0.0),
                  clip_files / "norate.npz")
    result = run("info", clip_files / "norate.npz", "--json")
    rows = json.loads(result.stdout, parse_constant=lambda name: pytest.fail(name))
    assert rows["per_marker"][1]["longest_gap_s"] is None
    table = run("info", clip_files / "norate.npz").stdout
    assert "with no frame rate (0 Hz)" in table
    # The longest gap in frames, and no "nan s" for its seconds.
    assert "nan" not in table and " fr      –" in table


def test_info_before_after_names_what_differs(clip_files):
    gapped = formats.read(clip_files / "gapped.npz")
    renamed = gapped.replace(labels=("X",) + gapped.labels[1:])
    formats.write(renamed, clip_files / "renamed.npz")
    formats.write(smooth_clip(299, 10), clip_files / "short.npz")
    names = run("info", clip_files / "gapped.npz", clip_files / "renamed.npz")
    assert names.exit_code == 123 and "marker names ('X' where it has 'MK00')" in names.stderr
    size = run("info", clip_files / "gapped.npz", clip_files / "short.npz")
    assert "(10 × 299, the original 10 × 300)" in size.stderr


def test_info_json_refuses_a_repaired_file_that_does_not_match(clip_files):
    # --json printed "before" and "after" tables of two different clips without a word,
    # where the table refuses them.
    formats.write(smooth_clip(299, 10), clip_files / "short.npz")
    result = run("info", clip_files / "gapped.npz", clip_files / "short.npz", "--json")
    assert result.exit_code == 123 and result.stdout == ""
    assert "(10 × 299, the original 10 × 300)" in result.stderr


def test_info_json_gaps_only_lists_only_markers_with_missing_samples(clip_files):
    # --gaps-only was ignored with --json: every marker was listed.
    alone = json.loads(run("info", clip_files / "gapped.npz", "--json", "--gaps-only").stdout)
    assert [r["marker"] for r in alone["per_marker"]] == ["MK01", "MK04"]
    assert alone["missing_samples"] == 100
    run("repair", clip_files / "gapped.npz", clip_files / "o.npz", "--method", "linear")
    both = json.loads(run("info", clip_files / "gapped.npz", clip_files / "o.npz", "--json",
                          "--gaps-only").stdout)
    assert [r["marker"] for r in both["before"]["per_marker"]] == ["MK01", "MK04"]
    assert [r["marker"] for r in both["after"]["per_marker"]] == ["MK01", "MK04"]


def test_gaps_report_lists_every_gap(clip_files):
    report = clip_files / "gaps.csv"
    run("repair", clip_files / "gapped.npz", clip_files / "o.npz", "--max-gap", "0.4s",
        "--gaps-report", report)
    lines = report.read_text().splitlines()
    assert lines[0] == "marker,first_frame,last_frame,length_frames,length_s,method,status"
    assert lines[1:] == ["MK01,51,110,60,0.5,,left: too long",
                         "MK04,151,190,40,0.333333,trnn,filled"]


def test_check_exits_1_when_gaps_are_left(clip_files):
    result = run("repair", clip_files / "gapped.npz", clip_files / "o.npz", "--max-gap", "10",
                 "--check")
    assert result.exit_code == 1


@pytest.mark.parametrize("args, code, words", [
    (["repair", "missing.npz", "o.npz"], 2, "no such file"),
    (["repair", "gapped.npz", "o.xyz"], 2, "unknown file type"),
    (["repair", "gapped.npz", "o.npz", "--rank", "-3"], 2, "--rank must be > 0"),
    (["repair", "gapped.npz", "o.npz", "--max-gap", "soon"], 2, "--max-gap"),
    (["simulate", "truth.npz", "s.npz", "--mr", "1.5"], 2, "mr must be in [0, 1)"),
    (["info", "skeleton.asf"], 2, "pass the .amc"),
    # A known suffix that is not written: advice about outputs, not about inputs.
    (["repair", "gapped.npz", "o.mat"], 2,
     "o.mat: .mat files are not written; name the output .c3d, .trc, .csv, .txt, .npz"),
    (["convert", "gapped.npz", "o.asf"], 2, "o.asf: .asf files are not written"),
    (["info", "broken.npz"], 123, "broken.npz"),
    # Found by an audit of the command line: these raised tracebacks (exit 1), printed
    # click's usage block, or wrote the output before failing.
    (["repair", "gapped.npz", "o.npz", "--method", "linear", "--rank", "5"], 2,
     "--rank does not apply to method 'linear'"),
    (["repair", "gapped.npz", "o.npz", "--method", "trnn-lowrank", "--rank", "31"], 2,
     "gapped.npz: --rank 31 is larger than this clip allows (30"),
    (["repair", "gapped.npz", "o.npz", "--mu", "nan"], 2, "--mu must be finite"),
    (["repair", "gapped.npz", "o.npz", "--max-gap", "infs"], 2, "--max-gap must be a finite"),
    (["repair", "gapped.npz", "o.npz", "--max-gap", "inf"], 2, "--max-gap must be a finite"),
    (["repair", "gapped.npz", "./gapped.npz"], 2, "refusing to overwrite the input file"),
    (["plot", "empty.npz", "-o", "p.png"], 123, "empty.npz: nothing to draw"),
    # The output folder is checked as repair and convert check it, not reported as the
    # temporary file's OSError (exit 123).
    (["plot", "gapped.npz", "-o", "nodir/p.png"], 2,
     "nodir/p.png: output folder nodir does not exist"),
    (["plot", "gapped.npz", "-o", "folder.png"], 2, "folder.png: is a folder"),
    # These said "unknown file type '(no suffix)'", the empty OUT naming itself ".".
    (["repair", "trials", "o.npz"], 2,
     "trials: is a folder; to repair the files in it give -o OUTDIR (or --in-place)"),
    (["info", "trials"], 2, "trials: is a folder, not a file"),
    (["convert", "trials", "o.npz"], 2, "trials: is a folder, not a file"),
    (["repair", "gapped.npz", ""], 2, "'OUT': the path is empty: name a file to write"),
    (["convert", "gapped.npz", ""], 2, "'OUT': the path is empty: name a file to write"),
    (["plot", "gapped.npz", "-o", ""], 2, "the path is empty: name a file to write"),
    (["repair", "gapped.npz", "o.npz", "--gaps-report", ""], 2, "the path is empty"),
    (["repair", "gapped.npz", "-o", ""], 2, "the path is empty: name a folder"),
    # As repair says it: the file named (it was "no marker matches NOPE" alone).
    (["plot", "gapped.npz", "-o", "p.png", "--markers", "NOPE"], 2,
     "gapped.npz: --markers NOPE matches no marker (the clip has MK00, MK01"),
    (["repair", "gapped.npz", "o.npz", "--method", "bogus"], 2,
     "Invalid value for '--method'"),
    (["repair", "gapped.npz", "o.npz", "--gaps-report", "nodir/g.csv"], 2,
     "folder nodir does not exist"),
    (["repair", "gapped.npz", "o.npz", "--gaps-report", "g.txt"], 2, ".csv or .json"),
    (["simulate", "truth.npz", "s.npz", "--ml", "10", "--seed", "-1"], 2, "seed must be ≥ 0"),
    (["repair", "one.npz", "o.npz"], 123, "one.npz: a clip of 1 frame(s) cannot be repaired"),
    (["repair", "gapped.npz", "o.bvh"], 2, "o.bvh: BVH output needs a BVH input"),
    (["convert", "gapped.npz", "o.amc"], 2, "o.amc: AMC output needs an AMC input"),
    (["repair", "gapped.npz", "o.npz", "--gaps-report", "folder.csv"], 2,
     "--gaps-report folder.csv is a folder"),
    # A gap length in seconds means nothing without a rate (it used to mean 0 frames).
    (["repair", "norate.npz", "o.npz", "--max-gap", "0.5s"], 2,
     "norate.npz: the file states no frame rate, so --max-gap 0.5s"),
    # An empty method list used to print an empty table and exit 0; refused before any run.
    (["bench", "accuracy", "--quick", "--methods", ""], 2, "--methods '' names no method"),
    (["bench", "accuracy", "--quick", "--methods", " , "], 2,
     "--methods ' , ' names no method"),
    (["bench", "accuracy", "--quick", "--methods", "linear,bogus"], 2,
     "unknown method(s) bogus"),
    # --markers counts the markers --ml hits; with --mr it was ignored without a word.
    (["simulate", "truth.npz", "s.npz", "--mr", "0.4", "--markers", "5"], 2,
     "--markers applies to --ml"),
])
def test_bad_input_gives_one_line_error_and_exit_code(clip_files, monkeypatch, args, code, words):
    monkeypatch.chdir(clip_files)
    (clip_files / "broken.npz").write_bytes(b"not a zip file at all")
    formats.write(smooth_clip(1, 3), clip_files / "one.npz")
    (clip_files / "folder.csv").mkdir()
    (clip_files / "folder.png").mkdir()
    (clip_files / "trials").mkdir()
    formats.write(with_gap(smooth_clip(100, 3), 1, 40, 45).replace(rate=0.0),
                  clip_files / "norate.npz")
    formats.write(Motion(np.zeros((5, 0, 3)), np.zeros((5, 0), bool), (), 100.0),
                  clip_files / "empty.npz")
    result = run(*args)
    assert result.exit_code == code
    assert words in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.output
    assert not (clip_files / "o.npz").exists() and not (clip_files / "s.npz").exists()


@pytest.mark.parametrize("out", ["o.xyz", "o.bvh", "nodir/o.c3d", "sub"])
def test_an_output_that_cannot_be_written_is_refused_before_the_repair(clip_files,
                                                                       monkeypatch, out):
    from mocapfill import pipeline

    (clip_files / "sub").mkdir()
    monkeypatch.chdir(clip_files)
    monkeypatch.setattr(pipeline, "repair", lambda *a, **k: pytest.fail("repair ran"))
    result = run("repair", "gapped.npz", out)
    assert result.exit_code == 2 and len(result.stderr.strip().splitlines()) == 1, \
        result.output


def test_failed_write_leaves_no_partial_output(clip_files, monkeypatch):
    from mocapfill.formats import npz

    def explode(motion, path, **_):
        path.write_bytes(b"half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(npz, "write", explode)
    result = run("repair", clip_files / "gapped.npz", clip_files / "o.npz")
    assert result.exit_code == 123
    assert list(clip_files.glob("*o.npz*")) == []


def test_gaps_report_never_replaces_the_input_or_the_output(clip_files, monkeypatch):
    monkeypatch.chdir(clip_files)
    formats.write(formats.read(clip_files / "gapped.npz"), clip_files / "in.csv")
    before = (clip_files / "in.csv").read_bytes()
    for report in ("./in.csv", "out.csv"):
        result = run("repair", "in.csv", "out.csv", "--method", "linear",
                     "--gaps-report", report)
        assert result.exit_code == 2 and "--gaps-report" in result.stderr
        assert (clip_files / "in.csv").read_bytes() == before
        assert not (clip_files / "out.csv").exists()
    assert run("repair", "in.csv", "out.csv", "--gaps-report", "gaps.csv").exit_code == 0
    assert (clip_files / "gaps.csv").read_text().startswith("marker,first_frame")
    assert sorted(p.name for p in clip_files.glob(".*")) == []    # no temporaries left


@pytest.mark.parametrize("args, words", [
    (["truth.npz", "truth.npz", "--json"], "truth.npz: nothing to score: no filled sample"),
    # The gapped file as TRUTH: every sample the repair filled is missing in it.
    (["gapped.npz", "o.npz"], "o.npz: nothing to score: no filled sample is observed in "
                              "the truth gapped.npz"),
    (["truth.npz", "o.npz", "--gapped", "truth.npz"], "truth.npz: nothing to score: no "
                                                       "sample missing here"),
    (["truth.npz", "gapped.npz", "--gapped", "gapped.npz"],
     "gapped.npz: nothing to score: none of the 100 samples to score is filled"),
])
def test_score_with_nothing_to_score_is_a_failed_file_not_an_rmse_of_nan(clip_files,
                                                                          monkeypatch,
                                                                          args, words):
    monkeypatch.chdir(clip_files)
    assert run("repair", "gapped.npz", "o.npz").exit_code == 0
    result = run("score", *args)
    assert result.exit_code == 123
    assert words in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert result.stdout == ""


def test_score_as_dict_is_valid_json_when_nothing_is_scored(clip_files):
    from mocapfill.metrics import score

    def no_nan(constant):
        raise AssertionError(f"{constant} is not JSON")

    truth = formats.read(clip_files / "truth.npz")
    payload = json.loads(json.dumps(score(truth, truth).as_dict()), parse_constant=no_nan)
    assert payload["missing_samples"] == 0 and payload["rmse"] is None


@pytest.mark.parametrize("truth_suffix", [".csv", ".trc"])
def test_score_without_gapped_finds_the_fills_of_a_repair_stored_in_another_format(
        clip_files, truth_suffix):
    # A truth printed with 3 decimals and a repair stored as float32 C3D differ in every
    # sample by rounding; only the filled samples are scored, as --gapped would score them.
    d = clip_files
    truth = formats.read(d / "truth.npz")
    formats.write(truth, d / f"truth{truth_suffix}", decimals=3)
    gapped = formats.read(d / "gapped.npz")
    formats.write(gapped.with_positions(formats.read(d / f"truth{truth_suffix}").positions,
                                        gapped.observed), d / "gapped.csv")
    assert run("repair", d / "gapped.csv", d / "o.c3d", "--method", "linear").exit_code == 0
    alone = run("score", d / f"truth{truth_suffix}", d / "o.c3d", "--json")
    with_gapped = run("score", d / f"truth{truth_suffix}", d / "o.c3d", "--gapped",
                      d / "gapped.csv", "--json")
    assert alone.exit_code == 0, alone.output
    scored, expected = json.loads(alone.stdout), json.loads(with_gapped.stdout)
    assert scored["missing_samples"] + scored["unfilled_samples"] == 60 + 40
    assert scored == pytest.approx(expected)


def test_score_refuses_files_whose_markers_or_units_differ(clip_files):
    truth = formats.read(clip_files / "truth.npz")
    renamed = truth.replace(labels=("OTHER",) + tuple(truth.labels[1:]))
    formats.write(renamed, clip_files / "renamed.npz")
    formats.write(truth.replace(units="unknown"), clip_files / "unknown.npz")
    for other, words in (("renamed.npz", "'OTHER'"),
                         ("unknown.npz", "is in unknown, truth file")):
        result = run("score", clip_files / "truth.npz", clip_files / other)
        assert result.exit_code == 123
        assert words in result.stderr and "truth.npz" in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    assert "'unknown' is not a known length" in result.stderr


def test_score_compares_files_in_different_known_length_units_in_mm(clip_files):
    # A CMU AMC (in/0.45) against the C3D convert wrote from it (mm) was refused.
    d = clip_files
    assert run("repair", d / "gapped.npz", d / "o.npz", "--method", "linear").exit_code == 0
    repaired = formats.read(d / "o.npz")
    formats.write(repaired.replace(positions=repaired.positions / 1000, units="m"),
                  d / "o-metres.npz")
    truth = formats.read(d / "truth.npz")
    factor = 25.4 / 0.45
    formats.write(truth.replace(positions=truth.positions / factor, units="in/0.45"),
                  d / "truth-cmu.npz")
    same = json.loads(run("score", d / "truth.npz", d / "o.npz", "--json").stdout)
    assert (same["missing_samples"], same["unfilled_samples"]) == (60, 40)
    for truth_file, repaired_file in (("truth.npz", "o-metres.npz"),
                                      ("truth-cmu.npz", "o.npz"),
                                      ("truth-cmu.npz", "o-metres.npz")):
        result = run("score", d / truth_file, d / repaired_file, "--json")
        assert result.exit_code == 0, result.output
        scored = json.loads(result.stdout)
        assert (scored["missing_samples"], scored["unfilled_samples"]) == (60, 40)
        assert scored["rmse_mm"] == pytest.approx(same["rmse_mm"], rel=1e-9)
        in_truth_units = same["rmse"] / (factor if truth_file == "truth-cmu.npz" else 1)
        assert scored["rmse"] == pytest.approx(in_truth_units, rel=1e-9)
    text = run("score", d / "truth-cmu.npz", d / "o.npz").stdout
    assert text.startswith(f"RMSE {same['rmse'] / factor:.6g} in/0.45 (") and \
        f"= {same['rmse_mm']:.3f} mm" in text


def test_input_file_is_never_modified(clip_files):
    before = (clip_files / "gapped.npz").read_bytes()
    run("repair", clip_files / "gapped.npz", clip_files / "o.npz")
    assert (clip_files / "gapped.npz").read_bytes() == before


def test_every_command_has_help_with_units():
    for command in ("repair", "simulate", "rank", "score", "info", "convert"):
        result = run(command, "--help")
        assert result.exit_code == 0 and "Usage" in result.output
    assert "seconds" in run("repair", "--help").output


def test_info_with_repaired_file_shows_before_and_after(clip_files):
    run("repair", clip_files / "gapped.npz", clip_files / "o.npz")
    result = run("info", clip_files / "gapped.npz", clip_files / "o.npz", "--gaps-only")
    lines = result.stdout.splitlines()
    assert "missing samples 100 -> 0" in lines[0]
    assert [line.split()[0] for line in lines[2:]] == ["MK01", "MK04"]
    assert "60/300" in lines[2] and "0/300" in lines[2]


def test_plot_command_writes_the_image(clip_files):
    pytest.importorskip("matplotlib")
    run("repair", clip_files / "gapped.npz", clip_files / "o.npz")
    result = run("plot", clip_files / "gapped.npz", clip_files / "o.npz", "-o",
                 clip_files / "p.png")
    assert result.exit_code == 0, result.output
    assert (clip_files / "p.png").read_bytes().startswith(b"\x89PNG")
    assert "MK01, MK04" in result.stderr


def test_cli_method_names_match_the_solver_registry():
    # The CLI keeps its own list so `mocapfill --help` need not import numpy; it must
    # name exactly the registered methods.
    from mocapfill.cli import METHOD_NAMES
    from mocapfill.solvers import METHODS

    assert set(METHOD_NAMES) == set(METHODS)


@pytest.mark.parametrize("option", ["rho", "eta0", "tol", "max_iter"])
def test_repair_help_states_each_methods_own_default(option):
    # "--max-iter: Default 500." held for the TrNN family and tsmc only (svt, ialm and
    # psvt stop at 1000, gaussian at 60); the same for --tol, --rho and --eta0.
    import inspect

    from mocapfill.solvers import METHODS, get_method

    help_text = next(" ".join(p.help.split()) for p in main.commands["repair"].params
                     if p.name == option)
    for method in METHODS:
        default = inspect.signature(get_method(method)).parameters.get(option)
        if method == "trnn" or default is None:     # trnn: trnn-lowrank's, stated as trnn
            continue
        value = default.default
        shown = (f"{value:.0e}" if value < 1e-3 else f"{value:g}").replace("e-0", "e-")
        named = "trnn" if method == "trnn-lowrank" else method
        said = [part for part in help_text.split(" / ") if re.search(rf"\b{shown}\b", part)]
        assert any(re.search(rf"[(, ]{re.escape(named)}[),]", part) for part in said), \
            (method, shown, help_text)


def test_a_bad_thread_count_is_a_usage_error_and_writes_nothing(clip_files, monkeypatch):
    monkeypatch.setenv("MOCAPFILL_THREADS", "zero")
    result = run("repair", clip_files / "gapped.npz", clip_files / "out.npz")
    assert result.exit_code == 2
    assert result.stderr.count("\n") == 1 and "MOCAPFILL_THREADS" in result.stderr
    assert not (clip_files / "out.npz").exists()


# A command interrupted in its solve: the solvers' run_all starts a solver thread (as the
# real one does), writes "started" and waits; SIGINT then reaches it as KeyboardInterrupt.
_INTERRUPTIBLE = """
import atexit, os, sys, threading, time
if os.path.exists("started"):       # a shell loop that went on to the next file
    sys.exit(0)
from mocapfill.solvers import gapwise

def stalled(jobs, lanes=None, **options):
    threading.Thread(target=time.sleep, args=(60,), name="mocapfill-0", daemon=True).start()
    open("started", "w").close()
    if os.environ.get("SELF_INTERRUPT"):
        raise KeyboardInterrupt
    time.sleep(60)

gapwise.run_all = stalled
atexit.register(lambda: print("finalised", flush=True))
sys.argv = ["mocapfill", "repair", "gapped.npz", sys.argv[1]]
from mocapfill.__main__ import run
run()
"""


def test_ctrl_c_ends_the_command_by_sigint_at_once_under_the_solver_threads(clip_files):
    # By SIGINT, not by exit(130): a shell loop over files stops only then (next test).
    # At once: finalising the interpreter while a solver thread was inside pocketfft
    # aborted the process (SIGABRT, 6 of 16 interrupted repairs of 85_12).
    import os
    import signal
    import subprocess

    done = subprocess.run([sys.executable, "-c", _INTERRUPTIBLE, "o.npz"], cwd=clip_files,
                          capture_output=True, text=True, timeout=60,
                          env={**os.environ, "SELF_INTERRUPT": "1"})
    assert done.returncode == -signal.SIGINT
    assert done.stderr == "mocapfill: error: interrupted\n"
    assert "finalised" not in done.stdout
    assert not (clip_files / "o.npz").exists()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX shells and process groups")
def test_ctrl_c_stops_a_shell_loop_over_files(clip_files):
    # Ctrl-C reaches the terminal's whole process group: the shell and the command. The
    # shell goes on with its loop unless the command died of SIGINT; mocapfill exited 130
    # by itself, and a loop over a thousand clips took a Ctrl-C per clip.
    import os
    import shutil
    import signal
    import subprocess
    import time

    if shutil.which("bash") is None:
        pytest.skip("no bash on this machine")
    script = clip_files / "interruptible.py"
    script.write_text(_INTERRUPTIBLE)
    loop = (f'for out in a.npz b.npz; do "{sys.executable}" {script.name} "$out"; '
            f'echo "after $out: $?"; done')

    def own_group_with_default_sigint():
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        os.setpgrp()

    shell = subprocess.Popen(["bash", "-c", loop], cwd=clip_files, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             preexec_fn=own_group_with_default_sigint)
    try:
        deadline = time.monotonic() + 60
        while not (clip_files / "started").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        os.killpg(shell.pid, signal.SIGINT)
        out, err = shell.communicate(timeout=60)
    finally:
        if shell.poll() is None:
            os.killpg(shell.pid, signal.SIGKILL)
    assert "after" not in out, out           # the loop stopped with the first file
    assert err.count("mocapfill: error: interrupted") == 1
    assert not list(clip_files.glob("[ab].npz"))


def _wait_for(path, seconds: float = 60) -> None:
    import time

    deadline = time.monotonic() + seconds
    while not path.exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert path.exists(), f"{path.name} never appeared"


@pytest.mark.parametrize(("stop", "words"), [("SIGTERM", "terminated"), ("SIGHUP", "hung up")])
def test_sigterm_and_sighup_stop_the_command_as_ctrl_c_does_and_end_it_so(clip_files, stop,
                                                                          words):
    # `timeout`, a scheduler's cancel, a closed terminal: the command stopped where it
    # stood (a file being written kept its temporary) and said nothing. Sent twice, as
    # `timeout` does (to the command, then to its process group).
    import signal
    import subprocess

    if not hasattr(signal, stop):
        pytest.skip(f"no {stop} here")
    signum = getattr(signal, stop)
    # With the signal's default action, whatever this test runs under: the command keeps
    # a caller's SIG_IGN (a suite started with `nohup` ignores SIGHUP), and then waited.
    command = subprocess.Popen([sys.executable, "-c", _INTERRUPTIBLE, "o.npz"],
                               cwd=clip_files, text=True, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE,
                               preexec_fn=lambda: signal.signal(signum, signal.SIG_DFL))
    try:
        _wait_for(clip_files / "started")
        command.send_signal(signum)
        command.send_signal(signum)
        out, err = command.communicate(timeout=60)
    finally:
        command.kill()
    assert command.returncode == -signum
    assert err == f"mocapfill: error: {words}\n"
    assert "finalised" not in out and not (clip_files / "o.npz").exists()


def test_a_second_sigterm_does_not_break_off_the_stopping_of_the_first(monkeypatch):
    # `timeout` sends SIGTERM to the command and then to its process group; a second
    # Terminated raised inside the clean-up (the pool's workers being stopped) left them
    # unstopped.
    import signal

    from mocapfill import _interrupt

    monkeypatch.setattr(_interrupt, "_TERMINATED", [])
    with pytest.raises(_interrupt.Terminated):
        _interrupt._terminate(signal.SIGTERM, None)
    try:
        _interrupt._terminate(signal.SIGTERM, None)
    except _interrupt.Terminated:           # (a KeyboardInterrupt: pytest would stop)
        pytest.fail("the second SIGTERM raised again")
    assert _interrupt.reason() == "terminated"


_BATCH_STALLING_ON_ITS_SECOND_FILE = """
import sys, time
from mocapfill import batch
from mocapfill.__main__ import run

real = batch.repair_file
def second_stalls(job):
    if job.input.name == "b.npz":
        open("started", "w").close()
        time.sleep(60)
    return real(job)

batch.repair_file = second_stalls
sys.argv = ["mocapfill", "repair", "in", "-o", "out", "-j", "1", "--report", "r.json"]
run()
"""


def test_sigterm_stops_a_batch_with_its_report_of_the_files_finished(clip_files):
    import signal
    import subprocess

    (clip_files / "in").mkdir()
    for name in ("a.npz", "b.npz"):
        (clip_files / "in" / name).write_bytes((clip_files / "gapped.npz").read_bytes())
    command = subprocess.Popen([sys.executable, "-c", _BATCH_STALLING_ON_ITS_SECOND_FILE],
                               cwd=clip_files, text=True, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    try:
        _wait_for(clip_files / "started")
        command.send_signal(signal.SIGTERM)
        _, err = command.communicate(timeout=60)
    finally:
        command.kill()
    assert command.returncode == -signal.SIGTERM
    assert err.strip().splitlines()[-1] == "mocapfill: error: terminated"
    report = json.loads((clip_files / "r.json").read_text())
    assert [Path(f["input"]).name for f in report["files"]] == ["a.npz"]
    assert sorted(p.name for p in (clip_files / "out").iterdir()) == ["a.npz"]


def test_ctrl_c_while_the_command_line_loads_is_one_line_not_a_traceback(clip_files):
    # The console script loads click and every command's definition (a tenth of a second)
    # before any of mocapfill's handlers runs; Ctrl-C there printed a traceback.
    import signal
    import subprocess

    script = """
import builtins, os, signal
real_import = builtins.__import__

def importing(name, *args, **kwargs):
    if name == "click":
        os.kill(os.getpid(), signal.SIGINT)
    return real_import(name, *args, **kwargs)

builtins.__import__ = importing
from mocapfill.__main__ import run
run()
"""
    done = subprocess.run([sys.executable, "-c", script, "repair", "gapped.npz", "o.npz"],
                          cwd=clip_files, capture_output=True, text=True, timeout=60)
    assert done.returncode == -signal.SIGINT
    assert done.stderr == "mocapfill: error: interrupted\n"
    assert not (clip_files / "o.npz").exists()


def test_a_one_frame_skeleton_clip_is_refused_in_channel_space_too(tmp_path):
    from .formats.test_bvh import write_bvh

    path = write_bvh(tmp_path, ["0 0 0 0 0 0 10 20 30"])
    for out in ("o.bvh", "o.trc"):      # channel space (same format), then positions
        result = run("repair", path, tmp_path / out)
        assert result.exit_code == 123, out
        assert "a clip of 1 frame(s) cannot be repaired" in result.stderr
        assert not (tmp_path / out).exists()


def test_an_output_that_cannot_be_written_is_named_not_its_temporary(clip_files):
    (clip_files / "folder.npz").mkdir()
    result = run("repair", clip_files / "gapped.npz", clip_files / "folder.npz")
    assert result.exit_code == 2        # refused before the repair
    assert "folder.npz: is a folder" in result.stderr and ".tmp" not in result.stderr
    assert not [p for p in clip_files.iterdir() if p.name.startswith(".")]


def test_info_and_repair_tell_the_user_what_the_reader_worked_around(clip_files):
    # A file that ends inside its last row (an interrupted copy) loses that row's last
    # cell; the reader's note must reach the user, not only the source handle.
    formats.write(formats.read(clip_files / "gapped.npz"), clip_files / "full.csv")
    text = (clip_files / "full.csv").read_text()
    (clip_files / "cut.csv").write_text(text.rstrip("\n")[:-2])
    info = run("info", clip_files / "cut.csv")
    assert "note: the file ends inside its last row" in info.stdout
    assert json.loads(run("info", clip_files / "cut.csv", "--json").stdout)["notes"]
    assert json.loads(run("info", clip_files / "full.csv", "--json").stdout)["notes"] == []
    repaired = run("repair", clip_files / "cut.csv", clip_files / "o.csv")
    assert repaired.exit_code == 0
    assert "note: " in repaired.stderr and "cut.csv" in repaired.stderr


def test_plot_info_and_score_agree_on_a_repaired_file_that_does_not_match(clip_files):
    formats.write(smooth_clip(120, 10), clip_files / "other.npz")
    for command in (["plot", clip_files / "gapped.npz", clip_files / "other.npz", "-o",
                     clip_files / "p.png"],
                    ["info", clip_files / "gapped.npz", clip_files / "other.npz"],
                    ["score", clip_files / "truth.npz", clip_files / "other.npz"]):
        result = run(*command)
        assert result.exit_code == 123, command[0]
        assert "other.npz" in result.stderr and len(result.stderr.splitlines()) == 1


@pytest.mark.parametrize("args", [
    ["repair", "gapped.npz", "out.npz/"],
    ["convert", "gapped.npz", "out.csv/"],
    ["simulate", "truth.npz", "out.npz/", "--ml", "10"],
    ["plot", "gapped.npz", "-o", "out.png/"],
    ["repair", "gapped.npz", "o.npz", "--gaps-report", "out.csv/"],
])
def test_an_output_name_ending_in_a_slash_is_a_usage_error_not_a_file(clip_files, monkeypatch,
                                                                      args):
    # pathlib drops the slash: `-o plots/` used to write a file called "plots".
    monkeypatch.chdir(clip_files)
    before = sorted(p.name for p in clip_files.iterdir())
    result = run(*args)
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1 and "ends with '/'" in result.stderr
    assert sorted(p.name for p in clip_files.iterdir()) == before


_COMMAND = [sys.executable, "-m", "mocapfill.cli"]


@pytest.mark.parametrize(("args", "code", "stream", "words"), [
    (["repair", "gapped.npz", "out.npz"], 0, "stderr", "2 gaps filled"),
    (["repair", "gapped.npz", "out.npz", "--max-gap", "10", "--check"], 1, "stderr",
     "left"),
    (["repair", "missing.npz", "out.npz"], 2, "stderr", "no such file"),
    (["repair", "broken.c3d", "out.npz"], 123, "stderr", "broken.c3d"),
    (["info", "gapped.npz", "--json"], 0, "stdout", '"frames": 300, "markers": 10'),
])
def test_the_command_exits_with_its_code_and_its_output_flushed(clip_files, args, code,
                                                                  stream, words):
    # The command ends without Python's finalisation (cli.run): its exit code and
    # everything it printed must still come out.
    import subprocess

    (clip_files / "broken.c3d").write_bytes(b"\x02P" + bytes(100))
    done = subprocess.run(_COMMAND + args, cwd=clip_files, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == code, done.stderr
    assert words in getattr(done, stream)
    if code == 0 and args[0] == "repair":
        assert formats.read(clip_files / "out.npz").observed.all()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX file descriptors")
@pytest.mark.parametrize(("closed", "code", "args"), [
    (1, 0, ["repair", "gapped.npz", "out.npz"]),
    (2, 0, ["repair", "gapped.npz", "out.npz"]),
    (2, 2, ["repair", "missing.npz", "out.npz"]),
    (1, 0, ["info", "gapped.npz", "--json"]),
    (2, 0, ["repair", "gapped.npz", "copy.npz", "-o", "batch", "-j", "2"]),
])
def test_a_closed_standard_stream_changes_no_exit_code(clip_files, closed, code, args):
    # Started with stdout or stderr closed (`>&-`), Python has sys.stdout = None: the
    # exit's flush of it raised AttributeError, a traceback and exit 1 after a repair that
    # had succeeded; a batch asked it whether it was a terminal before its first file.
    import os
    import shutil
    import subprocess

    shutil.copy(clip_files / "gapped.npz", clip_files / "copy.npz")

    done = subprocess.run(_COMMAND + args, cwd=clip_files, text=True, timeout=120,
                          stdout=subprocess.PIPE if closed == 2 else None,
                          stderr=subprocess.PIPE if closed == 1 else None,
                          preexec_fn=lambda: os.close(closed))
    assert done.returncode == code
    assert "Traceback" not in (done.stdout or "") + (done.stderr or "")
    if code == 0 and args[0] == "repair":
        repaired = ["batch/gapped.npz", "batch/copy.npz"] if "-o" in args else ["out.npz"]
        assert all(formats.read(clip_files / name).observed.all() for name in repaired)


_WITH_A_THREAD = """
import atexit, sys, threading, time
from mocapfill.cli import run
if sys.argv[1] == "thread":
    threading.Thread(target=time.sleep, args=(0.3,)).start()
atexit.register(lambda: print("finalised", flush=True))
sys.argv = ["mocapfill", "--version"]
run()
"""


@pytest.mark.parametrize("other", ["none", "thread"])
def test_the_command_exits_at_once_unless_another_thread_runs(other):
    import subprocess

    done = subprocess.run([sys.executable, "-c", _WITH_A_THREAD, other], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0 and "version" in done.stdout
    assert ("finalised" in done.stdout) == (other == "thread")


def test_convert_to_trc_leaves_points_that_are_not_markers_out_and_says_so(clip_files):
    clip = formats.read(clip_files / "gapped.npz")
    fillable = np.ones(clip.n_markers, bool)
    fillable[[2, 5]] = False                    # model outputs, as a C3D reader marks them
    formats.write(clip.replace(fillable=fillable), clip_files / "model.npz")
    result = run("convert", clip_files / "model.npz", clip_files / "out.trc")
    assert result.exit_code == 0, result.output
    note = (f"mocapfill: note: {clip_files / 'out.trc'}: 2 point(s) that are not marker "
            "trajectories")
    assert result.stderr.splitlines()[0].startswith(note)
    assert f"{clip.n_markers - 2} markers" in result.stderr.splitlines()[-1]
    written = formats.read(clip_files / "out.trc")
    assert written.labels == tuple(label for j, label in enumerate(clip.labels)
                                   if j not in (2, 5))


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
@pytest.mark.parametrize("through_link", [False, True])
def test_an_output_that_is_a_named_pipe_is_written_through_not_replaced(tmp_path,
                                                                         through_link):
    # Renaming the temporary file over a device or pipe replaced the node itself
    # (`bench accuracy --json /dev/full` left a JSON file in place of the device).
    import stat
    import threading

    from mocapfill.formats import write_text_atomically

    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    target = fifo
    if through_link:
        target = tmp_path / "link.json"
        target.symlink_to(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_text()), daemon=True)
    reader.start()
    write_text_atomically(target, '{"rows": []}')
    reader.join(timeout=10)
    assert got == ['{"rows": []}']
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert target.is_symlink() == through_link
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({fifo.name, target.name})


@pytest.mark.skipif(os.name != "posix", reason="a umask is POSIX")
def test_a_new_output_gets_the_umask_without_the_process_setting_it(tmp_path, monkeypatch):
    # The umask was read by setting it to 0 and back (os.umask): for that moment every
    # thread of the process created its files 0666 (a logging thread's under umask 077).
    def set_umask(mask):
        raise AssertionError("os.umask called: the umask was 0 for every thread meanwhile")

    mask = os.umask(0o027)
    try:
        monkeypatch.setattr(os, "umask", set_umask)
        formats.write_text_atomically(tmp_path / "report.json", "{}\n")
        formats.write(smooth_clip(20, 2), tmp_path / "out.c3d")
    finally:
        monkeypatch.undo()
        os.umask(mask)
    assert {p.name: p.stat().st_mode & 0o777 for p in tmp_path.iterdir()} == {
        "report.json": 0o640, "out.c3d": 0o640}


@pytest.mark.skipif(os.name != "posix", reason="POSIX modes")
@pytest.mark.parametrize("through_link", [False, True])
def test_an_output_written_over_an_existing_file_keeps_its_mode(clip_files, through_link):
    # The new file got the mode of a new one (0666 less the umask): an output made 0600
    # came out 0644 when a repair was written over it, where cp or open() keep 0600.
    old = clip_files / "old.npz"
    old.write_bytes(b"old")
    old.chmod(0o600)
    out = clip_files / ("link.npz" if through_link else "old.npz")
    if through_link:
        out.symlink_to(old)
    report = clip_files / "gaps.json"
    report.write_text("old")
    report.chmod(0o640)
    result = run("repair", clip_files / "gapped.npz", out, "--method", "linear",
                 "--gaps-report", report)
    assert result.exit_code == 0, result.output
    assert formats.read(out).n_frames == 300 and report.read_text() != "old"
    assert (out.stat().st_mode & 0o7777, report.stat().st_mode & 0o7777) == (0o600, 0o640)
    result = run("repair", clip_files / "gapped.npz", clip_files / "new.npz", "--method",
                 "linear")
    mask = os.umask(0)
    os.umask(mask)
    assert (clip_files / "new.npz").stat().st_mode & 0o777 == 0o666 & ~mask


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="root gives files away")
def test_an_output_written_over_another_users_file_as_root_keeps_its_owner(clip_files):
    # As --in-place keeps them: root's repair made the file root's, 0600 and its owner
    # locked out.
    out = clip_files / "out.npz"
    out.write_bytes(b"old")
    os.chown(out, 65534, 65533)
    out.chmod(0o600)
    result = run("repair", clip_files / "gapped.npz", out, "--method", "linear")
    assert result.exit_code == 0, result.output
    info = out.stat()
    assert (info.st_uid, info.st_gid, info.st_mode & 0o7777) == (65534, 65533, 0o600)


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="Linux's /dev/full")
@pytest.mark.parametrize("args", [
    ["plot", "gapped.npz", "-o", "full.png"], ["plot", "gapped.npz", "-o", "full.svg"],
    ["plot", "gapped.npz", "-o", "full.html"],
    ["repair", "gapped.npz", "-o", "out", "-j", "1", "--report", "full.json"],
])
def test_an_output_on_a_full_device_is_named_in_the_error(clip_files, monkeypatch, args):
    # A write to a device (written through, not replaced) fails with an OSError that
    # names no file: the error was "No space left on device" alone.
    if args[0] == "plot":
        pytest.importorskip("matplotlib")
    monkeypatch.chdir(clip_files)
    out = next(a for a in args if a.startswith("full."))
    (clip_files / out).symlink_to("/dev/full")
    result = run(*args)
    assert result.exit_code == 123
    assert result.stderr.splitlines()[-1] == f"mocapfill: error: {out}: No space left on device"


def test_a_plot_that_fails_to_be_written_names_its_file(clip_files, monkeypatch):
    # A full disk fails the write with an OSError naming no file (the temporary's name, had
    # it been named, the user never gave).
    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    def full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Figure, "savefig", full)
    monkeypatch.chdir(clip_files)
    result = run("plot", "gapped.npz", "-o", "p.png")
    assert result.exit_code == 123
    assert result.stderr == "mocapfill: error: p.png: No space left on device\n"
    assert sorted(p.name for p in clip_files.iterdir()) == ["gapped.npz", "truth.npz"]


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="Linux's /proc/self/fd")
def test_an_output_that_is_the_commands_own_stdout_file_gets_the_text_after_it(tmp_path):
    # `bench accuracy --json /dev/stdout > out.txt`: /dev/stdout links to /proc/self/fd/1,
    # a regular file there, so the temporary file was renamed over the link (as root, the
    # system's /dev/stdout became a regular file) and out.txt kept the table alone. A link
    # of our own to /proc/self/fd/1 stands in for /dev/stdout.
    import subprocess

    link = tmp_path / "stdout-link"
    link.symlink_to("/proc/self/fd/1")
    script = ("import sys; from pathlib import Path; "
              "from mocapfill.formats import write_text_atomically; "
              "print('table', flush=True); "
              "write_text_atomically(Path(sys.argv[1]), '{\"rows\": []}\\n'); print('end')")
    out = tmp_path / "out.txt"
    with open(out, "w") as stdout:
        done = subprocess.run([sys.executable, "-c", script, str(link)], stdout=stdout,
                              stderr=subprocess.PIPE, text=True,
                              cwd=Path(__file__).resolve().parents[1])
    assert done.returncode == 0, done.stderr
    assert out.read_text() == 'table\n{"rows": []}\nend\n'
    assert link.is_symlink() and os.readlink(link) == "/proc/self/fd/1"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt", "stdout-link"]


def test_bench_output_files_are_checked_before_the_run(tmp_path, monkeypatch):
    import mocapfill.bench
    import mocapfill.bench_paper

    ran = []
    monkeypatch.setattr(mocapfill.bench, "run_accuracy", lambda *a, **k: ran.append(1) or [])
    monkeypatch.setattr(mocapfill.bench_paper, "run_paper", lambda *a, **k: ran.append(1))
    for args in (["accuracy", "--quick", "--methods", "linear", "--json"], ["paper", "--output"]):
        result = CliRunner().invoke(main, ["bench", *args, str(tmp_path / "nodir" / "x.out")])
        assert result.exit_code == 2
        assert "output folder" in result.output and "does not exist" in result.output
        assert ".tmp" not in result.output
    assert ran == []


def test_bench_plots_folder_named_empty_is_refused_before_the_run(tmp_path, monkeypatch):
    # `--plots ''` was read as '.', so the whole run started, to draw into the current
    # folder; as -o '' of repair it is a usage error, before any work.
    import mocapfill.bench
    import mocapfill.bench_paper

    ran = []
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(mocapfill.bench, "run_accuracy", lambda *a, **k: ran.append(1) or [])
    monkeypatch.setattr(mocapfill.bench_paper, "run_paper", lambda *a, **k: ran.append(1))
    for args in (["accuracy", "--quick", "--methods", "linear"], ["paper", "--quick"]):
        result = CliRunner().invoke(main, ["bench", *args, "--plots", ""])
        assert result.exit_code == 2, result.output
        assert "the path is empty: name a folder" in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
    assert ran == [] and list(tmp_path.iterdir()) == []


def test_bench_accuracy_plots_without_matplotlib_is_refused_before_the_run(tmp_path,
                                                                            monkeypatch):
    # The charts were drawn after the whole run: without matplotlib, an ImportError's
    # traceback (exit 1) at the end, and no table printed.
    import mocapfill.bench

    ran = []
    monkeypatch.setitem(sys.modules, "matplotlib", None)        # import raises ImportError
    monkeypatch.setattr(mocapfill.bench, "run_accuracy", lambda *a, **k: ran.append(1) or [])
    result = CliRunner().invoke(main, ["bench", "accuracy", "--quick", "--methods", "linear",
                                       "--plots", str(tmp_path / "charts")])
    assert result.exit_code == 2, result.output
    assert "--plots needs matplotlib: pip install matplotlib" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert ran == [] and not (tmp_path / "charts").exists()


def test_bench_accuracy_runs_a_method_named_twice_once(monkeypatch):
    # `--methods linear,spline,linear` ran linear twice on every case: its rows twice in
    # --json, and its table cell the mean of both runs (timings of two runs).
    import mocapfill.bench

    asked = []
    monkeypatch.setattr(mocapfill.bench, "run_accuracy",
                        lambda quick, methods, **k: asked.append(methods) or [])
    result = CliRunner().invoke(main, ["bench", "accuracy", "--quick", "--methods",
                                       "linear, spline,linear"])
    assert result.exit_code == 0, result.output
    assert asked == [["linear", "spline"]]


def test_simulate_names_a_skeleton_file_with_nothing_to_remove_in_channel_space_too(tmp_path):
    # "123: one line on stderr names it and why": the channel-space proxy clip had no
    # path, so the BVH → BVH error did not say which file had nothing to remove.
    from .formats.test_bvh import write_bvh

    path = write_bvh(tmp_path, [" ".join(["nan"] * 9)] * 3)
    for out in ("o.bvh", "o.trc"):      # channel space (same format), then positions
        result = run("simulate", path, tmp_path / out, "--ml", "1")
        assert result.exit_code == 123, out
        assert f"{path}: " in result.stderr, result.stderr
        assert not (tmp_path / out).exists()


def test_a_skeleton_clip_with_no_observed_channel_fails_in_channel_space_too(tmp_path):
    # README: a file with nothing to repair from fails (exit 123) for a single file too.
    # BVH → TRC failed so, but BVH → BVH wrote an unchanged copy and exited 0.
    from .formats.test_bvh import write_bvh

    path = write_bvh(tmp_path, [" ".join(["nan"] * 9)] * 3)
    for out in ("o.bvh", "o.trc"):      # channel space (same format), then positions
        result = run("repair", path, tmp_path / out)
        assert result.exit_code == 123, (out, result.stderr)
        assert f"{path}: " in result.stderr and "nothing to fill from" in result.stderr
        assert not (tmp_path / out).exists()


@pytest.mark.parametrize("stem", ["a" * 250, "é" * 125])      # 250 bytes, + .json: 255
def test_an_output_whose_name_is_as_long_as_the_file_system_allows_is_written(clip_files,
                                                                              stem):
    # The temporary file beside it is named after it: ".<name>.<random>.tmp" passed the
    # 255-byte limit of a name, and a name the file system takes failed with "File name
    # too long" (exit 123).
    out = clip_files / f"{stem}.npz"
    report = clip_files / f"{stem}.json"
    result = run("repair", clip_files / "gapped.npz", out, "--gaps-report", report)
    assert result.exit_code == 0, result.output
    assert formats.read(out).observed.all() and json.loads(report.read_text())
    assert not [p for p in clip_files.iterdir() if p.name.startswith(".")]


def test_a_gaps_report_named_by_a_symlink_loop_is_written_in_its_place(clip_files):
    # Path.resolve() raised RuntimeError on a loop: a traceback, and exit 1, which is
    # --check's "gaps left".
    report = clip_files / "gaps.csv"
    report.symlink_to("gaps.csv")
    result = run("repair", clip_files / "gapped.npz", clip_files / "out.npz",
                 "--gaps-report", report)
    assert result.exit_code == 0, result.output
    assert not report.is_symlink() and report.read_text().startswith("marker,")


def _disk_full(self, *args, **kwargs):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))


def test_a_gaps_report_that_cannot_be_written_is_named_not_its_temporary(clip_files,
                                                                          monkeypatch):
    # The error named ".gaps.csv.x1y2z3.tmp", a file the user never asked for.
    monkeypatch.setattr(Path, "write_text", _disk_full)
    report = clip_files / "gaps.csv"
    result = run("repair", clip_files / "gapped.npz", clip_files / "out.npz",
                 "--gaps-report", report)
    assert result.exit_code == 123
    assert result.stderr == f"mocapfill: error: {report}: No space left on device\n"
    assert not [p for p in clip_files.iterdir() if p.name.startswith(".")]


@pytest.mark.parametrize("out_exists", [False, True])
def test_a_gaps_report_that_cannot_be_written_leaves_no_new_or_changed_output(
        clip_files, monkeypatch, out_exists):
    # OUT was written (an existing one replaced) before the report failed: a run that
    # exits 123 left its output as if it had succeeded.
    monkeypatch.chdir(clip_files)
    if out_exists:
        (clip_files / "out.npz").write_bytes(b"old")
    monkeypatch.setattr(Path, "write_text", _disk_full)
    result = run("repair", "gapped.npz", "out.npz", "--method", "linear",
                 "--gaps-report", "gaps.json")
    assert result.exit_code == 123
    assert result.stderr == "mocapfill: error: gaps.json: No space left on device\n"
    assert ((clip_files / "out.npz").read_bytes() == b"old") if out_exists \
        else not (clip_files / "out.npz").exists()
    assert sorted(p.name for p in clip_files.iterdir()) == (
        ["gapped.npz", *(["out.npz"] if out_exists else []), "truth.npz"])


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="Linux's /dev/full")
def test_a_gaps_report_on_a_full_device_leaves_no_output(clip_files, monkeypatch):
    monkeypatch.chdir(clip_files)
    (clip_files / "gaps.json").symlink_to("/dev/full")
    result = run("repair", "gapped.npz", "out.npz", "--method", "linear",
                 "--gaps-report", "gaps.json")
    assert result.exit_code == 123
    assert result.stderr == "mocapfill: error: gaps.json: No space left on device\n"
    assert not (clip_files / "out.npz").exists()


def test_an_output_that_cannot_be_written_leaves_no_new_gaps_report(clip_files,
                                                                    monkeypatch):
    from mocapfill.formats import npz

    def full(motion, path, **_):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.chdir(clip_files)
    (clip_files / "gaps.csv").write_text("old")
    monkeypatch.setattr(npz, "write", full)
    result = run("repair", "gapped.npz", "out.npz", "--method", "linear",
                 "--gaps-report", "gaps.csv")
    assert result.exit_code == 123
    assert result.stderr == "mocapfill: error: out.npz: No space left on device\n"
    assert (clip_files / "gaps.csv").read_text() == "old"
    assert sorted(p.name for p in clip_files.iterdir()) == ["gapped.npz", "gaps.csv",
                                                            "truth.npz"]


@pytest.mark.parametrize("suffix", [".npz", ".c3d", ".csv"])
def test_an_input_that_cannot_be_read_says_why_not_that_it_cannot_be_parsed(clip_files,
                                                                             monkeypatch,
                                                                             suffix):
    # An unreadable file (permission denied) was "cannot parse (PermissionError: ...)",
    # and an .npz "not an .npz archive (no zip signature)": its content was blamed.
    import builtins
    import io

    path = clip_files / f"in{suffix}"
    formats.write(formats.read(clip_files / "gapped.npz"), path)
    opened = builtins.open

    def denied(file, *args, **kwargs):
        if os.fspath(file) == str(path):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(file))
        return opened(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", denied)
    monkeypatch.setattr(io, "open", denied)
    result = run("repair", path, clip_files / f"out{suffix}")
    assert result.exit_code == 123
    assert result.stderr == f"mocapfill: error: {path}: cannot read (Permission denied)\n"


_HUGE_CSV = ("# units: mm, rate: 100\nFrame,Time,A_X,A_Y,A_Z,B_X,B_Y,B_Z\n1,0.00,1,2,3,4,5,6\n"
             "2,0.01,{v},2,3,4,5,6\n3,0.02,1,2,3,,,\n4,0.03,1,2,3,4,5,6\n"
             "5,0.04,1,2,3,4,5,6\n")
_TOO_LARGE = "huge.csv: a coordinate ({v:.6g}: marker A, frame 2) is too large to process"


@pytest.mark.parametrize("value", [1e308, 1e200])
@pytest.mark.parametrize("args", [
    ["repair", "huge.csv", "out.csv"], ["repair", "huge.csv", "out.csv", "--method", "pchip"],
    ["rank", "huge.csv"], ["score", "huge.csv", "ok.csv"], ["score", "ok.csv", "huge.csv"],
])
def test_a_coordinate_too_large_to_process_is_one_line_naming_the_file(tmp_path, monkeypatch,
                                                                      value, args):
    # 1e308 was a traceback (OverflowError: math range error) and exit 1, the code of
    # --check's gaps left; 1e200 scored "RMSE inf mm" with exit 0.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "huge.csv").write_text(_HUGE_CSV.format(v=value))
    (tmp_path / "ok.csv").write_text(_HUGE_CSV.format(v=1))
    result = run(*args)
    assert result.exit_code == 123, result.output
    assert result.stderr.startswith(f"mocapfill: error: {_TOO_LARGE.format(v=value)} ")
    assert len(result.stderr.splitlines()) == 1
    assert not (tmp_path / "out.csv").exists()


def test_a_coordinate_too_large_to_process_is_a_failed_file_of_a_batch(tmp_path,
                                                                      monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "huge.csv").write_text(_HUGE_CSV.format(v=1e308))
    (tmp_path / "ok.csv").write_text(_HUGE_CSV.format(v=1))
    result = run("repair", "huge.csv", "ok.csv", "-o", "out", "-j", "1")
    assert result.exit_code == 123, result.output
    assert result.stderr.splitlines()[0].startswith(
        f"mocapfill: error: {_TOO_LARGE.format(v=1e308)} ")
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["ok.csv"]


def test_a_channel_value_too_large_to_process_is_one_line_naming_the_file(tmp_path,
                                                                         monkeypatch):
    # Chest's translation (1.7e308 along x and y, turned 45°) overflows its position to inf,
    # a missing sample: the coordinates pass, and the channel crashed the unit scale.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "c.bvh").write_text(
        "HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition "
        "Zposition Zrotation Xrotation Yrotation\n  JOINT Chest\n  {\n    OFFSET 0 10 0\n"
        "    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n"
        "    End Site\n    {\n      OFFSET 0 10 0\n    }\n  }\n}\nMOTION\nFrames: 5\n"
        "Frame Time: 0.01\n0 0 0 0 0 0 0 0 0 0 0 0\n1 0 0 45 0 0 1.7e308 1.7e308 0 0 0 0\n"
        "2 0 0 0 0 0 0 0 0 nan nan nan\n3 0 0 0 0 0 0 0 0 0 0 0\n4 0 0 0 0 0 0 0 0 0 0 0\n")
    result = run("repair", "c.bvh", "out.bvh")
    assert result.exit_code == 123, result.output
    assert result.stderr.startswith("mocapfill: error: c.bvh: a channel value (1.7e+308: "
                                    "joint Chest, frame 2) is too large to process ")
    assert not (tmp_path / "out.bvh").exists()


def _deny_reading(monkeypatch, path: Path) -> None:
    """Make ``path`` unreadable to this process as mode 000 makes it for a user other than
    root (the tests may run as root, who reads it anyway): access() and open() refuse."""
    import builtins
    import io

    opened, access = builtins.open, os.access

    def denied(file, *args, **kwargs):
        if isinstance(file, (str, os.PathLike)) and os.fspath(file) == str(path):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), os.fspath(file))
        return opened(file, *args, **kwargs)

    monkeypatch.setattr(builtins, "open", denied)
    monkeypatch.setattr(io, "open", denied)
    monkeypatch.setattr(os, "access", lambda file, mode, *a, **k: (
        not (mode & os.R_OK and os.fspath(file) == str(path)) and access(file, mode, *a, **k)))


@pytest.mark.parametrize("args", [
    ["repair", "{x}", "o.npz"], ["info", "{x}"], ["info", "gapped.npz", "{x}"],
    ["rank", "{x}"], ["convert", "{x}", "o.npz"], ["score", "{x}", "gapped.npz"],
    ["score", "truth.npz", "gapped.npz", "--gapped", "{x}"], ["plot", "{x}", "-o", "o.svg"],
    ["simulate", "{x}", "o.npz", "--mr", "0.2"],
])
def test_an_unreadable_input_is_a_failed_file_not_a_usage_error(clip_files, monkeypatch,
                                                                 args):
    # click's check of IN made it "Invalid value for 'IN': Path 'x' is not readable", a
    # usage error (exit 2); the README puts a file that cannot be read under 123.
    monkeypatch.chdir(clip_files)
    formats.write(formats.read("gapped.npz"), clip_files / "x.npz")
    _deny_reading(monkeypatch, Path("x.npz"))
    result = run(*(a.format(x="x.npz") for a in args))
    assert result.exit_code == 123, result.output
    assert result.stderr == "mocapfill: error: x.npz: cannot read (Permission denied)\n"
    assert not (clip_files / "o.npz").exists() and not (clip_files / "o.svg").exists()


def test_an_unreadable_input_is_a_failed_file_of_a_batch(clip_files, monkeypatch):
    monkeypatch.chdir(clip_files)
    formats.write(formats.read("gapped.npz"), clip_files / "x.npz")
    _deny_reading(monkeypatch, Path("x.npz"))
    result = run("repair", "x.npz", "gapped.npz", "-o", "out", "-j", "1")
    assert result.exit_code == 123, result.output
    assert result.stderr.splitlines()[0] == ("mocapfill: error: x.npz: cannot read "
                                             "(Permission denied)")
    assert (clip_files / "out" / "gapped.npz").exists()


def test_an_unreadable_existing_output_is_replaced_not_refused(clip_files, monkeypatch):
    # Replaced by renaming, which its own permissions do not stop (as an output folder's
    # do); click's check of OUT made it a usage error.
    monkeypatch.chdir(clip_files)
    (clip_files / "o.npz").write_bytes(b"old")
    _deny_reading(monkeypatch, Path("o.npz"))
    result = run("convert", "gapped.npz", "o.npz")
    assert result.exit_code == 0, result.output
    assert (clip_files / "o.npz").read_bytes() != b"old"


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_simulate_in_channel_space_counts_the_joint_samples_hit_and_the_positions_lost(
        tmp_path, seed):
    # --ml 10 --markers 1 on a BVH written back as BVH removes one joint's channels for 10
    # frames; the joints those channels move lose their positions (Hips: Hips, Arm and
    # Arm_End; Arm: Arm_End alone). The line gave only the positions, which did not say
    # how many joint samples the protocol hit.
    from .formats.test_bvh import write_bvh

    rows = [f"{k} 0 0 {2 * k} {k} 0 {3 * k} 0 {k}" for k in range(40)]
    path = write_bvh(tmp_path, rows)
    result = run("simulate", path, tmp_path / "o.bvh", "--ml", "10", "--markers", "1",
                 "--seed", seed)
    assert result.exit_code == 0, result.output
    motion_rows = (tmp_path / "o.bvh").read_text().split("Frame Time: 0.01\n")[1].split("\n")
    cells = np.array([[c == "nan" for c in row.split()] for row in motion_rows if row])
    hips, arm = cells[:, :6].any(axis=1), cells[:, 6:].any(axis=1)
    joint_samples = int(hips.sum() + arm.sum())
    positions = int(3 * hips.sum() + (arm & ~hips).sum())      # Hips moves all three points
    assert joint_samples == 10
    assert (f"{positions} samples removed (joint positions; the channels of {joint_samples} "
            "joint samples were removed") in result.stderr, result.stderr


@pytest.mark.parametrize(("rate", "seconds"), [(250.0, "0.07"), (100.0, "0.29"), (120.0, "0.5"),
                                               (240.0, "0.0125")])
def test_max_gap_in_seconds_leaves_exactly_the_gaps_longer_than_that(tmp_path, rate, seconds):
    # Gaps of every length around the limit: a gap is left when its length in seconds
    # (frames / rate, as the report gives it) is longer than the seconds given. 17.5
    # frames at 250 Hz was rounded to 18, so an 18-frame gap (0.072 s) was filled.
    lengths = list(range(1, 70))
    clip = smooth_clip(120 * len(lengths), len(lengths), rate=rate)
    for marker, length in enumerate(lengths):
        clip = with_gap(clip, marker, 100 * marker + 10, 100 * marker + 10 + length)
    formats.write(clip, tmp_path / "g.npz")
    result = run("repair", tmp_path / "g.npz", tmp_path / "o.npz", "--method", "linear",
                 "--max-gap", f"{seconds}s", "--max-jump", "0", "--gaps-report",
                 tmp_path / "g.json")
    assert result.exit_code == 0, result.output
    statuses = [g["status"] for g in json.loads((tmp_path / "g.json").read_text())["gaps"]]
    limit = float(seconds)
    expected = ["left: too long" if length / rate > limit * (1 + 1e-12) else "filled"
                for length in lengths]
    assert statuses == expected


@pytest.mark.parametrize("zeros", [None, "auto", "off", "on"])
def test_zero_is_missing_on_fills_the_zero_samples_of_a_csv(tmp_path, zeros):
    # QTM-derived text files hold gaps as 0, 0, 0 (formats-and-conventions.md 1.1, 4.2).
    # --zero-is-missing once read C3D files only: asked for on a CSV it was ignored, the
    # zeros kept as data and the repair said "0 gaps filled" with exit 0. Now "on" reads
    # them as gaps (only then: a CSV carries no sign of the exporter) and fills them.
    src = tmp_path / "z.csv"
    text = "Frame,Time,A_X,A_Y,A_Z\n1,0,1,2,3\n2,0.01,0,0,0\n3,0.02,3,4,5\n"
    src.write_text(text)
    option = [] if zeros is None else ["--zero-is-missing", zeros]
    result = run("repair", src, tmp_path / "out.csv", "--method", "linear", *option)
    assert result.exit_code == 0, result.output
    assert "applies to" not in result.stderr
    filled = text.replace("2,0.01,0,0,0", "2,0.01,2,3,4")
    assert (tmp_path / "out.csv").read_text() == (filled if zeros == "on" else text)
    assert ("1 gaps filled" if zeros == "on" else "0 gaps filled") in result.stderr


def test_zero_is_missing_on_for_a_format_that_cannot_hold_it_is_noted(tmp_path):
    # A BVH stores joint angles, where 0 is an ordinary value: the option cannot apply.
    src = tmp_path / "j.bvh"
    src.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n  CHANNELS 3 Xposition "
                   "Yposition Zposition\n  End Site\n  {\n    OFFSET 0 1 0\n  }\n}\n"
                   "MOTION\nFrames: 2\nFrame Time: 0.01\n0 0 0\n1 1 1\n")
    note = (f"mocapfill: note: {src}: --zero-is-missing on applies to C3D, TRC and CSV "
            "files only; samples at exactly (0, 0, 0) in this file are read as data")
    result = run("info", src, "--zero-is-missing", "on")
    assert result.exit_code == 0, result.output
    assert note in result.stderr
    # repair shows it with the reader's notes once OUT is written; a repair that fails
    # after reading (--max-gap in seconds needs the file's rate) prints its error alone.
    done = run("repair", src, tmp_path / "o.bvh", "--zero-is-missing", "on")
    assert done.exit_code == 0, done.output
    assert done.stderr.splitlines()[0] == note and "->" in done.stderr.splitlines()[-1]
    failed = run("repair", src, tmp_path / "p.bvh", "--zero-is-missing", "on",
                 "--max-gap", "-1s")
    assert failed.exit_code == 2 and failed.stderr.count("\n") == 1, failed.stderr


def test_reader_notes_follow_the_written_output_and_a_failing_repair_prints_one_line(
        tmp_path):
    # A CSV cut inside its last row gets a reader note. It used to be printed before the
    # repair ran, so a repair that then failed (here on --max-gap, which needs the file's
    # rate) printed the note and its error: two lines. Now the notes come once OUT is
    # written, before the summary.
    src = tmp_path / "cut.csv"
    formats.write(with_gap(smooth_clip(200, 4), 1, 50, 80), src)
    text = src.read_text()
    src.write_text(text[:text.rstrip("\n").rfind(",") + 3])    # the last cell cut short
    failed = run("repair", src, tmp_path / "out.csv", "--max-gap", "-3")
    assert failed.exit_code == 2
    assert failed.stderr.count("\n") == 1 and "error: --max-gap" in failed.stderr
    assert not (tmp_path / "out.csv").exists()
    done = run("repair", src, tmp_path / "out.csv")
    assert done.exit_code == 0, done.output
    lines = done.stderr.splitlines()
    assert lines[0].startswith(f"mocapfill: note: {src}: ") and "cut short" in lines[0]
    assert lines[-1].startswith(f"{src} -> ") and len(lines) == 2


# ----------------------------------------------------------------------- files stating no rate

def _no_rate_file(folder: Path, kind: str) -> Path:
    """A gapped clip (MK01 missing in frames 20-24 of 60) in a file that states no frame
    rate: a plain CSV without a Time column, a headerless CSV, a TRC without DataRate or
    Time values, an AMC (which has no rate field)."""
    if kind == "amc":
        from tests.formats.test_acclaim import frame, write_pair

        frames = [frame(f, f"{f / 10:.2f} 0 0 0 0 0", None if 20 <= f < 25 else
                        f"{10 + 20 * np.sin(f / 9):.4f}", f"{f / 3:.4f} 5") for f in range(60)]
        return write_pair(folder, frames, stem="norate")
    clip = with_gap(smooth_clip(60, 4), 1, 20, 25)
    rows = []
    for f in range(clip.n_frames):
        cells = [format(v, ".4f") if clip.observed[f, j] else ""
                 for j in range(clip.n_markers) for v in clip.positions[f, j]]
        rows.append(cells)
    if kind == "trc":
        text = ("PathFileType\t4\t(X/Y/Z)\tnorate.trc\n"
                "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\t"
                "OrigDataStartFrame\tOrigNumFrames\n"
                "\t\t60\t4\tmm\t\t1\t60\n"
                "Frame#\tTime\t" + "".join(f"{name}\t\t\t" for name in clip.labels) + "\n\n"
                + "".join(f"{f + 1}\t\t" + "\t".join(cells) + "\n"
                          for f, cells in enumerate(rows)))
        path = folder / "norate.trc"
    else:
        header = ("" if kind == "headerless" else
                  ",".join(f"{name}_{axis}" for name in clip.labels for axis in "XYZ") + "\n")
        text = header + "".join(",".join(cells) + "\n" for cells in rows)
        path = folder / "norate.csv"
    path.write_text(text)
    return path


@pytest.mark.parametrize("kind", ["csv", "headerless", "trc", "amc"])
def test_a_file_stating_no_rate_reads_as_0_hz_and_refuses_max_gap_in_seconds(tmp_path, kind):
    # These files were read as 120 Hz without a word, so --max-gap 0.5s meant 60 frames of
    # a rate the file never stated; the README says such a file fails.
    folder = tmp_path / "in"
    folder.mkdir()
    path = _no_rate_file(folder, kind)
    assert formats.read(path).rate == 0
    assert "with no frame rate (0 Hz)" in run("info", path).stdout
    out = tmp_path / f"alone{path.suffix}"
    alone = run("repair", path, out, "--max-gap", "0.5s", "--method", "linear")
    assert alone.exit_code == 2, alone.output
    assert alone.stderr.splitlines() == [
        f"mocapfill: error: {path}: the file states no frame rate, so --max-gap 0.5s has no "
        "length in frames; give it in frames (40)"]
    assert not out.exists()
    # In a batch the file fails alone, and the batch exits 123 (some file failed).
    report_path = tmp_path / "report.json"
    many = run("repair", folder, "-o", tmp_path / "out", "-j", "1", "--max-gap", "0.5s",
               "--method", "linear", "--report", report_path)
    assert many.exit_code == 123, many.output
    record, = json.loads(report_path.read_text())["files"]
    assert record["status"] == "failed"
    assert record["reason"].startswith("the file states no frame rate, so --max-gap 0.5s")
    assert str(path) in many.stderr
    # In frames it needs no rate.
    framed = run("repair", path, out, "--max-gap", "40", "--method", "linear")
    assert framed.exit_code == 0, framed.output
    assert re.search(r": [12] gaps filled, 0 left", framed.stderr)     # AMC: arm and hand
    assert formats.read(out).observed.all() and formats.read(out).rate == 0


@pytest.mark.parametrize(("kind", "suffix"), [("csv", ".trc"), ("headerless", ".trc"),
                                            ("trc", ".csv"), ("amc", ".trc"), ("amc", ".csv")])
def test_converting_a_file_stating_no_rate_to_a_new_trc_or_csv_notes_120_hz(tmp_path, kind,
                                                                            suffix):
    path = _no_rate_file(tmp_path, kind)
    out = tmp_path / f"out{suffix}"
    result = run("convert", path, out)
    assert result.exit_code == 0, result.output
    assert (f"mocapfill: note: {out}: the clip's frame rate is not known (0 Hz): written "
            "as 120 Hz") in result.stderr.splitlines()
    assert formats.read(out).rate == 120
    # A copy in the file's own format is a patch of it: it states no rate either.
    same = tmp_path / f"same{path.suffix}"
    result = run("convert", path, same)
    assert result.exit_code == 0 and "note:" not in result.stderr, result.output
    assert formats.read(same).rate == 0


def test_an_unexpected_exception_is_an_internal_error_with_its_own_exit_code(
        clip_files, monkeypatch):
    # A bug: its traceback is kept for the report, then one line; the exit code is not
    # 1, which --check gives for gaps left (a script read a crash as unfilled gaps).
    from mocapfill import cli

    def broken(*args, **kwargs):
        raise ValueError("boom")

    monkeypatch.setattr(cli, "_read", broken)
    result = run("repair", clip_files / "gapped.npz", clip_files / "out.npz", "--check")
    assert result.exit_code == cli.EXIT_INTERNAL == 70
    assert "Traceback" in result.stderr
    assert result.stderr.splitlines()[-1] == (
        "mocapfill: error: internal error (a bug in mocapfill: please report it with the "
        "traceback above): ValueError: boom")
    assert not (clip_files / "out.npz").exists()


@pytest.mark.parametrize(("module", "function", "args"), [
    ("formats", "read", ["info", "gapped.npz"]),
    ("pipeline", "repair", ["repair", "gapped.npz", "out.npz"]),
    ("metrics", "score", ["score", "truth.npz", "gapped.npz"]),
])
def test_running_out_of_memory_is_one_line_naming_the_input_and_a_failed_file(
        clip_files, monkeypatch, module, function, args):
    # It named no file (a batch names the file it failed on).
    import importlib

    def too_big(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(importlib.import_module(f"mocapfill.{module}"), function, too_big)
    result = run(*[clip_files / a if a.endswith(".npz") else a for a in args])
    assert result.exit_code == 123
    assert result.stderr == (f"mocapfill: error: {clip_files / args[1]}: not enough memory "
                             "to finish the command\n")
    assert not (clip_files / "out.npz").exists()


def test_running_out_of_memory_before_any_file_is_read_names_none(monkeypatch):
    from mocapfill import cli

    def too_big(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(cli, "_read", too_big)
    result = run("info", "gapped.npz")
    assert result.exit_code == 123
    assert result.stderr == "mocapfill: error: not enough memory to finish the command\n"


def test_a_first_frame_beyond_64_bits_is_one_line_naming_the_file(tmp_path):
    # repair and convert to an NPZ crashed with a traceback (exit 70) in the writer.
    path = tmp_path / "huge.npz"
    np.savez(path, positions=np.ones((5, 2, 3)), first_frame=np.float64(1e300))
    for command in (["repair", path, tmp_path / "out.npz"],
                    ["convert", path, tmp_path / "out.npz"]):
        result = run(*command)
        assert result.exit_code == 123, result.output
        assert result.output.startswith(f"mocapfill: error: {path}: ")
        assert "first_frame must fit in 64 bits" in result.output
        assert "Traceback" not in result.output and result.output.count("\n") == 1
        assert not (tmp_path / "out.npz").exists()
