"""Experiment 2 — learning with insufficient options (the paper's Fig. 4).

40×40 world, 10×10 rooms; primitives and doorway options only — no option ends at the goal, so
the last room must be crossed with primitives. Paper: the imitator reaches the goal quickly and
reliably; the non-imitating agent failed to find it in 4 of 5 runs.

    python experiments/exp2_insufficient_options.py [--steps N] [--seeds K] [--preset paper|recommended] [--tie-break random|first] [--logdir runs]

(the same as ``himit run exp2``). Settings: ``himit_torch.runs.config.EXPERIMENTS["exp2"]``.
"""

import argparse
from dataclasses import replace

from himit_torch.learner.config import TIE_BREAKS
from himit_torch.learner.presets import PRESETS
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import run_experiment

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--steps", type=int, default=EXPERIMENTS["exp2"].steps)
parser.add_argument("--seeds", type=int, default=EXPERIMENTS["exp2"].seeds)
parser.add_argument("--preset", choices=sorted(PRESETS), help="paper or recommended")
parser.add_argument("--tie-break", choices=TIE_BREAKS, default="random", help="greedy ties")
parser.add_argument("--logdir", default="runs")
parser.add_argument("--resume", action="store_true")
parser.add_argument("--force", action="store_true")
args = parser.parse_args()

config = replace(EXPERIMENTS["exp2"], steps=args.steps, seeds=args.seeds)
if args.preset:
    config = config.with_preset(args.preset)
config = replace(config, learner=replace(config.learner, tie_break=args.tie_break))
run_experiment(config, f"{args.logdir}/exp2", resume=args.resume, force=args.force)
print(open(f"{args.logdir}/exp2/results.md").read())
