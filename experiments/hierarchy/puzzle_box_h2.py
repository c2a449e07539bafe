"""H2 of PROTOCOL.md: the puzzle box's study (``himit run puzzlebox``) without either setting,
with trial of untried own options where the mentor leads, and with trial and feasibility
testing; the study's settings otherwise (seeds 0–19, the paper's ε), its variants left out.

    python experiments/hierarchy/puzzle_box_h2.py [--logdir runs/hierarchy] [--seeds 20]

Each cell's record (``summary.json``, ``config.json``) is copied into
``experiments/results/hierarchy/puzzlebox_<cell>/``; ``analyse.py`` compares them.
"""

from __future__ import annotations

import argparse
import shutil
from dataclasses import replace
from pathlib import Path

from himit_torch.runs.puzzle_box import PuzzleBoxConfig, run_puzzle_box

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results" / "hierarchy"
#: The cells: name → the learner settings they change (PROTOCOL.md, amendment of 2026-11-26).
CELLS = {
    "off": {},
    "trial": {"mentor_trial": True},
    "trial_feasibility": {"mentor_trial": True, "mentor_feasibility": 3},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--logdir", default="runs/hierarchy")
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    for cell, settings in CELLS.items():
        base = PuzzleBoxConfig(seeds=args.seeds)
        config = replace(base, variants=(), learner=replace(base.learner, **settings))
        run_dir = Path(args.logdir) / f"puzzlebox_{cell}"
        run_puzzle_box(config, run_dir, force=True, progress=False)
        target = RESULTS / f"puzzlebox_{cell}"
        target.mkdir(parents=True, exist_ok=True)
        for name in ("summary.json", "config.json"):
            shutil.copy(run_dir / name, target / name)
        print(f"{cell}: {target}")


if __name__ == "__main__":
    main()
