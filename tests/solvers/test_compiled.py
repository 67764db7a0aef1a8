"""``solvers._compiled``: scipy's compiled routines without scipy.linalg's and scipy.fft's
Python layers, giving scipy's public functions' results bit for bit."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.fft
import scipy.linalg

from mocapfill.solvers import _compiled

ROOT = Path(__file__).resolve().parents[2]


def _same_bits(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("n", [7, 810, 4500, 4499])
def test_dct_and_idct_are_scipy_fft_bit_for_bit(dtype, n):
    x = np.random.default_rng(n).standard_normal((5, n)).astype(dtype)
    _same_bits(_compiled.dct(x), scipy.fft.dct(x, type=2, norm="ortho", axis=-1))
    _same_bits(_compiled.idct(x), scipy.fft.idct(x, type=2, norm="ortho", axis=-1))
    np.testing.assert_allclose(_compiled.idct(_compiled.dct(x)), x,
                               atol=1e-4 if dtype == np.float32 else 1e-12)


def test_idct_in_place_writes_its_input_and_dct_leaves_it_alone():
    x = np.random.default_rng(1).standard_normal((3, 64))
    kept = x.copy()
    coefficients = _compiled.dct(x)
    _same_bits(x, kept)
    out = _compiled.idct(coefficients, overwrite=True)
    assert out is coefficients
    np.testing.assert_allclose(out, kept, atol=1e-12)


def test_integer_input_is_transformed_in_double_precision():
    x = np.arange(12).reshape(2, 6)
    _same_bits(_compiled.dct(x), scipy.fft.dct(x, type=2, norm="ortho", axis=-1))


def test_good_size_is_next_fast_len():
    for n in [1, 2, 7, 97, 810, 4300, 4499, 4500, 216_001]:
        assert _compiled.good_size(n) == scipy.fft.next_fast_len(n, real=True)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_blas_and_lapack_routines_are_scipys(dtype):
    a = np.ones((2, 2), dtype=dtype)
    assert _compiled.blas("axpy", a) is scipy.linalg.get_blas_funcs("axpy", (a,))
    assert _compiled.blas("trsm", a, a) is scipy.linalg.get_blas_funcs("trsm", (a, a))
    assert _compiled.lapack("potrf", a) is scipy.linalg.get_lapack_funcs("potrf", (a,))
    # Mixed precisions take the double routine, as scipy does.
    assert _compiled.blas("axpy", a, np.ones(2)) is scipy.linalg.get_blas_funcs("axpy",
                                                                               (a, np.ones(2)))


def test_complex_arrays_are_refused():
    with pytest.raises(TypeError, match="complex"):
        _compiled.blas("axpy", np.ones(2, dtype=complex))


def test_threads_asking_for_a_module_at_once_get_it_loaded_once(monkeypatch):
    # The blend's first solves start side by side and reach the DCT together; two
    # threads initialising one extension at once once left a module without functions.
    import threading
    import time
    from types import SimpleNamespace

    name = "scipy.linalg._not_really_loaded"
    made = SimpleNamespace(__name__=name)
    calls = []

    def slow_load(wanted):
        calls.append(wanted)
        time.sleep(0.05)
        return made

    monkeypatch.setattr(_compiled, "_load_directly", slow_load)
    monkeypatch.delitem(_compiled._loaded, name, raising=False)
    start = threading.Barrier(8)
    got = []

    def ask():
        start.wait()
        got.append(_compiled.module(name))

    threads = [threading.Thread(target=ask) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    _compiled._loaded.pop(name, None)
    assert calls == [name]
    assert len(got) == 8 and all(module is made for module in got)


def test_a_loaded_module_without_its_functions_is_not_used(monkeypatch):
    from types import SimpleNamespace

    monkeypatch.setattr(_compiled, "_load_directly", lambda name: SimpleNamespace())
    monkeypatch.delitem(_compiled._loaded, _compiled.POCKETFFT, raising=False)
    monkeypatch.delitem(sys.modules, _compiled.POCKETFFT, raising=False)
    try:
        assert hasattr(_compiled.module(_compiled.POCKETFFT), "good_size")
    finally:
        _compiled._loaded.pop(_compiled.POCKETFFT, None)


def _banded(rng: np.random.Generator, lower: int, upper: int, n: int) -> np.ndarray:
    ab = rng.standard_normal((lower + upper + 1, n))
    ab[upper] += 10.0           # diagonally dominant: well conditioned
    return ab


@pytest.mark.parametrize("lower, upper", [(1, 1), (2, 3), (3, 3)])
@pytest.mark.parametrize("columns", [None, 4])
def test_solve_banded_is_scipys_bit_for_bit(lower, upper, columns):
    rng = np.random.default_rng(lower * 10 + upper)
    ab = _banded(rng, lower, upper, 50)
    b = rng.standard_normal(50 if columns is None else (50, columns))
    kept = ab.copy(), b.copy()
    x = _compiled.solve_banded(lower, upper, ab, b)
    _same_bits(x, scipy.linalg.solve_banded((lower, upper), ab, b))
    _same_bits(ab, kept[0])
    _same_bits(b, kept[1])


def test_solve_banded_reports_a_singular_system_and_misfit_shapes():
    ab = np.zeros((3, 5))
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        _compiled.solve_banded(1, 1, ab, np.ones(5))
    with pytest.raises(ValueError, match="do not fit"):
        _compiled.solve_banded(2, 1, ab, np.ones(5))


def test_solveh_banded_is_scipys_bit_for_bit():
    rng = np.random.default_rng(3)
    n = 40
    ab = np.zeros((3, n))
    ab[2] = 6.0 + rng.random(n)
    ab[1, 1:] = -1.0 - rng.random(n - 1)
    ab[0, 2:] = 0.5
    b = rng.standard_normal((n, 6)).astype(np.float32)
    _same_bits(_compiled.solveh_banded(ab, b), scipy.linalg.solveh_banded(ab, b))
    with pytest.raises(np.linalg.LinAlgError):
        _compiled.solveh_banded(-ab, b)


# A fresh interpreter: the repair's solvers load the compiled modules without importing
# scipy.linalg, scipy.fft or scipy's array-API layer (0.4 s of every command); and where
# the direct load fails, the usual import gives the same results.
SCRIPT = r"""
import sys
import numpy as np
from mocapfill.solvers import _compiled
if sys.argv[1] == "usual":
    _compiled._load_directly = lambda name: None
from mocapfill.solvers.trnn import complete
rng = np.random.default_rng(0)
t = np.linspace(0, 4 * np.pi, 300)
matrix = np.vstack([np.sin(k * t + k) for k in range(1, 13)]) * 100
observed = np.ones_like(matrix, dtype=bool)
observed[0:3, 100:140] = False
observed[6:9, 30:33] = False
filled = complete(matrix, observed)
heavy = [name for name in ("scipy.linalg", "scipy.fft", "scipy._lib._array_api")
         if name in sys.modules]
# scipy imported afterwards as usual, with the same routines.
import scipy.fft, scipy.linalg
a = np.ones(2, dtype=np.float32)
same = (scipy.linalg._fblas.saxpy is _compiled.blas("axpy", a)
        and scipy.linalg.get_lapack_funcs("potrf", (a,)) is _compiled.lapack("potrf", a)
        and scipy.fft.dct(a, norm="ortho").tobytes() == _compiled.dct(a).tobytes())
sys.stdout.write(",".join(heavy) + "\n" + str(same) + "\n" + filled.tobytes().hex())
"""


def _run(mode: str) -> tuple[str, str, str]:
    done = subprocess.run([sys.executable, "-c", SCRIPT, mode], capture_output=True,
                          text=True, cwd=ROOT, check=True)
    heavy, same, filled = done.stdout.split("\n")
    return heavy, same, filled


def test_the_default_method_does_not_import_scipys_python_layers_and_the_fallback_agrees():
    heavy, same, direct = _run("direct")
    assert heavy == ""
    assert same == "True"
    heavy, same, usual = _run("usual")
    assert "scipy.linalg" in heavy
    assert same == "True"
    assert direct == usual
