"""The puzzle box — Whiten et al.'s (2006) keyway-fruit task — run on the model: (a) speed,
imitation against options only and primitives only on a 4-skewer box; (b) copying the
organisation watched (skewer by skewer or step by step), but not the movements; (c) a fifth
skewer no demonstration showed, with the mentor's 4-skewer episodes mapped into the 5-skewer box
(the paper's footnote 2). 20 seeds per condition; results beside the study's three findings.

    python experiments/puzzle_box.py [--seeds K] [--steps N] [--logdir runs] [--resume] [--quick]

(the same as ``himit run puzzlebox``). Settings: ``himit_torch.runs.puzzle_box``; the world:
``himit_torch.worlds.puzzle_box``; committed results: ``experiments/results/puzzlebox/``.
"""

import argparse
from dataclasses import replace

import torch

from himit_torch.runs.puzzle_box import PuzzleBoxConfig, run_puzzle_box

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--seeds", type=int, default=PuzzleBoxConfig.seeds)
parser.add_argument("--steps", type=int, default=PuzzleBoxConfig.steps, help="steps of (a), (b)")
parser.add_argument("--transfer-steps", type=int, default=PuzzleBoxConfig.transfer_steps)
parser.add_argument("--logdir", default="runs")
parser.add_argument("--quick", action="store_true", help="tiny budget on small boxes (smoke test)")
parser.add_argument("--resume", action="store_true")
parser.add_argument("--force", action="store_true")
args = parser.parse_args()

torch.set_num_threads(1)  # tiny tensors: one thread per process is fastest
config = PuzzleBoxConfig(seeds=args.seeds, steps=args.steps, transfer_steps=args.transfer_steps)
if args.quick:
    config = replace(config.quick(), seeds=min(args.seeds, 2))
run_dir = f"{args.logdir}/{config.name}"
run_puzzle_box(config, run_dir, resume=args.resume, force=args.force)
print(open(f"{run_dir}/results.md").read())
