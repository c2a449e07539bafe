"""Exact evaluation of frozen option policies: a hand-solved corridor, Monte-Carlo rollouts of
the same policies (on the corridor and on the paper's 40×40 world), the optimum, and policies
that never reach the goal."""

import math

import numpy as np
import pytest
import torch
from scipy import stats

from himit_torch.exact.greedy_evaluation import (
    OptionPolicy,
    PolicyEvaluator,
    evaluate_option_choice,
    optimal_policy_evaluation,
    optimal_value,
)
from himit_torch.exact.option_models import (
    option_durations,
    option_models,
    option_models_and_durations,
)
from himit_torch.exact.planning import optimal_baseline, smdp_value_iteration
from himit_torch.mentor.policy import mentor_policy
from himit_torch.options.builders import learner_options, mentor_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.multirooms import MultiRooms
from himit_torch.worlds.table_world import TableWorld
from himit_torch.worlds.tabular import DynamicsTable

LEFT, RIGHT = 0, 1
SLIP, GAMMA, STEP, GOAL = 0.2, 0.9, -1.0, 10.0
LEVEL = 0.999  # the Monte-Carlo intervals: 99.9 % Student-t intervals of the rollout means


def corridor() -> TableWorld:
    """1×4 corridor: states 0 1 2 3, start 0, goal 3 (terminal). ``LEFT``/``RIGHT`` move one
    cell with probability 0.8 and stay put with probability ``SLIP`` = 0.2 (a wall at the left
    end: LEFT at 0 stays). Reward −1 a step, +10 for the step into the goal; γ = 0.9."""
    S, A = 4, 2
    succ = torch.zeros(S, A, 2, dtype=torch.int64)
    rew = torch.full((S, A, 2), STEP, dtype=torch.float64)
    for s in range(S):
        succ[s, LEFT] = torch.tensor([max(s - 1, 0), s])
        succ[s, RIGHT] = torch.tensor([min(s + 1, 3), s])
        if s == 2:
            rew[s, RIGHT, 0] = GOAL
    cdf = torch.tensor([1 - SLIP, 1.0], dtype=torch.float64).expand(S, A, 2).contiguous()
    terminal = torch.tensor([False, False, False, True])
    start = torch.tensor([1.0, 0.0, 0.0, 0.0], dtype=torch.float64)
    return TableWorld(DynamicsTable(succ, cdf, rew), start, terminal, gamma=GAMMA)


def run_right(world: TableWorld) -> Options:
    """One extended option: RIGHT until the goal (β = 0 elsewhere), from 0, 1 and 2."""
    S = world.num_states
    return Options(
        initiation=~world.terminal_mask[None],
        termination=torch.zeros(1, S),
        policy=torch.full((1, S), RIGHT, dtype=torch.int8),
        names=("run right",),
        kinds=("custom",),
    )


def test_the_corridor_by_hand():
    """Always RIGHT. Each cell takes a geometric number of steps G with P(G = k) = q pᵏ⁻¹
    (q = 0.8, p = 0.2): E[G] = 1/q = 1.25, E[γ^G] = qγ/(1 − pγ) = 0.72/0.82. Three cells:

    * steps per episode E[T] = 3/q = 3.75; the goal is certain (P(goal) = 1, reach share 1);
      goals per window of 100 steps = 100/3.75 = 26.667 (episode after episode);
    * V(0) = E[−(1 − γ^(T−1))/(1 − γ) + 10 γ^(T−1)] with E[γ^(T−1)] = φ/γ, φ = (0.72/0.82)³
      = 0.676949: V(0) = −(1 − 0.752166)/0.1 + 7.521655 = 5.043310.

    The same with the extended option "run right" (one decision per episode: the multi-time
    model carries the whole trip)."""
    world = corridor()
    phi = (0.72 / 0.82) ** 3
    value = -(1 - phi / GAMMA) / (1 - GAMMA) + GOAL * phi / GAMMA
    assert value == pytest.approx(5.043310, abs=1e-6)
    for options, choice in (
        (primitive_options(world), torch.tensor([RIGHT, RIGHT, RIGHT, -1])),
        (run_right(world), torch.tensor([0, 0, 0, -1])),
    ):
        result = PolicyEvaluator(world, options, window=100).evaluate(
            OptionPolicy.deterministic(choice)
        )
        assert result.steps_per_episode.item() == pytest.approx(3.75, rel=1e-12)
        assert result.goals_per_window.item() == pytest.approx(100 / 3.75, rel=1e-12)
        assert result.goal_probability.item() == pytest.approx(1.0, rel=1e-12)
        assert result.reach_share.item() == 1.0
        assert result.value_start.item() == pytest.approx(value, rel=1e-12)


def test_a_policy_that_never_reaches_the_goal():
    """Always LEFT: the run stays in 0…2 forever. Goal rate 0, reach share 0, P(goal) 0, steps
    per episode ∞, and V(0) = Σ γᵏ · (−1) = −1/(1 − γ) = −10. A state without an option on the
    way (RIGHT at 0, nothing at 1) is as stuck."""
    world = corridor()
    prims = primitive_options(world)
    evaluator = PolicyEvaluator(world, prims, window=100)
    for choice in ([LEFT, LEFT, LEFT, -1], [RIGHT, -1, RIGHT, -1]):
        result = evaluator.evaluate(OptionPolicy.deterministic(torch.tensor(choice)))
        assert result.goals_per_window.item() == 0.0
        assert result.reach_share.item() == 0.0
        assert result.goal_probability.item() == 0.0
        assert math.isinf(result.steps_per_episode.item())
    result = evaluator.evaluate(OptionPolicy.deterministic(torch.tensor([LEFT, LEFT, LEFT, -1])))
    assert result.value_start.item() == pytest.approx(-10.0, rel=1e-12)


def test_the_optimum_and_the_value_gap_on_the_corridor():
    """Always RIGHT is optimal on the corridor: V*(μ) = 5.043310 (above). The value gap of always
    LEFT is 5.043310 − (−10); of the optimum itself 0 (its own exact value, to the bit after
    round-off); NaN where the values were not solved."""
    world = corridor()
    v_star = optimal_value(world)
    assert v_star == pytest.approx(5.043310, abs=1e-6)
    evaluator = PolicyEvaluator(world, primitive_options(world), window=100)
    left, right = (OptionPolicy.deterministic(torch.tensor([a, a, a, -1])) for a in (LEFT, RIGHT))
    assert evaluator.evaluate(left).value_gap(v_star).item() == pytest.approx(v_star + 10.0)
    assert evaluator.evaluate(right).value_gap(v_star).item() == 0.0
    assert math.isnan(evaluator.evaluate(right, values=False).value_gap(v_star).item())


def test_a_coin_at_one_state_still_reaches_the_goal_surely():
    """RIGHT at 0 and 2; at 1 LEFT or RIGHT with probability ½ each (random ties). From 1 the
    run goes back to 0 half the time, but every return gets it another try: P(goal) = 1 and the
    goal is sure (share 1). Counting no terminal state as a goal, the same policy has P(goal)
    = 0, share 0 and rate 0, with a finite episode length."""
    world = corridor()
    prims = primitive_options(world)
    option = torch.tensor([[LEFT, RIGHT]]).expand(4, 2).contiguous()
    prob = torch.tensor([[0.0, 1.0], [0.5, 0.5], [0.0, 1.0], [0.0, 0.0]], dtype=torch.float64)
    policy = OptionPolicy(option, prob[None])
    result = PolicyEvaluator(world, prims, 100).evaluate(policy)
    assert result.reach_share.item() == 1.0
    assert result.goal_probability.item() == pytest.approx(1.0, rel=1e-12)
    no_goal = PolicyEvaluator(world, prims, 100, goal_mask=torch.zeros(4, dtype=torch.bool))
    result = no_goal.evaluate(policy)
    assert result.reach_share.item() == 0.0 and result.goal_probability.item() == 0.0
    assert result.goals_per_window.item() == 0.0
    assert math.isfinite(result.steps_per_episode.item())


# ------------------------------------------------------------------------------ Monte Carlo
def rollout_episodes(
    world, options: Options, policy: OptionPolicy, run: int, n: int, seed: int, cap: int = 100_000
):
    """``n`` independent episodes from the start distribution, each option run until β stops it
    or the episode ends (as the learner runs them): ``(steps [n], discounted return [n], ended
    at a goal [n], stuck [n])``. An episode that must choose at a state where the policy has no
    option (its row sums to 0: the ``"stuck"`` rule's untried states) is stuck there for good:
    it never ends nor reaches a goal, and its return is what it earned before (``V = 0`` at such a
    state, as the exact evaluation defines it); its steps are those before it got stuck.
    ``cap``: the most primitive steps any episode may take here (a guard, asserted)."""
    g = torch.Generator().manual_seed(seed)
    S = world.num_states
    start = getattr(world, "start_distribution", None)
    if start is None:
        start = torch.zeros(S, dtype=torch.float64)
        start[world.start_state] = 1.0
    cdf = policy.probability[run].cumsum(1)
    terminal = world.terminal_mask
    goal = getattr(world, "goal_mask", terminal)
    beta = options.termination.double()
    act = options.policy.long()

    def choose(s):
        u = torch.rand(s.shape[0], 1, generator=g, dtype=torch.float64) * cdf[s, -1:]
        o = policy.option[s, (cdf[s] <= u).sum(1).clamp(max=cdf.shape[1] - 1)]
        return torch.where(cdf[s, -1] > 0, o, torch.full_like(o, -1))  # −1: no option here

    s = torch.multinomial(start, n, replacement=True, generator=g)
    o = choose(s)
    steps = torch.zeros(n, dtype=torch.int64)
    ret = torch.zeros(n, dtype=torch.float64)
    discount = torch.ones(n, dtype=torch.float64)
    at_goal = torch.zeros(n, dtype=torch.bool)
    stuck = o < 0
    live = ~stuck
    while bool(live.any()):
        assert int(steps.max()) < cap, f"an episode ran past {cap} steps"
        i = live.nonzero()[:, 0]
        nxt, r = world.step(s[i], act[o[i], s[i]], generator=g)
        ret[i] += discount[i] * r.double()
        discount[i] *= world.gamma
        steps[i] += 1
        done = terminal[nxt]
        at_goal[i] = goal[nxt] & done
        live[i] = ~done
        s[i] = nxt
        stop = ~done & (torch.rand(i.numel(), generator=g, dtype=torch.float64) < beta[o[i], nxt])
        if bool(stop.any()):
            o[i[stop]] = choose(nxt[stop])
            stuck[i[stop]] = o[i[stop]] < 0
            live &= ~stuck
    return steps.double().numpy(), ret.numpy(), at_goal.double().numpy(), stuck.numpy()


def t_interval(x: np.ndarray) -> tuple[float, float]:
    return stats.t.interval(LEVEL, x.size - 1, loc=x.mean(), scale=stats.sem(x))


def assert_matches_rollouts(world, options, policy, result, n, seed):
    """Exact steps per episode, V^π(start) and P(goal) within the 99.9 % t-intervals of ``n``
    rolled-out episodes (≈ 3.3 standard errors of their means); goals per window = W · P(goal) /
    E[T]. Where some rolled-out episode got stuck (a state without an option), the exact steps
    per episode must be ``inf`` (and the goal rate 0); V^π and P(goal) are compared as ever: both
    are finite, the return and the goal of an episode being settled when it gets stuck."""
    for b in range(policy.batch):
        steps, ret, goal, stuck = rollout_episodes(world, options, policy, b, n, seed + b)
        checks = [(result.value_start[b], ret), (result.goal_probability[b], goal)]
        if stuck.any():
            assert math.isinf(float(result.steps_per_episode[b])), b
            assert float(result.goals_per_window[b]) == 0.0
        else:
            checks.append((result.steps_per_episode[b], steps))
        for exact, sample in checks:
            if sample.std() == 0:
                assert float(exact) == pytest.approx(sample[0], rel=1e-9)
                continue
            low, high = t_interval(sample)
            assert low <= float(exact) <= high, (b, float(exact), low, high)
        rate = result.window * result.goal_probability[b] / result.steps_per_episode[b]
        assert float(result.goals_per_window[b]) == pytest.approx(float(rate), rel=1e-12)


def test_stochastic_option_policies_on_the_corridor_equal_their_rollouts():
    """Two runs: uniform over LEFT/RIGHT at 1 and 2 (random ties), RIGHT at 0; and a mix of the
    extended option and LEFT. 20 000 episodes each."""
    world = corridor()
    options = Options.concat([primitive_options(world), run_right(world)])
    option = torch.tensor([[LEFT, RIGHT, 2]]).expand(4, 3).contiguous()
    prob = torch.tensor(
        [
            [[0.0, 1.0, 0.0], [0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.0, 0.0, 0.0]],
            [[0.0, 0.0, 1.0], [0.3, 0.0, 0.7], [0.6, 0.0, 0.4], [0.0, 0.0, 0.0]],
        ],
        dtype=torch.float64,
    )
    policy = OptionPolicy(option, prob)
    result = PolicyEvaluator(world, options, window=100).evaluate(policy)
    assert_matches_rollouts(world, options, policy, result, n=20_000, seed=1)


@pytest.mark.slow  # (20,000 rollouts on the 40×40 world, ≈ 3 s: CI's; the fast suite's are smaller)
def test_policies_on_the_papers_40x40_world_equal_their_rollouts():
    """On experiment 2's world (slip 0.1): the mentor's policy over its own options, and a
    stochastic mix over the learner's options (½ the optimal option, ½ the optimal primitive at
    every state). 4000 episodes each."""
    world = MultiRooms(size=40, rooms=10)
    mentor_opts = mentor_options(world)
    mentor = mentor_policy(world, mentor_opts)
    exact = evaluate_option_choice(world, mentor_opts, mentor.option, 5000)
    assert_matches_rollouts(
        world, mentor_opts, OptionPolicy.deterministic(mentor.option), exact, 4000, seed=7
    )
    options = learner_options(world)
    plan = smdp_value_iteration(option_models(world, options)).policy
    prims = primitive_options(world)
    best_prim = smdp_value_iteration(option_models(world, prims)).policy  # primitive o = o
    option = torch.stack([plan, best_prim], 1)
    prob = torch.where(option >= 0, 0.5, 0.0).double()
    prob = prob / prob.sum(1, keepdim=True).clamp(min=1)
    policy = OptionPolicy(option, prob[None])
    result = PolicyEvaluator(world, options, 5000).evaluate(policy)
    assert_matches_rollouts(world, options, policy, result, 4000, seed=11)


# ---------------------------------------------------------------------------- the references
def test_the_optimum_is_100_percent_of_itself_and_the_baselines_rate():
    world = MultiRooms(size=40, rooms=10)
    optimum = optimal_policy_evaluation(world, 5000)
    baseline = optimal_baseline(world)
    assert optimum.goals_per_window.item() == pytest.approx(baseline.goals_per(5000), rel=1e-10)
    assert optimum.value_start.item() == pytest.approx(baseline.value_start, abs=1e-8)
    assert optimum.percent_of(optimum.goals_per_window).item() == pytest.approx(100.0)
    assert optimum.reach_share.item() == 1.0
    # the mentor (wall-following options): 54.4 against 54.7 (himit info)
    mentor_opts = mentor_options(world)
    mentor = evaluate_option_choice(
        world, mentor_opts, mentor_policy(world, mentor_opts).option, 5000
    )
    assert mentor.goals_per_window.item() == pytest.approx(54.42, abs=0.01)
    assert 99.0 < mentor.percent_of(optimum.goals_per_window).item() < 100.0


def test_the_pair_of_models_is_the_two_calls_to_the_bit():
    world = MultiRooms(size=12, rooms=3, slip=0.2)
    options = learner_options(world, corners=True)
    pair = option_models_and_durations(world, options)
    for got, want in zip(pair, (option_models(world, options), option_durations(world, options))):
        assert torch.equal(got.row_state, want.row_state)
        assert torch.equal(got.reward, want.reward)
        assert torch.equal(got.transition.to_dense(), want.transition.to_dense())


def test_deterministic_policies_of_several_runs_share_their_slots():
    choice = torch.tensor([[0, 1, -1], [2, 1, -1], [0, 0, -1]])
    policy = OptionPolicy.deterministic(choice)
    assert policy.batch == 3 and policy.option.shape[0] == 3
    for b in range(3):
        for s in range(3):
            taken = policy.option[s][policy.probability[b, s] > 0].tolist()
            assert taken == ([] if choice[b, s] < 0 else [int(choice[b, s])])


@pytest.mark.parametrize(
    "make, match",
    [
        (
            lambda: OptionPolicy(torch.zeros(4, 1, dtype=torch.int64), torch.full((1, 4, 1), 0.5)),
            "sum to 1",
        ),
        (
            lambda: OptionPolicy(torch.full((4, 1), -1), torch.ones(1, 4, 1, dtype=torch.float64)),
            "unused slot",
        ),
        (lambda: OptionPolicy(torch.zeros(4, 1, dtype=torch.int64), torch.ones(4, 1)), "B, S, J"),
    ],
)
def test_bad_policies_are_refused(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_an_option_unavailable_at_its_state_is_refused():
    world = corridor()
    only_at_0 = Options(
        initiation=torch.tensor([[True, False, False, False]]),
        termination=torch.ones(1, 4),
        policy=torch.full((1, 4), RIGHT, dtype=torch.int8),
        names=("step right from 0",),
        kinds=("custom",),
    )
    with pytest.raises(ValueError, match="at state 1 where it is unavailable"):
        PolicyEvaluator(world, only_at_0, 10).evaluate(
            OptionPolicy.deterministic(torch.tensor([0, 0, -1, -1]))
        )


def test_round_off_in_the_option_models_is_not_a_way_out():
    """Always LEFT is stuck in 0…2 (above); round-off of the option models' solve planting
    ±1e-17 of probability into the goal must not make the chain look as if it could end (the
    near-singular system then failed to factor: FrozenLake 8×8, first-index ties)."""
    import scipy.sparse as sp

    world = corridor()
    evaluator = PolicyEvaluator(world, primitive_options(world), window=100)
    P = evaluator.P_prob.tolil()
    for row in range(P.shape[0]):
        P[row, 3] = P[row, 3] + (1e-17 if row % 2 else -1e-17)
    evaluator.P_prob = sp.csr_matrix(P)
    result = evaluator.evaluate(OptionPolicy.deterministic(torch.tensor([LEFT, LEFT, LEFT, -1])))
    assert result.goals_per_window.item() == 0.0 and result.reach_share.item() == 0.0
    assert math.isinf(result.steps_per_episode.item())
