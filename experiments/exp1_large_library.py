"""Experiment 1 — hierarchical imitation with a large library of options (the paper's Fig. 3).

80×80 world, 10×10 rooms; the learner has primitives, doorway options *and* 8 corner options per
room (extraneous, except the one that ends at the goal). Agents: imitation (plain and
confidence-tested mentor term), options only, primitives only; 5 seeds each, one batch.

    python experiments/exp1_large_library.py [--steps N] [--seeds K] [--preset paper|recommended] [--tie-break random|first] [--logdir runs] [--resume]

(the same as ``himit run exp1``). Settings: ``himit_torch.runs.config.EXPERIMENTS["exp1"]``.
"""

import argparse
from dataclasses import replace

from himit_torch.learner.config import TIE_BREAKS
from himit_torch.learner.presets import PRESETS
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import run_experiment

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--steps", type=int, default=EXPERIMENTS["exp1"].steps)
parser.add_argument("--seeds", type=int, default=EXPERIMENTS["exp1"].seeds)
parser.add_argument("--preset", choices=sorted(PRESETS), help="paper or recommended")
parser.add_argument("--tie-break", choices=TIE_BREAKS, default="random", help="greedy ties")
parser.add_argument("--logdir", default="runs")
parser.add_argument("--resume", action="store_true")
parser.add_argument("--force", action="store_true")
args = parser.parse_args()

config = replace(EXPERIMENTS["exp1"], steps=args.steps, seeds=args.seeds)
if args.preset:
    config = config.with_preset(args.preset)
config = replace(config, learner=replace(config.learner, tie_break=args.tie_break))
run_experiment(config, f"{args.logdir}/exp1", resume=args.resume, force=args.force)
print(open(f"{args.logdir}/exp1/results.md").read())
