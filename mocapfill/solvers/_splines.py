"""Interpolating splines along time, on numpy and LAPACK's banded solvers alone.

The spline candidates of the blend (degrees 3, 5 and 7) and the ``spline`` and ``pchip``
methods were built on ``scipy.interpolate``, whose import (with ``scipy.optimize``, which
it pulls in) cost about 0.17 s of every ``mocapfill repair``: 0.51 s for the scipy modules
the repair imported, against 0.34 s for ``scipy.linalg`` and ``scipy.fft``, which the
solvers needed then (now only their compiled modules, :mod:`mocapfill.solvers._compiled`).
The interpolants here are the same ones, and the tests check them
against scipy's:

- :func:`cubic_spline` — the C² cubic spline through the samples with not-a-knot, natural
  or clamped ends (``scipy.interpolate.CubicSpline``), from the tridiagonal system of its
  slopes (de Boor, *A Practical Guide to Splines*, 2001, ch. IV);
- :func:`pchip` — the monotone piecewise cubic of Fritsch & Carlson (1980) with the
  weighted harmonic mean slopes and three-point end slopes of Fritsch & Butland (1984),
  as ``scipy.interpolate.PchipInterpolator`` computes them;
- :func:`odd_spline` — the interpolating B-spline of odd degree k with de Boor's
  not-a-knot knots (``scipy.interpolate.make_interp_spline(x, y, k)``): the collocation
  system is banded and its B-splines come from de Boor's recurrence (BSPLVB).

Each takes increasing sample times ``x`` and values ``y`` of shape (n,) or (n, c) (columns
sharing the times, such as a marker's x, y, z) and returns a function of times inside
[x[0], x[-1]] with the shape of ``y`` after the first axis.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

Interpolant = Callable[[np.ndarray], np.ndarray]

END_CONDITIONS = ("not-a-knot", "natural", "clamped")


def _columns(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
    """x as float64, y as an (n, c) float64 array, and y's trailing shape."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if x.ndim != 1 or y.shape[:1] != x.shape:
        raise ValueError(f"x must be 1-D and y must have len(x) = {x.size} rows")
    if x.size > 1 and not (np.diff(x) > 0).all():
        raise ValueError("x must be strictly increasing")
    return x, y.reshape(x.size, -1), y.shape[1:]


def _hermite(x: np.ndarray, y: np.ndarray, slopes: np.ndarray, shape: tuple) -> Interpolant:
    """The piecewise cubic with values ``y`` and derivatives ``slopes`` at ``x``."""
    def evaluate(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        flat = t.ravel()
        i = np.clip(np.searchsorted(x, flat, side="right") - 1, 0, x.size - 2)
        h = (x[i + 1] - x[i])[:, None]
        s = (flat - x[i])[:, None] / h
        rest = 1.0 - s
        values = (rest * rest * ((1.0 + 2.0 * s) * y[i] + s * h * slopes[i])
                  + s * s * ((3.0 - 2.0 * s) * y[i + 1] - rest * h * slopes[i + 1]))
        return values.reshape(t.shape + shape)
    return evaluate


def cubic_spline(x: np.ndarray, y: np.ndarray, bc_type: str = "not-a-knot") -> Interpolant:
    """The C² cubic spline through (x, y); needs 4 samples (2 for natural or clamped ends).

    ``bc_type``: "not-a-knot" (the third derivative is continuous at x[1] and x[-2], so a
    cubic is reproduced exactly), "natural" (zero second derivative at both ends) or
    "clamped" (zero first derivative at both ends).
    """
    from ._compiled import solve_banded

    if bc_type not in END_CONDITIONS:
        raise ValueError(f"bc_type must be one of {END_CONDITIONS}, got {bc_type!r}")
    x, y, shape = _columns(x, y)
    n = x.size
    if n < (4 if bc_type == "not-a-knot" else 2):
        raise ValueError(f"a {bc_type} cubic spline needs more than {n} samples")
    dx = np.diff(x)
    slope = np.diff(y, axis=0) / dx[:, None]
    # Row i of the slopes' system (0 < i < n−1) is continuity of the second derivative at
    # x[i]; ab holds the upper, main and lower diagonals (LAPACK's band layout).
    ab = np.zeros((3, n))
    rhs = np.empty((n, y.shape[1]))
    ab[0, 2:] = dx[:-1]
    ab[1, 1:-1] = 2.0 * (dx[:-1] + dx[1:])
    ab[2, :-2] = dx[1:]
    rhs[1:-1] = 3.0 * (dx[1:, None] * slope[:-1] + dx[:-1, None] * slope[1:])
    if bc_type == "not-a-knot":
        d = x[2] - x[0]
        ab[1, 0], ab[0, 1] = dx[1], d
        rhs[0] = ((dx[0] + 2.0 * d) * dx[1] * slope[0] + dx[0] ** 2 * slope[1]) / d
        d = x[-1] - x[-3]
        ab[1, -1], ab[2, -2] = dx[-2], d
        rhs[-1] = (dx[-1] ** 2 * slope[-2] + (2.0 * d + dx[-1]) * dx[-2] * slope[-1]) / d
    elif bc_type == "natural":
        ab[1, 0], ab[0, 1], rhs[0] = 2.0, 1.0, 3.0 * slope[0]
        ab[1, -1], ab[2, -2], rhs[-1] = 2.0, 1.0, 3.0 * slope[-1]
    else:
        ab[1, 0], ab[0, 1], rhs[0] = 1.0, 0.0, 0.0
        ab[1, -1], ab[2, -2], rhs[-1] = 1.0, 0.0, 0.0
    slopes = solve_banded(1, 1, ab, rhs)
    return _hermite(x, y, slopes, shape)


def _pchip_end_slope(h0: float, h1: float, m0: np.ndarray, m1: np.ndarray) -> np.ndarray:
    """Three-point end slope, kept to the sign of m0 and to 3·|m0| where m0, m1 differ."""
    d = ((2.0 * h0 + h1) * m0 - h0 * m1) / (h0 + h1)
    d = np.where(np.sign(d) != np.sign(m0), 0.0, d)
    steep = (np.sign(m0) != np.sign(m1)) & (np.abs(d) > 3.0 * np.abs(m0))
    return np.where(steep, 3.0 * m0, d)


def pchip(x: np.ndarray, y: np.ndarray) -> Interpolant:
    """The monotone piecewise cubic Hermite interpolant through (x, y); needs 2 samples.

    Between samples it never leaves the range of its two end values, so it cannot
    overshoot; at a sample where the data turn (or are flat on one side) its slope is 0.
    """
    x, y, shape = _columns(x, y)
    if x.size < 2:
        raise ValueError(f"pchip needs 2 samples, got {x.size}")
    h = np.diff(x)
    m = np.diff(y, axis=0) / h[:, None]
    if x.size == 2:
        return _hermite(x, y, np.vstack([m, m]), shape)
    slopes = np.empty_like(y)
    w1 = (2.0 * h[1:] + h[:-1])[:, None]
    w2 = (h[1:] + 2.0 * h[:-1])[:, None]
    flat = (np.sign(m[1:]) != np.sign(m[:-1])) | (m[1:] == 0) | (m[:-1] == 0)
    # A slope of 0 (flat) or a subnormal one (w / m overflows to ±inf: the harmonic mean
    # is then 0, as for a flat side) needs no warning.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        harmonic = (w1 / m[:-1] + w2 / m[1:]) / (w1 + w2)
        slopes[1:-1] = np.where(flat, 0.0, 1.0 / harmonic)
    slopes[0] = _pchip_end_slope(h[0], h[1], m[0], m[1])
    slopes[-1] = _pchip_end_slope(h[-1], h[-2], m[-1], m[-2])
    return _hermite(x, y, slopes, shape)


def _intervals(knots: np.ndarray, t: np.ndarray, k: int, n: int) -> np.ndarray:
    """Index ``left`` of the knot span [knots[left], knots[left+1]) holding each t."""
    return np.clip(np.searchsorted(knots, t, side="right") - 1, k, n - 1)


def _bsplines(knots: np.ndarray, t: np.ndarray, left: np.ndarray, k: int) -> np.ndarray:
    """The k + 1 B-splines of degree k that are non-zero at each t (de Boor's BSPLVB).

    Returns (k + 1, len(t)); row r is B_{left−k+r}(t). The recurrence raises the degree
    one step at a time from the indicator of the span, vectorised over t and over the
    B-splines of each step (time along the fast axis).
    """
    steps = np.arange(k)[:, None]
    ahead = knots[left + steps + 1] - t          # deltar[r] = t_{left+r+1} − t
    behind = t - knots[left - steps]             # deltal[r] = t − t_{left−r}
    values = np.zeros((k + 1, t.size))
    values[0] = 1.0
    for j in range(k):
        right, back = ahead[:j + 1], behind[j::-1]
        term = values[:j + 1] / (right + back)
        values[:j + 1] = right * term
        values[1:j + 2] += back * term
    return values


def odd_spline(x: np.ndarray, y: np.ndarray, k: int) -> Interpolant:
    """The interpolating spline of odd degree k through (x, y), not-a-knot ends.

    Its knots are the samples without the (k − 1)/2 + 1 nearest each end (where the k + 1
    end knots are stacked), so the collocation matrix is square and banded; needs more
    than k samples. k = 3 is :func:`cubic_spline` with not-a-knot ends.
    """
    from ._compiled import lapack

    if k < 1 or k % 2 == 0:
        raise ValueError(f"the degree must be odd and positive, got {k}")
    x, y, shape = _columns(x, y)
    n = x.size
    if n <= k:
        raise ValueError(f"a spline of degree {k} needs more than {k} samples, got {n}")
    half = (k - 1) // 2
    knots = np.concatenate([np.full(k + 1, x[0]), x[half + 1:n - half - 1],
                            np.full(k + 1, x[-1])])
    left = _intervals(knots, x, k, n)
    rows = np.arange(n)
    cols = left - k + np.arange(k + 1)[:, None]                # (k + 1, n), as the B-splines
    lower, upper = int((rows - cols).max()), int((cols - rows).max())
    # LAPACK's gbsv straight away (scipy.linalg.solve_banded copies the bands into this
    # layout first, which doubled the solve): ``lower`` spare rows on top for the pivoting.
    # Written through flat indices (a third of the time of the 2-D fancy index).
    ab = np.zeros((2 * lower + upper + 1, n))
    ab.reshape(-1)[(lower + upper + rows - cols) * n + cols] = _bsplines(knots, x, left, k)
    gbsv = lapack("gbsv", ab)
    _, _, coefficients, info = gbsv(lower, upper, ab, y, overwrite_ab=True)
    if info != 0:
        raise ValueError(f"the collocation system of the degree-{k} spline is singular")

    def evaluate(t: np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        flat = t.ravel()
        at = _intervals(knots, flat, k, n)
        basis = _bsplines(knots, flat, at, k)
        picked = coefficients[at - k + np.arange(k + 1)[:, None]]     # (k + 1, p, c)
        return np.einsum("rp,rpc->pc", basis, picked).reshape(t.shape + shape)
    return evaluate
