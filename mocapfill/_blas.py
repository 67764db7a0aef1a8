"""One BLAS thread unless the user chose otherwise; standard library only.

Call :func:`one_thread_by_default` before numpy is first imported: the BLAS libraries read
these variables when they load. The command line does (``mocapfill/cli.py``), and so do
the measuring scripts, so that their figures are the command's: threaded BLAS rounds
differently, and the default method's validated choices could flip on that (WalkL_0001
gave 1.694 mm with two BLAS threads and 1.726 with one before the weights were bagged).
"""
from __future__ import annotations

import os

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def one_thread_by_default() -> None:
    """Set each BLAS thread variable to 1 where the environment does not set it.

    The solvers make many small products, where BLAS threads cost more than they give,
    and on a busy or batch-loaded machine threaded BLAS measured 5–18× slower.
    """
    for variable in VARIABLES:
        os.environ.setdefault(variable, "1")
