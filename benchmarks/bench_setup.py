"""What each world of ``himit run paper`` costs besides its learning: ``run_world`` with one
window of steps, in one process, for the six worlds (exp1 80×80, exp2 40×40, exp3 120×120,
96×96, 80×80 and 64×64, 5 seeds, the committed settings).

That is the mentor's exact policy and its demonstrations, both option sets, the exact option
models of the greedy references, the optimum's evaluation, the learner, logger, checkpoint,
greedy evaluation, curves and world figure: everything but the learning's steps (5,000 of them
per run here, ≈ 0.1–0.5 s a world). The kernels are loaded first, untimed. Prints each world's
seconds and their sum per repeat, and the median sum.

    python benchmarks/bench_setup.py [--repeats 3]

To compare with another checkout, run this script with ``PYTHONPATH`` set to it (the script
imports ``himit_torch`` from ``PYTHONPATH`` first), alternating the two.
"""

import argparse
import dataclasses
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

if not os.environ.get("PYTHONPATH"):  # (else the checkout PYTHONPATH names)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--repeats", type=int, default=3)
args = parser.parse_args()

import himit_torch  # noqa: E402
from himit_torch.runs.config import EXPERIMENTS  # noqa: E402
from himit_torch.runs.experiment import run_world  # noqa: E402
from himit_torch.runs.kernels import prepare_kernels  # noqa: E402

WORLDS = [("exp1", 80), ("exp2", 40), ("exp3", 120), ("exp3", 96), ("exp3", 80), ("exp3", 64)]

print(f"himit_torch from {Path(himit_torch.__file__).parent}", flush=True)
prepare_kernels()
sums = []
for repeat in range(args.repeats):
    parts, total = [], 0.0
    for name, size in WORLDS:
        config = EXPERIMENTS[name]
        short = dataclasses.replace(config, steps=config.window, checkpoint_every=config.window)
        with tempfile.TemporaryDirectory() as run_dir:
            start = time.perf_counter()
            run_world(short, size, Path(run_dir), resume=False, progress=False)
            seconds = time.perf_counter() - start
        parts.append(f"{name}/{size} {seconds:.2f}")
        total += seconds
    sums.append(total)
    print(f"repeat {repeat}: {total:.2f} s ({', '.join(parts)})", flush=True)
print(f"median of {len(sums)}: {statistics.median(sums):.2f} s")
