"""Experiment 3 — scaling up (the paper's Fig. 5).

Worlds 64×64, 80×80, 96×96 and 120×120 with rooms of 8 cells (8×8 … 15×15 rooms), the large
option library of experiment 1; total goals in 130,000 steps as a percentage of what the optimal
policy reaches in the same steps. Paper: the benefit of imitation grows with the world's size.
Add ``--sizes 64 80 96 120 240`` to go beyond the paper.

    python experiments/exp3_scaling.py [--sizes 64 80 96 120] [--steps N] [--seeds K]

(the same as ``himit run exp3``). Settings: ``himit_torch.runs.config.EXPERIMENTS["exp3"]``.
"""

import argparse
from dataclasses import replace

from himit_torch.learner.config import TIE_BREAKS
from himit_torch.learner.presets import PRESETS
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import run_experiment

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--sizes", type=int, nargs="+", default=list(EXPERIMENTS["exp3"].sizes))
parser.add_argument("--steps", type=int, default=EXPERIMENTS["exp3"].steps)
parser.add_argument("--seeds", type=int, default=EXPERIMENTS["exp3"].seeds)
parser.add_argument("--preset", choices=sorted(PRESETS), help="paper or recommended")
parser.add_argument("--tie-break", choices=TIE_BREAKS, default="random", help="greedy ties")
parser.add_argument("--logdir", default="runs")
parser.add_argument("--resume", action="store_true")
parser.add_argument("--force", action="store_true")
args = parser.parse_args()

config = replace(EXPERIMENTS["exp3"], sizes=tuple(args.sizes), steps=args.steps, seeds=args.seeds)
if args.preset:
    config = config.with_preset(args.preset)
config = replace(config, learner=replace(config.learner, tie_break=args.tie_break))
run_experiment(config, f"{args.logdir}/exp3", resume=args.resume, force=args.force)
print(open(f"{args.logdir}/exp3/results.md").read())
