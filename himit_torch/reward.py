"""Reward the learner assigns to the mentor's observed transitions (``R_m`` of eq. 2).

A reward module maps mentor transitions ``s → s'`` to rewards, batched. The mentor term at ``s``
uses ``R_m(s) = Σ_{s'} p_m(s'|s) r_m(s, s')``. For learning to stay sound (the paper, after eq. 2),
``R_m`` must not overestimate the learner's real reward: a module declares an ``upper_bound`` and
the learner checks it.
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import torch

__all__ = ["MentorReward", "KnownReward"]


@runtime_checkable
class MentorReward(Protocol):
    """What the learner needs from a reward module."""

    #: The largest reward the module can give; must not exceed the learner's real reward.
    upper_bound: float

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        """``[n]`` rewards for the mentor transitions ``sources[i] → successors[i]``."""
        ...


class KnownReward:
    """The world's own reward (the paper's experiments: ``R_m = R_obs``): the reward for entering
    ``s'``, as the learner itself would get it."""

    def __init__(self, world):
        self.state_reward = world.state_reward.double()
        if not bool(torch.isfinite(self.state_reward).all()):
            raise ValueError("KnownReward: the world's state_reward holds NaN or infinite values")
        self.upper_bound = float(self.state_reward.max())

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        return self.state_reward.to(successors.device)[successors]

    def __repr__(self) -> str:
        return "KnownReward()"
