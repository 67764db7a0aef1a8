"""The accuracy benchmark: table rendering and clean skips without data."""
from __future__ import annotations

from mocapfill import bench


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


def test_quick_subset_is_small():
    assert len(bench.cases(quick=True)) <= 4
