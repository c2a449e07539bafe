"""16 mixed runs on both cores against one run, in one process, alternating: the scaling check.

Builds, for each repeat, a fresh one-run learner (an imitator) and a fresh 16-run learner
(imitation / options / primitives in turn, seeds 0…15) on the 40×40 world with 10 rooms and the
experiments' planning (``plan_every = 4``, ``sweep_rounds = 1``), runs each 20,000 untimed
steps (past the first goals), then times ``learner.run(--steps)``. Prints the aggregate steps/s
of each per repeat, their ratio, and the medians: the scaling is the median of the per-repeat
ratios (the two measured side by side, so a change in the machine's load moves both).

``--baseline same-runs`` times, in place of the one imitator, each of the batch's 16 runs
alone (a fresh one-run learner each, the same agent, seed and steps, one after another on one
thread) and gives their steps over the sum of their times: the same work as the batch's, so
the ratio is the cores' scaling alone, not also the mix's cost against an imitator's, and the
one-run side is timed over as long as the batch's (one imitator's 100,000 steps take ≈ 0.15 s,
a sixteenth of it: a hiccup of the machine moves it most).

    python benchmarks/bench_scaling.py [--reps 5] [--steps 100000] [--batch 16]
        [--baseline imitator|same-runs]

On a virtual machine, the hypervisor's steal time (``top``: ``st``) takes from the second core
what it gives the first: read the ratio together with it.
"""

import argparse
import statistics

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--reps", type=int, default=5)
parser.add_argument("--steps", type=int, default=100_000, help="timed steps per run")
parser.add_argument("--batch", type=int, default=16)
parser.add_argument(
    "--baseline",
    choices=["imitator", "same-runs"],
    default="imitator",
    help="the one-run side: one imitator (default), or each of the batch's runs alone",
)
args = parser.parse_args()

from mixed_batch import timed  # noqa: E402


def rate(batch: int, steps: int) -> float:
    """Aggregate steps/s of ``batch`` runs over ``steps`` timed steps each: one learner of them
    all, or (``batch = 1``) the baseline."""
    if batch > 1:
        return batch * steps / timed(list(range(batch)), steps)
    if args.baseline == "imitator":
        return steps / timed([0], steps)
    return args.batch * steps / sum(timed([b], steps) for b in range(args.batch))


rate(1, 1000), rate(args.batch, 1000)  # (kernels loaded, pool started)
one, many = [], []
alone = "B=1" if args.baseline == "imitator" else f"{args.batch} runs alone"
for rep in range(args.reps):
    if rep % 2 == 0:  # (alternating which goes first)
        single = rate(1, args.steps)
        batch = rate(args.batch, args.steps)
    else:
        batch = rate(args.batch, args.steps)
        single = rate(1, args.steps)
    one.append(single)
    many.append(batch)
    print(f"rep {rep}: {alone} {one[-1]:,.0f}  B={args.batch} {many[-1]:,.0f} steps/s  "
          f"ratio {many[-1] / one[-1]:.2f}", flush=True)  # fmt: skip
ratios = [b / a for a, b in zip(one, many)]
print(f"MEDIAN of {args.reps}: {alone} {statistics.median(one):,.0f} steps/s, B={args.batch} "
      f"{statistics.median(many):,.0f} steps/s; scaling (median of the ratios) "
      f"{statistics.median(ratios):.2f} (range {min(ratios):.2f}-{max(ratios):.2f})")  # fmt: skip
