"""The Gymnasium environment: API checks, registration, determinism, rendering, true model."""

import warnings

import gymnasium
import numpy as np
import pytest
import torch
from gymnasium.utils.env_checker import check_env

from himit_torch.worlds.gym_env import ENV_ID, MultiRoomsEnv, register_envs
from himit_torch.worlds.multirooms import MultiRooms

E, S = 3, 1


@pytest.mark.parametrize("render_mode", [None, "rgb_array", "ansi"])
def test_check_env_without_warnings(render_mode):
    env = gymnasium.make(ENV_ID, size=8, rooms=2, render_mode=render_mode)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
    env.close()


def test_make_through_registered_id():
    register_envs()  # idempotent: a second registration changes nothing
    spec = gymnasium.spec(ENV_ID)
    env = gymnasium.make(ENV_ID, size=8, rooms=2, slip=0.0, goal=(3, 3))
    assert env.spec.max_episode_steps == spec.max_episode_steps == 10_000
    assert env.observation_space == gymnasium.spaces.Discrete(64)
    assert env.action_space == gymnasium.spaces.Discrete(4)
    world = env.unwrapped.world
    assert (world.size, world.rooms, world.slip, world.goal_state) == (8, 2, 0.0, 27)
    # The "module:id" form imports the module itself.
    again = gymnasium.make("himit_torch.worlds.gym_env:" + ENV_ID, size=6, rooms=2)
    assert again.unwrapped.world.num_states == 36


def test_time_limit_truncates():
    env = gymnasium.make(ENV_ID, size=6, rooms=2, max_episode_steps=3)
    env.reset(seed=0)
    outcomes = [env.step(0)[2:4] for _ in range(3)]  # north from (0,0): stays put
    assert outcomes == [(False, False), (False, False), (False, True)]


def rollout(seed: int, steps: int = 300) -> list[tuple]:
    """Observations, rewards and slips for a fixed random action sequence."""
    env = MultiRoomsEnv(size=8, rooms=2, slip=0.3)
    actions = np.random.default_rng(0).integers(4, size=steps)
    obs, _ = env.reset(seed=seed)
    out = [obs]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(int(a))
        out.append((obs, reward, terminated, info["executed_action"]))
        if terminated:
            obs, _ = env.reset()
            out.append(obs)
    return out


def test_same_seed_same_rollout():
    first, second = rollout(11), rollout(11)
    assert first == second
    assert first != rollout(12)  # same actions, other slips
    assert len({step[0] for step in first[1:] if isinstance(step, tuple)}) > 5  # it moved


def test_slip_comes_from_np_random_and_matches_the_world():
    """The env's step equals world.step fed with the env's own uniforms."""
    env = MultiRoomsEnv(size=8, rooms=2, slip=0.5)
    world = MultiRooms(size=8, rooms=2, slip=0.5)
    env.reset(seed=3)
    shadow = np.random.default_rng(3)  # Gymnasium seeds np_random with default_rng(seed)
    pos = world.start_state
    slipped = 0
    for t in range(200):
        a = t % 4
        u = shadow.random()
        nxt, reward = world.step(
            torch.tensor([pos]), torch.tensor([a]), torch.tensor([u], dtype=torch.float64)
        )
        obs, r, terminated, _, info = env.step(a)
        assert obs == int(nxt[0]) and r == pytest.approx(float(reward[0]))
        slipped += info["executed_action"] != a
        pos = obs
        if terminated:
            break
    assert slipped > 0


def test_reaching_the_goal():
    env = MultiRoomsEnv(size=6, rooms=2, slip=0.0, goal_reward=2.5)
    obs, info = env.reset(seed=0)
    assert obs == 0 and info == {}
    # (0,0) south to (1,0), east through the doorway (1,3) to (1,5), south through (3,5) to (5,5).
    path = [S] + [E] * 5 + [S] * 4
    rewards, terminated = [], False
    for i, a in enumerate(path):
        obs, reward, terminated, truncated, _ = env.step(a)
        rewards.append(reward)
        assert not truncated
        assert terminated == (i == len(path) - 1)
    assert obs == 35 and terminated
    assert rewards == [-0.01] * 9 + [2.5]


def test_render_modes():
    env = MultiRoomsEnv(size=6, rooms=2, render_mode="rgb_array", cell_pixels=4)
    env.reset(seed=0)
    image = env.render()
    assert isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.shape == (24, 24, 3)
    wall = image[3 * 4 + 2, 0 * 4 + 2]  # cell (3,0)
    free = image[0 * 4 + 2, 1 * 4 + 2]  # cell (0,1)
    door = image[1 * 4 + 2, 3 * 4 + 2]  # cell (1,3)
    goal = image[5 * 4 + 2, 5 * 4 + 2]
    agent = image[0 * 4 + 2, 0 * 4 + 2]  # agent on the start cell, drawn inset
    start_edge = image[0, 0]
    colours = {tuple(c) for c in (wall, free, door, goal, agent, start_edge)}
    assert len(colours) == 6
    assert wall.sum() < free.sum()  # walls dark
    env.step(E)
    assert not np.array_equal(env.render(), image)

    ansi = MultiRoomsEnv(size=6, rooms=2, render_mode="ansi")
    ansi.reset(seed=0)
    text = ansi.render()
    assert isinstance(text, str) and text.splitlines()[0] == "A..#.."
    assert text == ansi.world.render_ansi([0])


def test_render_without_mode_warns():
    env = MultiRoomsEnv(size=6, rooms=2)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None


def test_true_model_accessors():
    env = gymnasium.make(ENV_ID, size=6, rooms=2)
    base = env.unwrapped
    assert torch.equal(
        base.transition_model(sparse=False), base.world.transition_model(sparse=False)
    )
    torch.testing.assert_close(base.reward_model(), base.world.reward_model())
    P = base.P
    assert set(P) == set(base.world.free_mask.nonzero().flatten().tolist())
    assert sum(p for p, *_ in P[0][E]) == pytest.approx(1.0)
    assert (0.9, 1, -0.01, False) in P[0][E]
    assert P[35][0] == [(1.0, 35, 0.0, True)]  # the goal is absorbing
    # Toy-text expected rewards equal the world's R.
    R = base.reward_model()
    for s in (0, 29, 34):
        for a in range(4):
            assert sum(p * r for p, _, r, _ in P[s][a]) == pytest.approx(R[s, a].item())


def test_bad_arguments():
    with pytest.raises(ValueError, match="render_mode='human'"):
        MultiRoomsEnv(size=6, rooms=2, render_mode="human")
    with pytest.raises(ValueError, match="cell_pixels"):
        MultiRoomsEnv(size=6, rooms=2, cell_pixels=0)
    with pytest.raises(ValueError, match="not a multiple"):
        gymnasium.make(ENV_ID, size=7, rooms=2)
    env = MultiRoomsEnv(size=6, rooms=2)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="not in Discrete"):
        env.step(4)
