"""Trajectory plots in the visual language of Qualisys QTM: gaps shaded, filled segments
drawn distinctly (dashed, another colour) from measured ones.

matplotlib is an optional extra (``pip install '.[plot]'`` in the checkout, or ``pip install
matplotlib``).
"""
from __future__ import annotations

import html
import io
from pathlib import Path

import numpy as np

from .errors import FormatError, MocapfillError, ParameterError, named
from .formats import atomic_output, check_output_folder, write_text_atomically
from .gaps import missing_runs
from .motion import Motion, label_matches, matches_nothing

SUFFIXES = (".png", ".svg", ".html")
MAX_DEFAULT_MARKERS = 8
GAP_COLOUR = "#c8a27a"      # QTM's brown gap area
FILL_COLOUR = "#1f3a93"     # dark blue, dashed: computed samples
MEASURED_COLOUR = "#333333"


def _pick_markers(motion: Motion, patterns: tuple[str, ...]) -> list[int]:
    if patterns:
        chosen = [j for j, label in enumerate(motion.labels)
                  if label_matches(label, patterns)]
        if not chosen:
            raise ParameterError(matches_nothing(motion, "--markers", patterns))
        return chosen
    gapped = np.flatnonzero((~motion.observed).any(axis=0) & motion.fillable)
    if gapped.size == 0:
        gapped = np.arange(min(motion.n_markers, 3))
    # The markers with the most missing data are the ones worth looking at.
    order = np.argsort(-(~motion.observed[:, gapped]).sum(axis=0), kind="stable")
    return sorted(gapped[order][:MAX_DEFAULT_MARKERS].tolist())


def time_axis(motion: Motion) -> tuple[np.ndarray, str]:
    """Each frame's place on the x axis, and the axis label: seconds from frame 1 at the
    clip's rate, or the frame numbers where the clip has no rate (0 Hz: a C3D without
    ``POINT:RATE``, an AMC, a TRC or CSV stating none), which no time can be given to."""
    if motion.rate > 0:
        return (motion.first_frame - 1 + np.arange(motion.n_frames)) / motion.rate, "time (s)"
    return motion.first_frame + np.arange(motion.n_frames), "frame (no frame rate known)"


def plot(original: Motion, repaired: Motion | None, path: Path,
         markers: tuple[str, ...] = ()) -> list[str]:
    """Draw x/y/z over time for some markers and save to PNG, SVG or HTML (by suffix);
    over frame numbers for a clip without a frame rate (:func:`time_axis`).

    Parameters
    ----------
    original
        The clip as recorded; its missing samples are shaded.
    repaired
        The repaired clip (same frames and markers), or None to plot the gaps only.
        Samples missing in ``original`` but present here are drawn dashed.
    path
        Output file: .png, .svg or .html (an HTML page embedding the SVG).
    markers
        Names or globs; default: up to 8 markers with the most missing data.

    Returns
    -------
    list of str
        The labels plotted.
    """
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise FormatError(path, f"plot output must be one of {', '.join(SUFFIXES)}", exit_code=2)
    check_output_folder(path)
    if original.n_markers == 0 or original.n_frames == 0:
        raise MocapfillError(f"{named(original.path)}nothing to draw: the clip has "
                             f"{original.n_markers} markers and {original.n_frames} frames")
    if repaired is not None and repaired.positions.shape != original.positions.shape:
        # As score and info do: a file that does not match (exit 123), named.
        raise FormatError(repaired.path, "does not match the original in frames × markers")
    chosen = _pick_markers(original, markers)
    try:
        import matplotlib
    except ImportError:
        raise ParameterError("plotting needs matplotlib: pip install matplotlib (or '.[plot]' in "
                             "mocapfill's checkout)") from None
    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    time, time_label = time_axis(original)
    fig, axes = plt.subplots(len(chosen), 3, figsize=(13, 2.1 * len(chosen) + 0.8),
                             sharex=True, squeeze=False)
    for row, j in enumerate(chosen):
        runs = missing_runs(original.observed[:, j])
        for col, axis_name in enumerate("xyz"):
            ax = axes[row, col]
            for start, stop in runs:
                ax.axvspan(time[start], time[min(stop, len(time) - 1)], color=GAP_COLOUR,
                           alpha=0.35, lw=0)
            measured = np.where(original.observed[:, j], original.positions[:, j, col], np.nan)
            ax.plot(time, measured, color=MEASURED_COLOUR, lw=1.0)
            if repaired is not None:
                filled = repaired.observed[:, j] & ~original.observed[:, j]
                # Include the neighbouring measured samples so the fill joins visibly.
                show = filled | np.roll(filled, 1) | np.roll(filled, -1)
                values = np.where(show & repaired.observed[:, j],
                                  repaired.positions[:, j, col], np.nan)
                ax.plot(time, values, color=FILL_COLOUR, lw=1.4, ls="--")
            ax.set_ylabel(f"{original.labels[j]} {axis_name} ({original.units})", fontsize=8)
            ax.tick_params(labelsize=7)
    for ax in axes[-1]:
        ax.set_xlabel(time_label, fontsize=8)
    title = str(original.path.name if original.path else "clip")
    fig.suptitle(f"{title}: measured (solid), gaps (shaded)"
                 + (", filled (dashed)" if repaired is not None else ""), fontsize=10)
    fig.tight_layout()
    try:
        if suffix == ".html":
            buffer = io.StringIO()
            fig.savefig(buffer, format="svg")
            page = (f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'><title>"
                    f"{html.escape(title)}</title></head><body>\n{buffer.getvalue()}\n"
                    f"</body></html>\n")
            write_text_atomically(path, page)
        else:
            with atomic_output(path) as tmp:
                fig.savefig(tmp, dpi=110, format=suffix.lstrip("."))
    finally:
        plt.close(fig)
    return [original.labels[j] for j in chosen]
