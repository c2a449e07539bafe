"""BCO's refit, side by side: ``ClonedPolicy.refit`` (every cloning run in one call of each
function) against the same three functions called run by run (the loop it replaced).

    python benchmarks/bench_bco_refit.py [--runs 20] [--steps 20000] [--repeats 15]

40×40 world, ``--runs`` ``bco`` runs after ``--steps`` steps; medians of ``--repeats``, the two
alternating. Both give the same cloned policies (checked here, and in tests/learner/test_bco.py).
"""

import argparse
import statistics
import time

import torch

import himit_torch as ht
from himit_torch.mentor.cloning import clone_policy, inverse_model, relabel

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--runs", type=int, default=20)
parser.add_argument("--steps", type=int, default=20_000)
parser.add_argument("--repeats", type=int, default=15)
args = parser.parse_args()
torch.set_num_threads(1)

world = ht.MultiRooms(40, 10)
demos = ht.record_demonstrations(world, ht.mentor_policy(world, ht.mentor_options(world)), 20)
config = ht.LearnerConfig(window=5000, bco_every=10**9)
learner = ht.Learner(world, ht.learner_options(world), ["bco"] * args.runs,
                     list(range(args.runs)), config=config, demonstrations=demos)  # fmt: skip
learner.run(args.steps)
model, mentor, cloning, S = learner.model, learner.mentor, learner.cloning, world.num_states


def run_by_run() -> torch.Tensor:
    out = torch.full((args.runs, S), -1, dtype=torch.int64)
    for b in range(args.runs):
        E, Em = int(model.num_edges[b]), int(mentor.num_edges[b])
        edge_row = model.edge_row[b, :E]
        act = cloning.row_action[edge_row]
        own = act >= 0
        inverse = inverse_model(learner.rows.row_state[edge_row][own], act[own],
                                model.edge_successor[b, :E][own], model.edge_count[b, :E][own],
                                config.bco_inverse_model)  # fmt: skip
        sources = mentor.edge_row[b, :Em]
        labels = relabel(inverse, sources, mentor.edge_successor[b, :Em])
        out[b] = clone_policy(sources, labels, mentor.edge_count[b, :Em], S, world.num_actions)
    return out


def timed(f) -> float:
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


learner.refit_cloned_policy()
assert torch.equal(cloning.action[:, :S], run_by_run())
batched, looped = [], []
for _ in range(args.repeats):
    batched.append(timed(learner.refit_cloned_policy))
    looped.append(timed(run_by_run))
b, lo = statistics.median(batched), statistics.median(looped)
print(f"refit of {args.runs} runs: batched {1000 * b:.1f} ms, run by run {1000 * lo:.1f} ms "
      f"(batched/run-by-run {b / lo:.2f}; medians of {args.repeats})")  # fmt: skip
