"""Issue 11, item 4: imitator mechanisms against the non-imitators, many seeds, one world batch
per call. Writes one JSON per (experiment, variant, world size) with every run's window curve,
first goal, total goals and (imitators) the mentor-term diagnostics at the end.

    PYTHONPATH=$PWD python experiments/mechanism/run_mechanism.py --exp exp1 --variant baselines \
        --seeds 20 --out experiments/results/mechanism/raw
"""

from __future__ import annotations

import argparse
import json
import subprocess
import time
from dataclasses import asdict, replace
from pathlib import Path

from himit_torch import (
    Learner,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)
from himit_torch.mentor.diagnostics import mentor_margin_summary
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import optimal_reference

#: variant → (agents, LearnerConfig changes from the experiment's own learner settings)
VARIANTS = {
    "baselines": (("options", "primitives"), {}),
    "imitation": (("imitation",), {}),
    "confident": (("imitation_confident",), {}),
    "match": (("imitation",), {"mentor_choice": "match"}),
    "override5": (("imitation",), {"mentor_override_after": 5}),
    "override20": (("imitation",), {"mentor_override_after": 20}),
    "override100": (("imitation",), {"mentor_override_after": 100}),
    "fade5": (("imitation",), {"mentor_fade": 5.0}),
    "fade20": (("imitation",), {"mentor_fade": 20.0}),
    "fade100": (("imitation",), {"mentor_fade": 100.0}),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--exp", required=True, choices=sorted(EXPERIMENTS))
    ap.add_argument("--variant", required=True, choices=sorted(VARIANTS))
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--steps", type=int, default=None, help="default: the experiment's")
    ap.add_argument("--sizes", type=int, nargs="*", default=None)
    ap.add_argument("--engine", default="numba")
    ap.add_argument("--out", default="experiments/results/mechanism/raw")
    args = ap.parse_args()
    exp = EXPERIMENTS[args.exp]
    agents_v, changes = VARIANTS[args.variant]
    config = replace(exp.learner, **changes)
    steps = args.steps or exp.steps
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    dirty = bool(
        subprocess.run(
            ["git", "status", "--porcelain", "himit_torch"], capture_output=True, text=True
        ).stdout.strip()
    )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for size in args.sizes or exp.sizes:
        world = exp.world(size)
        options = learner_options(world, corners=exp.corner_options)
        mentor = mentor_policy(
            world, mentor_options(world, corners=exp.corner_options), exp.mentor_preference
        )
        agents = [a for a in agents_v for _ in seeds]
        run_seeds = [s for _ in agents_v for s in seeds]
        learner = Learner(world, options, agents, run_seeds, config=config, engine=args.engine)
        if any(a.startswith("imitation") for a in agents_v):
            for s in seeds:
                demos = record_demonstrations(world, mentor, exp.mentor_episodes, seed=s)
                learner.add_demonstrations(
                    demos, runs=[b for b, rs in enumerate(run_seeds) if rs == s]
                )
        start = time.perf_counter()
        learner.run(steps)
        wall = time.perf_counter() - start
        optimal_steps, _, _ = optimal_reference(world, config.window)
        record = {
            "experiment": args.exp,
            "variant": args.variant,
            "size": size,
            "steps": steps,
            "window": config.window,
            "agents": agents,
            "seeds": run_seeds,
            "optimal_steps": optimal_steps,
            "config": asdict(config),
            "engine": learner.engine.name,
            "commit": commit,
            "dirty_tree": dirty,
            "wall_seconds": wall,
            "goals": learner.views.goals.tolist(),
            "first_goal_step": learner.views.first_goal_step.tolist(),
            "curve": learner.metrics.curve().T.tolist(),
            "mentor_term_wins": [w.tolist() for w in learner.metrics.mentor_term_wins],
            "value_start": learner.views.state_values()[:, world.start_state].tolist(),
            "diagnostics": mentor_margin_summary(learner),
        }
        path = out / f"{args.exp}_{args.variant}_{size}.json"
        path.write_text(json.dumps(record))
        print(
            f"{path}: {wall:.0f} s, mean goals {sum(record['goals']) / len(agents):.1f}", flush=True
        )


if __name__ == "__main__":
    main()
