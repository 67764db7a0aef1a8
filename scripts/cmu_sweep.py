"""Score methods / solver options on the paper's CMU protocols (seeds 0–2, mean RMSE in mm).

Prints one line per (clip, protocol) with error / seconds for each variant. Needs
../shared/data/cmu. Example (the fourth-session table of docs/results.md):

    python scripts/cmu_sweep.py ml=20,ml=40,ml=60,mr=0.2,mr=0.4,mr=0.6 \
        'trnn:{}'
"""
from __future__ import annotations

import json
import sys
import time

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import CMU_CLIPS, SEEDS, _cmu_case, repair_options  # noqa: E402 (after the BLAS setting)
from mocapfill.metrics import score  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import repair  # noqa: E402 (after the BLAS setting)


def main(protocols: str, specs: list[str]) -> None:
    cases = []
    for item in protocols.split(","):
        kind, _, value = item.partition("=")
        cases.append((kind, float(value) if kind == "mr" else int(value)))
    variants = [(s.partition(":")[0], json.loads(s.partition(":")[2] or "{}")) for s in specs]
    for clip in CMU_CLIPS:
        for protocol in cases:
            errors, seconds = np.zeros(len(variants)), np.zeros(len(variants))
            for seed in SEEDS:
                truth, gapped = _cmu_case(clip, protocol, seed).load()
                for i, (method, options) in enumerate(variants):
                    started = time.perf_counter()
                    result = repair(gapped, repair_options(method, options))
                    seconds[i] += (time.perf_counter() - started) / len(SEEDS)
                    errors[i] += score(truth, result.motion, gapped).rmse_mm / len(SEEDS)
            print(f"{clip} {protocol[0]}={protocol[1]:g}",
                  " ".join(f"{e:8.3f}/{t:.1f}s" for e, t in zip(errors, seconds)), flush=True)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "ml=40", sys.argv[2:] or ["trnn:{}"])
