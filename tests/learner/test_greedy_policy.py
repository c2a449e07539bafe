"""``learner.views.greedy_policy``: the frozen greedy policy is what ``choose_rows`` picks at ε = 0
(every tied option, each equally often, or the first one), its rules for untried states
(``"uniform"``, ``"stuck"``), and its exact evaluation equals rolled-out episodes of it."""

import math

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
    policy = learner.views.greedy_policy()
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
    policy = learner.views.greedy_policy()
    result = PolicyEvaluator(world12, learner.options, 1000).evaluate(policy)
    short = (result.steps_per_episode < 500).nonzero()[:, 0]
    assert 0 in short.tolist()  # the imitator
    assert bool(((policy.probability[short] > 0).sum(-1) > 1).any())  # ties: stochastic
    sub = OptionPolicy(policy.option, policy.probability[short])
    picked = PolicyEvaluation(
        **{f: getattr(result, f)[short] for f in FIELDS}, window=result.window
    )
    assert_matches_rollouts(world12, learner.options, sub, picked, n=3000, seed=3)


# ------------------------------------------------------------------------- the untried rules
def learner8(world8, steps: int, tie_break: str = "random") -> Learner:
    """Every kind of run on 8×8 after ``steps`` steps (the bco run clones where its own moves
    explain the mentor's): few steps leave many states untried."""
    demos = record_demonstrations(world8, mentor_policy(world8, mentor_options(world8)), 3, seed=0)
    config = LearnerConfig(tie_break=tie_break, window=100)
    learner = Learner(
        world8,
        learner_options(world8),
        AGENTS + ["bco"],
        [0, 0, 0, 0],
        config=config,
        demonstrations=demos,
    )
    learner.run(steps)
    return learner


@pytest.mark.parametrize("tie_break", ["random", "first"])
def test_the_untried_rules_by_hand(world8, tie_break):
    """After 300 steps on 8×8 each run has live states where it has tried none of its enabled
    options. There the ``"uniform"`` rule (the default) takes each enabled option with
    probability 1/k (``tie_break="first"``: the first with probability 1), and ``"stuck"``
    gives the state no option: its row is 0 — exactly there, every other row the same bit for
    bit. A cloned action (planted at an untried state of the bco run) is a choice under both.
    An unknown rule is refused by name."""
    learner = learner8(world8, 300, tie_break)
    S, M, B = world8.num_states, learner.num_rows, learner.batch
    live = (~learner.terminal[:S]).nonzero()[:, 0]
    rows = learner.rows.state_rows[live]  # [L, J], padded with M
    enabled = learner.rows.row_enabled[:, rows]  # [B, L, J]
    tried = (enabled & (learner.model.row_count[:, rows] > 0)).any(-1)  # [B, L]
    untried = ~tried & enabled.any(-1)
    assert bool(untried.all(0).any()) and bool(tried.any(1).all())  # both kinds, every run
    bco = 3
    k = int(untried[bco].nonzero()[0, 0])
    planted = int(learner.rows.primitive_rows[live[k]].lt(M).nonzero()[-1, 0])  # an available move
    learner.cloning.action[bco, live[k]] = planted
    cloned = torch.zeros_like(untried)
    cloned[bco, k] = True

    uniform = learner.views.greedy_policy()
    assert torch.equal(
        learner.views.greedy_policy(untried="uniform").probability, uniform.probability
    )
    stuck = learner.views.greedy_policy(untried="stuck")
    assert torch.equal(stuck.option, uniform.option)
    p_uniform, p_stuck = uniform.probability[:, live], stuck.probability[:, live]
    no_choice = untried & ~cloned
    for b in range(B):
        for i in no_choice[b].nonzero()[:, 0].tolist():
            on = enabled[b, i].double()
            if tie_break == "first":
                on = (on.cumsum(0) == 1) & (on > 0)
            assert torch.equal(p_uniform[b, i], on.double() / on.sum()), (b, i)
    assert bool((p_stuck[no_choice] == 0).all())
    assert torch.equal(p_stuck[~no_choice], p_uniform[~no_choice])
    assert bool(((p_stuck.sum(-1) - 1).abs() < 1e-12)[~no_choice & enabled.any(-1)].all())
    clone_option = int(learner.rows.row_option[learner.rows.primitive_rows[live[k], planted]])
    j = uniform.option[live[k]].tolist().index(clone_option)
    assert float(p_stuck[bco, k, j]) == float(p_uniform[bco, k, j]) == 1.0
    with pytest.raises(ValueError, match=r"untried='never'.*\('uniform', 'stuck'\)"):
        learner.views.greedy_policy(untried="never")


def test_both_untried_rules_equal_rollouts_of_the_same_frozen_policy(world8):
    """The exact evaluation of the frozen greedy policies after 1000 steps on 8×8 against 3000
    rolled-out episodes of the same policies, under each rule (random ties: stochastic
    policies), of the runs whose episodes are short enough to roll out (the options-only run
    has not learned the way yet). Under ``"uniform"`` every episode ends: steps per episode,
    V^π(start) and P(goal) are compared. Under ``"stuck"`` the imitator can reach a state it has
    not tried, where its episode stops for good: steps per episode ``inf`` (seen in the
    rollouts: some episode gets stuck), goal rate 0, and P(goal) (the episodes that end at the
    goal before getting stuck) and V^π(start) (no reward once stuck) against the rollouts."""
    learner = learner8(world8, 1000)
    runs = [0, 2, 3]  # imitation, primitives, bco
    evaluator = PolicyEvaluator(world8, learner.options, 100)
    results = {}
    for rule in ("uniform", "stuck"):
        policy = learner.views.greedy_policy(runs, untried=rule)
        result = evaluator.evaluate(policy)
        results[rule] = result
        assert_matches_rollouts(world8, learner.options, policy, result, n=3000, seed=5)
    assert bool((results["uniform"].steps_per_episode < 100).all())
    stuck = results["stuck"]
    assert math.isinf(float(stuck.steps_per_episode[0])) and float(stuck.goals_per_window[0]) == 0
    assert 0.1 < float(stuck.goal_probability[0]) < 0.9  # some episodes end, some get stuck
    # no untried state on its way: the same policy where it goes, the same numbers
    same = [i for i in range(len(runs)) if math.isfinite(float(stuck.steps_per_episode[i]))]
    assert same
    for f in FIELDS:
        assert torch.equal(getattr(stuck, f)[same], getattr(results["uniform"], f)[same]), f
