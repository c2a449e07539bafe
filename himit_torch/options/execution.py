"""Executing options: one primitive step of given options from given states, with given uniforms.

An option ``o = (I, π, β)`` (Sutton, Precup & Singh 1999, Sec. 2) acts by its policy ``π`` and,
on arriving in ``s'``, terminates with probability ``β(s')`` (always at a terminal state).
:func:`option_step` is that step for a batch, written once for every torch caller: the torch
engine's tick, the learner's greedy trajectory and the mentor's rollout. The callers keep their
own random streams (counter-based uniforms, ``torch.Generator`` draws), so every draw is an input.
:func:`option_step_in_numbers` is the same step for one deterministic option from one state,
in Python numbers, for the callers that walk one state at a time (a path, a few episodes).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import torch

if TYPE_CHECKING:
    from himit_torch.worlds.tabular import DynamicsTable

__all__ = ["OptionTables", "OptionStep", "option_actions", "option_step", "option_step_in_numbers"]

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


def option_step_in_numbers(
    tables: OptionTables, dynamics: DynamicsTable, terminal: Sequence[bool]
) -> Callable[[int, int, float, float], tuple[int, bool]]:
    """``move(option, s, slip_u, stop_u) -> (s', stopped)``: :func:`option_step` of one
    deterministic option from one state, in Python numbers, on a world that steps by
    ``dynamics`` (its :class:`~himit_torch.DynamicsTable`); ``terminal``: the terminal states'
    flags as a sequence of bools.

    The same step to the bit: the action is the option's, the slot the first whose cumulative
    probability exceeds ``slip_u`` (as :meth:`DynamicsTable.step
    <himit_torch.DynamicsTable.step>` counts the entries ``≤ slip_u``: the cdf is
    non-decreasing), and the option stops at a terminal state or where ``β(s') > stop_u`` (β's
    float32 read exactly as a Python float, as torch compares it with a float64 uniform). Give
    ``slip_u`` as the caller's step would see it (a float32 uniform rounded to float32 first).
    A step of torch ops on one state costs ≈ 0.2 ms, this one a few µs.

    Raises:
        ValueError: the options are stochastic (``tables.policy`` is ``None``).
    """
    if tables.policy is None:
        raise ValueError(
            "option_step_in_numbers: stochastic options (OptionTables.policy_cdf) draw their "
            "actions; step them with option_step"
        )
    S = tables.num_states
    A, K = dynamics.cdf.shape[1:]
    slot_cdf = dynamics.cdf.reshape(-1).tolist()  # (S·A·K numbers, ≈ 230k on 120×120)
    successor = dynamics.successors.reshape(-1).tolist()
    action = tables.policy.cpu().numpy()  # (O·S entries: read one at a time, not listed)
    beta = tables.termination.cpu().numpy()

    def move(option: int, s: int, slip_u: float, stop_u: float) -> tuple[int, bool]:
        flat = (s * A + action.item(option * S + s)) * K
        k = 0
        while k < K - 1 and slot_cdf[flat + k] <= slip_u:
            k += 1
        after = successor[flat + k]
        return after, terminal[after] or beta.item(option * S + after) > stop_u

    return move
