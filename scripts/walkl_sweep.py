"""Score methods / solver options on the Gløersen–Federolf walking set (WalkL_0001–0010).

Prints the 3-D RMS error (mm) over the interior gap samples of each file and the mean, one
column per variant. Needs ../shared/data/walkl. Example (the η₀ sweep of docs/results.md):

    python scripts/walkl_sweep.py \
        'trnn-lowrank:{"eta0": 0.01}' 'trnn-lowrank:{"eta0": 0.05}' 'pca:{}'
"""
from __future__ import annotations

import json
import sys

from mocapfill._blas import one_thread_by_default

# One BLAS thread, as `mocapfill repair` runs, so that the figures are the command's.
one_thread_by_default()

import numpy as np  # noqa: E402 (after the BLAS setting)

from mocapfill.bench import WALKL_FILES, _walkl_case, repair_options  # noqa: E402 (after the BLAS setting)
from mocapfill.metrics import score  # noqa: E402 (after the BLAS setting)
from mocapfill.pipeline import repair  # noqa: E402 (after the BLAS setting)


def main(specs: list[str]) -> None:
    variants = []
    for spec in specs:
        method, _, options = spec.partition(":")
        variants.append((method, json.loads(options or "{}")))
    means = np.zeros(len(variants))
    for name in WALKL_FILES:
        truth, gapped = _walkl_case(name).load()
        errors = []
        for method, options in variants:
            result = repair(gapped, repair_options(method, options))
            errors.append(score(truth, result.motion, gapped).rmse_3d_mm)
        means += np.array(errors) / len(WALKL_FILES)
        print(name, " ".join(f"{e:7.4f}" for e in errors), flush=True)
    print("mean      ", " ".join(f"{e:7.4f}" for e in means))


if __name__ == "__main__":
    main(sys.argv[1:] or ["trnn-lowrank:{}"])
