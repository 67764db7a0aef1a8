"""Human and machine-readable reports: per-marker gap tables and per-gap repair records."""
from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path

from .errors import FormatError
from .gaps import summarise
from .motion import Motion


def reader_notes(motion: Motion) -> tuple[str, ...]:
    """What the reader noticed and worked around (a file ending inside its last row,
    ignored columns or sections): text formats keep these on their source handle."""
    return tuple(getattr(motion.source, "notes", None) or ())


def info_dict(motion: Motion, listed: Motion | None = None) -> dict:
    """The per-marker table of ``mocapfill info --json``.

    With ``listed`` (``--gaps-only``), only the markers with missing samples in that clip
    are in ``per_marker``: the clip itself, or the original of a repaired one.
    """
    rows = summarise(motion)
    if listed is not None:
        keep = (~listed.observed).any(axis=0)
        rows = [r for r, k in zip(rows, keep) if k]
        fillable = [f for f, k in zip(motion.fillable, keep) if k]
    else:
        fillable = list(motion.fillable)
    return {
        "file": None if motion.path is None else str(motion.path),
        "frames": motion.n_frames, "markers": motion.n_markers, "rate_hz": motion.rate,
        "units": motion.units,
        "notes": list(reader_notes(motion)),
        "missing_samples": int((~motion.observed).sum()),
        "per_marker": [{"marker": r.label, "missing": r.missing, "frames": r.frames,
                        "percent": round(r.percent, 3), "gaps": r.gaps,
                        "longest_gap_frames": r.longest,
                        # null, not NaN (not JSON), for a clip without a rate
                        "longest_gap_s": (round(r.longest_s, 4) if math.isfinite(r.longest_s)
                                          else None),
                        "fillable": bool(f)}
                       for r, f in zip(rows, fillable)],
    }


def format_info(motion: Motion, gaps_only: bool = False) -> str:
    """A table: marker, missing n/N (%), gaps, longest gap in frames and seconds.

    With ``gaps_only``, markers with no missing sample are left out of the table.
    """
    rows = summarise(motion)
    width = max([6] + [len(r.label) for r in rows])
    total = int((~motion.observed).sum())
    timing = (f"at {motion.rate:g} Hz ({motion.duration_s:.2f} s)" if motion.rate > 0
              else "with no frame rate (0 Hz)")
    lines = [f"{motion.path or 'clip'}: {motion.n_markers} markers × {motion.n_frames} frames "
             f"{timing}, units {motion.units}; "
             f"{total}/{motion.observed.size} samples missing "
             f"({100 * total / max(motion.observed.size, 1):.1f}%)",
             *(f"note: {note}" for note in reader_notes(motion)),
             f"{'marker':<{width}}  {'missing':>16}  {'gaps':>4}  {'longest':>15}"]
    for row, fillable in zip(rows, motion.fillable):
        if gaps_only and not row.missing:
            continue
        note = "" if fillable else "  (not a marker: never filled)"
        # (no seconds for a clip of no rate: "nan s" read as a fault)
        seconds = (f"{row.longest_s:6.3f} s" if math.isfinite(row.longest_s)
                   else f"{'–':>6}")
        lines.append(f"{row.label:<{width}}  {f'{row.missing}/{row.frames}':>9} "
                     f"({row.percent:5.1f}%)  {row.gaps:>4}  "
                     f"{row.longest:>5} fr {seconds}{note}")
    return "\n".join(lines)


def check_same_clip(before: Motion, after: Motion) -> None:
    """A FormatError naming ``after`` unless it has ``before``'s markers and frames (the
    before/after table of ``mocapfill info``, as text or JSON)."""
    if before.n_frames != after.n_frames or before.n_markers != after.n_markers:
        raise FormatError(after.path, f"does not match the original in markers × frames "
                                      f"({after.n_markers} × {after.n_frames}, the original "
                                      f"{before.n_markers} × {before.n_frames})")
    if before.labels != after.labels:
        a, b = next((a, b) for a, b in zip(before.labels, after.labels) if a != b)
        raise FormatError(after.path, f"does not match the original's marker names "
                                      f"({b!r} where it has {a!r})")


def format_info_before_after(before: Motion, after: Motion, gaps_only: bool = False) -> str:
    """Per-marker missing n/N, gaps and longest gap before and after a repair."""
    check_same_clip(before, after)
    rows_before, rows_after = summarise(before), summarise(after)
    width = max([6] + [len(r.label) for r in rows_before])
    lines = [f"{before.path or 'before'} -> {after.path or 'after'}: missing samples "
             f"{int((~before.observed).sum())} -> {int((~after.observed).sum())}",
             f"{'marker':<{width}}  {'missing before':>14}  {'after':>9}  {'gaps':>9}  "
             f"{'longest (fr)':>13}"]
    for b, a in zip(rows_before, rows_after):
        if gaps_only and not b.missing:
            continue
        lines.append(f"{b.label:<{width}}  {f'{b.missing}/{b.frames}':>14}  "
                     f"{f'{a.missing}/{a.frames}':>9}  {f'{b.gaps}->{a.gaps}':>9}  "
                     f"{f'{b.longest}->{a.longest}':>13}")
    return "\n".join(lines)


GAP_FIELDS = ("marker", "first_frame", "last_frame", "length_frames", "length_s", "method",
              "status")


def gap_rows(result) -> list[dict]:
    """One dict per gap of a RepairResult; frames numbered as the file numbers them."""
    motion = result.motion
    rows = []
    for outcome in result.gaps:
        gap = outcome.gap
        rows.append({"marker": gap.label, "first_frame": motion.first_frame + gap.start,
                     "last_frame": motion.first_frame + gap.stop - 1,
                     "length_frames": gap.length,
                     "length_s": round(gap.length / motion.rate, 6) if motion.rate else None,
                     "method": outcome.method if outcome.status == "filled" else "",
                     "status": outcome.status})
    return rows


def gaps_report_text(result, path: Path) -> str:
    """The per-gap report as CSV or JSON (by ``path``'s suffix), for the CLI to write with
    the repaired file (``formats.text_pending``)."""
    rows = gap_rows(result)
    suffix = path.suffix.lower()
    if suffix == ".json":
        text = json.dumps({"gaps": rows}, indent=1)
    elif suffix == ".csv":
        buffer = io.StringIO()
        writer = csv.DictWriter(buffer, fieldnames=GAP_FIELDS, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        text = buffer.getvalue()
    else:
        raise FormatError(path, "gaps report must be .csv or .json", exit_code=2)
    return text
