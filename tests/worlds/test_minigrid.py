"""MiniGrid tasks as tabular worlds: the table against MiniGrid's own ``step``, the encoder and
decoder, slip, the reward, the refusals, and a greedy policy replayed in MiniGrid itself."""

from __future__ import annotations

import copy
from collections import deque

import numpy as np
import pytest
import torch

pytest.importorskip("minigrid")

import gymnasium  # noqa: E402

import himit_torch as ht  # noqa: E402
from himit_torch.worlds.minigrid import (  # noqa: E402
    GOAL_REWARD,
    MINIGRID_ACTION_NAMES,
    STEP_REWARD,
    from_minigrid,
)

A = len(MINIGRID_ACTION_NAMES)


@pytest.fixture(scope="module")
def doorkey5():
    return from_minigrid("MiniGrid-DoorKey-5x5-v0")


def _paths(world) -> dict[int, list[int]]:
    """A shortest action path from the start to every state, on the world's table."""
    succ = world.dynamics_table().successors[:, :, -1].numpy()
    terminal = world.terminal_mask.numpy()
    paths = {0: []}
    queue = deque([0])
    while queue:
        s = queue.popleft()
        if terminal[s]:
            continue
        for a in range(A):
            t = int(succ[s, a])
            if t not in paths:
                paths[t] = paths[s] + [a]
                queue.append(t)
    return paths


def _check_pairs(world, states):
    env = world.make_env()
    paths = _paths(world)
    succ = world.dynamics_table().successors[:, :, -1].numpy()
    rewards = world.dynamics_table().rewards[:, :, -1].numpy()
    terminal = world.terminal_mask.numpy()
    raw = env.unwrapped
    checked = 0
    for s in states:
        world.reset_env(env)
        for a in paths[s]:
            raw.step(a)
        assert world.state_of(env) == s
        layout = world._layouts[id(raw)][1]
        for a in range(A):
            twin_raw, twin_layout = copy.deepcopy((raw, layout))
            _, reward, terminated, _, _ = twin_raw.step(a)
            t = int(succ[s, a])
            assert twin_layout.read(twin_raw) == world.state_key(t), (s, a)
            assert bool(terminated) == bool(terminal[t]), (s, a)
            assert (float(reward) > 0) == (rewards[s, a] == GOAL_REWARD), (s, a)
            checked += 1
    return checked


def test_table_is_minigrids_step_on_every_pair_of_a_small_task(doorkey5):
    live = np.flatnonzero(~doorkey5.terminal_mask.numpy())
    assert _check_pairs(doorkey5, live) == live.size * A


def test_table_is_minigrids_step_on_a_sample_of_a_task_with_three_doors():
    world = from_minigrid("MiniGrid-MultiRoom-N4-S5-v1")
    live = np.flatnonzero(~world.terminal_mask.numpy())
    sample = np.random.default_rng(0).choice(live, 60, replace=False)
    assert _check_pairs(world, sample) == 60 * A


@pytest.mark.slow
def test_table_is_minigrids_step_on_a_sample_of_doorkey_8x8():
    world = from_minigrid("MiniGrid-DoorKey-8x8-v0")
    live = np.flatnonzero(~world.terminal_mask.numpy())
    sample = np.random.default_rng(1).choice(live, 200, replace=False)
    assert _check_pairs(world, sample) == 200 * A


# The breadth-first counts (seed 0) left out the states entered at success; the world
# holds them as its terminal states.
COUNTS = {
    "MiniGrid-DoorKey-5x5-v0": 260,
    "MiniGrid-DoorKey-6x6-v0": 1272,
    "MiniGrid-Unlock-v0": 1024,
    "MiniGrid-KeyCorridorS3R1-v0": 156,
    "MiniGrid-MultiRoom-N2-S4-v0": 60,
    "MiniGrid-MultiRoom-N4-S5-v1": 1072,
    "MiniGrid-FourRooms-v0": 1036,
}


@pytest.mark.parametrize("env_id", sorted(COUNTS))
def test_reachable_states_match_an_independent_count(env_id):
    world = from_minigrid(env_id)
    assert world.num_states - int(world.terminal_mask.sum()) == COUNTS[env_id]
    assert bool(world.goal_mask.any())
    assert world.start_state == 0


def test_reward_and_termination(doorkey5):
    table = doorkey5.dynamics_table()
    rewards, succ = table.rewards[:, :, 0], table.successors[:, :, 0]
    into_goal = doorkey5.terminal_mask[succ]
    live = ~doorkey5.terminal_mask[:, None].expand_as(succ)
    assert torch.all(rewards[live & into_goal] == GOAL_REWARD)
    assert torch.all(rewards[live & ~into_goal] == STEP_REWARD)
    assert torch.equal(doorkey5.goal_mask, doorkey5.terminal_mask)
    assert doorkey5.action_names == MINIGRID_ACTION_NAMES


def test_encoder_and_decoder_round_trip(doorkey5):
    env = doorkey5.make_env()
    for s in range(doorkey5.num_states):
        doorkey5.set_state(env, s)
        assert doorkey5.state_of(env) == s
    # and MiniGrid steps from a decoded state as the table says (with its observations)
    s = int(np.flatnonzero(doorkey5.state_table[:, 3] == -1)[0])  # the key carried
    doorkey5.set_state(env, s)
    env.step(2)
    assert doorkey5.state_of(env) == int(doorkey5.dynamics_table().successors[s, 2, 0])
    assert "carrying yellow key" in doorkey5.describe_state(s)


def test_render_draws_the_state_as_minigrid_does(doorkey5):
    env = doorkey5.make_env(render_mode="rgb_array")
    s = int(doorkey5.dynamics_table().successors[0, 2, 0])  # one step forward (or a bump)
    doorkey5.set_state(env, s)
    assert np.array_equal(doorkey5.render(s), env.unwrapped.get_frame(highlight=False))
    assert not np.array_equal(doorkey5.render(0), doorkey5.render(1))  # the agent turned
    x, y, _ = doorkey5.state_key(s)[:3]
    assert doorkey5.cell_center([s]).tolist() == [[32 * x + 16, 32 * y + 16]]


def test_encoder_needs_the_worlds_reset(doorkey5):
    env = gymnasium.make("MiniGrid-DoorKey-5x5-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match="reset_env"):
        doorkey5.state_of(env)
    other = gymnasium.make("MiniGrid-DoorKey-6x6-v0")
    with pytest.raises(ValueError, match="not this world's layout"):
        doorkey5.reset_env(other)


def test_slip_takes_another_action_uniformly():
    slip = 0.25
    plain = from_minigrid("MiniGrid-DoorKey-5x5-v0")
    slippery = from_minigrid("MiniGrid-DoorKey-5x5-v0", slip=slip)
    P0, _ = ht.world_model(plain)
    P, _ = ht.world_model(slippery)
    P0, P = P0.to_dense(), P.to_dense()
    live = ~plain.terminal_mask
    for a in range(A):
        others = [b for b in range(A) if b != a]
        expected = (1 - slip) * P0[a] + slip / (A - 1) * sum(P0[b] for b in others)
        assert torch.allclose(P[a][live], expected[live])
    assert slippery.describe()["slip"] == slip


def test_describe_identifies_the_world(doorkey5):
    d = doorkey5.describe()
    assert d["kind"] == "minigrid" and d["id"] == "MiniGrid-DoorKey-5x5-v0" and d["seed"] == 0
    assert (
        from_minigrid("MiniGrid-DoorKey-5x5-v0", seed=1).describe()["fingerprint"]
        != (d["fingerprint"])
    )


def test_greedy_policy_of_exact_planning_replays_in_minigrid(doorkey5):
    """Value iteration on the world's table; its greedy actions, stepped in MiniGrid itself
    (rendered as MiniGrid draws it), reach the goal in the planned number of steps."""
    P, R = ht.world_model(doorkey5)
    plan = ht.value_iteration(P, R, doorkey5.gamma)
    env = doorkey5.make_env(render_mode="rgb_array")
    s = doorkey5.start_state
    durations = ht.option_durations(doorkey5, ht.primitive_options(doorkey5))
    planned = round(ht.expected_steps(durations, plan.policy, s, doorkey5.terminal_mask))
    steps, terminated, reward = 0, False, 0.0
    while not terminated and steps < 100:
        _, reward, terminated, _, _ = env.step(int(plan.policy[s]))
        steps += 1
        if not terminated:
            s = doorkey5.state_of(env)
    assert terminated and reward > 0 and steps == planned
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3


def test_learners_greedy_policy_replays_in_minigrid(doorkey5):
    """A short learning run (imitation of the mentor, 1 run); its greedy option policy, stepped
    in MiniGrid's own environment, reaches the goal."""
    options = ht.minigrid_options(doorkey5)
    mentor = ht.minigrid_mentor(doorkey5)
    demos = ht.record_demonstrations(doorkey5, mentor, episodes=5, seed=0)
    learner = ht.Learner(
        doorkey5,
        options,
        ["imitation"],
        [0],
        demonstrations=demos,
        reward=ht.KnownReward(doorkey5),
    )
    learner.run(3000)
    choice = learner.views.greedy_options()[0]
    env = doorkey5.make_env()
    s, option, reached = doorkey5.start_state, -1, False
    for _ in range(200):
        if option < 0:
            option = int(choice[s])
            assert option >= 0
        _, reward, terminated, _, _ = env.step(int(options.policy[option, s]))
        if terminated:
            reached = reward > 0
            break
        s = doorkey5.state_of(env)
        if float(options.termination[option, s]) >= 1.0:
            option = -1
    assert reached


# -------------------------------------------------------------------------------- refused
@pytest.mark.parametrize(
    "env_id, words",
    [
        ("MiniGrid-DoorKey-Nope-v0", "gymnasium.make failed"),
        ("", "gymnasium.make failed"),
        ("Taxi-v4", "not a MiniGrid environment"),
        ("MiniGrid-Dynamic-Obstacles-5x5-v0", "stochastic"),
        ("MiniGrid-GoToDoor-5x5-v0", "language mission"),
        ("MiniGrid-Fetch-5x5-N2-v0", "language mission"),
        ("BabyAI-GoToRedBallGrey-v0", "language mission"),
    ],
)
def test_refused_tasks(env_id, words):
    with pytest.raises(ValueError, match=words):
        from_minigrid(env_id)


def test_refuses_more_states_than_max_states():
    with pytest.raises(ValueError, match="max_states=100"):
        from_minigrid("MiniGrid-DoorKey-5x5-v0", max_states=100)


def test_refuses_a_stochastic_step_it_does_not_know_by_name():
    """A MiniGrid class of no known name whose step draws a random number."""
    from minigrid.envs import DoorKeyEnv

    class Jittery(DoorKeyEnv):
        def step(self, action):
            if self._rand_bool():
                action = 0
            return super().step(action)

    with pytest.raises(ValueError, match="drew a random number"):
        from_minigrid(Jittery(size=5))


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"slip": 1.0}, "slip"),
        ({"slip": "0.1"}, "slip"),
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"max_states": 0}, "max_states"),
        ({"gamma": 0.0}, "gamma"),
        ({"nope": 1}, "gymnasium.make failed"),
    ],
)
def test_refused_arguments(kwargs, words):
    with pytest.raises(ValueError, match=words):
        from_minigrid("MiniGrid-DoorKey-5x5-v0", **kwargs)


def test_kwargs_need_an_id():
    env = gymnasium.make("MiniGrid-DoorKey-5x5-v0")
    with pytest.raises(ValueError, match="need an environment id"):
        from_minigrid(env, max_steps=10)
    world = from_minigrid(env)  # an object: its spec's id is kept
    assert world.env_id == "MiniGrid-DoorKey-5x5-v0"


def test_door_state_follows_the_door(doorkey5):
    """DoorKey's door starts locked (2) and is unlocked — open (0), or closed again behind the
    agent (1) — in every state entered at success (the goal lies behind it); an unknown door is
    refused."""
    [door] = [n for n in doorkey5.object_names if "door" in n]
    state = doorkey5.door_state(door)
    assert int(state[doorkey5.start_state]) == 2
    assert (state[doorkey5.terminal_mask] != 2).all()
    assert set(state.tolist()) == {0, 1, 2}
    with pytest.raises(ValueError, match="no door"):
        doorkey5.door_state("the red door")


def test_goal_moved_keeps_the_layout_and_ends_the_task_there(doorkey5):
    # DoorKey 5×5, seed 0 (by hand): wall column x = 2, door (2, 1), key (1, 2), start (1, 3)
    # facing west, goal (3, 3). Moved to (3, 2): the right room is the column x = 3 entered at
    # (3, 1), so (3, 3) lies behind the new goal and is never reached.
    moved = from_minigrid("MiniGrid-DoorKey-5x5-v0", goal=(3, 2))
    assert moved.goal_cells == (2 * 5 + 3,) and doorkey5.goal_cells == (3 * 5 + 3,)
    assert moved.object_names == doorkey5.object_names
    assert moved.state_key(0) == doorkey5.state_key(0)
    assert moved.describe()["goal"] == [3, 2] and "goal" not in doorkey5.describe()
    cells = {moved.state_key(s)[:2] for s in range(moved.num_states)}
    assert (3, 2) in cells and (3, 3) not in cells
    # the optimum by hand: right (face north), pickup, forward, forward (1, 1), right (face
    # east), toggle, forward (door), forward (3, 1), right (face south), forward: 10 steps,
    # the last paying +1
    plan = ht.smdp_value_iteration(ht.option_models(moved, ht.primitive_options(moved)))
    steps, s = 0, 0
    while not bool(moved.terminal_mask[s]):
        s = int(moved.dynamics_table().successors[s, int(plan.policy[s]), -1])
        steps += 1
    assert steps == 10 and moved.state_key(s)[:2] == (3, 2)
    # the moved world's environment is reset with the goal moved
    env = moved.make_env()
    assert moved.state_of(env) == 0 and env.unwrapped.grid.get(3, 2).type == "goal"
    assert env.unwrapped.grid.get(3, 3) is None


@pytest.mark.parametrize(
    "goal, words",
    [
        ((0, 0), "wall"),
        ((1, 2), "key"),
        ((1, 3), "agent's start"),
        ((3, 7), "outside the grid"),
        ((3,), r"a cell \(x, y\)"),
        ("ab", r"a cell \(x, y\)"),
        ((1.5, 2), "whole number"),
    ],
)
def test_goal_moved_refused(goal, words):
    with pytest.raises(ValueError, match=words):
        from_minigrid("MiniGrid-DoorKey-5x5-v0", goal=goal)


def test_goal_moved_needs_one_goal_square():
    with pytest.raises(ValueError, match="has 0"):
        from_minigrid("MiniGrid-Unlock-v0", goal=(1, 1))


def test_states_from_matches_full_states(doorkey5):
    moved = from_minigrid("MiniGrid-DoorKey-5x5-v0", goal=(3, 2))
    mapped = doorkey5.states_from(moved, torch.arange(moved.num_states))
    for s, t in zip(range(moved.num_states), mapped.tolist()):
        assert doorkey5.state_key(t) == moved.state_key(s)
    # the other way: the agent on (3, 3) exists only in MiniGrid's own layout
    behind = next(s for s in range(doorkey5.num_states) if doorkey5.state_key(s)[:2] == (3, 3))
    with pytest.raises(ValueError, match="not reachable"):
        moved.states_from(doorkey5, [behind])
    with pytest.raises(ValueError, match="same layout"):
        doorkey5.states_from(from_minigrid("MiniGrid-DoorKey-6x6-v0"), [0])
    with pytest.raises(TypeError, match="from_minigrid"):
        doorkey5.states_from(ht.MultiRooms(8, 2), [0])
