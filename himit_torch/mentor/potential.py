"""A shaping potential from state-only demonstrations: the value of the mentor's observed chain.

Potential-based reward shaping (Ng, Harada & Russell 1999, *Policy invariance under reward
transformations*) adds ``F(s, s') = γ Φ(s') − Φ(s)`` to every step's reward; over an option that
runs ``k`` steps from ``s`` to ``s'`` the terms telescope to ``γ^k Φ(s') − Φ(s)``
(:func:`~himit_torch.learner.backups.shaped_option_backup`). Any ``Φ`` with ``Φ = 0`` at the
terminal states leaves the optimal policies unchanged. Brys et al. 2015 (*Reinforcement learning
from demonstration through shaping*) take ``Φ`` from demonstrations; with state-only
demonstrations the natural potential is what the demonstrations say a state is worth.

Definition (:func:`shaping_potential`). With ``p_m(s'|s)`` the demonstrations' transition counts,
normalised, and ``R_m(s) = Σ_{s'} p_m(s'|s) r_m(s, s')`` from the mentor-reward module the
imitators use, the **chain value** ``W`` solves, on the states ``s`` the mentor was seen leaving::

    W(s) = R_m(s) + γ Σ_{s'} p_m(s'|s) W(s'),

with ``W = 0`` at terminal states and ``W = v0`` (the learner's ``initial_value``) at every other
state the mentor was not seen leaving (a coarse or cut demonstration ends there). Then::

    Φ(s) = W(s) − v0   where the mentor was seen leaving s,     Φ(s) = 0   elsewhere.

Why these two constants:

* **0 off the mentor's states.** A constant ``c`` there shapes a move between two such states by
  ``(γ^k − 1) c``, which is 0 for every ``k`` only when ``c = 0``: with 0, everywhere the mentor
  was never seen the run is left exactly as the unshaped one (and ``Φ = 0`` at terminal states,
  which the invariance needs in episodic tasks).
* **``− v0`` on them.** Shaping is equivalent to starting the values at ``v0 + Φ`` (Wiewiora
  2003; :func:`~himit_torch.learner.backups.shaped_option_backup` says how exactly that holds in
  this learner). With ``Φ = W − v0`` a shaped run starts at ``W(s)``, the chain's value, on the
  mentor's states and at ``v0`` elsewhere. ``Φ = W`` would start it at ``v0 + W``, counting the
  value of never reaching the goal twice (with the paper's ``v0 = −1``: below ``v0`` wherever
  ``W < 0``, which would steer the run *away* from the mentor's path far from the goal).

``p_m`` is the maximum-likelihood model (``LearnerConfig.mentor_concentration`` is the mentor
term's prior, not the potential's). With an observation stride the mentor's moves span several
steps and ``γ`` per move undercounts the discount; the potential stays a potential (the optimal
policy is unchanged whatever ``Φ`` is), only its quality changes.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch

from himit_torch.validation import as_float

__all__ = ["mentor_chain_value", "shaping_potential"]


def _check_state_columns(where: str, sources: torch.Tensor, successors: torch.Tensor) -> None:
    """``sources`` and ``successors`` hold state indices: an integer tensor each (a float one
    would be truncated to states it never named; a bool one is a mask, not states)."""
    for name, column in (("sources", sources), ("successors", successors)):
        if not isinstance(column, torch.Tensor):
            raise TypeError(
                f"{where}: {name} must be a tensor of states, got {type(column).__name__}"
            )
        if column.dtype.is_floating_point or column.dtype.is_complex or column.dtype == torch.bool:
            raise ValueError(
                f"{where}: {name} must hold whole state indices (an integer tensor, e.g. "
                f"int64), got {column.dtype}; states are never truncated"
            )


def mentor_chain_value(
    sources: torch.Tensor,
    successors: torch.Tensor,
    counts: torch.Tensor,
    rewards: torch.Tensor,
    gamma: float,
    terminal: torch.Tensor,
    outside_value: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The value ``W`` of the mentor's observed chain (module docstring): the solution of
    ``W(s) = R_m(s) + γ Σ_{s'} p_m(s'|s) W(s')`` on the states the mentor was seen leaving, with
    ``W = 0`` at terminal states and ``outside_value`` at the others.

    Args:
        sources, successors: ``[E]`` int64, the observed moves ``s → s'`` (each pair once or
            more; repeated pairs add up).
        counts: ``[E]`` positive float, how often each move was seen.
        rewards: ``[E]`` ``r_m(s, s')`` of each move (the mentor-reward module's).
        gamma: the discount per move, in ``(0, 1]``.
        terminal: ``[S]`` bool.
        outside_value: ``W`` at non-terminal states the mentor was never seen leaving.

    Returns:
        ``(W [S] float64, seen [S] bool)``: ``seen`` where the mentor was seen leaving.

    Raises:
        ValueError: on mismatched shapes, states that are not an integer tensor (a float
            ``1.7`` is never truncated), a state out of range, a move out of a terminal state,
            a count that is not positive, or a chain with no way out at ``γ = 1`` (the system
            is singular).

    A chain a → b → goal (entering b pays −0.01, the goal +1; γ = 0.9): ``W(b) = 1``,
    ``W(a) = −0.01 + 0.9 · 1 = 0.89``.

    >>> import torch
    >>> W, seen = mentor_chain_value(
    ...     torch.tensor([0, 1]), torch.tensor([1, 2]), torch.tensor([1.0, 1.0]),
    ...     torch.tensor([-0.01, 1.0]), 0.9, torch.tensor([False, False, True, False]), -1.0)
    >>> [round(float(w), 4) for w in W], seen.tolist()
    ([0.89, 1.0, 0.0, -1.0], [True, True, False, False])
    """
    _check_state_columns("mentor_chain_value", sources, successors)
    for name, column in (("counts", counts), ("rewards", rewards), ("terminal", terminal)):
        if not isinstance(column, torch.Tensor):
            raise TypeError(
                f"mentor_chain_value: {name} must be a tensor, got {type(column).__name__}"
            )
    gamma = as_float("mentor_chain_value: gamma", gamma, 0.0, 1.0, low_open=True)
    outside_value = as_float("mentor_chain_value: outside_value", outside_value)
    E = sources.shape[0]
    if not (sources.shape == successors.shape == counts.shape == rewards.shape == (E,)):
        raise ValueError(
            f"mentor_chain_value: sources {tuple(sources.shape)}, successors "
            f"{tuple(successors.shape)}, counts {tuple(counts.shape)} and rewards "
            f"{tuple(rewards.shape)} must be four [E] tensors"
        )
    if terminal.dim() != 1 or terminal.dtype != torch.bool:
        raise ValueError("mentor_chain_value: terminal must be a [S] bool tensor")
    if not 0 < gamma <= 1:
        raise ValueError(f"mentor_chain_value: gamma={gamma} must lie in (0, 1]")
    S = terminal.shape[0]
    src = sources.cpu().long().numpy()
    dst = successors.cpu().long().numpy()
    c = counts.cpu().double().numpy()
    r = rewards.cpu().double().numpy()
    is_terminal = terminal.cpu().numpy()
    if E and (min(src.min(), dst.min()) < 0 or max(src.max(), dst.max()) >= S):
        raise ValueError(f"mentor_chain_value: states must lie in 0…{S - 1}")
    if E and not (np.isfinite(c).all() and (c > 0).all() and np.isfinite(r).all()):
        raise ValueError("mentor_chain_value: counts must be positive and rewards finite")
    if E and is_terminal[src].any():
        raise ValueError(
            "mentor_chain_value: a move out of a terminal state (an episode ends there)"
        )
    values = np.where(is_terminal, 0.0, float(outside_value))
    seen = np.zeros(S, dtype=bool)
    seen[src] = True
    states = np.flatnonzero(seen)
    if states.size:
        index = np.full(S, -1, dtype=np.int64)
        index[states] = np.arange(states.size)
        total = np.zeros(S)
        np.add.at(total, src, c)
        p = c / total[src]
        reward = np.zeros(states.size)
        np.add.at(reward, index[src], p * r)
        # Moves to states outside the chain bring their fixed values in as constants.
        inside = seen[dst]
        constant = reward.copy()
        np.add.at(constant, index[src[~inside]], gamma * p[~inside] * values[dst[~inside]])
        n = states.size
        chain = sp.csc_matrix(
            (gamma * p[inside], (index[src[inside]], index[dst[inside]])), shape=(n, n)
        )
        system = sp.identity(n, format="csc") - chain
        try:
            solution = spla.splu(system).solve(constant)
        except RuntimeError as error:  # "Factor is exactly singular"
            solution = np.full(n, np.nan)
            reason = str(error)
        else:
            reason = "non-finite solution"
        if not np.isfinite(solution).all():
            raise ValueError(
                f"mentor_chain_value: the chain's equations have no unique solution ({reason}): "
                "with γ = 1 some observed states never lead out of themselves; use γ < 1 or "
                "demonstrations that end at terminal states"
            )
        values[states] = solution
    return torch.from_numpy(values), torch.from_numpy(seen)


def shaping_potential(
    sources: torch.Tensor,
    successors: torch.Tensor,
    counts: torch.Tensor,
    rewards: torch.Tensor,
    gamma: float,
    terminal: torch.Tensor,
    initial_value: float,
) -> torch.Tensor:
    """The shaping potential of the demonstrations (module docstring): ``Φ(s) = W(s) − v0``
    where the mentor was seen leaving ``s`` (``W``: :func:`mentor_chain_value` with
    ``outside_value = v0``), 0 elsewhere, terminal states included. Arguments as
    :func:`mentor_chain_value`'s, ``initial_value`` the learner's ``v0``.

    Returns ``[S]`` float64. Raises as :func:`mentor_chain_value` does (``sources`` and
    ``successors`` an integer tensor each: float states are refused, never truncated).

    The chain above, with ``v0 = −1``: ``Φ(a) = 0.89 + 1``, ``Φ(b) = 1 + 1``, 0 at the goal and
    at the state never seen.

    >>> import torch
    >>> phi = shaping_potential(
    ...     torch.tensor([0, 1]), torch.tensor([1, 2]), torch.tensor([1.0, 1.0]),
    ...     torch.tensor([-0.01, 1.0]), 0.9, torch.tensor([False, False, True, False]), -1.0)
    >>> [round(float(x), 4) for x in phi]
    [1.89, 2.0, 0.0, 0.0]
    """
    _check_state_columns("shaping_potential", sources, successors)
    initial_value = as_float("shaping_potential: initial_value", initial_value)
    W, seen = mentor_chain_value(
        sources, successors, counts, rewards, gamma, terminal, initial_value
    )
    return torch.where(seen, W - float(initial_value), torch.zeros_like(W))
