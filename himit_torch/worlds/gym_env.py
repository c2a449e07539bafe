"""A Gymnasium environment around :class:`~himit_torch.worlds.multirooms.MultiRooms`.

The env is a thin shell: the dynamics are the world's own :meth:`MultiRooms.step` fed with one
uniform drawn from the env's ``np_random``, so the env and the library's batched loop share one
definition of slip. Registered as ``"himit_torch/MultiRooms-v0"`` when this module is imported
(Gymnasium 1.x no longer loads ``gymnasium.envs`` entry-point plugins by itself)::

    import gymnasium
    import himit_torch.worlds.gym_env  # registers the id
    env = gymnasium.make("himit_torch/MultiRooms-v0", size=8, rooms=2)

or, without importing first, ``gymnasium.make("himit_torch.worlds.gym_env:himit_torch/MultiRooms-v0")``.
"""

from __future__ import annotations

from collections.abc import Iterable
from functools import cached_property
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces

from himit_torch.worlds.multirooms import MultiRooms

__all__ = ["MultiRoomsEnv", "register_envs", "ENV_ID"]

#: The registered id.
ENV_ID = "himit_torch/MultiRooms-v0"

#: RGB colours of :meth:`MultiRoomsEnv.render` in ``"rgb_array"`` mode.
COLORS = {
    "free": (235, 235, 235),
    "wall": (40, 40, 40),
    "doorway": (214, 170, 90),
    "start": (90, 180, 90),
    "goal": (220, 60, 60),
    "agent": (50, 90, 220),
}


class MultiRoomsEnv(gymnasium.Env[int, int]):
    """The paper's multirooms gridworld as a Gymnasium environment.

    **Description**

    An ``size × size`` grid split into ``rooms × rooms`` rooms by wall rows and columns at
    multiples of ``size / rooms``, joined by one doorway cell in the middle of each wall segment
    between two neighbouring rooms (``closed_doorways`` turn some back into wall). The agent starts
    at ``start`` (top-left by default) and must reach ``goal`` (bottom-right by default). See
    :class:`~himit_torch.worlds.multirooms.MultiRooms` for the layout and the argument checks.

    **Action Space**

    ``Discrete(4)``: 0 = north (row − 1), 1 = south (row + 1), 2 = west (col − 1), 3 = east
    (col + 1). With probability ``1 − slip`` the chosen action is executed; otherwise one of the
    other three directions, uniformly. A move into a wall or off the grid leaves the agent in place.

    **Observation Space**

    ``Discrete(size * size)``: the cell index ``row * size + col``. Wall cells are never observed.

    **Rewards**

    ``goal_reward`` (+1.0) for entering the goal, ``step_reward`` (−0.01) for every other step.

    **Starting State**

    Always ``start`` (the world's ``start_state``).

    **Episode End**

    * Termination: the agent enters the goal.
    * Truncation: after ``max_episode_steps`` steps (10 000 when made through
      ``gymnasium.make``; pass ``max_episode_steps=`` to ``make`` to change it).

    **Arguments**

    The keyword arguments of :class:`~himit_torch.worlds.multirooms.MultiRooms` (``size``,
    ``rooms``, ``slip``, ``start``, ``goal``, ``closed_doorways``, ``step_reward``, ``goal_reward``, ``gamma``), plus
    ``render_mode`` (``None``, ``"rgb_array"`` or ``"ansi"``) and ``cell_pixels``, the side of
    one cell in the ``"rgb_array"`` image.

    **True model**

    ``env.unwrapped.world`` is the :class:`MultiRooms`; :meth:`transition_model` and
    :meth:`reward_model` return its ``P [A, S, S]`` and ``R [S, A]``, and :attr:`P` holds the same
    model in the toy-text format ``P[s][a] = [(prob, next_state, reward, terminated), ...]``.
    """

    metadata = {"render_modes": ["rgb_array", "ansi"], "render_fps": 4}

    def __init__(
        self,
        size: int = 40,
        rooms: int = 10,
        slip: float = 0.1,
        start: int | tuple[int, int] | None = None,
        goal: int | tuple[int, int] | None = None,
        closed_doorways: Iterable[int | tuple[int, int]] = (),
        step_reward: float = -0.01,
        goal_reward: float = 1.0,
        gamma: float = 0.99,
        render_mode: str | None = None,
        cell_pixels: int = 8,
    ):
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode={render_mode!r}: use None or one of {self.metadata['render_modes']}"
            )
        if (
            isinstance(cell_pixels, bool)
            or not isinstance(cell_pixels, (int, np.integer))
            or cell_pixels < 1
        ):
            raise ValueError(f"cell_pixels={cell_pixels!r} must be a positive whole number")
        self.world = MultiRooms(
            size=size,
            rooms=rooms,
            slip=slip,
            start=start,
            goal=goal,
            closed_doorways=closed_doorways,
            step_reward=step_reward,
            goal_reward=goal_reward,
            gamma=gamma,
        )
        self.render_mode = render_mode
        self.cell_pixels = int(cell_pixels)
        self.observation_space = spaces.Discrete(self.world.num_states)  # type: ignore[assignment]
        self.action_space = spaces.Discrete(self.world.num_actions)  # type: ignore[assignment]
        self.state: int | None = None

    # ------------------------------------------------------------------------------ Gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[int, dict[str, Any]]:
        """Start an episode at the world's start cell. ``options`` is accepted and ignored."""
        super().reset(seed=seed)
        self.state = self.world.start_state
        return self.state, {}

    def step(self, action: int) -> tuple[int, float, bool, bool, dict[str, Any]]:
        """Take one primitive action; the slip draw comes from ``self.np_random``.

        ``info["executed_action"]`` is the direction actually taken after a slip.
        """
        if self.state is None:
            raise RuntimeError("call reset() before step()")
        if not self.action_space.contains(action):
            raise ValueError(f"action {action!r} is not in {self.action_space}")
        positions = torch.tensor([self.state], dtype=torch.int64)
        actions = torch.tensor([int(action)], dtype=torch.int64)
        uniforms = torch.tensor([self.np_random.random()], dtype=torch.float64)
        nxt, rewards = self.world.step(positions, actions, uniforms)
        executed = int(self.world.slipped_actions(actions, uniforms)[0])
        self.state = int(nxt[0])
        terminated = self.state == self.world.goal_state
        reward = float(rewards[0])
        return self.state, reward, terminated, False, {"executed_action": executed}

    def render(self) -> np.ndarray | str | None:
        """``"rgb_array"``: ``[size·cell_pixels, size·cell_pixels, 3]`` uint8 picture (walls dark,
        doorways ochre, start green, goal red, agent blue); ``"ansi"``: the world's text picture."""
        if self.render_mode is None:
            gymnasium.logger.warn(
                "render() called without a render_mode; pass render_mode="
                "'rgb_array' or 'ansi' to the constructor or to gymnasium.make"
            )
            return None
        agents = () if self.state is None else (self.state,)
        if self.render_mode == "ansi":
            return self.world.render_ansi(agents)
        return self._rgb_array(agents)

    def _rgb_array(self, agents: Iterable[int]) -> np.ndarray:
        w, N, k = self.world, self.world.size, self.cell_pixels
        grid = np.empty((N * N, 3), dtype=np.uint8)
        grid[:] = COLORS["free"]
        grid[w.wall_mask.numpy()] = COLORS["wall"]
        grid[w.doorway_mask.numpy()] = COLORS["doorway"]
        grid[w.start_state] = COLORS["start"]
        grid[w.goal_state] = COLORS["goal"]
        image = np.repeat(np.repeat(grid.reshape(N, N, 3), k, axis=0), k, axis=1)
        pad = k // 4  # the agent is an inset square, so the cell's own colour still shows
        for s in agents:
            r, c = w.coords(s)
            image[r * k + pad : (r + 1) * k - pad, c * k + pad : (c + 1) * k - pad] = COLORS[
                "agent"
            ]
        return image

    # ------------------------------------------------------------------------------ true model
    def transition_model(self, sparse: bool = True) -> torch.Tensor:
        """The world's true ``P [A, S, S]`` (see :meth:`MultiRooms.transition_model`)."""
        return self.world.transition_model(sparse=sparse)

    def reward_model(self) -> torch.Tensor:
        """The world's expected reward ``R [S, A]`` (see :meth:`MultiRooms.reward_model`)."""
        return self.world.reward_model()

    @cached_property
    def P(self) -> dict[int, dict[int, list[tuple[float, int, float, bool]]]]:
        """Toy-text model ``P[s][a] = [(prob, next_state, reward, terminated), ...]`` over free
        cells; the goal is absorbing with reward 0, as in :meth:`transition_model`."""
        P = self.transition_model(sparse=True).coalesce()
        (a_idx, s_idx, t_idx), probs = P.indices().tolist(), P.values().tolist()
        free, goal = self.world.free_mask.tolist(), self.world.goal_state
        out: dict[int, dict[int, list]] = {
            s: {a: [] for a in range(self.world.num_actions)}
            for s in range(self.world.num_states)
            if free[s]
        }
        for a, s, t, p in zip(a_idx, s_idx, t_idx, probs):
            if not free[s]:
                continue
            reward = (
                0.0
                if s == goal
                else (self.world.goal_reward if t == goal else self.world.step_reward)
            )
            out[s][a].append((p, t, reward, t == goal))
        return out


def register_envs() -> None:
    """Register ``"himit_torch/MultiRooms-v0"`` with Gymnasium (idempotent).

    Called when this module is imported; also named as the ``gymnasium.envs`` entry point in
    ``pyproject.toml`` for Gymnasium versions that load plugins.
    """
    if ENV_ID in gymnasium.registry:
        return
    gymnasium.register(
        id=ENV_ID, entry_point="himit_torch.worlds.gym_env:MultiRoomsEnv", max_episode_steps=10_000
    )


register_envs()
