"""The tabular-world protocol every learner world follows, and the dynamics table the
compiled engine reads (successors, their cdf and rewards per state and action)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import torch

__all__ = ["TabularWorld", "DynamicsTable"]


@runtime_checkable
class TabularWorld(Protocol):
    """What the learner needs from a world: a batched step, a start, terminal states, a reward.

    Any tabular world with these members works with :class:`himit_torch.Learner`, not only
    :class:`MultiRooms`.
    """

    num_states: int
    num_actions: int
    start_state: int
    gamma: float

    @property
    def terminal_mask(self) -> torch.Tensor:  # [S] bool: reaching one ends the episode
        ...

    def step(
        self, positions: torch.Tensor, actions: torch.Tensor, uniforms: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``positions [B], actions [B], uniforms [B] in [0, 1)`` → ``(next [B], reward [B])``."""
        ...


@dataclass(frozen=True)
class DynamicsTable:
    """A world's one-step dynamics as a table, the form the compiled engine reads.

    Executing action ``a`` in state ``s`` with the uniform ``u`` gives successor
    ``successors[s, a, k]`` and reward ``rewards[s, a, k]`` for the first slot ``k`` with
    ``u < cdf[s, a, k]`` (``cdf`` non-decreasing along ``k``, its last entry 1). A world whose
    ``dynamics_table()`` returns one must step exactly by :meth:`step` (MultiRooms does), so that
    every engine draws the same successors from the same uniforms.

    Shapes: ``successors [S, A, K]`` int64, ``cdf [S, A, K]`` float64, ``rewards [S, A, K]``
    float64 (a reward per transition ``(s, a, s')``).
    """

    successors: torch.Tensor
    cdf: torch.Tensor
    rewards: torch.Tensor

    def __post_init__(self):
        if (
            not (self.successors.shape == self.cdf.shape == self.rewards.shape)
            or self.cdf.dim() != 3
        ):
            raise ValueError(
                f"DynamicsTable: successors {tuple(self.successors.shape)}, cdf "
                f"{tuple(self.cdf.shape)} and rewards {tuple(self.rewards.shape)} must "
                "share one shape [S, A, K]"
            )
        if not bool(torch.isfinite(self.rewards).all()):
            raise ValueError("DynamicsTable: rewards must be finite")
        if bool((self.cdf.diff(dim=-1) < 0).any()) or not bool((self.cdf[..., -1] == 1.0).all()):
            raise ValueError(
                "DynamicsTable: cdf must be non-decreasing along its last axis and end at 1"
            )

    def step(
        self, positions: torch.Tensor, actions: torch.Tensor, uniforms: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``positions [B], actions [B], uniforms [B]`` → ``(next [B] int64, reward [B] float64)``."""
        actions = actions.long()  # e.g. an Options.policy entry (int8)
        cdf = self.cdf[positions, actions]  # [B, K]
        slot = (cdf <= uniforms.to(torch.float64)[:, None]).sum(1).clamp(max=cdf.shape[1] - 1)
        flat = (positions * self.cdf.shape[1] + actions) * self.cdf.shape[2] + slot
        return (
            self.successors.view(-1).index_select(0, flat),
            self.rewards.view(-1).index_select(0, flat),
        )

    def to(self, device: torch.device | str) -> DynamicsTable:
        return DynamicsTable(
            self.successors.to(device), self.cdf.to(device), self.rewards.to(device)
        )
