"""The accuracy benchmark: table rendering and clean skips without data."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from mocapfill import bench
from mocapfill.solvers import METHODS

from .helpers import smooth_clip, with_gap


def _row(case, method, err, seconds=1.0, dataset="cmu", seed=0):
    return {"dataset": dataset, "case": case, "seed": seed, "method": method,
            "rmse_mm": err, "rmse_3d_mm": err, "seconds": seconds, "samples": 10, "note": ""}


def test_table_averages_seeds_and_bolds_the_best_method():
    rows = [_row("85_02 ml=40", "trnn", 1.0, seed=0), _row("85_02 ml=40", "trnn", 3.0, seed=1),
            _row("85_02 ml=40", "spline", 5.0, seed=0), _row("85_02 ml=40", "spline", 5.0, seed=1)]
    table = bench.format_table(rows)
    assert "| cmu 85_02 ml=40 | **2.00** / 1.00s | 5.00 / 1.00s |" in table


def test_missing_data_becomes_a_row_note_not_an_error(monkeypatch, tmp_path):
    monkeypatch.setattr(bench, "SHARED_DATA", tmp_path / "absent")
    case = bench.cases(quick=True)[0]
    rows = bench.run_case(case, ["linear"])
    assert rows[0]["rmse_mm"] is None and rows[0]["note"].startswith("skipped")
    assert "skipped" in bench.format_table(rows)


def test_a_missing_walkl_file_is_named_in_the_skip_note(monkeypatch, tmp_path):
    # scipy's loadmat of an absent file said "OSError: Reader needs file name or open
    # file-like object": neither which file nor why. As the CMU cases say it.
    (tmp_path / "walkl").mkdir()
    monkeypatch.setattr(bench, "SHARED_DATA", tmp_path)
    case = next(c for c in bench.cases(quick=True) if c.dataset == "walkl")
    note = bench.run_case(case, ["linear"])[0]["note"]
    assert note == f"skipped: FormatError: {tmp_path / 'walkl' / 'WalkL.mat'}: no such file"


def test_a_chart_whose_write_fails_leaves_no_half_written_file(monkeypatch, tmp_path):
    # The charts were saved under their own names: a write that failed (a full disk,
    # Ctrl-C) left half a PNG where a previous run's chart had been.
    import pytest

    pytest.importorskip("matplotlib")
    from matplotlib.figure import Figure

    from mocapfill import bench_paper

    def failing(self, fname, *args, **kwargs):
        Path(fname).write_bytes(b"\x89PNG half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", failing)
    (tmp_path / "accuracy-cmu.png").write_bytes(b"previous chart")
    summary = bench.summarise([_row("85_02 ml=40", "linear", 2.0)])
    with pytest.raises(OSError):
        bench.plot_summary(summary, tmp_path)
    setup = bench_paper.Setup("mocapfill bench paper", "today", "box", "cpu", 2, "3", "2",
                              "1", "0.0", "x")
    results = bench_paper.PaperResults(bench_paper.PaperConfig.quick(), setup)
    results.ranks.append(object())
    monkeypatch.setattr(bench_paper, "_plot_ranks", lambda plt, results: plt.figure())
    with pytest.raises(OSError):
        bench_paper.write_plots(results, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["accuracy-cmu.png"]
    assert (tmp_path / "accuracy-cmu.png").read_bytes() == b"previous chart"


def test_quick_subset_is_small():
    assert len(bench.cases(quick=True)) <= 4


def _jumping_fill(matrix, observed, **_options):
    """A method whose fill of every gap sits far from the data (jumps in at both ends)."""
    return np.where(observed, matrix, matrix[observed].max() + 10.0)


def _gapped_case() -> tuple[bench.Case, int]:
    truth = smooth_clip(n_frames=300, n_markers=6)
    gapped = with_gap(with_gap(with_gap(truth, 1, 100, 130), 4, 200, 240), 2, 0, 10)
    interior = 30 + 40                      # marker samples; the end gap is left and not scored
    return bench.Case("cmu", "synthetic ml", 0, lambda: (truth, gapped)), interior


def test_every_method_is_scored_on_every_interior_gap_sample(monkeypatch):
    # The pipeline's jump check would put back a fill that starts with a jump and the
    # method would be scored on the gaps it filled plausibly only (psvt on 85_02 ml=40:
    # 400 of 1,200 samples). The benchmark scores each method's own fill of them all.
    monkeypatch.setitem(METHODS, "jumping", f"{__name__}:_jumping_fill")
    case, interior = _gapped_case()
    jumping, linear = bench.run_case(case, ["jumping", "linear"])
    assert jumping["note"] == "" and jumping["samples"] == interior
    assert jumping["unfilled"] == 0 and linear["unfilled"] == 0
    assert linear["samples"] == interior
    assert jumping["rmse_mm"] > 10 * linear["rmse_mm"]


def test_unfilled_samples_are_marked_in_the_table():
    rows = [_row("85_02 ml=40", "psvt", 1.0), _row("85_02 ml=40", "trnn", 2.0)]
    rows[0]["unfilled"] = 240
    table = bench.format_table(rows)
    assert "| cmu 85_02 ml=40 | **1.00**† / 1.00s | 2.00 / 1.00s |" in table
    assert "85_02 ml=40 / psvt: 240 interior samples left unfilled, not scored" in table


def test_the_table_says_which_error_each_dataset_line_gives():
    # walkl lines give the 3-D error, CMU lines the RMSE over coordinates (√3 smaller for
    # the same fills): the printed table did not say which.
    rows = [_row("WalkL_0001", "trnn", 1.0, dataset="walkl"), _row("85_02 ml=40", "trnn", 2.0)]
    table = bench.format_table(rows)
    assert "- walkl lines: 3-D RMS marker error (mm) over the interior gap samples" in table
    assert "- cmu lines: the paper's RMSE over the missing coordinates (mm" in table
