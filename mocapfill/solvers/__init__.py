"""Completion methods behind one signature.

Every method is ``fn(matrix, observed, **options) -> completed``:

- ``matrix``: (m, n) float64, m = 3·markers (rows 3j..3j+2 are x, y, z of marker j),
  n = frames. Entries where ``observed`` is False are undefined (NaN) and must be ignored.
- ``observed``: (m, n) bool, True where the entry is data. Whole marker samples
  (all three rows of a marker) are observed or missing together.
- returns a new (m, n) float64 array, finite everywhere. Inputs are never modified.
  A method may change observed entries (a robust method separates outliers); the repair
  pipeline restores them afterwards.

Methods do not print, do not read files and never depend on units: the pipeline hands
them rows centred and scaled to unit RMS (see ``mocapfill.pipeline``). A method marked
``fn.takes_centre`` also gets ``centre=`` (rows,), each row's centre in that scale, for
what needs the markers' true positions (distances, rigid bodies).
"""
from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable

import numpy as np

from ..errors import ParameterError

Method = Callable[..., np.ndarray]

# name -> "module:function"; imported lazily so `mocapfill --help` stays fast.
METHODS: dict[str, str] = {
    "trnn": "mocapfill.solvers.trnn:complete",
    "trnn-paper": "mocapfill.solvers.trnn:complete_paper",
    "trnn-lowrank": "mocapfill.solvers.trnn:complete_lowrank",
    "linear": "mocapfill.solvers.interp:linear",
    "spline": "mocapfill.solvers.interp:spline",
    "pchip": "mocapfill.solvers.interp:pchip",
    "pca": "mocapfill.solvers.pca:complete",
    "gaussian": "mocapfill.solvers.gaussian:complete",
    "svt": "mocapfill.solvers.svt:complete",
    "tsmc": "mocapfill.solvers.tsmc:complete",
    "ialm": "mocapfill.solvers.rpca:ialm",
    "psvt": "mocapfill.solvers.rpca:psvt",
}


def get_method(name: str) -> Method:
    """The completion function registered under ``name``."""
    try:
        module_name, func_name = METHODS[name].split(":")
    except KeyError:
        raise ParameterError(
            f"unknown method {name!r}; choose one of {', '.join(METHODS)}") from None
    return getattr(importlib.import_module(module_name), func_name)


def option_parameters(fn: Method) -> dict[str, inspect.Parameter]:
    """The keyword options ``fn`` takes (besides matrix and observed), as signature
    parameters (name, default, annotation).

    A method that passes ``**options`` on to another declares it as ``fn.forwards_to``;
    its own parameter wins where both name an option.
    """
    params = list(inspect.signature(fn).parameters.values())[2:]
    own = {p.name: p for p in params if p.kind in (p.KEYWORD_ONLY, p.POSITIONAL_OR_KEYWORD)}
    if getattr(fn, "takes_centre", False):      # the pipeline's to give, not an option
        own.pop("centre", None)
    forwards_to = getattr(fn, "forwards_to", None)
    return {**(option_parameters(forwards_to) if forwards_to else {}), **own}


def option_names(fn: Method) -> frozenset[str]:
    """The keyword options ``fn`` takes (besides matrix and observed)."""
    return frozenset(option_parameters(fn))
