"""BCO's refit, side by side: ``ClonedPolicy.refit`` compiled (the CPU's way since it was
compiled, :mod:`himit_torch.learner.cloned_refit`) against the torch functions it replaced
(``ClonedPolicy.actions_in_torch``: every cloning run in one call of ``inverse_model``,
``relabel`` and ``clone_policy``, the refit as it was), in one process on the same models.

    python benchmarks/bench_bco_refit.py [--size 40] [--runs 20] [--steps 20000] [--repeats 15]

``--runs`` ``bco`` runs on a ``--size`` world of exp2's kind (10×10 cells a room) after
``--steps`` steps, torch on one thread as every ``himit`` process runs it; medians of
``--repeats``, the two alternating. Both give the same cloned actions (checked here, and in
tests/learner/test_cloned_refit.py).
"""

import argparse
import statistics
import time

import torch

import himit_torch as ht

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--size", type=int, default=40)
parser.add_argument("--runs", type=int, default=20)
parser.add_argument("--steps", type=int, default=20_000)
parser.add_argument("--repeats", type=int, default=15)
args = parser.parse_args()
torch.set_num_threads(1)

world = ht.MultiRooms(args.size, 10)
demos = ht.record_demonstrations(world, ht.mentor_policy(world, ht.mentor_options(world)), 20)
config = ht.LearnerConfig(window=5000, bco_every=10**9)
learner = ht.Learner(world, ht.learner_options(world), ["bco"] * args.runs,
                     list(range(args.runs)), config=config, demonstrations=demos)  # fmt: skip
learner.run(args.steps)
cloning, S = learner.cloning, world.num_states
runs = cloning.runs()


def in_torch() -> None:
    cloning.action[runs, :S] = cloning.actions_in_torch(runs, learner.model, learner.mentor)


def timed(f) -> float:
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


in_torch()
reference = cloning.action.clone()
learner.refit_cloned_policy()  # (the first call loads or compiles the kernel)
assert torch.equal(cloning.action, reference)
compiled, looped = [], []
for _ in range(args.repeats):
    compiled.append(timed(learner.refit_cloned_policy))
    looped.append(timed(in_torch))
c, t = statistics.median(compiled), statistics.median(looped)
edges = int(learner.model.num_edges.sum())
print(f"refit of {args.runs} runs ({edges} own edges, {args.size}×{args.size}): compiled "
      f"{1000 * c:.2f} ms, torch {1000 * t:.2f} ms (torch/compiled {t / c:.1f}×; medians of "
      f"{args.repeats})")  # fmt: skip
