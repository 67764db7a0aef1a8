"""Batch repair: discovery, mirrored outputs, resume, failures, report, exit codes, Dask."""
from __future__ import annotations

import contextlib
import errno
import importlib.util
import json
import multiprocessing
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from click.testing import CliRunner

import mocapfill
from mocapfill import batch, formats
from mocapfill.cli import main
from mocapfill.pipeline import RepairOptions

from .helpers import smooth_clip, with_gap

# Linear interpolation: fast, and its fills always pass the pipeline's jump check, so every
# gapped file is "repaired" whatever the solver defaults are tuned to.
LINEAR = ("--method", "linear")
N_GAPPED = 20
SUMMARY = re.compile(r"^\d+ repaired(, \d+ (unchanged|skipped|failed))*(, \d+ gaps? left)? "
                     r"in \d+\.\d s$")


def _clip_tree(root: Path, corrupt: bool = True) -> dict[str, Path]:
    """20 gapped clips in nested folders, one gap-free clip and (optionally) a corrupt one.

    Input times are set a minute in the past so outputs are clearly newer (resume).
    """
    files = {}
    for i in range(N_GAPPED):
        folder = root / f"subject{i % 3}" / ("walk" if i % 2 else "run")
        folder.mkdir(parents=True, exist_ok=True)
        files[f"gapped{i}"] = folder / f"trial{i:02d}.npz"
        formats.write(with_gap(smooth_clip(240, 8, rate=480.0, seed=i), i % 8, 100, 120),
                      files[f"gapped{i}"])
    files["complete"] = root / "complete.npz"
    formats.write(smooth_clip(240, 8, seed=99), files["complete"])
    if corrupt:
        files["corrupt"] = root / "subject1" / "corrupt.npz"
        files["corrupt"].write_bytes(b"PK\x03\x04 truncated archive")
    (root / "notes.txt").write_text("not a motion file")
    past = time.time() - 60
    for path in files.values():
        os.utime(path, (past, past))
    return files


@pytest.fixture
def tree(tmp_path):
    return tmp_path / "data", _clip_tree(tmp_path / "data")


@pytest.fixture
def clean_tree(tmp_path):
    return tmp_path / "data", _clip_tree(tmp_path / "data", corrupt=False)


def run(*args):
    return CliRunner().invoke(main, ["repair", *[str(a) for a in args]])


def _report(path: Path) -> dict:
    return json.loads(path.read_text())


def _assert_mirrored_and_faithful(root: Path, out: Path, files: dict[str, Path]) -> None:
    for key, source in files.items():
        target = out / source.relative_to(root)
        if key == "corrupt":
            assert not target.exists()
            continue
        before, after = formats.read(source), formats.read(target)
        assert after.observed.all(), target
        assert np.array_equal(after.positions[before.observed],
                              before.positions[before.observed]), target
    assert not list(out.rglob(".*")), "temporary files left behind"


def _assert_batch_outcome(root: Path, out: Path, files, result, report_path: Path) -> None:
    assert result.exit_code == 123, result.output
    _assert_mirrored_and_faithful(root, out, files)
    report = _report(report_path)
    counts = ("files", "repaired", "unchanged", "skipped", "failed")
    assert [report["summary"][k] for k in counts] == [22, 20, 1, 0, 1]
    by_input = {Path(r["input"]).name: r for r in report["files"]}
    assert by_input["corrupt.npz"]["status"] == "failed"
    assert "corrupt.npz" not in by_input["corrupt.npz"]["reason"]  # the path is its own field
    assert by_input["corrupt.npz"]["reason"]
    assert by_input["complete.npz"] == by_input["complete.npz"] | {
        "status": "unchanged", "reason": "no gaps", "gaps_filled": 0, "frames": 240}
    assert by_input["trial07.npz"]["gaps_filled"] == 1
    assert by_input["trial07.npz"]["gaps_left"] == 0
    assert by_input["trial07.npz"]["seconds"] > 0
    lines = result.stderr.strip().splitlines()
    assert lines[0].startswith("mocapfill: error: ") and "corrupt.npz" in lines[0]
    assert SUMMARY.match(lines[-1]) and lines[-1].startswith("20 repaired, 1 unchanged, 1 failed")


def test_local_pool_mirrors_the_tree_and_reports_the_corrupt_file(tree, tmp_path):
    root, files = tree
    before = {p: p.read_bytes() for p in files.values()}
    result = run(root, "-o", tmp_path / "out", "-j", "2", "--report", tmp_path / "r.json",
                 *LINEAR)
    _assert_batch_outcome(root, tmp_path / "out", files, result, tmp_path / "r.json")
    assert not (tmp_path / "out" / "notes.txt").exists()
    assert {p: p.read_bytes() for p in files.values()} == before


# The cluster and the command run in a child process, and this one never imports Dask: a
# LocalCluster leaves threads in the process that started it (Dask's offload pool, which
# lives as long as the process), where the blend's second pass is never forked, and
# importing `distributed` makes every exception picklable (tblib), which changes what a
# forked child can send back. tests/solvers/test_threads.py checks both after this file.
_DASK_BATCH = """
import subprocess, sys
import distributed
with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                              dashboard_address=None) as cluster:
    done = subprocess.run([sys.executable, "-m", "mocapfill", "repair", *sys.argv[1:],
                           "--scheduler", cluster.scheduler_address],
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
# The command's stderr on this script's stdout: the cluster logs its own shutdown on
# stderr ("CommClosedError: ConnectionPool closing."), after the summary line.
sys.stdout.write(done.stderr)
sys.exit(done.returncode)
"""


def test_dask_local_cluster_runs_the_same_batch(tree, tmp_path):
    if importlib.util.find_spec("distributed") is None:
        pytest.skip("dask.distributed is not installed")
    root, files = tree
    args = [str(a) for a in (root, "-o", tmp_path / "out", "--report", tmp_path / "r.json",
                             *LINEAR)]
    done = subprocess.run([sys.executable, "-c", _DASK_BATCH, *args], capture_output=True,
                          text=True, timeout=300)
    result = SimpleNamespace(exit_code=done.returncode, stderr=done.stdout,
                             output=done.stdout + done.stderr)
    _assert_batch_outcome(root, tmp_path / "out", files, result, tmp_path / "r.json")


def test_exit_code_is_0_when_no_file_fails(clean_tree, tmp_path):
    root, _ = clean_tree
    result = run(root, "-o", tmp_path / "out", "-j", "1", *LINEAR)
    assert result.exit_code == 0, result.output
    assert result.stderr.strip().splitlines() == [result.stderr.strip()]  # one summary line
    assert result.stderr.startswith("20 repaired, 1 unchanged in ")


@pytest.mark.parametrize("kind", ["one frame", "no marker observed"])
def test_an_empty_clip_fails_alone_and_in_a_batch_with_the_same_reason(tmp_path, kind):
    # A one-frame clip used to exit 123 alone but count as "unchanged" (and be copied) in a
    # batch; both now report it as bad input.
    from mocapfill.motion import Motion

    source = tmp_path / "in" / "sub" / "empty.npz"
    source.parent.mkdir(parents=True)
    if kind == "one frame":
        clip = smooth_clip(1, 4)
    else:
        clip = smooth_clip(50, 4)
        clip = Motion(clip.positions, np.zeros_like(clip.observed), clip.labels, clip.rate,
                      clip.units)
    formats.write(clip, source)
    alone = run(source, tmp_path / "alone.npz", *LINEAR)
    assert alone.exit_code == 123 and not (tmp_path / "alone.npz").exists()
    report_path = tmp_path / "report.json"
    many = run(tmp_path / "in", "-o", tmp_path / "out", "-j", "1", "--report", report_path,
               *LINEAR)
    assert many.exit_code == 123, many.output
    assert not (tmp_path / "out" / "sub").exists()     # no empty folder either
    record, = _report(report_path)["files"]
    assert record["status"] == "failed"
    assert record["reason"] and str(source) not in record["reason"]
    assert record["reason"] in alone.stderr         # the single file's one line


@pytest.mark.parametrize("option", ["--markers", "--exclude"])
def test_a_marker_pattern_that_matches_nothing_fails_alone_exit_2_and_each_file_in_a_batch(
        tmp_path, option):
    source = tmp_path / "in" / "trial.npz"
    source.parent.mkdir()
    formats.write(with_gap(smooth_clip(100, 4), 1, 40, 50), source)
    alone = run(source, tmp_path / "alone.npz", option, "MK1", *LINEAR)   # MK01 misspelt
    assert alone.exit_code == 2 and not (tmp_path / "alone.npz").exists()
    assert f"{option} MK1 matches no marker" in alone.stderr
    report_path = tmp_path / "report.json"
    many = run(tmp_path / "in", "-o", tmp_path / "out", "-j", "1", "--report", report_path,
               option, "MK1", *LINEAR)
    assert many.exit_code == 123, many.output
    record, = _report(report_path)["files"]
    assert record["status"] == "failed" and f"{option} MK1 matches no marker" in record["reason"]
    assert not (tmp_path / "out" / "trial.npz").exists()


def test_check_summary_counts_the_gaps_left_and_records_keep_the_output_formats_notes(
        tmp_path):
    # Two clips each with a gap at its first frame (left by default) and an interior one;
    # one point of each is not a marker, which a TRC cannot hold.
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(2):
        clip = with_gap(with_gap(smooth_clip(120, 4, seed=i), 0, 0, 5), 1, 40, 50)
        formats.write(clip.replace(fillable=np.array([True, True, True, False])),
                      folder / f"t{i}.npz")
    report_path = tmp_path / "r.json"
    result = run(folder, "-o", tmp_path / "out", "-j", "1", "--suffix", ".trc", "--check",
                 "--report", report_path, *LINEAR)
    assert result.exit_code == 1, result.output
    summary = result.stderr.strip().splitlines()[-1]
    assert SUMMARY.match(summary) and summary.startswith("2 repaired, 2 gaps left in ")
    for record in _report(report_path)["files"]:
        assert record["gaps_left"] == 1
        note, = record["notes"]
        assert note.startswith("1 point(s) that are not marker trajectories")
        assert formats.read(record["output"]).n_markers == 3


def test_check_on_a_resumed_batch_counts_the_gaps_left_in_skipped_outputs(tmp_path):
    # The first run leaves the edge gap of each clip (exit 1 under --check); the rerun
    # skips both outputs as up to date, and exited 0 under --check: it counted no gap in
    # outputs it did not write. An output that cannot be read is a failure there.
    folder = tmp_path / "in"
    folder.mkdir()
    for i in range(2):
        formats.write(with_gap(with_gap(smooth_clip(120, 4, seed=i), 0, 0, 5), 1, 40, 50),
                      folder / f"t{i}.npz")
        os.utime(folder / f"t{i}.npz", (time.time() - 60,) * 2)
    out = tmp_path / "out"
    first = run(folder, "-o", out, "-j", "1", "--check", *LINEAR)
    assert first.exit_code == 1, first.output
    report_path = tmp_path / "r.json"
    again = run(folder, "-o", out, "-j", "1", "--check", "--report", report_path, *LINEAR)
    assert again.exit_code == 1, again.output
    assert again.stderr.strip().splitlines()[-1].startswith("0 repaired, 2 skipped, 2 gaps left")
    records = _report(report_path)["files"]
    assert [(r["status"], r["gaps_left"]) for r in records] == [("skipped", 1)] * 2
    # The same counts as the outputs' own gaps, found by reading them.
    for record in records:
        assert (~formats.read(record["output"]).observed).any(axis=0).sum() == 1
    # Without --check a skipped output is not read.
    (out / "t1.npz").write_bytes(b"PK\x03\x04 not an archive")
    os.utime(out / "t1.npz")
    assert run(folder, "-o", out, "-j", "1", *LINEAR).exit_code == 0
    broken = run(folder, "-o", out, "-j", "1", "--check", "--report", report_path, *LINEAR)
    assert broken.exit_code == 123, broken.output
    record = next(r for r in _report(report_path)["files"] if r["input"].endswith("t1.npz"))
    assert record["status"] == "failed"
    assert "cannot be read for --check" in record["reason"] and "t1.npz" in record["reason"]


def test_records_keep_what_the_reader_worked_around(tmp_path):
    # A TRC whose Frame# column skips numbers: `repair IN OUT` prints the reader's note,
    # and a batch's record keeps it (the gap report's frames are rows, not the file's).
    folder = tmp_path / "in"
    folder.mkdir()
    formats.write(with_gap(smooth_clip(60, 4), 1, 20, 30), folder / "t.trc")
    lines = (folder / "t.trc").read_text().splitlines(keepends=True)
    row = next(i for i, line in enumerate(lines) if line.startswith("40\t"))
    lines[row] = "70" + lines[row][2:]
    (folder / "t.trc").write_text("".join(lines))
    report_path = tmp_path / "r.json"
    result = run(folder, "-o", tmp_path / "out", "-j", "1", "--report", report_path, *LINEAR)
    assert result.exit_code == 0, result.output
    record, = _report(report_path)["files"]
    assert record["status"] == "repaired"
    note, = record["notes"]
    assert note.startswith("the Frame# column is not consecutive (39 then 70 at line ")


def test_rerun_skips_up_to_date_outputs_and_redoes_changed_inputs(clean_tree, tmp_path):
    root, files = clean_tree
    out = tmp_path / "out"
    assert run(root, "-o", out, "-j", "1", *LINEAR).exit_code == 0
    files["gapped3"].touch()  # the input changed after its output was written
    result = run(root, "-o", out, "-j", "1", "--report", tmp_path / "r.json", *LINEAR)
    assert result.exit_code == 0
    statuses = {Path(r["input"]).name: r["status"] for r in _report(tmp_path / "r.json")["files"]}
    assert statuses.pop("trial03.npz") == "repaired"
    assert set(statuses.values()) == {"skipped"}


def test_an_empty_file_where_an_output_goes_is_not_an_up_to_date_output(clean_tree,
                                                                          tmp_path):
    # An empty file newer than the input (touched, a copy that failed) was "skipped" on
    # every rerun; outputs are written whole and no format's output is empty.
    root, files = clean_tree
    out = tmp_path / "out"
    empty = out / files["gapped0"].relative_to(root)
    empty.parent.mkdir(parents=True)
    empty.touch()
    result = run(root, "-o", out, "-j", "1", "--report", tmp_path / "r.json", *LINEAR)
    assert result.exit_code == 0, result.output
    record = next(r for r in _report(tmp_path / "r.json")["files"]
                  if Path(r["input"]) == files["gapped0"])
    assert record["status"] == "repaired"
    assert formats.read(empty).observed.all()


def test_a_folder_where_an_output_goes_is_not_an_up_to_date_output(clean_tree, tmp_path):
    # A folder newer than the input at the output's path was "skipped" (exit 0): the file
    # was never repaired, and no rerun would repair it.
    root, files = clean_tree
    out = tmp_path / "out"
    (out / files["gapped0"].relative_to(root)).mkdir(parents=True)
    result = run(root, "-o", out, "-j", "1", "--report", tmp_path / "r.json", *LINEAR)
    assert result.exit_code == 123, result.output
    record = next(r for r in _report(tmp_path / "r.json")["files"]
                  if Path(r["input"]) == files["gapped0"])
    assert record["status"] == "failed" and "folder" in record["reason"]


def test_force_redoes_up_to_date_outputs(clean_tree, tmp_path):
    root, _ = clean_tree
    out = tmp_path / "out"
    run(root, "-o", out, "-j", "1", *LINEAR)
    result = run(root, "-o", out, "-j", "1", "--force", *LINEAR)
    assert result.stderr.startswith("20 repaired, 1 unchanged in ")


def test_output_folder_inside_the_input_folder_is_not_scanned(clean_tree):
    root, _ = clean_tree
    run(root, "-o", root / "repaired", "-j", "1", *LINEAR)
    again = run(root, "-o", root / "repaired", "-j", "1", *LINEAR)
    assert again.stderr.startswith("0 repaired, 21 skipped in ")


@pytest.mark.parametrize("pattern", ["**/*.npz", "*"])
def test_output_folder_inside_a_globs_folder_is_not_scanned(clean_tree, pattern):
    # A glob matched the outputs of the first run, so the rerun that should resume was
    # refused ("out/complete.npz is an input"), or repaired the outputs again.
    root, _ = clean_tree
    first = run(f"{root}/{pattern}", "-o", root / "out", "-j", "1", *LINEAR)
    assert first.exit_code == 0, first.output
    again = run(f"{root}/{pattern}", "-o", root / "out", "-j", "1", *LINEAR)
    assert again.exit_code == 0, again.output
    assert again.stderr.startswith("0 repaired, 21 skipped in ")
    assert not (root / "out" / "out").exists()


def test_refuses_to_write_outputs_over_inputs_without_in_place(clean_tree):
    root, files = clean_tree
    before = files["gapped0"].read_bytes()
    result = run(root, "-o", root, *LINEAR)
    assert result.exit_code == 2
    assert "refusing to overwrite" in result.stderr
    assert files["gapped0"].read_bytes() == before


def test_in_place_repairs_the_target_of_a_symbolic_link_and_keeps_the_link(tmp_path):
    target = tmp_path / "target.npz"
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), target)
    (tmp_path / "links").mkdir()
    link = tmp_path / "links" / "clip.npz"
    link.symlink_to(target)
    result = run(tmp_path / "links", "--in-place", "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and link.resolve() == target
    assert formats.read(target).observed.all()
    assert not [p for p in tmp_path.rglob(".*")]


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0, reason="root gives files away")
def test_in_place_as_root_keeps_the_files_owner_and_group(tmp_path):
    # The file is replaced by a new one, which was root's: 0600 and its owner locked out.
    source = tmp_path / "clip.npz"
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), source)
    os.chown(source, 65534, 65533)
    source.chmod(0o600)
    result = run(tmp_path, "--in-place", "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 0, result.output
    info = source.stat()
    assert (info.st_uid, info.st_gid, info.st_mode & 0o777) == (65534, 65533, 0o600)
    assert formats.read(source).observed.all()


def test_in_place_where_the_owner_cannot_be_kept_still_repairs(tmp_path, monkeypatch):
    def refused(*args):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    source = tmp_path / "clip.npz"
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), source)
    monkeypatch.setattr(os, "chown", refused, raising=False)
    result = run(tmp_path, "--in-place", "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 0, result.output
    assert formats.read(source).observed.all()


def test_in_place_repairs_inputs_atomically_and_leaves_complete_files_untouched(clean_tree):
    root, files = clean_tree
    untouched = files["complete"].stat().st_mtime_ns
    result = run(root, "--in-place", "-j", "2", *LINEAR)
    assert result.exit_code == 0, result.output
    assert formats.read(files["gapped5"]).observed.all()
    assert files["complete"].stat().st_mtime_ns == untouched
    assert not list(root.rglob(".*"))


def test_in_place_amc_beside_several_skeletons_leaves_no_extra_file(tmp_path):
    from .formats.test_acclaim import ASF, frame, write_pair

    frames = [frame(1), frame(2, arm="10"), frame(3, arm=None), frame(4, arm="30")]
    amc = write_pair(tmp_path, frames, stem="10_01", asf_name="10.asf")
    (tmp_path / "09.asf").write_text(ASF.replace("length 3", "length 4", 1))
    result = run(tmp_path, "--in-place", "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 0, result.output
    assert formats.read(amc).observed.all()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["09.asf", "10.asf", "10_01.amc"]


def test_an_edited_skeleton_makes_a_resumed_batch_redo_its_amc(tmp_path):
    # Only the AMC's time was compared: an edited .asf left the output skipped, the old
    # skeleton beside it.
    from .formats.test_acclaim import ASF, frame, write_pair

    data = tmp_path / "data"
    data.mkdir()
    frames = [frame(1), frame(2, arm="10"), frame(3, arm=None), frame(4, arm="30")]
    write_pair(data, frames, stem="10_01", asf_name="10.asf")
    out = tmp_path / "out"
    assert run(data, "-o", out, "-j", "1", "--max-jump", "0", *LINEAR).exit_code == 0
    assert run(data, "-o", out, "-j", "1", "--report", tmp_path / "a.json",
               *LINEAR).exit_code == 0
    assert [r["status"] for r in _report(tmp_path / "a.json")["files"]] == ["skipped"]
    skeleton = data / "10.asf"
    skeleton.write_text(ASF.replace("length 3", "length 4", 1))
    later = (out / "10_01.amc").stat().st_mtime_ns + 10**9
    os.utime(skeleton, ns=(later, later))
    assert run(data, "-o", out, "-j", "1", "--max-jump", "0", "--report", tmp_path / "b.json",
               *LINEAR).exit_code == 0
    assert [r["status"] for r in _report(tmp_path / "b.json")["files"]] == ["repaired"]
    # The old skeleton is never replaced: the new one goes beside the AMC under the name
    # its reader tries first, so the output reads with the edited skeleton.
    from mocapfill.formats.acclaim import find_asf

    assert find_asf(out / "10_01.amc").read_text() == skeleton.read_text()


def test_a_link_to_no_file_in_a_walked_folder_is_a_failed_file(clean_tree, tmp_path):
    # It was skipped without a word: a trial whose file went missing went unnoticed.
    root, _ = clean_tree
    (root / "gone.npz").symlink_to(tmp_path / "nowhere.npz")
    result = run(root, "-o", tmp_path / "out", "-j", "1", "--report", tmp_path / "r.json",
                 *LINEAR)
    assert result.exit_code == 123
    record, = [r for r in _report(tmp_path / "r.json")["files"]
               if Path(r["input"]).name == "gone.npz"]
    assert record["status"] == "failed" and "no such file" in record["reason"]


def test_globs_mirror_the_tree_under_their_fixed_folder(clean_tree, tmp_path):
    root, _ = clean_tree
    result = run(f"{root}/subject*/walk/*.npz", "-o", tmp_path / "out", "-j", "1", *LINEAR)
    assert result.exit_code == 0, result.output
    written = sorted(p.relative_to(tmp_path / "out").as_posix()
                     for p in (tmp_path / "out").rglob("*.npz"))
    assert written == sorted(p.relative_to(root).as_posix()
                             for p in root.glob("subject*/walk/*.npz"))
    assert len(written) == N_GAPPED // 2


def test_a_double_star_glob_does_not_follow_links_to_folders(tmp_path, monkeypatch):
    # glob's ** follows them: a link to the folder above found the file 41 times over
    # (written 400 characters deep), and two such links ran for ever.
    monkeypatch.chdir(tmp_path)
    for top, links in (("g", {"loop": ".."}), ("g2", {"up": "..", "self": "../real"})):
        (tmp_path / top / "real").mkdir(parents=True)
        formats.write(with_gap(smooth_clip(240, 8, rate=480.0), 1, 100, 120),
                      tmp_path / top / "real" / "r.npz")
        for name, target in links.items():
            (tmp_path / top / "real" / name).symlink_to(target)
        report = mocapfill.repair_many(f"{top}/**/*.npz", f"out-{top}", jobs=1,
                                       options=RepairOptions(method="linear"))
        assert [(r.input, r.output) for r in report.records] == [
            (f"{top}/real/r.npz", f"out-{top}/real/r.npz")]
    assert sorted(str(p) for p in Path("out-g").rglob("*")) == ["out-g/real",
                                                                 "out-g/real/r.npz"]


@pytest.mark.parametrize("args, words", [
    (["a.npz", "b.npz", "--jobs", "2"], "--jobs applies to batches"),
    (["a.npz", "b.npz", "--force"], "--force applies to batches"),
    (["a.npz", "b.npz", "--force", "--jobs", "2"], "--force, --jobs apply to batches"),
    (["a.npz", "b.npz", "c.npz"], "got 3 path(s)"),
    (["missing_folder", "-o", "out"], "no such file or folder"),
    (["*.json", "-o", "out"], "none of the 1 path(s) this pattern matches is a motion file"),
    (["folder.json", "-o", "out"], "no motion file in folder.json (folders are searched"),
    (["x.npz", "-o", "out", "--in-place"], "not both"),
    (["x.npz", "-o", "out", "--gaps-report", "g.csv"], "--report FILE.json"),
    (["x.npz", "-o", "out", "--report", "folder.json"], "--report must name a .json file"),
    (["x.npz", "-o", "out", "--report", "out/sub/r.json"], "--report must name a .json file"),
    (["x.npz", "-o", "r.json", "--report", "r.json"], "is where the -o folder r.json goes"),
    (["x.npz", "-o", "r.json/sub", "--report", "./r.json"], "is where the -o folder"),
    (["x.npz", "x.csv", "-o", "out", "--suffix", ".trc"],
     "differ only in their suffix, which --suffix replaces"),
    # -j was ignored without a word: the cluster's workers run the files.
    (["x.npz", "-o", "out", "-j", "4", "--scheduler", "tcp://127.0.0.1:8786"],
     "--jobs does not apply with --scheduler"),
])
def test_batch_usage_errors_exit_2_with_one_line(tmp_path, monkeypatch, args, words):
    monkeypatch.chdir(tmp_path)
    formats.write(smooth_clip(50, 3), tmp_path / "x.npz")
    formats.write(smooth_clip(50, 3), tmp_path / "x.csv")
    (tmp_path / "folder.json").mkdir()
    result = run(*args)
    assert result.exit_code == 2
    assert not (tmp_path / "out").exists()      # refused before any file was repaired
    assert words in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_a_glob_ending_in_txt_takes_the_txt_files_a_folder_walk_leaves(tmp_path,
                                                                       monkeypatch):
    # .txt, too generic to pick up in a folder, is read as CSV when named: 'e/*.txt' found
    # trial.txt, left it out, and exited 0 with "0 repaired".
    monkeypatch.chdir(tmp_path)
    (tmp_path / "e").mkdir()
    (tmp_path / "e" / "trial.txt").write_text("a_X,a_Y,a_Z\n1,2,3\n,,\n3,4,5\n4,5,6\n")
    result = run("e/*.txt", "-o", "out", *LINEAR)
    assert result.exit_code == 0, result.output
    assert result.stderr.startswith("1 repaired")
    assert formats.read(tmp_path / "out" / "trial.txt").observed.all()
    result = run("e", "-o", "out2", *LINEAR)
    assert result.exit_code == 2
    assert "no motion file in e" in result.stderr


def test_the_report_may_go_in_the_output_folder_the_batch_creates(tmp_path, monkeypatch):
    # -o out --report out/batch.json on a first run: out does not exist yet; it was
    # refused as "not in an existing folder". The report's folder is made for it even when
    # no output made it (every file failed).
    monkeypatch.chdir(tmp_path)
    formats.write(with_gap(smooth_clip(50, 3), 1, 20, 25), tmp_path / "x.npz")
    result = run("x.npz", "-o", "out", "--report", "out/batch.json", *LINEAR)
    assert result.exit_code == 0, result.output
    record, = _report(tmp_path / "out" / "batch.json")["files"]
    assert record["status"] == "repaired"
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    result = run("bad.npz", "-o", "out2", "--report", "out2/batch.json", *LINEAR)
    assert result.exit_code == 123, result.output
    record, = _report(tmp_path / "out2" / "batch.json")["files"]
    assert record["status"] == "failed"


def test_a_report_that_cannot_be_written_still_leaves_the_summary_line(tmp_path,
                                                                       monkeypatch):
    # A full disk at the end of a long batch: the error about the report came alone, and
    # how many files were repaired was nowhere.
    import errno

    from mocapfill.batch import BatchReport

    def full(self, path):
        raise OSError(errno.ENOSPC, "No space left on device", str(path))

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(BatchReport, "write_json", full)
    formats.write(with_gap(smooth_clip(50, 3), 1, 20, 25), tmp_path / "x.npz")
    result = run("x.npz", "-o", "out", "--report", "r.json", *LINEAR)
    assert result.exit_code != 0
    lines = result.stderr.strip().splitlines()
    assert SUMMARY.match(lines[0]) and lines[0].startswith("1 repaired"), lines
    assert "No space left on device" in lines[-1] and len(lines) == 2, lines


@pytest.mark.parametrize("in_place", [False, True])
def test_an_input_changed_while_it_was_repaired_is_redone_or_left_as_it_is(tmp_path,
                                                                          monkeypatch,
                                                                          in_place):
    # A file still being copied in (or edited) while the batch repairs it: its output was
    # newer than the input, so every rerun skipped it; in place, the repair of the old
    # content replaced the new.
    from mocapfill import pipeline

    folder = tmp_path / "in"
    folder.mkdir()
    path = folder / "x.trc"
    formats.write(with_gap(smooth_clip(60, 3), 1, 20, 30), path)
    real_repair = pipeline.repair

    def repair_while_it_changes(motion, options=None):
        with open(path, "a") as f:
            f.write("\n")                          # the file grows meanwhile
        os.utime(path, ns=(time.time_ns(), time.time_ns() + 10**9))
        return real_repair(motion, options)

    monkeypatch.setattr(pipeline, "repair", repair_while_it_changes)
    changed = path.read_bytes()
    args = ["--in-place"] if in_place else ["-o", tmp_path / "out"]
    report_path = tmp_path / "r.json"
    result = run(folder, *args, "-j", "1", "--report", report_path, *LINEAR)
    record, = _report(report_path)["files"]
    if in_place:
        assert result.exit_code == 123, result.output
        assert record["status"] == "failed"
        assert "changed while it was repaired; left as it is" in record["reason"]
        assert path.read_bytes() == changed + b"\n"      # the new content, untouched
    else:
        assert result.exit_code == 0, result.output
        assert record["status"] == "repaired"
        assert any("changed while it was repaired" in note for note in record["notes"])
        out = tmp_path / "out" / "x.trc"
        assert formats.read(out).observed.all()
        assert not batch._is_up_to_date(path, out)          # the next run redoes it


@pytest.mark.parametrize("address", ["garbage", ""])
def test_a_malformed_scheduler_address_is_a_usage_error_not_a_traceback(tmp_path,
                                                                       monkeypatch, address):
    if importlib.util.find_spec("distributed") is None:
        pytest.skip("dask.distributed is not installed")
    monkeypatch.chdir(tmp_path)
    formats.write(with_gap(smooth_clip(50, 3), 1, 20, 25), tmp_path / "x.npz")
    result = run("x.npz", "-o", "out", "--scheduler", address, *LINEAR)
    assert result.exit_code == 2, result.output
    assert f"Dask scheduler address {address!r}" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_repair_many_from_python(tree, tmp_path):
    root, _ = tree
    calls = []
    report = mocapfill.repair_many(
        [root], tmp_path / "out", options=RepairOptions(method="linear"), jobs=1,
        progress=lambda done, total, record: calls.append((done, total, record)))
    assert (report.repaired, report.unchanged, report.skipped, report.failed) == (20, 1, 0, 1)
    assert report.exit_code() == 123
    assert report.summary().startswith("20 repaired, 1 unchanged, 1 failed in ")
    assert calls[0] == (0, 22, None) and calls[-1][:2] == (22, 22)
    assert report.frames == 21 * 240


@pytest.mark.parametrize("kwargs", [dict(max_gap_s=-1.0), dict(max_gap_s=float("nan")),
                                    dict(max_gap_s=float("inf")),
                                    dict(zero_is_missing="maybe")])
def test_repair_many_refuses_bad_arguments_before_any_file(clean_tree, tmp_path, kwargs):
    # These failed every file one by one ("ValueError: cannot convert float NaN to
    # integer"), where a bad --jobs or --suffix is a ParameterError up front.
    root, _ = clean_tree
    with pytest.raises(mocapfill.ParameterError):
        mocapfill.repair_many([root], tmp_path / "out", jobs=1,
                              options=RepairOptions(method="linear"), **kwargs)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("options", "hint"), [
    ({"method": "linear"}, ": mocapfill.RepairOptions(**options) makes one of a dict"),
    ("linear", "")])
def test_repair_many_refuses_options_that_are_not_repair_options_before_any_file(
        clean_tree, tmp_path, options, hint):
    # A dict failed every file one by one with a TypeError.
    root, _ = clean_tree
    with pytest.raises(TypeError, match=re.escape(
            f"repair_many() takes a RepairOptions as options, got {type(options).__name__}"
            f"{hint}")):
        mocapfill.repair_many([root], tmp_path / "out", jobs=1, options=options)
    assert not (tmp_path / "out").exists()


def test_max_gap_in_seconds_fails_a_file_without_rate_and_converts_at_each_files_rate(
        tmp_path):
    root = tmp_path / "data"
    root.mkdir()
    gapped = with_gap(smooth_clip(200, 4), 1, 100, 130)        # a 30-frame gap
    formats.write(gapped.replace(rate=0.0), root / "norate.npz")
    formats.write(gapped.replace(rate=100.0), root / "slow.npz")   # 0.3 s: filled
    formats.write(gapped.replace(rate=50.0), root / "fast.npz")    # 0.6 s: left
    report = mocapfill.repair_many([root], tmp_path / "out", jobs=1, max_gap_s=0.5,
                                   options=RepairOptions(method="linear"))
    records = {Path(r.input).name: r for r in report.records}
    assert records["norate.npz"].status == "failed"
    assert records["norate.npz"].reason.startswith("the file states no frame rate")
    assert records["slow.npz"].status == "repaired"
    assert formats.read(tmp_path / "out" / "slow.npz").observed.all()
    assert not formats.read(tmp_path / "out" / "fast.npz").observed.all()


def test_a_write_that_fails_names_the_output_a_read_the_input_alone(tmp_path, monkeypatch):
    # Records are reported under the input's name: "in/a.npz: No space left on device"
    # said nothing of the output's disk, which was the full one.
    from mocapfill.errors import FormatError

    root = tmp_path / "in"
    root.mkdir()
    formats.write(with_gap(smooth_clip(200, 4), 1, 100, 130), root / "a.npz")
    (root / "b.npz").write_bytes(b"not a numpy archive")

    def full_disk(motion, path, **options):
        raise FormatError(path, "No space left on device")

    monkeypatch.setattr(formats, "write", full_disk)
    report = mocapfill.repair_many([root], tmp_path / "out", jobs=1,
                                   options=RepairOptions(method="linear"))
    reasons = {Path(r.input).name: r.reason for r in report.records}
    assert reasons["a.npz"] == f"{tmp_path / 'out' / 'a.npz'}: No space left on device"
    # A read error's file is the input, which the record names already: not twice.
    assert reasons["b.npz"] and str(root) not in reasons["b.npz"]


def test_a_report_cut_short_leaves_the_last_good_one(tmp_path, monkeypatch):
    # A full disk (or a second Ctrl-C) while the report is written: the last good report
    # stays, not half of a JSON document, and no temporary is left beside it.
    import errno

    path = tmp_path / "r.json"
    batch.BatchReport().write_json(path)
    before = path.read_text()
    real = Path.write_text

    def half_then_full(self, text, *args, **kwargs):
        real(self, text[:len(text) // 2], *args, **kwargs)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Path, "write_text", half_then_full)
    with pytest.raises(OSError):
        batch.BatchReport(records=[batch.FileRecord("a.c3d", "o/a.c3d", "repaired")]
                          ).write_json(path)
    assert path.read_text() == before and json.loads(before)
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]


def test_a_skeleton_suffix_for_marker_inputs_fails_each_file_before_its_repair(
        clean_tree, tmp_path, monkeypatch):
    import mocapfill.pipeline

    root, _ = clean_tree
    monkeypatch.setattr(mocapfill.pipeline, "repair", lambda *a, **k: pytest.fail("ran"))
    report = mocapfill.repair_many([root], tmp_path / "out", suffix=".bvh", jobs=1,
                                   options=RepairOptions(method="linear"))
    assert report.failed == N_GAPPED + 1
    assert {r.reason for r in report.failures} == {
        "BVH output needs a BVH input (positions cannot be turned into joint angles); "
        "write .c3d/.trc/.csv instead"}


def test_ctrl_c_stops_the_pool_and_leaves_no_temporary_files(clean_tree, tmp_path):
    root, _ = clean_tree

    def interrupt_after_first(done, total, record):
        if done == 1:
            raise KeyboardInterrupt

    # Children of earlier tests may still be on their way out (the Dask test's workers,
    # which LocalCluster does not wait for): this batch's workers are what must be gone.
    earlier = set(multiprocessing.active_children())
    with pytest.raises(batch.BatchInterrupted) as caught:
        mocapfill.repair_many(root, tmp_path / "out", options=RepairOptions(method="linear"),
                              jobs=2, progress=interrupt_after_first)
    records = caught.value.report.records   # the first, and any finished meanwhile
    assert records and all(Path(r.output).is_file() for r in records)
    assert set(multiprocessing.active_children()) - earlier == set()
    assert not list((tmp_path / "out").rglob(".*"))


def test_ctrl_c_reports_every_file_whose_output_is_written(clean_tree, tmp_path):
    # Results the workers had sent but the batch had not handed out yet (it was paused,
    # `kill -STOP`, or busy in its progress callback) were dropped on Ctrl-C: outputs on
    # disk, missing from --report, whose README says it holds the files finished so far.
    root, files = clean_tree
    out = tmp_path / "out"

    def interrupt_once_all_are_written(done, total, record):
        if done == 1:
            deadline = time.monotonic() + 60
            while len(list(out.rglob("*.npz"))) < total and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(0.2)         # the last result on its way back
            raise KeyboardInterrupt

    with pytest.raises(batch.BatchInterrupted) as caught:
        mocapfill.repair_many(root, out, options=RepairOptions(method="linear"), jobs=2,
                              progress=interrupt_once_all_are_written)
    written = {str(path) for path in out.rglob("*.npz")}
    assert len(written) == len(files)
    assert {r.output for r in caught.value.report.records} == written


def test_ctrl_c_exits_130(clean_tree, tmp_path, monkeypatch):
    root, _ = clean_tree

    def interrupted(job):
        raise KeyboardInterrupt

    monkeypatch.setattr(batch, "repair_file", interrupted)
    result = run(root, "-o", tmp_path / "out", "-j", "1", "--report", tmp_path / "r.json")
    assert result.exit_code == 130
    assert "interrupted" in result.stderr
    assert _report(tmp_path / "r.json")["summary"]["files"] == 0


def test_a_stopped_worker_prints_no_ignored_exceptions(monkeypatch, capsys):
    # SIGTERM's exit is raised wherever the worker is; what it leaves half-built fails
    # again in __del__ (np.savez's ZipFile: "Exception ignored in ... AttributeError:
    # 'ZipFile' object has no attribute '_writing'"), printed with its traceback on the
    # user's terminal after Ctrl-C.
    import signal

    class HalfBuilt:
        def __del__(self):
            raise AttributeError("'HalfBuilt' object has no attribute '_writing'")

    monkeypatch.setattr(sys, "unraisablehook", sys.__unraisablehook__)
    HalfBuilt()
    assert "Exception ignored" in capsys.readouterr().err      # what a user saw

    monkeypatch.setattr(batch, "_TERMINATING", [])
    with pytest.raises(SystemExit):
        batch._exit_on_terminate(signal.SIGTERM, None)
    HalfBuilt()
    assert capsys.readouterr().err == ""


_POOL_PARENT = """
import multiprocessing, os, sys, time
from concurrent.futures import ProcessPoolExecutor
from mocapfill import batch

if __name__ == "__main__":
    pool = ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"),
                               initializer=batch._single_threaded_worker,
                               initargs=(os.getpid(),))
    pool.submit(time.sleep, 0).result()                 # the worker is up
    if sys.argv[1] == "busy":
        pool.submit(time.sleep, 60)
    print(*pool._processes, flush=True)
    time.sleep(60)
"""


def _running(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("worker", ["idle", "busy"])
def test_workers_leave_when_the_pool_process_is_killed(tmp_path, worker):
    # `timeout`, a scheduler's cancel or the OOM killer ends the batch without a word to
    # its workers; an idle one waited on the pool's queue for ever (it holds the pipe's
    # other end itself), a busy one finished its file first.
    import signal
    import subprocess

    script = tmp_path / "pool_parent.py"
    script.write_text(_POOL_PARENT)
    parent = subprocess.Popen([sys.executable, str(script), worker], stdout=subprocess.PIPE,
                              text=True)
    try:
        workers = [int(pid) for pid in parent.stdout.readline().split()]
        assert workers and all(_running(pid) for pid in workers)
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait(10)
    deadline = time.monotonic() + 15
    while any(_running(pid) for pid in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_running(pid) for pid in workers)


_HANG_UP_PROBE = """
import multiprocessing, signal, sys
from multiprocessing import resource_tracker
import mocapfill
from mocapfill.pipeline import RepairOptions


def _ignores_sighup(pid):
    with open(f"/proc/{pid}/status") as status:
        mask = next(line for line in status if line.startswith("SigIgn:")).split()[1]
    return bool(int(mask, 16) & 1 << (signal.SIGHUP - 1))


if __name__ == "__main__":
    seen = []

    def look(done, total, record):
        if done == 1:
            seen.extend(_ignores_sighup(p.pid) for p in multiprocessing.active_children())
            seen.append(_ignores_sighup(resource_tracker._resource_tracker._pid))

    previous = signal.getsignal(signal.SIGHUP)
    mocapfill.repair_many(sys.argv[1], sys.argv[2],
                          options=RepairOptions(method="linear"), jobs=2, progress=look)
    print(len(seen), all(seen), signal.getsignal(signal.SIGHUP) == previous)
"""


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
def test_the_pools_processes_ignore_a_terminals_hang_up(clean_tree, tmp_path):
    # A closed terminal sends SIGHUP to its whole process group: the pool's resource
    # tracker died of it (then was started again, with a KeyError traceback per
    # semaphore) and the workers mid-write left their temporaries. The command stops
    # them itself. In a fresh process, whose resource tracker the batch starts.
    import subprocess

    root, _ = clean_tree
    script = tmp_path / "probe.py"
    script.write_text(_HANG_UP_PROBE)
    done = subprocess.run([sys.executable, str(script), str(root), str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    count, ignored, restored = done.stdout.split()
    assert int(count) >= 3                      # two workers and the tracker
    assert ignored == "True" and restored == "True"     # and this process as it was


def test_a_worker_stopped_by_the_pool_starts_no_further_file(tmp_path, monkeypatch):
    # The pool's worker loop catches the SystemExit that SIGTERM raises in a job and goes
    # on to the next queued file: after Ctrl-C that file was repaired, written (3 s after
    # the signal, for 85_12) and left out of the report.
    import signal

    source = tmp_path / "in.npz"
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), source)
    job = batch.FileJob(source, tmp_path / "out" / "in.npz", RepairOptions(method="linear"))
    exits = []

    def fake_exit(code):
        exits.append(code)
        raise SystemExit(code)

    monkeypatch.setattr(os, "_exit", fake_exit)
    monkeypatch.setattr(batch, "_TERMINATING", [])     # this process's flag, restored after
    with pytest.raises(SystemExit):
        batch._exit_on_terminate(signal.SIGTERM, None)
    with pytest.raises(SystemExit):
        batch.repair_file(job)
    assert exits == [128 + signal.SIGTERM]
    assert not (tmp_path / "out").exists()


def test_in_place_repairs_a_file_whose_name_is_as_long_as_the_file_system_allows(tmp_path):
    # In place, the temporary file is named after the input, and formats.write's own
    # temporary after that one: both passed the 255-byte limit of a name.
    path = tmp_path / f"{'a' * 251}.npz"
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), path)
    result = run(path, "--in-place", "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 0, result.output
    assert formats.read(path).observed.all()
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


@pytest.mark.parametrize("in_place", [False, True])
def test_temporaries_of_an_output_with_a_long_name_are_found_to_be_removed(tmp_path,
                                                                           in_place):
    # What a worker killed mid-write leaves, as formats.write and an in-place write name it.
    output = tmp_path / f"{'a' * 251}.npz"
    job = batch.FileJob(output if in_place else tmp_path / "in.npz", output,
                        in_place=in_place)
    with pytest.raises(InterruptedError), contextlib.ExitStack() as stack:
        if in_place:
            outer = stack.enter_context(formats.atomic_output(output, suffix=".inplace.npz"))
            made = [outer, stack.enter_context(formats.atomic_output(Path(outer)))]
        else:
            made = [stack.enter_context(formats.atomic_output(output))]
        assert all(os.path.exists(p) for p in made)
        batch.remove_temp_files([job])
        assert not [p for p in made if os.path.exists(p)]
        raise InterruptedError


@pytest.mark.parametrize("in_place", [False, True])
def test_a_stopped_batch_leaves_the_temporaries_of_another_writer_of_its_outputs(tmp_path,
                                                                                 in_place):
    # Its temporaries were found by the output's name alone: a batch stopped (Ctrl-C, a
    # worker that died) removed those of a `mocapfill repair` (or another batch) writing
    # the same output name in the same folder, which then failed ("No such file or
    # directory").
    source = tmp_path / "in" / "clip.npz"
    source.parent.mkdir()
    for path in (source.parent / "a.npz", source):     # repaired in that order
        formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), path)
    out = source.parent if in_place else tmp_path / "out"
    out.mkdir(exist_ok=True)

    def interrupt(done, total, record):
        if done:        # after a.npz: clip.npz's temporaries are the batch's to remove
            raise KeyboardInterrupt

    with contextlib.ExitStack() as stack:
        # The other writer's temporaries, named as formats.write and an in-place write
        # name them in its process.
        if in_place:
            outer = stack.enter_context(formats.atomic_output(source, suffix=".inplace.npz"))
            theirs = [outer, stack.enter_context(formats.atomic_output(Path(outer)))]
        else:
            theirs = [stack.enter_context(formats.atomic_output(out / "clip.npz"))]
        Path(theirs[-1]).write_bytes(source.read_bytes())
        with pytest.raises(batch.BatchInterrupted) as caught:
            mocapfill.repair_many(source.parent, None if in_place else out,
                                  in_place=in_place, options=RepairOptions(method="linear"),
                                  jobs=1, progress=interrupt)
        assert [Path(r.input).name for r in caught.value.report.records] == ["a.npz"]
        assert all(os.path.exists(p) for p in theirs)
    assert formats.read(out / "clip.npz").n_frames == 200


def test_a_batch_removes_the_skeleton_temporary_a_killed_worker_left_beside_an_amc(tmp_path):
    # The .asf copied beside a repaired AMC is written to a temporary file first; a worker
    # killed then left it, since only the output's own temporaries were looked for.
    output = tmp_path / "10_01.amc"
    job = batch.FileJob(tmp_path / "in" / "10_01.amc", output, temp_token="b4tch")
    made = {}
    for token in ("b4tch", "12345"):
        reset = formats.TEMP_TOKEN.set(token)
        try:
            made[token] = formats.create_temp(tmp_path, "10.asf", ".tmp")
        finally:
            formats.TEMP_TOKEN.reset(reset)
    (tmp_path / "10.asf").write_text("kept")
    batch.remove_temp_files([job])
    assert not os.path.exists(made["b4tch"]) and os.path.exists(made["12345"])
    assert (tmp_path / "10.asf").read_text() == "kept"
    # Not beside another format's output.
    made["b4tch"] = formats.create_temp(tmp_path, "10.asf", ".tmp")
    batch.remove_temp_files([batch.FileJob(tmp_path / "a.npz", tmp_path / "b.npz",
                                           temp_token=str(os.getpid()))])
    assert os.path.exists(made["b4tch"])


def test_a_batch_removes_the_skeleton_temporary_of_a_long_named_amc(tmp_path):
    # The skeleton's temporary is named as any other (formats.temp_prefix), its name cut
    # short where it would pass NAME_MAX bytes: cut inside ".asf" the glob on ".asf."
    # missed it (an output of 236 bytes with the batch's 8-character token).
    token = "b4tch123"
    for length in range(224, 240):
        stem = "s" * length
        output = tmp_path / f"{stem}.amc"
        job = batch.FileJob(tmp_path / "in" / output.name, output, temp_token=token)
        reset = formats.TEMP_TOKEN.set(token)
        try:
            made = formats.create_temp(tmp_path, f"{stem}.asf", ".tmp")
        finally:
            formats.TEMP_TOKEN.reset(reset)
        batch.remove_temp_files([job])
        assert not os.path.exists(made), length


@pytest.mark.parametrize("in_place", [False, True])
def test_a_batch_removes_the_temporaries_named_with_its_token_only(tmp_path, in_place):
    output = tmp_path / "clip.npz"
    job = batch.FileJob(output if in_place else tmp_path / "in.npz", output,
                        in_place=in_place, temp_token="b4tch")
    made = {}
    with pytest.raises(InterruptedError), contextlib.ExitStack() as stack:
        for token in ("b4tch", "12345"):
            stack.callback(formats.TEMP_TOKEN.reset, formats.TEMP_TOKEN.set(token))
            if in_place:
                outer = stack.enter_context(formats.atomic_output(output,
                                                                  suffix=".inplace.npz"))
                made[token] = [outer, stack.enter_context(formats.atomic_output(Path(outer)))]
            else:
                made[token] = [stack.enter_context(formats.atomic_output(output))]
        batch.remove_temp_files([job])
        assert [os.path.exists(p) for p in made["b4tch"]] == [False] * len(made["b4tch"])
        assert all(os.path.exists(p) for p in made["12345"])
        raise InterruptedError


def test_an_output_named_by_a_symlink_loop_is_written_in_its_place(tmp_path):
    # Path.resolve() and the resume check's stat() raised on a loop: a traceback before
    # any file was repaired, and exit 1, which is --check's "gaps left".
    source = tmp_path / "in" / "clip.npz"
    source.parent.mkdir()
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), source)
    out = tmp_path / "out"
    out.mkdir()
    (out / "clip.npz").symlink_to("clip.npz")
    result = run(source.parent, "-o", out, "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 0, result.output
    assert formats.read(out / "clip.npz").observed.all()


def test_a_report_that_cannot_be_written_is_named_not_its_temporary(clean_tree, tmp_path,
                                                                     monkeypatch):
    # The error named ".batch.json.x1y2z3.tmp", a file the user never asked for.
    root, _ = clean_tree

    def disk_full(self, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(Path, "write_text", disk_full)
    report = tmp_path / "batch.json"
    result = run(root, "-o", tmp_path / "out", "-j", "1", "--report", report, *LINEAR)
    assert result.exit_code == 123
    assert f"mocapfill: error: {report}: No space left on device\n" in result.stderr
    assert ".tmp" not in result.stderr
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_temporaries_of_an_in_place_write_through_a_symlink_are_found_to_be_removed(
        tmp_path):
    # An in-place write replaces the link's target, so its temporaries lie beside the
    # target; they were looked for beside the link, and a worker killed mid-write left
    # them there.
    target = tmp_path / "data" / "clip.npz"
    target.parent.mkdir()
    target.write_bytes(b"")
    (tmp_path / "links").mkdir()
    link = tmp_path / "links" / "clip.npz"
    link.symlink_to(target)
    job = batch.FileJob(link, link, in_place=True)
    with pytest.raises(InterruptedError), contextlib.ExitStack() as stack:
        outer = stack.enter_context(formats.atomic_output(target, suffix=".inplace.npz"))
        made = [outer, stack.enter_context(formats.atomic_output(Path(outer)))]
        batch.remove_temp_files([job])
        assert not [p for p in made if os.path.exists(p)]
        raise InterruptedError


def test_an_in_place_write_that_fails_names_the_input_not_its_temporary(tmp_path,
                                                                        monkeypatch):
    # The record's reason named ".clip.npz.x1y2z3.inplace.npz", a file the user never saw.
    from mocapfill.formats import npz

    path = tmp_path / "clip.npz"
    formats.write(with_gap(smooth_clip(200, 6), 2, 50, 80), path)
    before = path.read_bytes()

    def disk_full(motion, out, **options):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out))

    monkeypatch.setattr(npz, "write", disk_full)
    result = run(path, "--in-place", "-j", "1", "--max-jump", "0", *LINEAR)
    assert result.exit_code == 123
    assert f"mocapfill: error: {path}: No space left on device\n" in result.stderr
    assert ".inplace" not in result.stderr and ".tmp" not in result.stderr
    assert path.read_bytes() == before
    assert [p.name for p in tmp_path.iterdir()] == ["clip.npz"]


def test_max_gap_in_seconds_leaves_a_gap_just_longer_than_that_in_a_batch(tmp_path):
    # 0.07 s at 250 Hz is 17.5 frames: an 18-frame gap (0.072 s) is longer and is left,
    # a 17-frame one (0.068 s) filled. Rounding to 18 frames filled both.
    root = tmp_path / "data"
    root.mkdir()
    clip = with_gap(with_gap(smooth_clip(200, 4, rate=250.0), 1, 50, 68), 2, 100, 117)
    formats.write(clip, root / "a.npz")
    report = mocapfill.repair_many([root], tmp_path / "out", jobs=1, max_gap_s=0.07,
                                   options=RepairOptions(method="linear", max_jump_mm=0))
    (record,) = report.records
    assert (record.gaps_filled, record.gaps_left) == (1, 1)
    observed = formats.read(tmp_path / "out" / "a.npz").observed
    assert not observed[50:68, 1].any() and observed[100:117, 2].all()


def test_repair_many_reads_zero_gaps_of_text_files_when_asked(tmp_path):
    # --zero-is-missing reached C3D files only; a folder of QTM-derived CSV/TRC files with
    # gaps at (0, 0, 0) came out "unchanged" whatever it was given.
    root = tmp_path / "data"
    root.mkdir()
    (root / "z.csv").write_text("Frame,Time,A_X,A_Y,A_Z\n1,0,1,2,3\n2,0.01,0,0,0\n"
                                "3,0.02,3,4,5\n")
    outcomes = {}
    for setting in ("auto", "on"):
        report = mocapfill.repair_many([root], tmp_path / setting, jobs=1,
                                       options=RepairOptions(method="linear"),
                                       zero_is_missing=setting)
        outcomes[setting] = (report.repaired, report.unchanged)
    assert outcomes == {"auto": (0, 1), "on": (1, 0)}
    assert (tmp_path / "on" / "z.csv").read_text().splitlines()[2] == "2,0.01,2,3,4"


def _worker_dying_on_die_files(parent):
    """A worker initializer (by reference, so spawned workers import it from here) whose
    ``repair_file`` kills its process on a file named die*, as the OOM killer would."""
    batch._single_threaded_worker(parent)
    repair = batch.repair_file

    def dying(job):
        if job.input.name.startswith("die"):
            os._exit(137)
        return repair(job)

    batch.repair_file = dying


def test_a_worker_that_dies_fails_its_own_file_only(tmp_path, monkeypatch):
    # A worker's death broke the pool, and every file not finished, started or not, was
    # failed with "worker process died": 0 repaired, 8 failed for one kill.
    root = tmp_path / "data"
    root.mkdir()
    for i, name in enumerate(["a", "b", "c", "die", "e", "f"]):
        formats.write(with_gap(smooth_clip(240, 8, rate=480.0, seed=i), 1, 100, 120),
                      root / f"{name}.npz")
    monkeypatch.setattr(batch, "_single_threaded_worker", _worker_dying_on_die_files)
    report = mocapfill.repair_many(root, tmp_path / "out", jobs=2,
                                   options=RepairOptions(method="linear"))
    by_name = {Path(r.input).name: r for r in report.records}
    assert by_name.pop("die.npz").reason == batch.WORKER_DIED
    assert {r.status for r in by_name.values()} == {"repaired"}, report.records
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "a.npz", "b.npz", "c.npz", "e.npz", "f.npz"]
