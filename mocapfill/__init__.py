"""mocapfill: repair gaps in motion-capture data with low-rank completion.

The public API::

    from mocapfill import read, write, repair, simulate_gaps, estimate_rank, rmse

    motion = read("trial.c3d")            # Motion: positions, observed mask, labels, ...
    result = repair(motion)               # RepairResult: .motion, .gaps
    write(result.motion, "trial-filled.c3d")

Names are imported on first use, so ``mocapfill --help`` does not pay for numpy and scipy.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

# public name -> module that defines it
_API = {
    "read": "formats", "write": "formats",
    "repair": "pipeline", "RepairOptions": "pipeline", "RepairResult": "pipeline",
    "complete_matrix": "pipeline",
    "simulate_gaps": "gaps", "find_gaps": "gaps",
    "estimate_rank": "rank",
    "rmse": "metrics", "score": "metrics",
    "Motion": "motion",
    "MocapfillError": "errors", "FormatError": "errors", "ParameterError": "errors",
    "NothingToRepair": "errors",
    "repair_many": "batch",
}
__all__ = sorted(_API)


def __getattr__(name: str):
    if name in _API:
        value = getattr(importlib.import_module(f".{_API[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'mocapfill' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(list(globals()) + __all__)
