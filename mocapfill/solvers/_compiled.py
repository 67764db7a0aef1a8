"""scipy's compiled BLAS, LAPACK and pocketfft, without scipy.linalg's and scipy.fft's
Python layers.

The solvers call a handful of compiled routines that scipy ships: BLAS axpy and trsm,
LAPACK potrf, potri, gtsv, gbsv and pbsv, and pocketfft's DCT. Importing them the
usual way (``scipy.linalg``, ``scipy.fft``) runs those packages' ``__init__``, which
load scipy's array-API layer; that layer copies numpy's namespace attribute by
attribute and so imports numpy.testing, numpy.f2py, numpy.ma and more. Measured on a
2-vCPU machine (scipy 1.16 and 1.17, numpy 2.4): ``import scipy.linalg, scipy.fft``
took 0.39 s on top of numpy's 0.09 s, in every command, for a 2 s repair of an
85_12-sized clip; the three extension modules alone load in 0.025 s.

So the extension modules (``scipy.linalg._fblas``, ``scipy.linalg._flapack``,
``scipy.fft._pocketfft.pypocketfft``) are loaded from scipy's installed folder by their
file names, without executing the packages above them. They are kept here, not entered
in ``sys.modules``: a later ``import scipy.linalg`` loads its module as usual, and Python
gives it the same routines (an extension module is initialised once per process). The
routines are the very objects ``scipy.linalg.get_blas_funcs`` and ``scipy.fft.dct``
reach, called with the arguments those functions pass, so results are the same bit for
bit (``tests/test_compiled.py``). Where a module cannot be loaded that way (another
layout, a platform whose scipy needs its ``__init__`` to find its libraries), it is
imported the usual way: slower, the same results.
"""
from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import os
import sys
import threading
from types import ModuleType

import numpy as np

BLAS = "scipy.linalg._fblas"
LAPACK = "scipy.linalg._flapack"
POCKETFFT = "scipy.fft._pocketfft.pypocketfft"


def _load_directly(name: str) -> ModuleType | None:
    """The extension module ``name`` loaded from its file, or None where that fails."""
    try:
        spec = importlib.util.find_spec("scipy")     # finds, does not run, scipy/__init__
        if spec is None or not spec.submodule_search_locations:
            return None
        parts = name.split(".")[1:]
        folder = os.path.join(spec.submodule_search_locations[0], *parts[:-1])
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = os.path.join(folder, parts[-1] + suffix)
            if os.path.isfile(path):
                loader = importlib.machinery.ExtensionFileLoader(name, path)
                module_spec = importlib.util.spec_from_file_location(name, path,
                                                                     loader=loader)
                module = importlib.util.module_from_spec(module_spec)
                loader.exec_module(module)
                # Python enters a module like these in sys.modules when it first loads
                # it; taken out again, so that scipy's own import later runs as usual
                # (and sets the attribute on its package). It gets the same routines.
                sys.modules.pop(name, None)
                return module
    except Exception:       # any failure: the usual import below decides
        return None
    return None


_loaded: dict[str, ModuleType] = {}
# One thread loads a module at a time: the blend's first two solves start side by side
# and reach the DCT together, and two threads initialising one extension module at once
# left one of them with a module missing its functions ("module ... pypocketfft has no
# attribute 'good_size'", seen once in a benchmark run).
_loading = threading.Lock()
# A function each module must have; a module without it is not used.
_EXPECTED = {BLAS: "daxpy", LAPACK: "dpotrf", POCKETFFT: "good_size"}


def module(name: str) -> ModuleType:
    """One of the extension modules above: scipy's own if scipy already imported it,
    else loaded from its file, else imported the usual way. Safe to call from several
    threads at once.
    """
    found = _loaded.get(name)
    if found is not None:
        return found
    with _loading:
        found = _loaded.get(name)
        if found is None:
            if name in sys.modules:     # through the import system, which waits for
                found = importlib.import_module(name)     # an import in progress
            else:
                found = _load_directly(name)
            if found is None or not hasattr(found, _EXPECTED.get(name, "__name__")):
                found = importlib.import_module(name)
            _loaded[name] = found
    return found


def _prefix(arrays: tuple[np.ndarray, ...]) -> str:
    # scipy's find_best_blas_type for real arrays: single precision only when every
    # array is float32 (or narrower), double otherwise.
    dtype = np.result_type(*arrays) if arrays else np.dtype(np.float64)
    if dtype.kind == "c":
        raise TypeError("complex arrays are not supported here")
    return "s" if dtype in (np.float16, np.float32) else "d"


def blas(name: str, *arrays: np.ndarray):
    """The BLAS routine ``name`` for the arrays' precision (``get_blas_funcs``)."""
    return getattr(module(BLAS), _prefix(arrays) + name)


def lapack(name: str, *arrays: np.ndarray):
    """The LAPACK routine ``name`` for the arrays' precision (``get_lapack_funcs``)."""
    return getattr(module(LAPACK), _prefix(arrays) + name)


def _transform(x: np.ndarray, kind: int, overwrite: bool) -> np.ndarray:
    x = np.asarray(x)
    if x.dtype not in (np.float32, np.float64):
        x = x.astype(np.float64)
        overwrite = True
    # pocketfft's arguments as scipy.fft passes them: axes, normalisation 1 (÷√N, which
    # with ``ortho`` left at its default makes the transform orthonormal), the output
    # array or None, one thread.
    return module(POCKETFFT).dct(x, kind, (x.ndim - 1,), 1, x if overwrite else None, 1)


def dct(x: np.ndarray, *, overwrite: bool = False) -> np.ndarray:
    """The orthonormal DCT-II along the last axis
    (``scipy.fft.dct(x, type=2, norm="ortho", axis=-1)``)."""
    return _transform(x, 2, overwrite)


def idct(x: np.ndarray, *, overwrite: bool = False) -> np.ndarray:
    """The inverse of :func:`dct` (``scipy.fft.idct(x, type=2, norm="ortho", axis=-1)``),
    in place with ``overwrite``."""
    return _transform(x, 3, overwrite)


def good_size(n: int) -> int:
    """The smallest length ≥ n whose real FFT is fast (``scipy.fft.next_fast_len(n,
    real=True)``)."""
    return int(module(POCKETFFT).good_size(n, True))


def _solved(info: int, routine: str) -> None:
    if info > 0:
        raise np.linalg.LinAlgError(f"singular matrix ({routine})")
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of {routine}")


def solve_banded(lower: int, upper: int, ab: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``scipy.linalg.solve_banded((lower, upper), ab, b)`` for float arrays of two or more
    rows: tridiagonal systems by LAPACK gtsv, others by gbsv. Inputs are not modified."""
    ab, b = np.asarray(ab), np.asarray(b)
    if ab.shape[0] != lower + upper + 1 or ab.shape[-1] != b.shape[0] or b.shape[0] < 2:
        raise ValueError(f"bands {ab.shape} and right-hand side {b.shape} do not fit "
                         f"({lower}, {upper}) bands")
    if lower == upper == 1:
        gtsv = lapack("gtsv", ab, b)
        _, _, _, x, info = gtsv(ab[2, :-1], ab[1, :], ab[0, 1:], b)
        _solved(info, "gtsv")
        return x
    gbsv = lapack("gbsv", ab, b)
    work = np.zeros((2 * lower + upper + 1, ab.shape[1]),
                    dtype=np.float32 if _prefix((ab, b)) == "s" else np.float64)
    work[lower:] = ab
    _, _, x, info = gbsv(lower, upper, work, b, overwrite_ab=True)
    _solved(info, "gbsv")
    return x


def solveh_banded(ab: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``scipy.linalg.solveh_banded(ab, b)`` (upper bands, positive definite, three or more
    bands) by LAPACK pbsv. Inputs are not modified."""
    ab, b = np.asarray(ab), np.asarray(b)
    if ab.shape[0] < 3 or ab.shape[-1] != b.shape[0]:
        raise ValueError(f"bands {ab.shape} and right-hand side {b.shape} do not fit")
    pbsv = lapack("pbsv", ab, b)
    _, x, info = pbsv(ab, b, lower=0)
    _solved(info, "pbsv")
    return x
