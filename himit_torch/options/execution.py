"""Executing options: one primitive step of given options from given states, with given uniforms.

An option ``o = (I, π, β)`` (Sutton, Precup & Singh 1999, Sec. 2) acts by its policy ``π`` and,
on arriving in ``s'``, terminates with probability ``β(s')`` (always at a terminal state).
:func:`option_step` is that step for a batch, written once for every torch caller: the torch
engine's tick, the learner's greedy trajectory and the mentor's rollout. The callers keep their
own random streams (counter-based uniforms, ``torch.Generator`` draws), so every draw is an input.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import torch

__all__ = ["OptionTables", "OptionStep", "option_actions", "option_step"]

#: ``step(positions [N], actions [N], uniforms [N]) -> (successors [N], rewards [N])``: one
#: primitive step of the world (slips decided by the uniforms).
WorldStep = Callable[[torch.Tensor, torch.Tensor, torch.Tensor], tuple[torch.Tensor, torch.Tensor]]


@dataclass(frozen=True)
class OptionTables:
    """The options as flat tables: option ``o`` at state ``s`` sits at ``o · S + s``."""

    num_states: int
    termination: torch.Tensor
    """``[O · S]`` β (float32 compares with float64 uniforms exactly as float64 would)."""
    policy: torch.Tensor | None
    """``[O · S]`` deterministic options' actions, or ``None`` (stochastic options)."""
    policy_cdf: torch.Tensor | None
    """``[O · S, A]`` stochastic options' cumulative action probabilities, or ``None``."""

    def __post_init__(self) -> None:
        if (self.policy is None) == (self.policy_cdf is None):
            raise ValueError(
                "OptionTables needs exactly one of policy (deterministic options) and "
                "policy_cdf (stochastic options)"
            )


class OptionStep(NamedTuple):
    """What one primitive step of options did (all ``[N]``)."""

    successors: torch.Tensor
    rewards: torch.Tensor
    at_terminal: torch.Tensor
    """The successor is terminal (the option ends there)."""
    stopped: torch.Tensor
    """The option terminated: at a terminal state, or ``β(s') > stop_u``."""


def option_actions(tables: OptionTables, flat: torch.Tensor, action_u: torch.Tensor | None):
    """The actions of options at ``flat = o · S + s [N]``: the deterministic policy's, or the
    first action whose cumulative probability exceeds ``action_u [N]`` (inverse-cdf sampling;
    ``action_u`` on the scale of the cdf's last entry)."""
    if tables.policy is not None:
        return tables.policy[flat].long()
    assert tables.policy_cdf is not None  # (OptionTables holds one of the two)
    if action_u is None:
        raise ValueError("option_actions: stochastic options need action_u (one uniform each)")
    cdf = tables.policy_cdf
    return (
        torch.searchsorted(cdf[flat], action_u[:, None].contiguous())
        .squeeze(1)
        .clamp(max=cdf.shape[1] - 1)
    )


def option_step(
    tables: OptionTables,
    options: torch.Tensor,
    positions: torch.Tensor,
    step: WorldStep,
    terminal: torch.Tensor,
    slip_u: torch.Tensor,
    stop_u: torch.Tensor,
    action_u: torch.Tensor | None = None,
    actions: torch.Tensor | None = None,
) -> OptionStep:
    """One primitive step of ``options [N]`` from ``positions [N]``: the option's action
    (:func:`option_actions` with ``action_u``, unless ``actions`` were drawn elsewhere), the
    world's ``step`` with ``slip_u``, and the termination test ``β_o(s') > stop_u`` (always
    at a ``terminal`` state).

    Args:
        tables: the options' :class:`OptionTables`.
        terminal: ``[S]`` (or ``[S + 1]``) bool, the terminal states.
        slip_u, stop_u: ``[N]`` uniforms of the world step and of the termination test.
        action_u: ``[N]`` uniforms of stochastic policies (see :func:`option_actions`).
        actions: ``[N]`` actions chosen by the caller (e.g. drawn with ``torch.multinomial``).
    """
    S = tables.num_states
    if actions is None:
        actions = option_actions(tables, options * S + positions, action_u)
    successors, rewards = step(positions, actions, slip_u)
    at_terminal = terminal[successors]
    stopped = at_terminal | (tables.termination[options * S + successors] > stop_u)
    return OptionStep(successors, rewards, at_terminal, stopped)
