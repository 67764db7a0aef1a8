"""The interpolants of ``solvers._splines`` against scipy's own.

scipy stays installed (the solvers use ``scipy.linalg`` and ``scipy.fft``), so the
reference implementations are at hand: every interpolant must agree with
``scipy.interpolate`` to rounding on irregular sample times (a row of a marker with gaps),
for one row and for a marker's three columns at once.
"""
from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.interpolate import CubicSpline, PchipInterpolator, make_interp_spline

from mocapfill.solvers import _splines


def _samples(seed: int, n: int = 300, frames: int = 1000, columns: int | None = 3):
    """Irregular integer times (gaps of many lengths) and a random-walk trajectory."""
    rng = np.random.default_rng(seed)
    x = np.sort(rng.choice(frames, n, replace=False)).astype(np.float64)
    shape = (n,) if columns is None else (n, columns)
    y = np.cumsum(rng.standard_normal(shape), axis=0)
    t = np.setdiff1d(np.arange(x[0], x[-1] + 1), x)          # the missing frames
    return x, y, t


def _close(ours: np.ndarray, theirs: np.ndarray) -> None:
    assert ours.shape == theirs.shape
    np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12 * np.abs(theirs).max())


@pytest.mark.parametrize("columns", [None, 3])
@pytest.mark.parametrize("bc_type", ["not-a-knot", "natural", "clamped"])
def test_cubic_spline_is_scipys(bc_type, columns):
    for seed in range(3):
        x, y, t = _samples(seed, columns=columns)
        _close(_splines.cubic_spline(x, y, bc_type)(t), CubicSpline(x, y, bc_type=bc_type)(t))


@pytest.mark.parametrize("columns", [None, 3])
def test_pchip_is_scipys(columns):
    for seed in range(3):
        x, y, t = _samples(seed, columns=columns)
        _close(_splines.pchip(x, y)(t), PchipInterpolator(x, y)(t))
    x, y, t = _samples(0, n=2, columns=columns)
    _close(_splines.pchip(x, y)(t), PchipInterpolator(x, y)(t))


def test_pchip_on_subnormal_steps_is_flat_there_without_a_warning():
    # w / m overflows where a step is subnormal (a property test's data): the harmonic
    # mean of the slopes is then 0, as beside a flat step, and nothing is worth a warning.
    x = np.arange(4.0)
    y = np.array([0.0, 1e-310, 3e-310, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ours = _splines.pchip(x, y)(np.array([0.5, 1.5, 2.5]))
    with np.errstate(over="ignore"):            # scipy's own division warns
        theirs = PchipInterpolator(x, y)(np.array([0.5, 1.5, 2.5]))
    _close(ours, theirs)


@pytest.mark.parametrize("columns", [None, 3])
@pytest.mark.parametrize("degree", [3, 5, 7])
def test_odd_spline_is_make_interp_spline(degree, columns):
    for seed in range(3):
        x, y, t = _samples(seed, columns=columns)
        _close(_splines.odd_spline(x, y, degree)(t), make_interp_spline(x, y, k=degree)(t))
    # The fewest samples the degree allows (all knots stacked at the ends).
    x, y, t = _samples(3, n=degree + 1, frames=40, columns=columns)
    _close(_splines.odd_spline(x, y, degree)(t), make_interp_spline(x, y, k=degree)(t))


def test_splines_interpolate_and_reproduce_their_polynomials():
    x = np.array([0.0, 1, 2, 5, 6, 9, 10, 11, 15, 16, 17, 20])
    for degree in (3, 5, 7):
        y = (x / 10) ** degree - 2 * x
        f = _splines.odd_spline(x, y, degree)
        np.testing.assert_allclose(f(x), y, atol=1e-9)
        t = np.arange(21.0)
        np.testing.assert_allclose(f(t), (t / 10) ** degree - 2 * t, atol=1e-9)
    cubic = x ** 3 / 100 - x
    np.testing.assert_allclose(_splines.cubic_spline(x, cubic)(np.arange(21.0)),
                               np.arange(21.0) ** 3 / 100 - np.arange(21.0), atol=1e-9)


def test_too_few_samples_and_bad_input_are_refused():
    with pytest.raises(ValueError, match="more than 3 samples"):
        _splines.cubic_spline(np.arange(3.0), np.ones(3))
    with pytest.raises(ValueError, match="more than 5 samples"):
        _splines.odd_spline(np.arange(5.0), np.ones(5), 5)
    with pytest.raises(ValueError, match="odd"):
        _splines.odd_spline(np.arange(9.0), np.ones(9), 4)
    with pytest.raises(ValueError, match="increasing"):
        _splines.pchip(np.array([0.0, 2.0, 1.0]), np.ones(3))
    with pytest.raises(ValueError, match="bc_type"):
        _splines.cubic_spline(np.arange(6.0), np.ones(6), "periodic")


def test_repair_imports_neither_scipy_interpolate_nor_optimize(tmp_path):
    # The point of this module: a repair leaves them unimported (0.17 s of start-up).
    from mocapfill.formats import write

    from ..helpers import smooth_clip, with_gap

    source = tmp_path / "in.trc"
    write(with_gap(with_gap(smooth_clip(), 2, 100, 140), 5, 200, 203), source)
    code = ("import sys; from mocapfill.cli import main\n"
            "try:\n"
            f"    main(['repair', {str(source)!r}, {str(tmp_path / 'out.trc')!r}])\n"
            "except SystemExit as exit:\n"
            "    assert not exit.code, exit.code\n"
            "print(sorted(m for m in sys.modules\n"
            "            if m.startswith(('scipy.interpolate', 'scipy.optimize'))))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]", done.stdout
    assert (tmp_path / "out.trc").exists()
