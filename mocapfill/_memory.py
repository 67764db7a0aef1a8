"""The C heap: its settings for the command line, and handing freed pages back.

numpy takes every array's memory from the C library's ``malloc``. glibc serves requests
above a threshold (128 KB at first, raised to the size of the largest such block freed,
up to 32 MB) with a fresh ``mmap`` of the system, and hands the top of its heap back
whenever more than twice that threshold lies free there. Each time, the pages are
faulted in again, zeroed, on their next use. A repair allocates and frees arrays of a
few MB thousands of times (the candidates' temporaries: 85_12 is 123 × 4500, 4.4 MB in
float64), so :func:`tune_heap` fixes both thresholds where the command line starts.
"""
from __future__ import annotations

import functools
import os

# glibc's mallopt parameters (malloc.h).
_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3

# Arrays below this come from the heap: every array of a clip solved whole, and the
# windows' temporaries (12,000 frames × 123 rows, 11.8 MB); larger ones (a long clip's
# matrix) are mapped and unmapped as before.
MMAP_THRESHOLD = 32 << 20
# Free memory at the top of the heap is kept up to this much (the explicit
# :func:`release_memory` after each window and pool job still hands it all back).
TRIM_THRESHOLD = 256 << 20

# The variables by which a user sets glibc's heap; where any is set, the user's choice
# stands.
_USER_SETTINGS = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_",
                  "MALLOC_MMAP_MAX_")


def tune_heap() -> bool:
    """Fix glibc's mmap and trim thresholds (:data:`MMAP_THRESHOLD`,
    :data:`TRIM_THRESHOLD`) for this process and the processes it forks; whether they
    were set (False without glibc, or where the user set the heap's variables).

    Measured on the 2-vCPU test machine, alternated runs of ``mocapfill repair``
    (medians of 9–11): 85_02 ml = 40 0.78 → 0.70 s and 0.70 → 0.67 s, 85_12 ml = 40
    1.26 → 1.21 s and 1.38 → 1.35 s; the 30-minute clip's repair the same (43.8 against
    42.6 s, total PSS 910 against 935 MB); outputs identical. (Setting the trim
    threshold alone made them slower: 0.77 → 0.98 s on 85_02, since any such setting also
    ends glibc's raising of the mmap threshold.)
    """
    if any(name in os.environ for name in _USER_SETTINGS):
        return False
    mallopt = _libc("mallopt")
    if mallopt is None:
        return False
    return bool(mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and \
        bool(mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))


def release_memory() -> None:
    """Hand the C heap's free pages back to the system (glibc's ``malloc_trim``).

    Each thread allocates from its own malloc arena, and freed arrays of a few MB stayed
    there: on a long clip solved in windows the resident memory crept up window after
    window (a 40,000-frame clip: 440 → 760 MB). A no-op where the C library has no
    ``malloc_trim`` (not glibc).
    """
    trim = _libc("malloc_trim")
    if trim is not None:
        trim(0)


@functools.lru_cache(maxsize=4)
def _libc(name: str):
    """The C library's function ``name``, or None where there is none."""
    import ctypes

    try:
        # The process's own symbols: the C library on Linux, without searching for it.
        return getattr(ctypes.CDLL(None), name)
    except (OSError, AttributeError, TypeError):   # not there; Windows has no CDLL(None)
        return None
