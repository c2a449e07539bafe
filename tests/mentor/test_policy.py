"""The mentor: optimal over its own options with a preference for extended ones, state-only demos."""

import dataclasses

import numpy as np
import pytest
import torch

from himit_torch.exact.option_models import option_models
from himit_torch.exact.planning import smdp_value_iteration
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import MentorPolicy, mentor_policy, record_demonstrations, run_mentor
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.worlds.multirooms import MultiRooms


@pytest.fixture(scope="module")
def world() -> MultiRooms:
    return MultiRooms(size=20, rooms=2, slip=0.1)


@pytest.fixture(scope="module")
def policy(world) -> MentorPolicy:
    return mentor_policy(world, mentor_options(world))


def perimeter_mask(world: MultiRooms) -> np.ndarray:
    """``[S]`` free cells with a wall cell or the grid's edge among their 8 neighbours."""
    N = world.size
    wall = world.wall_mask.numpy().reshape(N, N)
    padded = np.pad(wall, 1, constant_values=True)
    near = np.zeros_like(wall)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            near |= padded[1 + dr : 1 + dr + N, 1 + dc : 1 + dc + N]
    return (near & ~wall).ravel()


def test_mentor_reaches_goal_from_start(world, policy):
    rollout = run_mentor(world, policy, episodes=8, seed=0)
    assert len(rollout.states) == 8
    for states in rollout.states:
        assert states.dtype == torch.int64
        assert states[0] == world.start_state and states[-1] == world.goal_state
        assert (states[:-1] != world.goal_state).all()
    # Optimal trips here are ≈ 44 steps; a mentor that wanders would take far longer.
    assert max(len(s) - 1 for s in rollout.states) < 80


def test_mentor_takes_most_steps_inside_extended_options(world):
    for corners, most in ((False, 0.5), (True, 0.25)):
        opts = mentor_options(world, corners=corners)
        rollout = run_mentor(world, mentor_policy(world, opts), episodes=10, seed=1)
        counts = rollout.decision_counts()
        steps = sum(len(s) - 1 for s in rollout.states)
        # A primitive decision is exactly one step; every other step ran inside an extended option.
        assert counts.get("primitive", 0) / steps < most
        assert counts["doorway"] >= 10  # at least one doorway option per episode
        assert sum(len(d) for d in rollout.decisions) == sum(counts.values())


def test_mentor_travels_along_the_walls(world, policy):
    perimeter = perimeter_mask(world) | world.doorway_mask.numpy()
    mentor_states = torch.cat(run_mentor(world, policy, episodes=10, seed=2).states).numpy()
    direct = mentor_policy(world, learner_options(world))  # same subgoals, direct routes
    direct_states = torch.cat(run_mentor(world, direct, episodes=10, seed=2).states).numpy()
    assert perimeter[mentor_states].mean() > 0.75
    assert perimeter[mentor_states].mean() > perimeter[direct_states].mean() + 0.15


def test_zero_tolerance_is_the_strict_greedy_optimum(world):
    opts = mentor_options(world)
    strict = mentor_policy(world, opts, prefer_extended_within=0.0)
    plan = smdp_value_iteration(option_models(world, opts))
    assert torch.equal(strict.option, plan.policy)
    assert torch.equal(strict.values, plan.values)
    assert strict.tolerance == 0.0


def test_preference_picks_extended_options_within_tolerance(world, policy):
    opts = policy.options
    models = option_models(world, opts)
    plan = smdp_value_iteration(models)
    assert policy.tolerance == pytest.approx(abs(world.step_reward))
    q = torch.full((opts.num_options, world.num_states), -torch.inf, dtype=torch.float64)
    q[models.row_option, models.row_state] = plan.q
    states = torch.nonzero(policy.option >= 0).flatten()
    chosen_q = q[policy.option[states], states]
    # Never worse than the optimum by more than the tolerance …
    assert (chosen_q >= plan.values[states] - policy.tolerance - 1e-12).all()
    # … and a primitive is kept only where no extended option is within the tolerance.
    extended = ~opts.is_primitive
    best_extended = q[extended][:, states].max(0).values
    kept_primitive = ~policy.extended[states]
    assert (
        best_extended[kept_primitive] < plan.values[states][kept_primitive] - policy.tolerance
    ).all()
    # The preference matters: somewhere the strict optimum takes a primitive and the mentor doesn't.
    strict_primitive = (plan.policy >= 0) & opts.is_primitive[plan.policy.clamp(min=0)]
    assert (policy.extended & strict_primitive).any()


def test_same_seed_same_demonstrations(world, policy):
    a = record_demonstrations(world, policy, episodes=5, seed=7)
    b = record_demonstrations(world, policy, episodes=5, seed=7)
    c = record_demonstrations(world, policy, episodes=5, generator=torch.Generator().manual_seed(7))
    d = record_demonstrations(world, policy, episodes=5, seed=8)
    assert all(torch.equal(x, y) for x, y in zip(a.episodes, b.episodes))
    assert all(torch.equal(x, y) for x, y in zip(a.episodes, c.episodes))
    assert any(not torch.equal(x, y) for x, y in zip(a.episodes, d.episodes))


def test_record_demonstrations_keeps_states_only(world, policy):
    demos = record_demonstrations(world, policy, episodes=3, seed=0)
    assert isinstance(demos, Demonstrations)
    assert demos.num_episodes == 3
    assert demos.world_description == world.describe()
    public = {name for name in dir(demos) if not name.startswith("_")}
    assert not any("action" in n or "option" in n or "decision" in n for n in public)


def test_options_are_accepted_in_place_of_a_policy(world, policy):
    from_options = record_demonstrations(world, mentor_options(world), episodes=3, seed=4)
    from_policy = record_demonstrations(world, policy, episodes=3, seed=4)
    assert all(torch.equal(x, y) for x, y in zip(from_options.episodes, from_policy.episodes))


def test_mentor_errors(world, policy):
    with pytest.raises(ValueError, match="prefer_extended_within=-0.5 must be ≥ 0"):
        mentor_policy(world, mentor_options(world), prefer_extended_within=-0.5)
    with pytest.raises(ValueError, match="episodes=0"):
        run_mentor(world, policy, episodes=0)
    with pytest.raises(ValueError, match="either generator or seed"):
        run_mentor(world, policy, episodes=1, seed=0, generator=torch.Generator())
    with pytest.raises(ValueError, match="did not reach the goal within max_steps_per_episode=5"):
        run_mentor(world, policy, episodes=2, seed=0, max_steps_per_episode=5)


def _rollout_fields(rollout) -> list[tuple[str, int, torch.Tensor]]:
    return [
        (name, e, x)
        for name in ("states", "decisions", "decision_states", "randomised", "decision_steps")
        for e, x in enumerate(getattr(rollout, name))
    ]


def _mentor_in(name: str):
    """``(world, mentor)``: the worlds the mentor's fast path is checked on."""
    from himit_torch.options.builders import primitive_options
    from himit_torch.worlds.gymnasium import from_gymnasium

    if name in ("rooms", "corners"):
        world = MultiRooms(size=20, rooms=2) if name == "rooms" else MultiRooms(32, 4, slip=0.2)
        return world, mentor_policy(world, mentor_options(world, corners=name == "corners"))
    world = (
        from_gymnasium("Taxi-v4")
        if name == "taxi (a start distribution)"
        else from_gymnasium("FrozenLake-v1", is_slippery=True)
    )
    return world, mentor_policy(world, primitive_options(world))


@pytest.mark.parametrize(
    "name", ["rooms", "corners", "taxi (a start distribution)", "slippery lake (three slots)"]
)
def test_rollout_in_numbers_equals_the_batch_of_torch_ops(name, monkeypatch):
    """run_mentor steps deterministic options on a world with a dynamics table in Python numbers
    (_rollout_in_numbers); the batch's torch ops (_rollout_in_tensors) are the obvious
    computation: the same states, decisions, decision states and flags, dtypes included, and
    the same errors when an episode runs out of steps and where the policy has no option."""
    import himit_torch.mentor.policy as policy_module

    world, mentor = _mentor_in(name)
    assert policy_module._steps_by_table(world) is not None  # (the fast path is taken)
    for seed in range(3):
        fast = run_mentor(world, mentor, episodes=6, seed=seed, max_steps_per_episode=10_000)
        with monkeypatch.context() as m:
            m.setattr(policy_module, "_steps_by_table", lambda world: None)
            slow = run_mentor(world, mentor, episodes=6, seed=seed, max_steps_per_episode=10_000)
        assert sum(len(s) for s in slow.states) > 6 * 3, name  # (episodes of some length)
        for (field, e, a), (_, _, b) in zip(_rollout_fields(fast), _rollout_fields(slow)):
            assert a.dtype == b.dtype and torch.equal(a, b), f"{name}, seed {seed}: {field}[{e}]"

    def error_both_ways(policy, max_steps: int, match: str) -> None:
        messages = []
        for steps_by_table in (policy_module._steps_by_table, lambda world: None):
            with monkeypatch.context() as m:
                m.setattr(policy_module, "_steps_by_table", steps_by_table)
                with pytest.raises(ValueError, match=match) as err:
                    run_mentor(world, policy, episodes=6, seed=2, max_steps_per_episode=max_steps)
            messages.append(str(err.value))
        assert messages[0] == messages[1]

    longest = max(len(s) for s in slow.states)
    error_both_ways(mentor, longest - 2, "did not reach the goal")
    # a state on the way (not a start) where the policy has no option
    decided, starts = torch.cat(slow.decision_states), torch.stack([s[0] for s in slow.states])
    broken = dataclasses.replace(mentor, option=mentor.option.clone())
    broken.option[int(decided[~torch.isin(decided, starts)][0])] = -1
    error_both_ways(broken, 10_000, "has no usable option at state")
