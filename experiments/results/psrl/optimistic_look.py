"""One look at the imitator under an optimistic prior (results.md, "Experiment 2 with an
optimistic prior"): exp2's world, seed 0, near-greedy (ε = 0.01), concentration 1, initial value
0, the mean-model imitator beside options-only in one batch, 30k steps. Prints goals, V(start),
how many states each run has visited, and the imitator's most visited states: their V, whether
the mentor term wins there, and the Q and tries of their options.

Usage: python experiments/results/psrl/optimistic_look.py [steps]"""

import sys
from dataclasses import replace

import torch

from himit_torch import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.runs.config import EXPERIMENTS


def main(steps: int = 30_000) -> None:
    cfg = EXPERIMENTS["exp2"]
    config = replace(cfg.learner, concentration=1.0, initial_value=0.0, eps_start=0.01)
    world = cfg.world(40)
    mentor = mentor_policy(
        world, mentor_options(world, corners=cfg.corner_options), cfg.mentor_preference
    )
    demos = record_demonstrations(world, mentor, cfg.mentor_episodes, seed=0)
    options = learner_options(world, corners=cfg.corner_options)
    learner = Learner(world, options, ["imitation", "options"], [0, 0], config=config)
    learner.add_demonstrations(demos, runs=[0])
    learner.run(steps)
    values = learner.views.state_values()
    visited = (learner.views.visit_counts() > 0).sum(1).tolist()
    print(f"after {learner.views.t} steps (imitation, options):")
    print(
        f"  goals {learner.views.goals.tolist()}, V(start) {values[:, world.start_state].tolist()}"
    )
    print(f"  states visited {visited} of {world.num_states}")
    print("  the imitator's most visited states:")
    visits = learner.views.visit_counts()[0]
    for state in visits.argsort(descending=True)[:6].tolist():
        runs, states = torch.tensor([[0]]), torch.tensor([[state]])
        _, q, usable, _, _, tries = learner.cache.own_values(runs, states)
        _, _, mentor_won = learner.cache.state_backup(runs, states)
        tried = [
            f"Q {float(qq):.3f} ×{int(n)}"
            for qq, n, u in zip(q[0, 0], tries[0, 0], usable[0, 0])
            if u and n > 0
        ]
        untried = int((usable[0, 0] & (tries[0, 0] == 0)).sum())
        print(
            f"    {state}: {int(visits[state])} visits, V {float(values[0, state]):.3f}, "
            f"mentor term wins: {bool(mentor_won)}; tried {tried}; {untried} untried at Q = 0"
        )


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
