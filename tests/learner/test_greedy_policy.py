"""``Learner.greedy_policy``: the frozen greedy policy is what ``choose_rows`` picks at ε = 0
(every tied option, each equally often, or the first one), and its exact evaluation equals
rolled-out episodes of it."""

import pytest
import torch

from himit_torch.exact.greedy_evaluation import OptionPolicy, PolicyEvaluation, PolicyEvaluator
from himit_torch.learner.choice import choose_rows
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from tests.exact.test_greedy_evaluation import assert_matches_rollouts

AGENTS = ["imitation", "options", "primitives"]
FIELDS = ("value_start", "goal_probability", "steps_per_episode", "goals_per_window", "reach_share")


def trained(world, tie_break: str, mentor_choice: str = "greedy", steps: int = 3000) -> Learner:
    demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 5, seed=0)
    config = LearnerConfig(tie_break=tie_break, mentor_choice=mentor_choice, window=1000)
    learner = Learner(
        world, learner_options(world), AGENTS, [0, 1, 2], config=config, demonstrations=demos
    )
    learner.run(steps)
    return learner


@pytest.mark.parametrize(
    "tie_break, mentor_choice", [("random", "greedy"), ("first", "greedy"), ("random", "match")]
)
def test_the_frozen_policy_is_what_choose_rows_picks_at_epsilon_zero(
    world12, tie_break, mentor_choice
):
    learner = trained(world12, tie_break, mentor_choice)
    policy = learner.greedy_policy()
    S, J = policy.option.shape
    live = (~learner.terminal[:S]).nonzero()[:, 0]
    states = live[learner.rows.state_rows[live, 0] < learner.num_rows]  # states with options
    picked = [set() for _ in range(learner.batch)]
    for b in range(learner.batch):
        runs = torch.full_like(states, b)
        seen = [set() for _ in states.tolist()]
        for i in range(J):  # u spaced 1/J apart: every one of ≤ J candidates is picked once
            u = torch.tensor([[0.5, (i + 0.5) / J]], dtype=torch.float64).expand(states.numel(), 2)
            rows = choose_rows(
                learner.cache,
                runs,
                states,
                u,
                torch.zeros(states.numel(), dtype=torch.float64),
                mentor_choice,
                tie_break,
            )
            for k, o in enumerate(learner.rows.row_option[rows].tolist()):
                seen[k].add(o)
        for k, s in enumerate(states.tolist()):
            p = policy.probability[b, s]
            support = set(policy.option[s][p > 0].tolist())
            assert support == seen[k], (b, s)
            assert torch.allclose(p[p > 0], torch.full_like(p[p > 0], 1 / len(support)))
            if tie_break == "first":
                assert len(support) == 1
            picked[b] |= {len(support)}
    if tie_break == "random":  # ties (untried states: every enabled option) do occur
        assert any(max(sizes) > 1 for sizes in picked)
    terminal = learner.terminal[:S].nonzero()[:, 0]
    assert bool((policy.probability[:, terminal] == 0).all())


def test_a_trained_learners_greedy_policies_equal_their_rollouts(world12):
    """Stochastic (random ties) frozen policies after 10 000 steps on 12×12, of the runs whose
    episodes are short enough to roll out (the imitator's and the primitives-only run's; the
    options-only run has not learned the way yet: ≈ 10⁵ steps an episode): exact steps per
    episode, V^π(start) and P(goal) within the 99.9 % t-intervals of 3000 episodes."""
    learner = trained(world12, "random", steps=10_000)
    policy = learner.greedy_policy()
    result = PolicyEvaluator(world12, learner.options, 1000).evaluate(policy)
    short = (result.steps_per_episode < 500).nonzero()[:, 0]
    assert 0 in short.tolist()  # the imitator
    assert bool(((policy.probability[short] > 0).sum(-1) > 1).any())  # ties: stochastic
    sub = OptionPolicy(policy.option, policy.probability[short])
    picked = PolicyEvaluation(
        **{f: getattr(result, f)[short] for f in FIELDS}, window=result.window
    )
    assert_matches_rollouts(world12, learner.options, sub, picked, n=3000, seed=3)
