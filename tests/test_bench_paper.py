"""The paper's experiments (mocapfill.bench_paper): tiny configurations, real solvers."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocapfill.bench_paper import (
    IALM,
    PSVT,
    CompletionCell,
    PaperConfig,
    PaperResults,
    RankCell,
    RpcaCell,
    Setup,
    blas_threads,
    format_markdown,
    run_experiments,
    run_rpca_grid,
    synthetic_rpca,
)

from .conftest import SHARED_DATA

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

TINY_SYNTHETIC = dict(m=200, n=60, ranks=(5,), ratios=(0.05,), repeats=1)
# Every figure once, on the first 200 frames of one clip: a few seconds.
TINY = PaperConfig(**TINY_SYNTHETIC, rank_clips=("85_02",), rank_mr=(0.2,), rank_ml=(20,),
                   rank_seeds=(1,), truncation_clips=("85_02",), truncation_ranks=(5, 15),
                   truncation_mr=(0.2,), truncation_ml=(), completion_clips=("85_02",),
                   completion_mr=(0.2,), completion_ml=(), completion_seeds=(1,),
                   completion_methods=("trnn-paper", "tsmc"), max_frames=200)

FIGURE_TABLES = {  # heading -> the header row of its table
    "### Fig. 2: NRE": "| r₀ | cr | TrNN ρ=1.5 | TrNN ρ=1.2 | PSVT | IALM |",
    "### Fig. 3: solver time": "| r₀ | cr | TrNN ρ=1.5 | TrNN ρ=1.2 | PSVT | IALM |",
    "## Fig. 4": "| clip | mr = 0.2 |",
    "## Fig. 5": "| r | mr = 0.2 |",
    "## Fig. 6": "| clip (frames) | gaps | trnn-paper RMSE | tsmc RMSE | trnn-paper s |",
}


def _table_after(markdown: str, heading: str) -> str:
    """The first table row after ``heading``."""
    section = markdown.split(heading, 1)[1]
    return next(line for line in section.splitlines() if line.startswith("|"))


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory) -> tuple[PaperResults, Path]:
    if not (SHARED_DATA / "cmu" / "85_02.c3d").exists():
        pytest.skip("../shared/data/cmu/85_02.c3d absent")
    pytest.importorskip("matplotlib")
    plots = tmp_path_factory.mktemp("plots")
    return run_experiments(TINY, plots, command="test"), plots


def test_synthetic_matrix_has_rank_r0_and_a_fraction_cr_of_bounded_outliers():
    D, truth = synthetic_rpca(200, 60, 5, 0.05, np.random.default_rng(0))
    sparse = D - truth
    assert np.linalg.matrix_rank(truth) == 5
    assert np.count_nonzero(sparse) == round(0.05 * 200 * 60)
    assert np.abs(sparse).max() <= 10.0


def test_synthetic_matrix_depends_only_on_the_seed():
    first = synthetic_rpca(50, 20, 3, 0.1, np.random.default_rng(7))[0]
    second = synthetic_rpca(50, 20, 3, 0.1, np.random.default_rng(7))[0]
    assert np.array_equal(first, second)


def test_trnn_rpca_and_ialm_recover_the_low_rank_part_of_a_tiny_grid():
    with blas_threads(1):  # a threaded BLAS on a busy machine: 100x slower on 200 x 60
        cells = {c.method: c for c in run_rpca_grid(PaperConfig(**TINY_SYNTHETIC))}
    assert set(cells) == {"TrNN ρ=1.5", "TrNN ρ=1.2", PSVT, IALM}
    for method in ("TrNN ρ=1.5", "TrNN ρ=1.2", IALM):
        assert max(cells[method].nre) < 1e-5, method
        assert min(cells[method].seconds) > 0


def test_rpca_grid_is_reproducible():
    config = PaperConfig(m=60, n=30, ranks=(3,), ratios=(0.1,), repeats=2)
    with blas_threads(1):
        first = [c.nre for c in run_rpca_grid(config)]
        assert first == [c.nre for c in run_rpca_grid(config)]


def test_markdown_has_the_table_of_every_figure(tiny_run):
    markdown = format_markdown(tiny_run[0])
    for heading, header in FIGURE_TABLES.items():
        assert _table_after(markdown, heading).startswith(header), heading


def test_every_missing_coordinate_is_scored_in_mm(tiny_run):
    results = tiny_run[0]
    rmse = [e for c in results.truncation + results.completion for e in c.rmse_mm]
    assert all(np.isfinite(rmse)) and not results.notes
    # Under 10 cm and above 0.01 mm: millimetres, not metres or file units.
    assert 0.01 < min(rmse) and max(rmse) < 100.0


def test_plots_are_written_as_png_files(tiny_run):
    results, folder = tiny_run
    assert [p.name for p in results.plots] == ["fig2_nre.png", "fig3_time.png", "fig4_rank.png",
                                               "fig5_truncated_rank.png",
                                               "fig6_trnn_vs_tsmc.png"]
    for path in results.plots:
        assert path.parent == folder
        assert path.read_bytes()[:8] == PNG_MAGIC


def test_without_shared_data_the_synthetic_figures_still_run(tmp_path):
    absent = tmp_path / "no-data"
    results = run_experiments(PaperConfig(**TINY_SYNTHETIC), data_dir=absent)
    assert results.rpca and not (results.ranks or results.truncation or results.completion)
    markdown = format_markdown(results)
    assert _table_after(markdown, "### Fig. 2: NRE").startswith("| r₀ | cr |")
    for figure in ("## Fig. 4", "## Fig. 5", "## Fig. 6"):
        assert f"skipped: {absent} absent" in markdown.split(figure, 1)[1]


def test_without_matplotlib_the_report_has_tables_and_a_note(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib", None)   # import matplotlib -> ImportError
    results = run_experiments(PaperConfig(**TINY_SYNTHETIC), tmp_path / "plots",
                              data_dir=tmp_path / "no-data")
    assert results.plots == [] and not list(tmp_path.glob("plots/*.png"))
    assert "matplotlib is not installed" in format_markdown(results)


def _fake_results() -> PaperResults:
    config = PaperConfig(ranks=(10,), ratios=(0.1,), rank_seeds=(1, 2))
    setup = Setup("mocapfill bench paper", "today", "box", "cpu", 2, "3", "2", "1", "0.0", "x")
    results = PaperResults(config, setup)
    results.rpca = [RpcaCell(k, 10, 0.1, (1e-8,), (0.5,))
                    for k in ("TrNN ρ=1.5", "TrNN ρ=1.2", PSVT, IALM)]
    results.ranks = [RankCell("85_02", "mr", 0.2, (21, 23))]
    results.truncation = [CompletionCell("85_02", 810, "mr", 0.2, "trnn-paper", (2.0,), (1.0,), r)
                          for r in (5, 15)]
    results.completion = [CompletionCell("85_02", 810, "ml", 40, k, (e,), (1.0,))
                          for k, e in (("trnn-paper", 3.0), ("tsmc", 4.0), ("trnn", 1.0))]
    return results


def test_markdown_marks_the_best_method_and_counts_wins():
    markdown = format_markdown(_fake_results())
    row = next(line for line in markdown.splitlines() if line.startswith("| 85_02 (810) | ml"))
    assert "| **1.00** |" in row and "**3.00**" not in row
    assert "trnn-paper below tsmc in 1/1 rows" in markdown
    assert "| 85_02 | 21–23 | 21–23 |" in markdown
    assert "Cells recovered (mean NRE < 1e-05): TrNN ρ=1.5 1/1" in markdown


def test_blas_threads_restores_the_previous_count():
    from threadpoolctl import threadpool_info, threadpool_limits

    def counts():
        return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]

    if not counts():
        pytest.skip("no BLAS library found by threadpoolctl")
    with threadpool_limits(3, user_api="blas"):
        before = counts()
        with blas_threads(1) as description:
            assert set(counts()) == {1} and description.startswith("1 (set in ")
        assert counts() == before
