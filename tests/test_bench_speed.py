"""The speed benchmark's machinery (timings themselves are never asserted)."""
import numpy as np

from mocapfill.bench_speed import SpeedRow, _synthetic, format_speed_table, iteration_floor_ms


def test_synthetic_long_clip_has_the_requested_shape_and_gap_share():
    clip = _synthetic(3000, 7, 0.05, seed=1)
    assert clip.positions.shape == (3000, 7, 3)
    missing = 1 - clip.observed.mean()
    assert 0.04 < missing < 0.08
    assert clip.observed[0].all() and clip.observed[-1].all()


def test_floor_is_a_positive_number_of_milliseconds():
    floor = iteration_floor_ms(30, 500)
    assert np.isfinite(floor) and floor > 0


def test_table_lists_every_case():
    rows = [SpeedRow("a", "trnn", 10, 2, 3, 0.1, 0.2, 0.3, 50.0, target_s=1.0, iterations=7,
                     ms_per_iteration=1.5, floor_ms_per_iteration=0.5),
            SpeedRow("b", "tsmc", 10, 2, 1, 0.4, 0.4, 0.4, 60.0)]
    table = format_speed_table(rows)
    assert table.count("\n") == 3
    assert "| a | trnn | 0.100 / 0.200 / 0.300 | 1.0 | 7 | 1.5 | 0.5 | 50 |" in table
