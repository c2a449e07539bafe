"""What each world of ``himit run paper`` costs before its learning starts: the first steps of
``run_world`` (its private helpers, in its order), in one process, for the six worlds (exp1
80×80, exp2 40×40, exp3 120×120, 96×96, 80×80 and 64×64, 5 seeds, the committed settings).

That is the mentor's options, exact policy, demonstrations and exact goal rate; the learner's
options and the learner; the optimum's evaluation; the exact option models of the greedy
references. (Not the logger, checkpoints or the world's figure: what those cost depends on the
learning.) The kernels are loaded first, untimed. Prints each world's seconds and their sum per
repeat, and the median sum.

    python benchmarks/bench_setup.py [--repeats 3]

To compare with another checkout, run this script with ``PYTHONPATH`` set to it (the script
imports ``himit_torch`` from ``PYTHONPATH`` first), alternating the two.
"""

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

if not os.environ.get("PYTHONPATH"):  # (else the checkout PYTHONPATH names)
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--repeats", type=int, default=3)
args = parser.parse_args()

import himit_torch  # noqa: E402
from himit_torch.runs import experiment  # noqa: E402
from himit_torch.runs.config import EXPERIMENTS  # noqa: E402
from himit_torch.runs.kernels import prepare_kernels  # noqa: E402

WORLDS = [("exp1", 80), ("exp2", 40), ("exp3", 120), ("exp3", 96), ("exp3", 80), ("exp3", 64)]


def set_up(name: str, size: int) -> float:
    """Seconds of ``run_world``'s steps before the learning, for one world."""
    config = EXPERIMENTS[name]
    seeds, agents, run_seeds = experiment.batch_runs(config.agents, config.first_seed, config.seeds)
    start = time.perf_counter()
    batch = experiment._WorldBatch(
        config, size, Path("unused"), config.world(size), seeds, agents, run_seeds
    )
    mentoring = experiment._mentoring(batch)
    _, options = experiment._learner(batch, mentoring)
    _, _, optimal = experiment.optimal_reference(batch.world, config.window)
    experiment._greedy_tracker(batch, options, mentoring.mentor_eval, optimal)
    return time.perf_counter() - start


print(f"himit_torch from {Path(himit_torch.__file__).parent}", flush=True)
prepare_kernels()
sums = []
for repeat in range(args.repeats):
    parts, total = [], 0.0
    for name, size in WORLDS:
        seconds = set_up(name, size)
        parts.append(f"{name}/{size} {seconds:.2f}")
        total += seconds
    sums.append(total)
    print(f"repeat {repeat}: {total:.2f} s ({', '.join(parts)})", flush=True)
print(f"median of {len(sums)}: {statistics.median(sums):.2f} s")
