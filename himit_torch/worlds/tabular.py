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
    float64 (a reward per transition ``(s, a, s')``), all three tensors (lists and
    arrays are refused rather than converted: their dtype would be a guess), none empty.

    Raises:
        ValueError: not tensors, shapes that differ or are empty, successors that are not int64
            states in ``0…S−1``, a NaN or infinite entry, or a cdf that is not a cumulative
            distribution (a negative probability, not ending at 1).
    """

    successors: torch.Tensor
    cdf: torch.Tensor
    rewards: torch.Tensor

    def __post_init__(self):
        # Tensors only, not array-likes converted here: the dtypes are the contract (int64
        # successors index the tables, float64 cdf is compared with float64 uniforms), and a
        # list of numbers carries none — [[[1]]] would become an int64 cdf, [[[0.0]]] float
        # successors. So the caller says which, with torch.as_tensor(…, dtype=…).
        for name, dtype in (("successors", "int64"), ("cdf", "float64"), ("rewards", "float64")):
            value = getattr(self, name)
            if not isinstance(value, torch.Tensor):
                raise ValueError(
                    f"DynamicsTable.{name} must be a torch.Tensor, got {type(value).__name__}; "
                    f"convert it with torch.as_tensor(…, dtype=torch.{dtype})"
                )
        succ, cdf, rewards = self.successors, self.cdf, self.rewards
        if not (succ.shape == cdf.shape == rewards.shape) or cdf.dim() != 3:
            raise ValueError(
                f"DynamicsTable: successors {tuple(succ.shape)}, cdf {tuple(cdf.shape)} and "
                f"rewards {tuple(rewards.shape)} must share one shape [S, A, K]"
            )
        if 0 in cdf.shape:
            raise ValueError(
                f"DynamicsTable: shape [S, A, K] = {list(cdf.shape)} is empty; a world needs at "
                "least one state, one action and one outcome slot"
            )
        if succ.dtype != torch.int64:
            raise ValueError(f"DynamicsTable.successors must be int64 states, got {succ.dtype}")
        for name, value in (("cdf", cdf), ("rewards", rewards)):
            if not value.is_floating_point():
                raise ValueError(f"DynamicsTable.{name} must be a float tensor, got {value.dtype}")
            if not bool(torch.isfinite(value).all()):
                raise ValueError(f"DynamicsTable.{name} must be finite (it holds NaN or ±inf)")
        S = cdf.shape[0]
        if int(succ.min()) < 0 or int(succ.max()) >= S:
            raise ValueError(
                f"DynamicsTable.successors hold states outside 0…{S - 1} (S = {S}, the first "
                "dimension)"
            )
        if bool((cdf[..., 0] < 0).any()):
            raise ValueError(
                "DynamicsTable.cdf: a negative probability (cdf[s, a, 0] < 0); the cdf holds "
                "cumulative probabilities in [0, 1]"
            )
        if bool((cdf.diff(dim=-1) < 0).any()) or not bool((cdf[..., -1] == 1.0).all()):
            raise ValueError(
                "DynamicsTable.cdf must be non-decreasing along its last axis and end at 1 "
                "(a negative probability makes it decrease)"
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
