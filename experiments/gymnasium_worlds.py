"""Hierarchical imitation on Gymnasium's tabular environments: Taxi, CliffWalking, FrozenLake 8×8.

For each task an optimal mentor (value iteration on the true model) is watched through its
states only; imitation (options + mentor term), options only and primitives only learn over 10
seeds each, in one batch per task. Results: mean ± 95 % CI over seeds, figures, TensorBoard logs.

    python experiments/gymnasium_worlds.py [--seeds K] [--steps N] [--tasks taxi,…] [--preset paper|recommended] [--tie-break random|first] [--logdir runs]

(the same as ``himit run gymnasium``; about 7 minutes on a 2-core CPU). Settings:
``himit_torch.runs.gymnasium``; committed results: ``experiments/results/<preset>-<ties>/gymnasium/``.
"""

import argparse
from dataclasses import replace

import torch

from himit_torch.learner.config import TIE_BREAKS
from himit_torch.learner.presets import PRESETS
from himit_torch.runs.gymnasium import TASKS, GymExperimentConfig, run_gym_experiment

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--seeds", type=int, default=GymExperimentConfig.seeds)
parser.add_argument(
    "--agents", nargs="+", default=list(GymExperimentConfig.agents), help="agents of AGENTS"
)
parser.add_argument("--steps", type=int, default=None, help="steps per run (default: per task)")
parser.add_argument(
    "--tasks",
    # the three above (MiniGrid's tasks, also in TASKS, are the benchmark's own part)
    default=",".join(GymExperimentConfig.tasks),
    help=f"some of {','.join(TASKS)} (default {','.join(GymExperimentConfig.tasks)})",
)
parser.add_argument(
    "--window",
    type=int,
    default=GymExperimentConfig.window,
    help="steps per window of goals and greedy evaluation",
)
parser.add_argument(
    "--preset", choices=sorted(PRESETS), help="a preset of himit_torch.learner.presets"
)
parser.add_argument("--tie-break", choices=TIE_BREAKS, default="random", help="greedy ties")
parser.add_argument("--logdir", default="runs")
parser.add_argument("--quick", action="store_true", help="tiny budget (smoke test)")
parser.add_argument("--force", action="store_true")
args = parser.parse_args()

torch.set_num_threads(1)  # tiny tensors: one thread per process is fastest
config = GymExperimentConfig(
    seeds=args.seeds,
    steps=args.steps,
    tasks=tuple(args.tasks.split(",")),
    window=args.window,
    agents=tuple(args.agents),
)
if args.quick:
    config = config.quick()
if args.preset:
    config = config.with_preset(args.preset)
config = replace(config, learner=replace(config.learner, tie_break=args.tie_break))
run_gym_experiment(config, f"{args.logdir}/{config.name}", force=args.force)
print(open(f"{args.logdir}/{config.name}/results.md").read())
