"""The C heap's settings (mocapfill._memory)."""
import ctypes
import sys

import pytest

from mocapfill._memory import release_memory, tune_heap


def _has_mallopt() -> bool:
    try:
        return hasattr(ctypes.CDLL(None), "mallopt") and sys.platform.startswith("linux")
    except (OSError, TypeError):
        return False


@pytest.mark.skipif(not _has_mallopt(), reason="glibc's mallopt (Linux)")
def test_the_heap_thresholds_are_set_unless_the_user_set_the_heap(monkeypatch):
    for name in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_TOP_PAD_",
                 "MALLOC_MMAP_MAX_"):
        monkeypatch.delenv(name, raising=False)
    assert tune_heap() is True
    monkeypatch.setenv("MALLOC_TRIM_THRESHOLD_", "131072")
    assert tune_heap() is False


def test_the_command_line_sets_the_heap_before_numpy_is_imported():
    # The settings must come before numpy's first arrays: cli sets them at import.
    import subprocess

    script = ("import sys, mocapfill._memory as m\n"
              "calls = []\n"
              "m.tune_heap = lambda: calls.append('numpy' in sys.modules)\n"
              "import mocapfill.cli\n"
              "print(calls)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[False]"


def test_releasing_memory_is_harmless_anywhere():
    release_memory()
    release_memory()
