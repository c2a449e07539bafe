"""The TensorBoard maps of several worlds in one process (``MapRenderer``): the figures the
process shares, set to each world, against figures built for each world (the shared ones
dropped first, as every renderer built its own before), alternating, in one process.

For each of the paper's six worlds, in the order the reproduction's two processes meet them
(exp1 80×80, exp2 40×40, exp3 120×120, 96×96, 80×80, 64×64), draws three values, visits and
greedy-option maps of random data; prints each way's seconds per world and in all, per repeat,
and the medians of the totals. (The first world of a process builds the figures either way.)

    python benchmarks/bench_maps.py [--repeats 3]
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--repeats", type=int, default=3)
args = parser.parse_args()

import numpy as np  # noqa: E402

from himit_torch import MultiRooms, learner_options  # noqa: E402
from himit_torch.viz import plotting  # noqa: E402

WORLDS = [(80, 10, True), (40, 10, False), (120, 15, True), (96, 12, True), (80, 10, True),
          (64, 8, True)]  # fmt: skip
worlds = [(MultiRooms(N, rooms), corners) for N, rooms, corners in WORLDS]
options = [learner_options(w, corners=corners) for w, corners in worlds]
rng = np.random.default_rng(0)


def draw_all(shared: bool) -> list[float]:
    """Seconds of each world's nine maps; ``shared=False``: no figures to share at each world."""
    seconds = []
    for (world, _), opts in zip(worlds, options):
        if not shared:
            plotting._MAP_FIGURES.clear()
        renderer = plotting.MapRenderer(world, opts)
        S = world.num_states
        began = time.perf_counter()
        for k in range(3):
            visits = rng.integers(0, 100, S).astype(float)
            renderer.values(-rng.random(S), f"values V(s) after 300,000 steps\nimitation {k}")
            renderer.visits(visits, visits > 50, f"visits up to 300,000 steps\nimitation {k}")
            renderer.policy(rng.integers(-1, len(opts.names), S), f"greedy option\nimitation {k}")
        seconds.append(time.perf_counter() - began)
    return seconds


draw_all(True)  # (fonts and matplotlib's caches, either way's first use)
totals: dict[bool, list[float]] = {True: [], False: []}
for rep in range(args.repeats):
    for shared in (True, False) if rep % 2 == 0 else (False, True):
        seconds = draw_all(shared)
        totals[shared].append(sum(seconds))
        print(f"rep {rep} {'shared' if shared else 'built per world':15s} "
              + " ".join(f"{s:.2f}" for s in seconds) + f"  total {sum(seconds):.2f} s")  # fmt: skip
print(f"MEDIAN of {args.repeats}: shared {statistics.median(totals[True]):.2f} s, built per "
      f"world {statistics.median(totals[False]):.2f} s")  # fmt: skip
