"""The greedy path of a world figure (``learner.views.greedy_trajectory``): its steps in Python numbers
against the same steps as ``option_step`` on the world's own ``step`` (the path a world without a
dynamics table takes, and every path took before), on the paper's largest world.

Trains an imitator and an options-only run on 120×120 (12×12 rooms) for ``--train`` steps, then
draws each run's path for two seeds both ways, up to the world figure's ``20·N²/room`` steps
(28,800), checks that both ways give the same states, and prints each path's length and
seconds.

    python benchmarks/bench_greedy_path.py [--train 20000]
"""

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--train", type=int, default=20_000, help="steps each run learns first")
args = parser.parse_args()

import torch  # noqa: E402

from himit_torch import (  # noqa: E402
    Learner,
    MultiRooms,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)

N, ROOMS = 120, 12
world = MultiRooms(N, ROOMS)
demos = record_demonstrations(world, mentor_policy(world, mentor_options(world, False)), 20, seed=0)
learner = Learner(
    world, learner_options(world), ["imitation", "options"], [0, 1], demonstrations=demos
)
learner.run(args.train)
max_steps = 20 * N * N // (N // ROOMS)
in_numbers = learner.tables
by_tensors = dataclasses.replace(in_numbers, dynamics=None)  # (option_step, world.step)

print(f"{N}×{N}, trained {args.train:,} steps, paths of up to {max_steps:,} steps")
print("run seed   steps   numbers (s)   option_step (s)   ratio")
for run in range(learner.batch):
    for seed in range(2):
        seconds = []
        paths = []
        for tables in (in_numbers, by_tensors):
            learner.tables = tables
            began = time.perf_counter()
            paths.append(learner.views.greedy_trajectory(run, max_steps, seed))
            seconds.append(time.perf_counter() - began)
        learner.tables = in_numbers
        if not torch.equal(*paths):
            sys.exit(f"run {run} seed {seed}: the two ways drew different paths")
        print(
            f"{run:3d} {seed:4d} {len(paths[0]) - 1:7,d} {seconds[0]:13.3f} {seconds[1]:17.3f} "
            f"{seconds[1] / seconds[0]:7.1f}×"
        )
