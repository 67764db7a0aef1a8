"""Hostile input: hundreds of byte-level mutations of real files of every format must end
in success or a clean mocapfill error — no traceback, no hang, no memory blow-up, input
unchanged. Fixed seed, bounded time."""
import json
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from .conftest import SHARED_DATA

# Small real files, one or two per format (the mutation targets).
SEEDS = ["c3d/btk-sample02__pc_real.c3d", "c3d/btk-sample02__DEC_INT.C3D",
         "c3d/btk-sample02__sgi_int.c3d", "trc/btk-Res16bits.trc",
         "csv/mogapfill-gait-raw-headerless.csv", "bvh/bvh_test1.bvh", "cmu/10_01.amc"]
MEMORY_LIMIT = 3 * 1024 ** 3


def _limit_memory():
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


@pytest.mark.parametrize("seed, cases", [(20261121, 210)])
def test_mutated_files_fail_cleanly(tmp_path, seed, cases):
    files = [SHARED_DATA / s for s in SEEDS if (SHARED_DATA / s).exists()]
    if not files:
        pytest.skip("../shared/data absent: no real files to mutate")
    root = Path(__file__).resolve().parents[1]
    completed = subprocess.run(
        [sys.executable, "-m", "tests.fuzz_runner", str(seed), str(cases), str(tmp_path),
         *map(str, files)],
        cwd=root, capture_output=True, text=True, timeout=900, preexec_fn=_limit_memory)
    assert completed.returncode == 0, completed.stderr[-2000:]
    outcome = json.loads(completed.stdout.strip().splitlines()[-1])
    assert outcome["failures"] == [], json.dumps(outcome["failures"][:10], indent=1)
