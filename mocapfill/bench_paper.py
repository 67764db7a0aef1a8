"""The paper's experiments (``mocapfill bench paper``): Hu et al. 2018, Section III.

Each figure of the paper becomes a table (and, with matplotlib, one PNG):

- **Fig. 2–3** — synthetic robust PCA. D = X* + S* with X* = A·B (standard normal factors,
  rank r₀) and a fraction cr of entries of S* uniform in [−10, 10]; TrNN-RPCA (μ = 0,
  everything observed, d = r = r₀, λ = 1/√max(m, n), η₀ = 1.25/‖D‖₂, ε = 1e−7) with the
  paper's ρ = 1.5 and with ρ = 1.2 (``shared/docs/MODEL.md``: 1.5 stops early), against
  IALM (Lin, Chen & Ma 2010) and PSVT (Oh et al. 2016, N = r₀, ρ = 1.1 as in its authors'
  code). NRE = ‖X̃ − X*‖_F/‖X*‖_F
  and the solver's wall time over a grid of r₀ × cr.
- **Fig. 4** — the rank estimate r̃ (:func:`mocapfill.rank.estimate_rank`) of CMU clips
  gapped by random missing (ratio mr) and continuous missing (length ml).
- **Fig. 5** — RMSE of ``trnn-paper`` against the truncated rank r.
- **Fig. 6** — RMSE and time of ``trnn-paper`` against ``tsmc`` (Feng et al. 2014), with
  our default ``trnn`` as a third line, over mr and ml.

RMSE is the paper's: ‖(X − X̂)_{Ω^c}‖_F/√|Ω^c| over every coordinate the simulation
removed, in mm. The gapped matrix is completed with
:func:`mocapfill.pipeline.complete_matrix` directly (not ``repair``, which leaves end gaps
open), so every removed entry is scored. Seeds are fixed: the same configuration gives the
same gaps and matrices on every machine. Clips that need ``../shared/data`` are skipped
with a note when it is absent; the synthetic figures always run.

Timings depend on BLAS threading: the matrices here are small (m ≤ 1000, mocap m ≤ 123),
and on a machine shared with other work a multi-threaded OpenBLAS was 5–8× slower than one
thread. The experiments therefore run with one BLAS thread (``PaperConfig.blas_threads``,
set through OpenBLAS's own ``*_set_num_threads`` for the duration of the run and restored
after); the setup section records what was set and the load average at the start.
"""
from __future__ import annotations

import contextlib
import datetime
import math
import os
import platform
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._blas import VARIABLES
from .bench import SHARED_DATA

# Clips of ../shared/data/cmu by name. 10_01 (801 frames) is the paper's 'score' motion;
# the C3D clips are the nearest in length to its 'jump' (439) and 'boxing' (4840).
CMU_CLIPS = {"85_02": "cmu/85_02.c3d", "10_01": "cmu/10_01.amc",
             "02_05": "cmu/02_05.c3d", "85_12": "cmu/85_12.c3d"}
ASF_UNIT_MM = 25.4 / 0.45          # the paper's RMSE is in these units (CMU ASF/AMC)

TRNN_RPCA = "TrNN ρ={rho:g}"
PSVT, IALM = "PSVT", "IALM"
RECOVERED_NRE = 1e-5

# The paper's Sec. III-B timings (s) of TrNN and TSMC, by clip length in frames.
PAPER_SECONDS = {439: (2.8976, 3.7151), 801: (6.3003, 16.1250), 4840: (63.2687, 690.2639)}


@dataclass(frozen=True)
class PaperConfig:
    """What to run. :meth:`full` is the reproduction, :meth:`quick` a ~1-minute smoke run.

    Protocol grids are (mr values, ml values); seeds are the gap-simulation seeds.
    ``max_frames`` crops every clip (tests).
    """

    m: int = 1000
    n: int = 200
    ranks: tuple[int, ...] = (10, 20, 40, 60, 80)
    ratios: tuple[float, ...] = (0.05, 0.1, 0.2, 0.3)
    repeats: int = 3
    rhos: tuple[float, ...] = (1.5, 1.2)
    rank_clips: tuple[str, ...] = ("85_02", "10_01", "02_05", "85_12")
    rank_mr: tuple[float, ...] = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6)
    rank_ml: tuple[int, ...] = (10, 20, 30, 40, 50, 60)
    rank_seeds: tuple[int, ...] = (1, 2, 3)
    truncation_clips: tuple[str, ...] = ("85_02", "10_01")
    truncation_ranks: tuple[int, ...] = (1, 5, 10, 15, 20, 30)
    truncation_mr: tuple[float, ...] = (0.2, 0.3, 0.4, 0.5, 0.6)
    truncation_ml: tuple[int, ...] = (20, 30, 40, 50, 60)
    truncation_seeds: tuple[int, ...] = (1,)
    completion_clips: tuple[str, ...] = ("85_02", "10_01", "02_05", "85_12")
    completion_mr: tuple[float, ...] = (0.2, 0.4, 0.6)
    completion_ml: tuple[int, ...] = (20, 40, 60)
    completion_seeds: tuple[int, ...] = (1, 2)
    completion_methods: tuple[str, ...] = ("trnn-paper", "tsmc", "trnn")
    max_frames: int | None = None
    seed: int = 2018
    blas_threads: int | None = 1

    @classmethod
    def full(cls) -> PaperConfig:
        return cls()

    @classmethod
    def quick(cls) -> PaperConfig:
        return cls(m=400, n=200, ranks=(10, 40), ratios=(0.05, 0.2), repeats=1,
                   rank_clips=("85_02", "10_01"), rank_mr=(0.2, 0.4, 0.6),
                   rank_ml=(20, 40, 60), rank_seeds=(1,),
                   truncation_clips=("85_02",), truncation_ranks=(1, 5, 15, 30),
                   truncation_mr=(0.2, 0.6), truncation_ml=(20, 60),
                   completion_clips=("85_02",), completion_mr=(0.2, 0.6),
                   completion_ml=(20, 60), completion_seeds=(1,))


# ------------------------------------------------------------------ results


@dataclass(frozen=True)
class RpcaCell:
    """Fig. 2–3: one method at one (r₀, cr), over the repeats."""

    method: str
    r0: int
    cr: float
    nre: tuple[float, ...]
    seconds: tuple[float, ...]


@dataclass(frozen=True)
class RankCell:
    """Fig. 4: r̃ of one gapped clip, one value per seed."""

    clip: str
    protocol: str          # "mr" or "ml"
    value: float
    ranks: tuple[int, ...]


@dataclass(frozen=True)
class CompletionCell:
    """Fig. 5 (``rank`` set) and Fig. 6: one method on one gapped clip, per seed."""

    clip: str
    frames: int
    protocol: str
    value: float
    method: str
    rmse_mm: tuple[float, ...]
    seconds: tuple[float, ...]
    rank: int | None = None


@dataclass(frozen=True)
class Setup:
    """Where and how the experiments ran."""

    command: str
    date: str
    machine: str
    cpu: str
    cores: int | None
    python: str
    numpy: str
    blas_threads: str
    load_average: str
    revision: str


@dataclass
class PaperResults:
    """Everything :func:`format_markdown` needs; notes and seconds are keyed by figure."""

    config: PaperConfig
    setup: Setup
    rpca: list[RpcaCell] = field(default_factory=list)
    ranks: list[RankCell] = field(default_factory=list)
    truncation: list[CompletionCell] = field(default_factory=list)
    completion: list[CompletionCell] = field(default_factory=list)
    notes: dict[str, list[str]] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    plots: list[Path] = field(default_factory=list)

    def note(self, figure: str, text: str) -> None:
        self.notes.setdefault(figure, []).append(text)


def _mean(values) -> float:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


# ------------------------------------------------------------------ Fig. 2-3


def synthetic_rpca(m: int, n: int, r0: int, cr: float,
                   rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """D = X* + S* of Sec. III-A and X*: rank-r₀ Gaussian product, sparse U[−10, 10]."""
    low_rank = rng.standard_normal((m, r0)) @ rng.standard_normal((r0, n))
    sparse = np.zeros(m * n)
    support = rng.choice(m * n, size=int(round(cr * m * n)), replace=False)
    sparse[support] = rng.uniform(-10.0, 10.0, support.size)
    return low_rank + sparse.reshape(m, n), low_rank


def rpca_methods(rhos: tuple[float, ...]) -> list[str]:
    return [TRNN_RPCA.format(rho=rho) for rho in rhos] + [PSVT, IALM]


def solve_rpca(method: str, D: np.ndarray, r0: int, rhos: tuple[float, ...]) -> np.ndarray:
    """The low-rank part of D by one of :func:`rpca_methods`, with the paper's settings."""
    from .solvers.rpca import ialm, psvt
    from .solvers.trnn import trnn

    everything = np.ones(D.shape, bool)
    if method == IALM:
        return ialm(D, everything)
    if method == PSVT:
        return psvt(D, everything, rank=r0)
    rho = next(r for r in rhos if TRNN_RPCA.format(rho=r) == method)
    m, n = D.shape
    # ‖D‖₂ is part of the method (η₀), as it is inside IALM and PSVT: timed with it.
    return trnn(D, everything, rank=r0, d=r0, lam=1.0 / np.sqrt(max(m, n)), mu=0.0, rho=rho,
                eta0=1.25 / np.linalg.norm(D, 2), tol=1e-7, max_iter=1000).X


def run_rpca_grid(config: PaperConfig) -> list[RpcaCell]:
    """Fig. 2–3: NRE and time of every method over r₀ × cr, ``config.repeats`` times."""
    methods = rpca_methods(config.rhos)
    cells = []
    for r0 in config.ranks:
        for cr in config.ratios:
            nre: dict[str, list[float]] = {k: [] for k in methods}
            seconds: dict[str, list[float]] = {k: [] for k in methods}
            for repeat in range(config.repeats):
                rng = np.random.default_rng((config.seed, r0, int(round(cr * 1000)), repeat))
                D, truth = synthetic_rpca(config.m, config.n, r0, cr, rng)
                for method in methods:
                    started = time.perf_counter()
                    estimate = solve_rpca(method, D, r0, config.rhos)
                    seconds[method].append(time.perf_counter() - started)
                    nre[method].append(float(np.linalg.norm(estimate - truth)
                                             / np.linalg.norm(truth)))
            cells += [RpcaCell(k, r0, cr, tuple(nre[k]), tuple(seconds[k])) for k in methods]
    return cells


# ------------------------------------------------------------------ clips


def load_clip(name: str, data_dir: Path, max_frames: int | None = None):
    """The named CMU clip in mm (cropped to ``max_frames``), or None when absent."""
    from . import formats

    path = data_dir / CMU_CLIPS[name]
    if not path.exists():
        return None
    motion = formats.read(path, units="mm") if path.suffix == ".amc" else formats.read(path)
    if motion.units != "mm":
        raise ValueError(f"{path}: expected positions in mm, got {motion.units!r}")
    if max_frames is not None and motion.n_frames > max_frames:
        motion = motion.with_positions(motion.positions[:max_frames],
                                       motion.observed[:max_frames])
    return motion


def _protocols(mr: tuple, ml: tuple) -> list[tuple[str, float]]:
    return [("mr", v) for v in mr] + [("ml", v) for v in ml]


def gapped_matrices(motion, protocol: str, value: float, seed: int):
    """(truth, gapped matrix, its mask, scored mask) for one simulated gap pattern."""
    from .gaps import simulate_gaps

    truth, present = motion.matrix()
    gapped = simulate_gaps(motion, **{protocol: value}, seed=seed)
    matrix, observed = gapped.matrix()
    return truth, matrix, observed, present & ~observed


def score_method(motion, protocol: str, value: float, seed: int, method: str,
                 **options) -> tuple[float, float]:
    """(RMSE in mm over every removed coordinate, solve seconds) of one method."""
    from .pipeline import complete_matrix

    truth, matrix, observed, scored = gapped_matrices(motion, protocol, value, seed)
    started = time.perf_counter()
    completed = complete_matrix(matrix, observed, method, **options)
    seconds = time.perf_counter() - started
    return float(np.sqrt(np.mean((completed - truth)[scored] ** 2))), seconds


def _clips(names: tuple[str, ...], data_dir: Path, config: PaperConfig,
           results: PaperResults, figure: str):
    for name in names:
        motion = load_clip(name, data_dir, config.max_frames)
        if motion is None:
            results.note(figure, f"{name} skipped: {data_dir / CMU_CLIPS[name]} absent")
            continue
        yield name, motion


def run_ranks(config: PaperConfig, data_dir: Path, results: PaperResults) -> None:
    """Fig. 4: r̃ over mr and ml."""
    from .rank import estimate_rank

    for name, motion in _clips(config.rank_clips, data_dir, config, results, "fig4"):
        for protocol, value in _protocols(config.rank_mr, config.rank_ml):
            ranks = []
            for seed in config.rank_seeds:
                _, matrix, observed, _ = gapped_matrices(motion, protocol, value, seed)
                ranks.append(estimate_rank(matrix, observed).rank)
            results.ranks.append(RankCell(name, protocol, value, tuple(ranks)))


def _completion_cell(name, motion, protocol, value, seeds, method, results, figure,
                     **options) -> CompletionCell:
    rmse, seconds = [], []
    for seed in seeds:
        try:
            error, spent = score_method(motion, protocol, value, seed, method, **options)
        except Exception as exc:  # one failed cell must not lose a 30-minute run
            results.note(figure, f"{method} failed on {name} {protocol}={value:g} "
                                 f"seed {seed}: {type(exc).__name__}: {exc}")
            error, spent = math.nan, math.nan
        rmse.append(error)
        seconds.append(spent)
    return CompletionCell(name, motion.n_frames, protocol, value, method, tuple(rmse),
                          tuple(seconds), options.get("rank"))


def run_truncation(config: PaperConfig, data_dir: Path, results: PaperResults) -> None:
    """Fig. 5: trnn-paper's RMSE against the truncated rank r."""
    for name, motion in _clips(config.truncation_clips, data_dir, config, results, "fig5"):
        for protocol, value in _protocols(config.truncation_mr, config.truncation_ml):
            for rank in config.truncation_ranks:
                results.truncation.append(_completion_cell(
                    name, motion, protocol, value, config.truncation_seeds, "trnn-paper",
                    results, "fig5", rank=rank))


def run_completion(config: PaperConfig, data_dir: Path, results: PaperResults) -> None:
    """Fig. 6: trnn-paper, tsmc and trnn over mr and ml."""
    for name, motion in _clips(config.completion_clips, data_dir, config, results, "fig6"):
        for protocol, value in _protocols(config.completion_mr, config.completion_ml):
            for method in config.completion_methods:
                results.completion.append(_completion_cell(
                    name, motion, protocol, value, config.completion_seeds, method, results,
                    "fig6"))


# ------------------------------------------------------------------ driver


def _cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _revision() -> str:
    try:
        root = Path(__file__).resolve().parents[1]
        head = subprocess.run(["git", "-C", str(root), "describe", "--always", "--dirty"],
                              capture_output=True, text=True, timeout=10)
        return head.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


@contextlib.contextmanager
def blas_threads(count: int | None):
    """Run the block with ``count`` BLAS threads; yields a description of what was set.

    threadpoolctl sets the count in every BLAS library loaded (numpy's and scipy's
    OpenBLAS; scipy's is loaded first) and restores the previous counts afterwards. With
    ``count`` None (or no BLAS library found) nothing changes and the description says
    so.
    """
    import scipy.linalg  # noqa: F401  (its own OpenBLAS, to be set as well)
    from threadpoolctl import threadpool_info, threadpool_limits

    names = [info["internal_api"] for info in threadpool_info() if info["user_api"] == "blas"]
    if count is None or not names:
        env = ", ".join(f"{k}={os.environ[k]}" for k in VARIABLES if k in os.environ)
        yield env or "library default (all cores)"
        return
    with threadpool_limits(limits=int(count), user_api="blas"):
        kinds = ", ".join(sorted({"OpenBLAS" if n == "openblas" else n for n in names}))
        plural = "y" if len(names) == 1 else "ies"
        yield f"{count} (set in {len(names)} {kinds} librar{plural})"


def describe_setup(command: str, threads: str) -> Setup:
    try:
        load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    except OSError:
        load = "unknown"
    return Setup(command=command,
                 date=datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z"),
                 machine=platform.platform(), cpu=_cpu_name(), cores=os.cpu_count(),
                 python=platform.python_version(), numpy=np.__version__,
                 blas_threads=threads, load_average=load, revision=_revision())


def run_experiments(config: PaperConfig, plots_dir: Path | None = None, *,
                    data_dir: Path | None = None, command: str = "") -> PaperResults:
    """Run every figure of ``config``; write PNGs into ``plots_dir`` when given."""
    with blas_threads(config.blas_threads) as threads:
        return _run(config, plots_dir, data_dir, describe_setup(command, threads))


def _run(config: PaperConfig, plots_dir: Path | None, data_dir: Path | None,
         setup: Setup) -> PaperResults:
    data_dir = SHARED_DATA if data_dir is None else Path(data_dir)
    results = PaperResults(config, setup)
    if not data_dir.is_dir():
        for figure in ("fig4", "fig5", "fig6"):
            results.note(figure, f"skipped: {data_dir} absent (the CMU clips live there)")
    stages = (("fig2-3", lambda: results.rpca.extend(run_rpca_grid(config))),
              ("fig4", lambda: run_ranks(config, data_dir, results)),
              ("fig5", lambda: run_truncation(config, data_dir, results)),
              ("fig6", lambda: run_completion(config, data_dir, results)))
    for figure, stage in stages:
        if figure != "fig2-3" and not data_dir.is_dir():
            continue
        started = time.perf_counter()
        stage()
        results.seconds[figure] = time.perf_counter() - started
    if plots_dir is not None:
        results.plots = write_plots(results, Path(plots_dir))
    return results


def run_paper(quick: bool, plots_dir: Path | None, *,
              data_dir: Path | None = None) -> PaperResults:
    """Reproduce the paper's Figs. 2–6 (``mocapfill bench paper [--plots DIR] [--quick]``).

    Parameters
    ----------
    quick
        A small grid on m = 400 and one clip: about a minute instead of about half an hour.
    plots_dir
        Folder for one PNG per figure (needs matplotlib; skipped with a note without it).
    data_dir
        Where the CMU clips are; default ``../shared/data``.

    Returns
    -------
    PaperResults
        Render it with :func:`format_markdown`.
    """
    command = "mocapfill bench paper" + (" --quick" if quick else "") + \
        (f" --plots {plots_dir}" if plots_dir is not None else "")
    config = PaperConfig.quick() if quick else PaperConfig.full()
    return run_experiments(config, plots_dir, data_dir=data_dir, command=command)


# ------------------------------------------------------------------ markdown


def _sci(value: float) -> str:
    return "–" if not math.isfinite(value) else f"{value:.1e}"


def _fixed(value: float, digits: int = 2) -> str:
    return "–" if not math.isfinite(value) else f"{value:.{digits}f}"


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)] + \
        ["| " + " | ".join(row) + " |" for row in rows]


def _label(protocol: str, value: float) -> str:
    return f"{protocol} = {value:g}"


def _notes(results: PaperResults, figure: str) -> list[str]:
    return [f"> {text}" for text in results.notes.get(figure, [])]


def _rpca_section(results: PaperResults) -> list[str]:
    config = results.config
    methods = rpca_methods(config.rhos)
    by_key = {(c.method, c.r0, c.cr): c for c in results.rpca}
    lines = ["## Fig. 2–3: synthetic robust PCA", "",
             f"m = {config.m}, n = {config.n}, {config.repeats} repeat(s) per cell (the paper: "
             "m = 1000, n = 200, 30 repeats). TrNN-RPCA: μ = 0, d = r = r₀, λ = 1/√max(m, n), "
             "η₀ = 1.25/‖D‖₂, ε = 1e−7, with the paper's ρ = 1.5 and ρ = 1.2; IALM with its "
             "paper's ALM settings (ρ = 1.5, ε = 1e−7), PSVT with N = r₀ and its authors' "
             "code's ρ = 1.1 (ε = 1e−7). Mean over the repeats.", ""]
    if not results.rpca:
        return lines + ["(not run)", ""]
    cells = [(r0, cr) for r0 in config.ranks for cr in config.ratios]
    for title, attr, fmt in (("Fig. 2: NRE = ‖X̃ − X*‖_F / ‖X*‖_F", "nre", _sci),
                             ("Fig. 3: solver time (s)", "seconds", _fixed)):
        rows = [[str(r0), f"{cr:g}"] + [fmt(_mean(getattr(by_key[(k, r0, cr)], attr)))
                                        for k in methods] for r0, cr in cells]
        lines += [f"### {title}", ""] + _table(["r₀", "cr"] + methods, rows) + [""]
    recovered = ", ".join(
        f"{k} {sum(_mean(by_key[(k, r0, cr)].nre) < RECOVERED_NRE for r0, cr in cells)}"
        f"/{len(cells)}" for k in methods)
    times = ", ".join(f"{k} {_fixed(_mean([_mean(by_key[(k, *c)].seconds) for c in cells]))} s"
                      for k in methods)
    lines += [f"Cells recovered (mean NRE < {RECOVERED_NRE:g}): {recovered}.",
              f"Mean time per solve: {times}.", ""]
    return lines + _notes(results, "fig2-3")


def _ranks_section(results: PaperResults) -> list[str]:
    lines = ["## Fig. 4: rank estimate r̃ against mr and ml", "",
             "r̃ from `estimate_rank` (linear interpolation along time, rows centred, unit "
             "RMS, largest i with σ_i − σ_{i+1} ≥ 1e−3·σ₁; the paper's raw θ = 0.1 is "
             "unit-dependent). Seeds: " + ", ".join(map(str, results.config.rank_seeds)) +
             "; a range is min–max over them. The paper's claim: r̃ stays stable as mr and ml "
             "grow.", ""]
    for protocol in ("mr", "ml"):
        cells = [c for c in results.ranks if c.protocol == protocol]
        if not cells:
            continue
        values = sorted({c.value for c in cells})
        clips = list(dict.fromkeys(c.clip for c in cells))
        by_key = {(c.clip, c.value): c.ranks for c in cells}
        rows = []
        for clip in clips:
            spread = [r for v in values for r in by_key[(clip, v)]]
            row = [clip] + [_range(by_key[(clip, v)]) for v in values]
            rows.append(row + [f"{min(spread)}–{max(spread)}"])
        lines += _table(["clip"] + [_label(protocol, v) for v in values] + ["all"], rows) + [""]
    if not results.ranks:
        lines += ["(no clip available)", ""]
    return lines + _notes(results, "fig4")


def _range(values: tuple[int, ...]) -> str:
    low, high = min(values), max(values)
    return str(low) if low == high else f"{low}–{high}"


def _truncation_section(results: PaperResults) -> list[str]:
    config = results.config
    lines = ["## Fig. 5: RMSE (mm) of trnn-paper against the truncated rank r", "",
             "`complete_matrix(..., \"trnn-paper\", rank=r)`: the paper's settings "
             "(λ = 100/√max(m, n), μ = 100, ρ = 1.4, η₀ = 1e−5, ε = 1e−4) on the centred, "
             "unit-RMS clip. Gap seeds: " + ", ".join(map(str, config.truncation_seeds)) +
             ". Best r per column in bold. The paper: RMSE is lowest near r = 15 everywhere "
             f"(its RMSE ≤ 0.03 ASF units = {0.03 * ASF_UNIT_MM:.1f} mm for mr < 0.4).", ""]
    for clip in dict.fromkeys(c.clip for c in results.truncation):
        cells = [c for c in results.truncation if c.clip == clip]
        settings = list(dict.fromkeys((c.protocol, c.value) for c in cells))
        ranks = sorted({c.rank for c in cells})
        by_key = {(c.protocol, c.value, c.rank): _mean(c.rmse_mm) for c in cells}
        best = {s: min(ranks, key=lambda r, s=s: _finite_or_inf(by_key[(*s, r)]))
                for s in settings}
        rows = [[str(r)] + [_bold(_fixed(by_key[(*s, r)]), best[s] == r) for s in settings]
                for r in ranks]
        lines += [f"### {clip} ({cells[0].frames} frames)", ""]
        lines += _table(["r"] + [_label(*s) for s in settings], rows) + [""]
        lines += ["Best r: " + ", ".join(f"{_label(*s)} → {best[s]}" for s in settings) + ".",
                  ""]
    if not results.truncation:
        lines += ["(no clip available)", ""]
    return lines + _notes(results, "fig5")


def _finite_or_inf(value: float) -> float:
    return value if math.isfinite(value) else math.inf


def _bold(text: str, on: bool) -> str:
    return f"**{text}**" if on else text


def _schedule(method: str) -> str:
    """ρ, η₀ and ε a method runs with by default, read from its signature."""
    import inspect

    from .solvers import get_method

    try:
        defaults = inspect.signature(get_method(method)).parameters
    except (ValueError, TypeError, ImportError):
        return "?"
    shown = [f"{symbol} = {defaults[name].default:g}"
             for name, symbol in (("rho", "ρ"), ("eta0", "η₀"), ("tol", "ε"))
             if name in defaults and isinstance(defaults[name].default, (int, float))]
    return "(" + ", ".join(shown) + ")" if shown else "(own schedule)"


def _completion_section(results: PaperResults) -> list[str]:
    config = results.config
    methods = list(config.completion_methods)
    lines = ["## Fig. 6: trnn-paper against TSMC (and our default trnn)", "",
             "RMSE (mm) over every removed coordinate, mean over gap seeds "
             + ", ".join(map(str, config.completion_seeds)) + "; time (s) of "
             "`complete_matrix` per solve. Best RMSE per row in bold. Penalty schedules: "
             + "; ".join(f"{k} {_schedule(k)}" for k in methods)
             + " (the paper's ρ = 1.4, ε = 1e−4 stops before convergence, MODEL.md). The "
             "paper: TrNN beats TSMC, more so as mr and ml grow.", ""]
    cells = results.completion
    if not cells:
        return lines + ["(no clip available)", ""] + _notes(results, "fig6")
    by_key = {(c.clip, c.protocol, c.value, c.method): c for c in cells}
    settings = list(dict.fromkeys((c.clip, c.frames, c.protocol, c.value) for c in cells))
    rows = []
    wins = {k: 0 for k in methods}
    paper_beats_tsmc = 0
    for clip, frames, protocol, value in settings:
        rmse = {k: _mean(by_key[(clip, protocol, value, k)].rmse_mm) for k in methods}
        best = min(methods, key=lambda k: _finite_or_inf(rmse[k]))
        wins[best] += 1
        paper_beats_tsmc += rmse.get("trnn-paper", math.inf) < rmse.get("tsmc", -math.inf)
        seconds = [_fixed(_mean(by_key[(clip, protocol, value, k)].seconds)) for k in methods]
        rows.append([f"{clip} ({frames})", _label(protocol, value)]
                    + [_bold(_fixed(rmse[k]), k == best) for k in methods] + seconds)
    header = ["clip (frames)", "gaps"] + [f"{k} RMSE" for k in methods] + \
        [f"{k} s" for k in methods]
    lines += _table(header, rows) + [""]
    lines += ["Lowest RMSE: " + ", ".join(f"{k} {wins[k]}/{len(settings)}" for k in methods)
              + (f"; trnn-paper below tsmc in {paper_beats_tsmc}/{len(settings)} rows."
                 if {"trnn-paper", "tsmc"} <= set(methods) else "."), ""]
    lines += ["### Time per clip (s, mean over every gap setting) against the paper's", ""]
    time_rows = []
    for clip, frames in dict.fromkeys((c.clip, c.frames) for c in cells):
        mean_s = [_fixed(_mean([s for c in cells if c.clip == clip and c.method == k
                                for s in c.seconds])) for k in methods]
        paper_frames = min(PAPER_SECONDS, key=lambda f: abs(f - frames))
        paper = "–"
        if abs(paper_frames - frames) <= 0.25 * paper_frames:  # a clip of similar length
            trnn_s, tsmc_s = PAPER_SECONDS[paper_frames]
            paper = f"{trnn_s:.2f} / {tsmc_s:.2f} ({paper_frames} frames)"
        time_rows.append([f"{clip} ({frames})"] + mean_s + [paper])
    lines += _table(["clip (frames)"] + [f"{k} s" for k in methods]
                    + ["paper TrNN / TSMC s (clip)"], time_rows) + [""]
    return lines + _notes(results, "fig6")


def format_markdown(results: PaperResults) -> str:
    """The report: setup, then one section with its table(s) per figure."""
    setup = results.setup
    config = results.config
    lines = ["# The paper's experiments (Hu et al. 2018, Section III), reproduced", "",
             f"- Command: `{setup.command or 'run_experiments(...)'}`",
             f"- Date: {setup.date}; revision: {setup.revision}",
             f"- Machine: {setup.machine}; CPU: {setup.cpu}; {setup.cores} logical cores; "
             f"BLAS threads: {setup.blas_threads}; load average at start (1, 5, 15 min): "
             f"{setup.load_average}",
             f"- Python {setup.python}, numpy {setup.numpy}",
             "- Wall time per figure: " + (", ".join(
                 f"{k} {v:.0f} s" for k, v in results.seconds.items()) or "–")
             + f"; total {sum(results.seconds.values()) / 60:.1f} min",
             "- Paper's machine: Intel Core i5 at 2.4 GHz, 4 GB (MATLAB); compare times as "
             "ratios only.", ""]
    if config.max_frames is not None:
        lines += [f"Clips cropped to their first {config.max_frames} frames.", ""]
    for section in (_rpca_section, _ranks_section, _truncation_section, _completion_section):
        lines += section(results) + [""]
    if results.plots:
        lines += ["## Plots", ""] + [f"- `{p.name}`" for p in results.plots] + [""]
    lines += _notes(results, "plots")
    return "\n".join(lines).rstrip() + "\n"


# ------------------------------------------------------------------ plots

PLOT_DPI = 90


def write_plots(results: PaperResults, plots_dir: Path) -> list[Path]:
    """One PNG per figure into ``plots_dir``; none (and a note) without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        results.note("plots", "matplotlib is not installed (pip install matplotlib, or "
                              "'.[plot]' in mocapfill's checkout): tables only, no plots")
        return []
    from .formats import atomic_output

    plots_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, draw, present in (
            ("fig2_nre.png", lambda: _plot_rpca(plt, results, "nre"), results.rpca),
            ("fig3_time.png", lambda: _plot_rpca(plt, results, "seconds"), results.rpca),
            ("fig4_rank.png", lambda: _plot_ranks(plt, results), results.ranks),
            ("fig5_truncated_rank.png", lambda: _plot_truncation(plt, results),
             results.truncation),
            ("fig6_trnn_vs_tsmc.png", lambda: _plot_completion(plt, results),
             results.completion)):
        if not present:
            continue
        figure = draw()
        path = plots_dir / name
        try:
            with atomic_output(path) as tmp:    # never half a chart (a full disk, Ctrl-C)
                figure.savefig(tmp, dpi=PLOT_DPI, format="png")
        finally:
            plt.close(figure)
        written.append(path)
    return written


def _plot_rpca(plt, results: PaperResults, attr: str):
    config = results.config
    methods = rpca_methods(config.rhos)
    by_key = {(c.method, c.r0, c.cr): c for c in results.rpca}
    grids = {k: np.array([[_mean(getattr(by_key[(k, r0, cr)], attr)) for cr in config.ratios]
                          for r0 in config.ranks]) for k in methods}
    if attr == "nre":
        grids = {k: np.log10(np.maximum(g, 1e-12)) for k, g in grids.items()}
        title, low, high = "log₁₀ NRE", -8.0, 0.0
    else:
        title, low, high = "time (s)", 0.0, max(float(np.nanmax(g)) for g in grids.values())
    figure, axes = plt.subplots(1, len(methods), figsize=(2.6 * len(methods) + 1, 3.2),
                                squeeze=False, constrained_layout=True)
    for ax, k in zip(axes[0], methods):
        image = ax.imshow(grids[k], origin="lower", aspect="auto", vmin=low, vmax=high,
                          cmap="viridis")
        ax.set_xticks(range(len(config.ratios)), [f"{cr:g}" for cr in config.ratios])
        ax.set_yticks(range(len(config.ranks)), [str(r) for r in config.ranks])
        ax.set_xlabel("cr")
        ax.set_title(k)
        for i in range(len(config.ranks)):
            for j in range(len(config.ratios)):
                value = grids[k][i, j]
                ax.text(j, i, f"{value:.0f}" if attr == "nre" else f"{value:.1f}",
                        ha="center", va="center", fontsize=7,
                        color="white" if value < (low + high) / 2 else "black")
    axes[0][0].set_ylabel("r₀")
    figure.colorbar(image, ax=axes[0].tolist(), label=title)
    figure.suptitle(f"Fig. {2 if attr == 'nre' else 3}: {title}, m = {config.m}, "
                    f"n = {config.n}")
    return figure


def _protocol_axes(plt, rows: int):
    figure, axes = plt.subplots(rows, 2, figsize=(9, 3.2 * rows), squeeze=False,
                                constrained_layout=True)
    return figure, axes


def _plot_ranks(plt, results: PaperResults):
    figure, axes = _protocol_axes(plt, 1)
    for ax, protocol in zip(axes[0], ("mr", "ml")):
        for clip in dict.fromkeys(c.clip for c in results.ranks):
            cells = [c for c in results.ranks if c.clip == clip and c.protocol == protocol]
            if not cells:
                continue
            x = [c.value for c in cells]
            mean = np.array([np.mean(c.ranks) for c in cells])
            spread = np.array([[mean[i] - min(c.ranks), max(c.ranks) - mean[i]]
                               for i, c in enumerate(cells)]).T
            ax.errorbar(x, mean, yerr=spread, marker="o", capsize=3, label=clip)
        ax.set_xlabel(protocol)
        ax.set_ylabel("estimated rank r̃")
        ax.set_ylim(bottom=0)
        ax.legend(fontsize=8)
    figure.suptitle("Fig. 4: rank estimate against missing ratio and gap length")
    return figure


def _plot_truncation(plt, results: PaperResults):
    clips = list(dict.fromkeys(c.clip for c in results.truncation))
    figure, axes = _protocol_axes(plt, len(clips))
    for row, clip in zip(axes, clips):
        for ax, protocol in zip(row, ("mr", "ml")):
            cells = [c for c in results.truncation if c.clip == clip and c.protocol == protocol]
            for value in dict.fromkeys(c.value for c in cells):
                line = [c for c in cells if c.value == value]
                ax.plot([c.rank for c in line], [_mean(c.rmse_mm) for c in line], marker="o",
                        label=_label(protocol, value))
            if not cells:
                ax.set_axis_off()
                continue
            ax.set_xlabel("truncated rank r")
            ax.set_ylabel("RMSE (mm)")
            ax.set_yscale("log")
            ax.set_title(f"{clip}, {'random' if protocol == 'mr' else 'continuous'} missing")
            ax.legend(fontsize=7)
    figure.suptitle("Fig. 5: trnn-paper RMSE against the truncated rank")
    return figure


def _plot_completion(plt, results: PaperResults):
    clips = list(dict.fromkeys(c.clip for c in results.completion))
    methods = list(results.config.completion_methods)
    figure, axes = plt.subplots(2, len(clips), figsize=(3.4 * len(clips) + 0.6, 6.2),
                                squeeze=False, constrained_layout=True)
    for column, clip in enumerate(clips):
        for row, protocol in enumerate(("mr", "ml")):
            ax = axes[row][column]
            if not any(c.clip == clip and c.protocol == protocol for c in results.completion):
                ax.set_axis_off()
                continue
            for method in methods:
                line = [c for c in results.completion
                        if c.clip == clip and c.protocol == protocol and c.method == method]
                ax.plot([c.value for c in line], [_mean(c.rmse_mm) for c in line],
                        marker="o", label=method)
            ax.set_xlabel(protocol)
            ax.set_yscale("log")
            ax.set_title(clip, fontsize=9)
            if column == 0:
                ax.set_ylabel("RMSE (mm)")
    axes[0][0].legend(fontsize=7)
    figure.suptitle("Fig. 6: RMSE of trnn-paper, tsmc and trnn")
    return figure
