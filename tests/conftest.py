"""Shared fixtures. Real files live in ../shared/data (never copied here); tests that need
them skip with a reason when the folder is absent."""
from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from hypothesis import settings

from mocapfill._blas import one_thread_by_default

# BLAS on one thread for the whole suite, as the command line has it (mocapfill/cli.py sets
# the variables before numpy loads). Without this, the first test module importing the
# command line set them after numpy had loaded BLAS on every core: the rest of the suite
# ran threaded BLAS while mocapfill took the variables for the user's choice, and the
# real-data tests took 6 times as long.
one_thread_by_default()

# Hypothesis keeps no example database (a failing example is printed in the failure), and
# what else it stores (a cache of the constants in the code under test, written while
# pytest collects) goes to the system's temporary folder, as numpy's and scipy's conftests
# have it, not to .hypothesis/ in the folder pytest runs in.
settings.register_profile("mocapfill", database=None)
settings.load_profile("mocapfill")
try:    # (not in Hypothesis's documented API: where a release moves it, .hypothesis/ it is)
    from hypothesis.configuration import set_hypothesis_home_dir
except ImportError:
    pass
else:
    set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "mocapfill-hypothesis")

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def shared_file(relative: str) -> Path:
    """Path of a file under ../shared/data, or skip the calling test when it is absent."""
    path = SHARED_DATA / relative
    if not path.exists():
        pytest.skip(f"real-data file {relative} not available (../shared/data absent)")
    return path


def shared_files(folder: str, *suffixes: str) -> list[Path]:
    """Files of a shared folder with the given suffixes (case-insensitive); [] when absent."""
    root = SHARED_DATA / folder
    if not root.is_dir():
        return []
    return sorted(p for p in root.iterdir() if p.suffix.lower() in suffixes)


@pytest.fixture
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data absent")
    return SHARED_DATA
