"""The accuracy benchmark: every completion method on the shared real data, fixed seeds.

Cases
-----
- **walkl**: the Gløersen & Federolf (2016) treadmill-walking test set. ``WalkL.mat`` is
  the gap-free truth; ``WalkL_0001..0010.mat`` carry real occlusion patterns (NaN). The
  score is the 3-D RMS marker error (mm) over the interior gap samples, as in their paper.
- **cmu**: the paper's protocols (Hu et al. 2018, Sec. III-B) on the CMU clips 85_02, 02_05,
  85_12 (C3D, mm) and the joint positions of 10_01.amc when an ASF/AMC reader is there:
  random missing ``mr`` ∈ {0.2, 0.4, 0.6} and continuous missing ``ml`` ∈ {20, 40, 60}
  frames of 10 markers, seeds 0, 1, 2. The score is the paper's RMSE over missing
  coordinates (mm), averaged over the seeds.

Gaps touching the clip ends are left unfilled by the repair pipeline and are not scored.
Every method is scored on every interior missing sample: the benchmark repairs with the
pipeline's jump check off (:func:`repair_options`). With the check on, a method whose fills
start with a jump has those gaps put back as missing and is scored on the rest only; on
85_02 at ml = 40, ``psvt`` kept 400 of the 1,200 samples of the three seeds, and its
13.69 mm over those beat every method filling all 1,200. The pipeline's check protects
users' files; in a comparison it would let a method choose the gaps it is judged on.
Real files are read from ``../shared/data`` (next to the repository); when they are absent
every case becomes one row with a note instead of failing.

The core never prints: :func:`run_accuracy` returns rows, :func:`format_table` renders them.
"""
from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .gaps import find_gaps, simulate_gaps
from .metrics import score
from .motion import Motion
from .pipeline import RepairOptions, repair
from .solvers import METHODS

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

WALKL_FILES = [f"WalkL_{i:04d}" for i in range(1, 11)]
CMU_CLIPS = ["85_02", "02_05", "85_12", "10_01"]
CMU_PROTOCOLS = [("mr", 0.2), ("mr", 0.4), ("mr", 0.6), ("ml", 20), ("ml", 40), ("ml", 60)]
SEEDS = [0, 1, 2]
# Rate of the walkl recordings is not stored in the .mat files; no default method uses it.
WALKL_RATE_HZ = 100.0

QUICK_WALKL = ["WalkL_0001"]
QUICK_CMU = [("85_02", ("mr", 0.4)), ("85_02", ("ml", 40))]
QUICK_SEEDS = [0]


@dataclass(frozen=True)
class Case:
    """One gapped clip with its truth; ``load`` builds (truth, gapped) lazily."""

    dataset: str
    name: str            # e.g. "WalkL_0003" or "85_02 ml=40"
    seed: int | None
    load: Callable[[], tuple[Motion, Motion]]


def _walkl_motion(path: Path) -> Motion:
    from scipy.io import loadmat

    from .errors import FormatError

    if not path.is_file():      # loadmat's "Reader needs file name or open file-like object"
        raise FormatError(path, "no such file")
    data = np.asarray(loadmat(path)["data"], dtype=np.float64)       # frames × (3·markers)
    positions = data.reshape(data.shape[0], -1, 3)
    labels = tuple(f"M{j + 1:02d}" for j in range(positions.shape[1]))
    return Motion(positions, np.isfinite(positions).all(axis=2), labels, WALKL_RATE_HZ, "mm")


def _cmu_motion(clip: str) -> Motion:
    from .formats import read

    folder = SHARED_DATA / "cmu"
    if clip == "10_01":
        # Joint positions of the ASF/AMC clip, converted to mm under the CMU convention.
        return read(folder / f"{clip}.amc", units="mm")
    return read(folder / f"{clip}.c3d")


def _walkl_case(name: str) -> Case:
    def load() -> tuple[Motion, Motion]:
        folder = SHARED_DATA / "walkl"
        return _walkl_motion(folder / "WalkL.mat"), _walkl_motion(folder / f"{name}.mat")
    return Case("walkl", name, None, load)


def _cmu_case(clip: str, protocol: tuple[str, float], seed: int) -> Case:
    kind, value = protocol

    def load() -> tuple[Motion, Motion]:
        truth = _cmu_motion(clip)
        gapped = simulate_gaps(truth, seed=seed, **{kind: value})
        return truth, gapped
    return Case("cmu", f"{clip} {kind}={value:g}", seed, load)


def cases(quick: bool = False) -> list[Case]:
    """The benchmark cases in table order; ``quick`` keeps a small subset (< ~1 min)."""
    if quick:
        return ([_walkl_case(n) for n in QUICK_WALKL]
                + [_cmu_case(c, p, s) for c, p in QUICK_CMU for s in QUICK_SEEDS])
    return ([_walkl_case(n) for n in WALKL_FILES]
            + [_cmu_case(c, p, s) for c in CMU_CLIPS for p in CMU_PROTOCOLS for s in SEEDS])


def _row(case: Case, method: str, **fields) -> dict:
    row = {"dataset": case.dataset, "case": case.name, "seed": case.seed, "method": method,
           "rmse_mm": None, "rmse_3d_mm": None, "seconds": None, "samples": None,
           "unfilled": None, "note": ""}
    row.update(fields)
    return row


def repair_options(method: str, solver_options: dict | None = None) -> RepairOptions:
    """How the benchmark repairs: ``method``'s own fill of every interior gap, scored whole.

    The jump check is off (``max_jump_mm=0``), so no method is scored on a subset of the
    gaps of its own choosing (see the module notes); the scripts of ``scripts/`` use it too.
    """
    return RepairOptions(method=method, solver_options=dict(solver_options or {}),
                         max_jump_mm=0.0)


def _interior_missing(motion: Motion) -> np.ndarray:
    """(frames, markers) True on the samples of gaps with an observed sample on both sides."""
    inside = np.zeros(motion.observed.shape, dtype=bool)
    for gap in find_gaps(motion):
        if not (gap.at_start or gap.at_end):
            inside[gap.start:gap.stop, gap.marker] = True
    return inside


def run_case(case: Case, methods: list[str]) -> list[dict]:
    """Score every method on one case; failures and missing data become row notes."""
    try:
        truth, gapped = case.load()
    except Exception as exc:  # absent data or a reader not written yet: note, don't fail
        return [_row(case, m, note=f"skipped: {type(exc).__name__}: {exc}") for m in methods]
    rows = []
    # Interior gap samples with a truth: a method that leaves one of them missing is scored
    # on fewer samples than the others (the same mask for every method).
    scorable = _interior_missing(gapped) & truth.observed
    for method in methods:
        started = time.perf_counter()
        try:
            result = repair(gapped, repair_options(method))
        except Exception as exc:
            rows.append(_row(case, method, note=f"failed: {type(exc).__name__}: {exc}"))
            continue
        seconds = time.perf_counter() - started
        s = score(truth, result.motion, gapped)
        unfilled = scorable & ~result.motion.observed
        rows.append(_row(case, method, rmse_mm=s.rmse_mm, rmse_3d_mm=s.rmse_3d_mm,
                         seconds=seconds, samples=s.missing_samples,
                         unfilled=int(unfilled.sum())))
    return rows


def run_accuracy(quick: bool = False, methods: list[str] | None = None,
                 json_path: str | Path | None = None,
                 plots_dir: str | Path | None = None) -> list[dict]:
    """Run the accuracy benchmark.

    Parameters
    ----------
    quick
        A small subset (WalkL_0001, 85_02 at mr = 0.4 and ml = 40, one seed).
    methods
        Method names (default: every registered method).
    json_path
        Write the rows as JSON there.
    plots_dir
        Write one bar chart per case group there (needs matplotlib, the ``plot`` extra).

    Returns
    -------
    list of dict
        One row per (case, seed, method): dataset, case, seed, method, rmse_mm (paper RMSE
        over coordinates), rmse_3d_mm (3-D RMS marker error), seconds, samples (scored),
        unfilled (interior missing samples the method left missing, not scored), note.
    """
    methods = list(METHODS) if methods is None else list(methods)
    rows: list[dict] = []
    for case in cases(quick):
        rows.extend(run_case(case, methods))
    if json_path is not None:
        from .formats import write_text_atomically

        write_text_atomically(json_path, json.dumps(rows, indent=1))
    if plots_dir is not None:
        plot_summary(summarise(rows), Path(plots_dir))
    return rows


def case_metric(dataset: str) -> str:
    """The error each dataset is judged by: 3-D RMS for walkl, the paper's RMSE for CMU."""
    return "rmse_3d_mm" if dataset == "walkl" else "rmse_mm"


def summarise(rows: list[dict]) -> list[dict]:
    """Mean error and time over seeds per (dataset, case, method)."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["dataset"], row["case"], row["method"]), []).append(row)
    out = []
    for (dataset, name, method), members in groups.items():
        metric = case_metric(dataset)
        errors = [r[metric] for r in members if r[metric] is not None]
        times = [r["seconds"] for r in members if r["seconds"] is not None]
        notes = sorted({r["note"] for r in members if r["note"]})
        unfilled = sum(r.get("unfilled") or 0 for r in members)
        out.append({"dataset": dataset, "case": name, "method": method, "metric": metric,
                    "error_mm": float(np.mean(errors)) if errors else None,
                    "seconds": float(np.mean(times)) if times else None,
                    "runs": len(errors), "unfilled": unfilled, "note": "; ".join(notes)})
    return out


def format_table(rows: list[dict]) -> str:
    """A markdown table: one line per case, one column per method, "error mm / time s".

    The best error of each line is in bold. walkl lines give the 3-D RMS marker error, CMU
    lines the paper's RMSE over coordinates (mean over seeds); a note under the table
    says so for each dataset in it. A method that left interior
    samples unfilled is scored on fewer samples than the others: its cell is marked † and
    a note under the table counts them.
    """
    summary = summarise(rows)
    methods = list(dict.fromkeys(r["method"] for r in summary))
    lines_keys = list(dict.fromkeys((r["dataset"], r["case"]) for r in summary))
    cell = {(r["dataset"], r["case"], r["method"]): r for r in summary}
    header = "| case | " + " | ".join(methods) + " |"
    out = [header, "|" + "---|" * (len(methods) + 1)]
    notes = []
    for key in lines_keys:
        errors = {m: cell[(*key, m)]["error_mm"] for m in methods if (*key, m) in cell}
        finite = [e for e in errors.values() if e is not None]
        best = min(finite) if finite else None
        cells = []
        for m in methods:
            entry = cell.get((*key, m))
            if entry is None or entry["error_mm"] is None:
                cells.append("—")
                if entry is not None and entry["note"]:
                    notes.append(f"{key[1]} / {m}: {entry['note']}")
                continue
            text = f"{entry['error_mm']:.2f}"
            if entry["error_mm"] == best:
                text = f"**{text}**"
            if entry.get("unfilled"):
                text += "†"
                notes.append(f"{key[1]} / {m}: {entry['unfilled']} interior samples left "
                             "unfilled, not scored")
            cells.append(f"{text} / {entry['seconds']:.2f}s")
        label = f"{key[0]} {key[1]}"
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    # A mean line per dataset over the cases where every method gave an error.
    for dataset in dict.fromkeys(k[0] for k in lines_keys):
        keys = [k for k in lines_keys if k[0] == dataset
                and all(cell.get((*k, m), {}).get("error_mm") is not None for m in methods)]
        if not keys:
            continue
        means = [f"{np.mean([cell[(*k, m)]['error_mm'] for k in keys]):.2f}" for m in methods]
        out.append(f"| **{dataset} mean** ({len(keys)} cases) | " + " | ".join(means) + " |")
    # What each line's figure is: the lines alone did not say that walkl's is the 3-D
    # error, √3 times the RMSE over coordinates the CMU lines give for the same fills.
    notes += [f"{dataset} lines: {METRIC_WORDS[case_metric(dataset)]}"
              for dataset in dict.fromkeys(k[0] for k in lines_keys)]
    if notes:
        out.append("")
        out.extend(f"- {n}" for n in dict.fromkeys(notes))
    return "\n".join(out)


METRIC_WORDS = {
    "rmse_3d_mm": "3-D RMS marker error (mm) over the interior gap samples, then seconds "
                  "per repair",
    "rmse_mm": "the paper's RMSE over the missing coordinates (mm; the 3-D error is √3 "
               "times it), mean over the seeds, then seconds per repair",
}


def plot_summary(summary: list[dict], folder: Path) -> list[Path]:
    """One bar chart (error per method) per dataset; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .formats import atomic_output

    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for dataset in dict.fromkeys(r["dataset"] for r in summary):
        subset = [r for r in summary if r["dataset"] == dataset and r["error_mm"] is not None]
        if not subset:
            continue
        case_names = list(dict.fromkeys(r["case"] for r in subset))
        methods = list(dict.fromkeys(r["method"] for r in subset))
        fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(case_names) * len(methods) / 4), 4))
        width = 0.8 / len(methods)
        for k, method in enumerate(methods):
            vals = [next((r["error_mm"] for r in subset
                          if r["case"] == c and r["method"] == method), np.nan)
                    for c in case_names]
            ax.bar(np.arange(len(case_names)) + k * width, vals, width, label=method)
        ax.set_xticks(np.arange(len(case_names)) + 0.4 - width / 2)
        ax.set_xticklabels(case_names, rotation=45, ha="right")
        ax.set_yscale("log")
        ax.set_ylabel(f"{subset[0]['metric']} (mm)")
        ax.legend(fontsize="small", ncol=2)
        fig.tight_layout()
        path = folder / f"accuracy-{dataset}.png"
        try:
            with atomic_output(path) as tmp:    # never half a chart (a full disk, Ctrl-C)
                fig.savefig(tmp, dpi=120, format="png")
        finally:
            plt.close(fig)
        written.append(path)
    return written
