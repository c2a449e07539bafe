"""Bellman backups of the paper, as pure functions on batched tensors.

Naming follows rlax: a leading ``...`` is any batch shape (runs, states); ``K`` indexes successor
slots (padding slots carry weight 0); ``J`` indexes the options available in a state; ``A``
primitive actions. Each function cites the equation it implements.

These functions are the learner's backups (the torch engine's and every diagnostic's): its value
cache (:mod:`himit_torch.learner.values`) keeps the sums over successors as cached numerators,
updated incrementally, and hands them to :func:`trusted_augmented_backup` (eq. 2 with the
learner's rules for trusting the mentor term, :func:`confident_mentor`, :func:`mentor_override`
and :func:`faded_mentor_term`). Where a sum over successors is computed from scratch it is the
sparse form the models keep, per-run edge lists (:func:`option_backup_edges`,
:func:`mentor_backup_edges`). Tests check the incremental caches against these from-scratch sums.

Each function first checks the kinds, ranks and shapes of its arguments (as rlax asserts them):
an argument that is no tensor (a list, ``None``, a NumPy array), a mask that is not a bool
tensor, or an argument of another shape is a ``ValueError`` naming the function, the argument,
its shape and the shape expected, never a silent broadcast or an ``AttributeError``. The checks
compare types, dtypes and shapes only (no tensor op): a few microseconds a call
(``benchmarks/bench_arg_checks.py``: ≈ 5 µs for :func:`augmented_backup`'s, where declaring
the same kinds, dtypes and shapes with jaxtyping annotations checked by beartype costs
≈ 170 µs, and refuses a list with a ``TypeCheckError`` of several lines).
"""

from __future__ import annotations

import numbers
from typing import Any, NamedTuple

import numpy as np
import torch

__all__ = [
    "option_backup",
    "option_backup_edges",
    "mentor_backup_edges",
    "shaped_option_backup",
    "mentor_backup",
    "segment_reward",
    "segment_discount",
    "segment_mentor_backup",
    "augmented_option_backup",
    "augmented_primitive_backup",
    "options_only_backup",
    "primitives_only_backup",
    "dirichlet_value_moments",
    "dirichlet_variance",
    "confident_mentor",
    "MentorConfidence",
    "mentor_override",
    "feasible_mentor",
    "best_mentor",
    "faded_mentor_term",
    "augmented_backup",
    "trusted_augmented_backup",
]


def _shape_text(x: Any) -> str:
    shape = getattr(x, "shape", None)
    return f"shape {tuple(shape)}" if shape is not None else f"no shape (a {type(x).__name__})"


def _refuse(function: str, name: str, x: Any, expected: str) -> ValueError:
    """The error for argument ``name`` of ``function`` whose shape is not ``expected``."""
    return ValueError(f"{function}: {name} has {_shape_text(x)}; expected {expected}")


def _rank(function: str, name: str, x: Any, least: int, spec: str) -> None:
    """Refuse ``x`` unless it is a tensor of rank ``least`` or more (``spec``: ``[..., K]``)."""
    if not isinstance(x, torch.Tensor) or x.ndim < least:
        raise _refuse(function, name, x, f"a tensor {spec} (rank ≥ {least})")


def _same(function: str, spec: str, shape: Any, **named: Any) -> None:
    """Refuse each of ``named`` that is not a tensor of shape ``shape`` (``spec`` says which it
    is)."""
    for name, x in named.items():
        if not isinstance(x, torch.Tensor) or x.shape != shape:
            raise _refuse(function, name, x, f"a tensor {spec} = {tuple(shape)}")


def _masks(function: str, **named: Any) -> None:
    """Refuse each of ``named`` that is not a bool tensor (a mask; 0/1 numbers are not one)."""
    for name, x in named.items():
        if x.dtype != torch.bool:
            raise ValueError(f"{function}: {name} has dtype {x.dtype}; expected a bool mask")


def _number(function: str, name: str, x: Any) -> None:
    """Refuse ``x`` unless it is a real number (not a bool, not a tensor)."""
    if type(x) is float or type(x) is int:  # the common case, without the ABC's check
        return
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Real):
        raise ValueError(f"{function}: {name}={x!r} ({type(x).__name__}); expected a real number")


def _broadcasts(shape: Any, to: Any) -> bool:
    """Whether a tensor of ``shape`` broadcasts to ``to`` without growing it (shapes only)."""
    if len(shape) > len(to):
        return False
    return all(a == 1 or a == b for a, b in zip(reversed(shape), reversed(to)))


def option_backup(
    reward: torch.Tensor, weights: torch.Tensor, successor_values: torch.Tensor
) -> torch.Tensor:
    """Option value with a multi-time model (Sutton, Precup & Singh 1999; paper Sec. II)::

        Q(s, o) = r(s, o) + Σ_{s'} p^o_{ss'} V(s')

    Args:
        reward: ``[...]`` expected discounted reward ``r(s, o)``.
        weights: ``[..., K]`` multi-time weights ``p^o_{ss'} = Σ_k p(s', k) γ^k``.
        successor_values: ``[..., K]`` ``V(s')`` of the same successors.

    An option that earns −0.02 and ends in ``s'₁`` after 2 steps with probability 0.5 or in
    ``s'₂`` after 3 steps otherwise (γ = 0.9: weights 0.5·0.81 and 0.5·0.729):

    >>> import torch
    >>> q = option_backup(torch.tensor(-0.02), torch.tensor([0.405, 0.3645]), torch.tensor([1.0, -1.0]))
    >>> round(float(q), 4)
    0.0205
    """
    _rank("option_backup", "weights", weights, 1, "[..., K]")
    _same("option_backup", "[..., K] as weights", weights.shape, successor_values=successor_values)
    _same("option_backup", "[...], weights' without K", weights.shape[:-1], reward=reward)
    return reward + (weights * successor_values).sum(-1)


def option_backup_edges(
    reward: torch.Tensor,
    runs: torch.Tensor,
    rows: torch.Tensor,
    weights: torch.Tensor,
    successor_values: torch.Tensor,
) -> torch.Tensor:
    """:func:`option_backup` over the sparse form the models keep, a COO edge list batched over
    runs (Sutton, Precup & Singh 1999; paper Sec. II)::

        Q[b, m] = r[b, m] + Σ_{e : runs_e = b, rows_e = m} w_e V_e

    Each row's sum runs in edge order (so a row rebuilt from its edges is reproducible).

    Args:
        reward: ``[B, M]`` ``r(s, o)`` per run and row.
        runs, rows: ``[N]`` int64, each edge's run and row.
        weights: ``[N]`` ``p^o_{ss'}`` of each edge.
        successor_values: ``[N]`` ``V(s')`` of each edge's successor.
    Returns a new ``[B, M]`` tensor.
    """
    if not isinstance(reward, torch.Tensor) or reward.ndim != 2:
        raise _refuse("option_backup_edges", "reward", reward, "[B, M] (rank 2)")
    if not isinstance(runs, torch.Tensor) or runs.ndim != 1:
        raise _refuse("option_backup_edges", "runs", runs, "[N] (rank 1)")
    _same(
        "option_backup_edges",
        "[N] as runs",
        runs.shape,
        rows=rows,
        weights=weights,
        successor_values=successor_values,
    )
    out = reward.clone()
    out.view(-1).index_add_(0, runs * reward.shape[1] + rows, weights * successor_values)
    return out


def mentor_backup_edges(
    shape: tuple[int, int],
    runs: torch.Tensor,
    rows: torch.Tensor,
    counts: torch.Tensor,
    rewards: torch.Tensor,
    discounts: torch.Tensor,
    successor_values: torch.Tensor,
) -> torch.Tensor:
    """The mentor term's sum over the sparse form the mentor model keeps, a COO edge list of
    observed moves batched over runs (Price & Boutilier 2003; paper eq. 1–2; the segment form
    of ``LearnerConfig.mentor_segments``)::

        N[b, m] = Σ_{e : runs_e = b, rows_e = m} c_e (r_e + d_e V_e)

    the numerator of the mentor term of row ``m`` (a state, per mentor): divided by the row's
    count ``n = Σ c_e`` it is :func:`segment_mentor_backup` with ``p_m = c / n``, and with every
    move one step (``d_e = γ``) :func:`mentor_backup` with ``R_m(s) = Σ p_m r_e``. Each row's
    sum runs in edge order (so a row rebuilt from its edges is reproducible).

    Args:
        shape: ``(B, M)``, the runs and the mentor rows of the output.
        runs, rows: ``[N]`` int64, each edge's run (``0 … B − 1``) and mentor row (``0 … M − 1``).
        counts: ``[N]`` ``c_e``, how often the move was observed.
        rewards: ``[N]`` ``r_e``, the reward the learner assigns the move (:func:`segment_reward`
            of it with segments).
        discounts: ``[N]`` ``d_e = E[γ^k]`` of the move (:func:`segment_discount`; ``γ`` for one
            step).
        successor_values: ``[N]`` ``V(s')`` of the move's successor.
    Returns a new ``[B, M]`` tensor of ``counts``' dtype (0 in a row without edges).

    Run 0 was seen twice moving ``0 → 1`` (``r = −0.01``, ``V(1) = 0.5``) and once ``0 → 2`` in
    3 steps (``r = −0.0271``, ``d = 0.729``, ``V(2) = 1``); γ = 0.9:
    ``2 (−0.01 + 0.45) + (−0.0271 + 0.729) = 1.5819``.

    >>> import torch
    >>> n = mentor_backup_edges((1, 2), torch.tensor([0, 0]), torch.tensor([0, 0]),
    ...                         torch.tensor([2.0, 1.0]), torch.tensor([-0.01, -0.0271]),
    ...                         torch.tensor([0.9, 0.729]), torch.tensor([0.5, 1.0]))
    >>> [round(x, 4) for x in n[0].tolist()]
    [1.5819, 0.0]
    """
    if not isinstance(runs, torch.Tensor) or runs.ndim != 1:
        raise _refuse("mentor_backup_edges", "runs", runs, "[N] (rank 1)")
    _same(
        "mentor_backup_edges",
        "[N] as runs",
        runs.shape,
        rows=rows,
        counts=counts,
        rewards=rewards,
        discounts=discounts,
        successor_values=successor_values,
    )
    if (
        not isinstance(shape, (tuple, list))
        or len(shape) != 2
        or not all(isinstance(n, numbers.Integral) and not isinstance(n, bool) for n in shape)
    ):
        raise ValueError(
            f"mentor_backup_edges: shape={shape!r}; expected (B, M), two whole-number sizes"
        )
    out = torch.zeros(shape, dtype=counts.dtype, device=counts.device)
    out.view(-1).index_add_(
        0, runs * shape[1] + rows, counts * (rewards + discounts * successor_values)
    )
    return out


def shaped_option_backup(
    reward: torch.Tensor,
    weights: torch.Tensor,
    successor_values: torch.Tensor,
    potential: torch.Tensor,
    successor_potentials: torch.Tensor,
) -> torch.Tensor:
    """Option value with potential-based shaping (Ng, Harada & Russell 1999; Brys et al. 2015)
    on a multi-time model::

        Q'(s, o) = r(s, o) + Σ_{s'} p^o_{ss'} [V'(s') + Φ(s')] − Φ(s)

    An option run ``k`` steps from ``s`` to ``s'`` earns the shaped return
    ``Σ_t γ^t (r_t + γ Φ(s_{t+1}) − Φ(s_t)) = Σ_t γ^t r_t + γ^k Φ(s') − Φ(s)``: the shaping terms
    telescope, so in expectation they add ``Σ_{s'} p^o_{ss'} Φ(s') − Φ(s)`` (``p^o`` carries
    ``γ^k``) to :func:`option_backup`. ``Φ`` must be 0 at terminal states (their ``V'`` is 0).

    **Invariance.** If ``V' = V − Φ`` then ``Q' = Q − Φ(s)``: at every state all options move by
    the same ``Φ(s)``, so the greedy and the optimal options are those of the unshaped model
    (``tests/exact``: value iteration on shaped and unshaped option models).

    **Wiewiora (2003): shaping ≡ initial values.** A learner that shapes with ``Φ`` and starts at
    ``V'₀`` makes the same choices as the unshaped learner started at ``V'₀ + Φ`` on the same
    experience. Here it holds exactly, not only for Q-learning: in ``U = V' + Φ`` the shaped
    backup *is* :func:`option_backup` (``Q' + Φ(s) = r + Σ p^o U(s')``), choices compare ``Q'`` at
    one state (so ``Φ(s)`` cancels), and sweeping priorities are differences (``Φ`` cancels).
    What it changes is where the learner uses a value it has not learned: the start value ``v0``
    of every state becomes ``v0 + Φ(s)``. The learner implements exactly that (``pbrs`` agents:
    :meth:`~himit_torch.learner.values.ValueCache.set_potential`; its ``V`` holds ``U``), and
    refuses the two other places the prior enters (``concentration > 0``, whose unseen outcome
    would be worth ``v0 + Φ(s)``, and ``untried_value``, which would be ``u + Φ(s)``), which it
    does not shift.

    Args:
        reward: ``[...]`` ``r(s, o)``; weights: ``[..., K]`` multi-time weights
            ``p^o_{ss'} = Σ_k p(s', k) γ^k``; successor_values: ``[..., K]`` the shaped values
            ``V'(s')``; potential: ``[...]`` ``Φ(s)``; successor_potentials: ``[..., K]``
            ``Φ(s')``.

    One step (γ = 0.9) from ``s`` (``Φ = 2``) to ``s'`` (``Φ = 1``, ``V' = 0.5``) paying −0.01:
    ``−0.01 + 0.9 · (0.5 + 1) − 2 = −0.66``.

    >>> import torch
    >>> q = shaped_option_backup(torch.tensor(-0.01), torch.tensor([0.9]), torch.tensor([0.5]),
    ...                          torch.tensor(2.0), torch.tensor([1.0]))
    >>> round(float(q), 4)
    -0.66
    """
    f = "shaped_option_backup"
    _rank(f, "weights", weights, 1, "[..., K]")
    _same(f, "[..., K] as weights", weights.shape, successor_values=successor_values)
    _same(f, "[..., K] as weights", weights.shape, successor_potentials=successor_potentials)
    _same(f, "[...], weights' without K", weights.shape[:-1], reward=reward, potential=potential)
    return option_backup(reward, weights, successor_values + successor_potentials) - potential


def mentor_backup(
    mentor_reward: torch.Tensor,
    mentor_probs: torch.Tensor,
    successor_values: torch.Tensor,
    gamma: float,
) -> torch.Tensor:
    """Value of duplicating the mentor's (unseen) action (Price & Boutilier 2003; paper eq. 1–2)::

        R_m(s) + γ Σ_{s'} p_m(s' | s) V(s')

    Args:
        mentor_reward: ``[...]`` ``R_m(s)``, the reward the learner assigns to the mentor.
        mentor_probs: ``[..., K]`` ``p_m(s' | s)``.
        successor_values: ``[..., K]``.
    """
    _rank("mentor_backup", "mentor_probs", mentor_probs, 1, "[..., K]")
    _same(
        "mentor_backup",
        "[..., K] as mentor_probs",
        mentor_probs.shape,
        successor_values=successor_values,
    )
    _same(
        "mentor_backup",
        "[...], mentor_probs' without K",
        mentor_probs.shape[:-1],
        mentor_reward=mentor_reward,
    )
    return mentor_reward + gamma * (mentor_probs * successor_values).sum(-1)


def segment_reward(
    last_reward: torch.Tensor,
    delay: torch.Tensor,
    unseen_step_reward: torch.Tensor | float,
    gamma: float,
) -> torch.Tensor:
    """Expected discounted reward of an observed mentor move of ``k`` primitive steps, scored as
    an option is (SMDP form; Sutton, Precup & Singh 1999; ``LearnerConfig.mentor_segments``)::

        r̃(s, s') = E[ Σ_{i<k−1} γ^i u + γ^(k−1) r_m(s, s') ]
                 = u (1 − d̄) / (1 − γ) + d̄ r_m(s, s'),      d̄ = E[γ^(k−1)]

    Only the move's ends are seen: its last step earns what the reward module gives the observed
    transition (``r_m(s, s')``); each unseen step before it earns ``u``
    (``unseen_step_reward``; the learner takes the least reward its module gives any of the
    run's observed moves, so that ``u`` never exceeds what the mentor was seen earning for a
    step). With every move one step (``d̄ = 1``) it is ``r_m(s, s')`` exactly.

    Args:
        last_reward: ``[...]`` ``r_m(s, s')``.
        delay: ``[...]`` ``d̄ = E[γ^(k−1)]`` over the edge's observations (``edge_delay /
            edge_count``), in ``(0, 1]``.
        unseen_step_reward: ``u``, ``[...]`` or a number.
        gamma: the world's discount, ``< 1`` (a move of unknown length cannot be summed at 1).

    A 3-step move into the goal (``+1``) with ``u = −0.01``, ``γ = 0.9``:
    ``−0.01 (1 + 0.9) + 0.81 · 1 = 0.791``.

    >>> import torch
    >>> round(float(segment_reward(torch.tensor(1.0), torch.tensor(0.81), -0.01, 0.9)), 6)
    0.791
    """
    _rank("segment_reward", "last_reward", last_reward, 0, "[...]")
    _same("segment_reward", "[...] as last_reward", last_reward.shape, delay=delay)
    if not isinstance(unseen_step_reward, torch.Tensor):
        _number("segment_reward", "unseen_step_reward", unseen_step_reward)
    elif unseen_step_reward.shape not in ((), last_reward.shape):
        raise _refuse(
            "segment_reward",
            "unseen_step_reward",
            unseen_step_reward,
            f"a number, [] or [...] as last_reward = {tuple(last_reward.shape)}",
        )
    _number("segment_reward", "gamma", gamma)
    if not 0 < gamma < 1:
        raise ValueError(
            f"segment_reward: gamma={gamma}; the segment term needs a discount in (0, 1)"
        )
    return unseen_step_reward * (1 - delay) / (1 - gamma) + delay * last_reward


def segment_discount(delay: torch.Tensor, gamma: float) -> torch.Tensor:
    """``E[γ^k] = γ · E[γ^(k−1)]``: the discount of an observed mentor move's successor value
    (:func:`segment_reward`'s ``delay``, ``[...]``: any shape); ``γ`` for one-step moves."""
    _rank("segment_discount", "delay", delay, 0, "a tensor [...]")
    return gamma * delay


def segment_mentor_backup(
    segment_rewards: torch.Tensor,
    segment_discounts: torch.Tensor,
    mentor_probs: torch.Tensor,
    successor_values: torch.Tensor,
) -> torch.Tensor:
    """The mentor term over segments (SMDP form; ``LearnerConfig.mentor_segments``): each
    observed move ``s → s'`` scored as an option is, with its discounted reward and discount::

        M(s) = Σ_{s'} p_m(s'|s) ( r̃(s, s') + E[γ^k](s, s') V(s') )

    With every move one step (``r̃ = r_m``, ``E[γ^k] = γ``) it is :func:`mentor_backup`.

    Args:
        segment_rewards: ``[..., K]`` :func:`segment_reward` per successor.
        segment_discounts: ``[..., K]`` :func:`segment_discount` per successor.
        mentor_probs, successor_values: ``[..., K]``.

    Two moves seen from ``s``: to ``a`` in 1 step (twice), to ``b`` in 3 steps (once);
    ``γ = 0.9``, ``r̃ = (−0.01, −0.0271)``, ``V = (0.5, 1.0)``:
    ``(2/3)(−0.01 + 0.9 · 0.5) + (1/3)(−0.0271 + 0.729 · 1.0) = 0.52730``.

    >>> import torch
    >>> m = segment_mentor_backup(torch.tensor([-0.01, -0.0271]), torch.tensor([0.9, 0.729]),
    ...                           torch.tensor([2 / 3, 1 / 3]), torch.tensor([0.5, 1.0]))
    >>> round(float(m), 5)
    0.5273
    """
    _rank("segment_mentor_backup", "mentor_probs", mentor_probs, 1, "[..., K]")
    _same(
        "segment_mentor_backup",
        "[..., K] as mentor_probs",
        mentor_probs.shape,
        segment_rewards=segment_rewards,
        segment_discounts=segment_discounts,
        successor_values=successor_values,
    )
    return (mentor_probs * (segment_rewards + segment_discounts * successor_values)).sum(-1)


def options_only_backup(option_q: torch.Tensor, available: torch.Tensor) -> torch.Tensor:
    """SMDP Bellman optimality (paper Sec. II): ``V(s) = max_{o ∈ O(s)} Q(s, o)``. States with
    no available option get ``-inf``: every state, where there are no options at all (``J = 0``).

    Args:
        option_q: ``[..., J]``; available: ``[..., J]`` bool.
    """
    _rank("options_only_backup", "option_q", option_q, 1, "[..., J]")
    _same("options_only_backup", "[..., J] as option_q", option_q.shape, available=available)
    _masks("options_only_backup", available=available)
    if option_q.shape[-1] == 0:  # no option at all (J = 0): nothing is available anywhere
        return torch.full(option_q.shape[:-1], float("-inf"), dtype=option_q.dtype,
                          device=option_q.device)  # fmt: skip
    neg_inf = torch.full_like(option_q, float("-inf"))
    return torch.where(available, option_q, neg_inf).max(-1).values


def augmented_option_backup(
    option_q: torch.Tensor,
    available: torch.Tensor,
    mentor_term: torch.Tensor,
    mentor_available: torch.Tensor,
) -> torch.Tensor:
    """The paper's eq. 2, the augmented Bellman equation with options::

        V(s) = max( max_{o ∈ O_obs(s)} Q(s, o),  R_m(s) + γ Σ p_m(s'|s) V(s') )

    Args:
        option_q: ``[..., J]`` option values (:func:`option_backup`).
        available: ``[..., J]`` bool.
        mentor_term: ``[...]`` (:func:`mentor_backup`).
        mentor_available: ``[...]`` bool, where the mentor was observed (and its term is trusted).
    """
    _rank("augmented_option_backup", "option_q", option_q, 1, "[..., J]")
    _same("augmented_option_backup", "[..., J] as option_q", option_q.shape, available=available)
    _same(
        "augmented_option_backup",
        "[...], option_q's without J",
        option_q.shape[:-1],
        mentor_term=mentor_term,
        mentor_available=mentor_available,
    )
    _masks("augmented_option_backup", available=available, mentor_available=mentor_available)
    own = options_only_backup(option_q, available)
    return augmented_backup(own, mentor_term, mentor_available)[0]


def augmented_backup(
    own_value: torch.Tensor, mentor_term: torch.Tensor, mentor_available: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The outer max of the paper's eq. 2: ``V(s) = max(own value, mentor term)`` where the
    mentor term is available, else the own value.

    Args:
        own_value: ``[...]`` :func:`options_only_backup`; mentor_term: ``[...]``;
        mentor_available: ``[...]`` bool.
    Returns ``(V [...], mentor_won [...] bool)``: where the mentor term is available and above
    the own value.

    >>> import torch
    >>> value, won = augmented_backup(
    ...     torch.tensor([-0.5, -0.5, -0.5]),  # own value
    ...     torch.tensor([-0.2, -0.9, -0.2]),  # mentor term
    ...     torch.tensor([True, True, False]),  # where the mentor was seen
    ... )
    >>> value, won
    (tensor([-0.2000, -0.5000, -0.5000]), tensor([ True, False, False]))
    """
    _rank("augmented_backup", "own_value", own_value, 0, "[...]")
    _same(
        "augmented_backup",
        "[...] as own_value",
        own_value.shape,
        mentor_term=mentor_term,
        mentor_available=mentor_available,
    )
    _masks("augmented_backup", mentor_available=mentor_available)
    return (
        torch.where(mentor_available, torch.maximum(own_value, mentor_term), own_value),
        mentor_available & (mentor_term > own_value),
    )


def primitives_only_backup(
    reward: torch.Tensor, probs: torch.Tensor, successor_values: torch.Tensor, gamma: float
) -> torch.Tensor:
    """Bellman optimality with primitive actions (paper Sec. II, first equation)::

        V(s) = max_a r(s, a) + γ Σ_{s'} p(s' | s, a) V(s')

    Args:
        reward: ``[..., A]``; probs, successor_values: ``[..., A, K]``.
    """
    _rank("primitives_only_backup", "probs", probs, 2, "[..., A, K]")
    _same(
        "primitives_only_backup",
        "[..., A, K] as probs",
        probs.shape,
        successor_values=successor_values,
    )
    _same("primitives_only_backup", "[..., A], probs' without K", probs.shape[:-1], reward=reward)
    return (reward + gamma * (probs * successor_values).sum(-1)).max(-1).values


def augmented_primitive_backup(
    observer_reward: torch.Tensor,
    probs: torch.Tensor,
    successor_values: torch.Tensor,
    mentor_probs: torch.Tensor,
    mentor_successor_values: torch.Tensor,
    mentor_available: torch.Tensor,
    gamma: float,
) -> torch.Tensor:
    """The paper's eq. 1 (implicit imitation, Price & Boutilier 2003), primitives only::

        V(s) = R_obs(s) + γ max( max_a Σ p_obs(s'|s,a) V(s'),  Σ p_m(s'|s) V(s') )

    Args:
        observer_reward: ``[...]`` ``R_obs(s)``.
        probs, successor_values: ``[..., A, K]`` the observer's action models.
        mentor_probs, mentor_successor_values: ``[..., K]``.
        mentor_available: ``[...]`` bool.
    """
    f = "augmented_primitive_backup"
    _rank(f, "probs", probs, 2, "[..., A, K]")
    _same(f, "[..., A, K] as probs", probs.shape, successor_values=successor_values)
    _same(f, "[...], probs' without A and K", probs.shape[:-2], observer_reward=observer_reward)
    _same(f, "[...], probs' without A and K", probs.shape[:-2], mentor_available=mentor_available)
    _rank(f, "mentor_probs", mentor_probs, 1, "[..., K]")
    if mentor_probs.shape[:-1] != observer_reward.shape:
        raise _refuse(
            f, "mentor_probs", mentor_probs, f"[..., K] with [...] = {tuple(observer_reward.shape)}"
        )
    _same(
        f,
        "[..., K] as mentor_probs",
        mentor_probs.shape,
        mentor_successor_values=mentor_successor_values,
    )
    _masks(f, mentor_available=mentor_available)
    own = (probs * successor_values).sum(-1).max(-1).values
    mentor = (mentor_probs * mentor_successor_values).sum(-1)
    return observer_reward + gamma * torch.where(mentor_available, torch.maximum(own, mentor), own)


def dirichlet_value_moments(
    counts: torch.Tensor, outcome_values: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Mean and variance of ``Σ_k p_k u_k`` for ``p ~ Dirichlet(counts)`` and fixed outcome
    values ``u``: mean ``Σ ᾱ_k u_k`` and variance ``(Σ ᾱ_k u_k² − mean²) / (α_0 + 1)`` with
    ``ᾱ = α / α_0``. Used for the confidence test of the mentor term (Price & Boutilier 2003).

    Args:
        counts: ``[..., K]`` Dirichlet concentrations (0 = absent outcome).
        outcome_values: ``[..., K]``.
    """
    _rank("dirichlet_value_moments", "counts", counts, 1, "[..., K]")
    _same(
        "dirichlet_value_moments", "[..., K] as counts", counts.shape, outcome_values=outcome_values
    )
    total = counts.sum(-1)
    p = counts / total.clamp(min=1e-300)[..., None]
    u = torch.where(counts > 0, outcome_values, torch.zeros_like(outcome_values))
    mean = (p * u).sum(-1)
    second = (p * u * u).sum(-1)
    var = dirichlet_variance(mean, second, total)
    return mean, torch.where(total > 0, var, torch.full_like(var, float("inf")))


def dirichlet_variance(
    mean: torch.Tensor, second_moment: torch.Tensor, total: torch.Tensor
) -> torch.Tensor:
    """Variance of ``Σ_k p_k u_k`` for ``p ~ Dirichlet(α)`` from the posterior-mean moments
    ``mean = Σ ᾱ_k u_k`` and ``second_moment = Σ ᾱ_k u_k²`` and ``total = α_0``:
    ``(second_moment − mean²)⁺ / (α_0 + 1)`` (the clamp absorbs rounding below 0).

    All ``[...]``. (:func:`dirichlet_value_moments` from counts; the learner from its cached
    numerators.)"""
    _rank("dirichlet_variance", "mean", mean, 0, "[...]")
    _same(
        "dirichlet_variance", "[...] as mean", mean.shape, second_moment=second_moment, total=total
    )
    return (second_moment - mean * mean).clamp(min=0) / (total + 1)


def confident_mentor(
    mentor_mean: torch.Tensor,
    mentor_var: torch.Tensor,
    own_mean: torch.Tensor,
    own_var: torch.Tensor,
    own_available: torch.Tensor,
    z: float,
) -> torch.Tensor:
    """Price & Boutilier's confidence test: trust the mentor term at ``s`` only where its lower
    bound beats the upper bound of every own option,

        E[M] − z·sd[M]  >  max_o ( E[Q(s,o)] + z·sd[Q(s,o)] ).

    Args:
        mentor_mean, mentor_var: ``[...]``; own_mean, own_var, own_available: ``[..., J]``.
        z: width of the bounds in standard deviations.
    Returns ``[...]`` bool (True where no own option is available).
    """
    f = "confident_mentor"
    _rank(f, "own_mean", own_mean, 1, "[..., J]")
    _same(f, "[..., J] as own_mean", own_mean.shape, own_var=own_var, own_available=own_available)
    _same(
        f,
        "[...], own_mean's without J",
        own_mean.shape[:-1],
        mentor_mean=mentor_mean,
        mentor_var=mentor_var,
    )
    _masks(f, own_available=own_available)
    upper = (
        torch.where(
            own_available, own_mean + z * own_var.sqrt(), torch.full_like(own_mean, float("-inf"))
        ).amax(-1)
        if own_mean.shape[-1]
        else torch.full(own_mean.shape[:-1], float("-inf"), dtype=own_mean.dtype)
    )
    return (mentor_mean - z * mentor_var.sqrt()) > upper


class MentorConfidence(NamedTuple):
    """The inputs of :func:`confident_mentor` for :func:`trusted_augmented_backup`."""

    own_var: torch.Tensor
    """``[..., J]`` posterior variances of the own options' values."""
    mentor_var: torch.Tensor
    """``[...]`` posterior variance of the mentor term."""
    tested: torch.Tensor
    """``[...]`` bool: where the test applies (elsewhere the mentor term passes)."""
    z: float


def mentor_override(
    observed: torch.Tensor, own_tries: torch.Tensor | None, override_after: float | None
) -> torch.Tensor:
    """Where the mentor term takes part in eq. 2 once the learner's own experience overrides it
    (``LearnerConfig.mentor_override_after``): where the mentor was ``observed`` and the learner
    has started fewer than ``override_after`` own options there (all observed states if
    ``None``).

    Args:
        observed: ``[...]`` bool.
        own_tries: ``[...]`` own options started at ``s`` (may be ``None`` when
            ``override_after`` is ``None``).
        override_after: ``LearnerConfig.mentor_override_after``.
    """
    _rank("mentor_override", "observed", observed, 0, "[...] bool")
    _masks("mentor_override", observed=observed)
    if own_tries is not None:
        _same("mentor_override", "[...] as observed", observed.shape, own_tries=own_tries)
    if override_after is None:
        return observed
    _number("mentor_override", "override_after", override_after)
    if own_tries is None:
        raise ValueError("mentor_override: override_after given, so own_tries is needed")
    return observed & (own_tries < override_after)


def feasible_mentor(
    reached: torch.Tensor, tries: torch.Tensor, enabled: torch.Tensor, min_tries: int
) -> torch.Tensor:
    """Feasibility testing over options (``LearnerConfig.mentor_feasibility``; Price &
    Boutilier's action feasibility testing, JAIR 2003, with option termination models in place
    of action models): the mentor term at ``s`` is dropped once the learner's own options there
    show that none of them reproduces the mentor's move — every enabled option tried at least
    ``min_tries`` times at ``s``, and none of those tries ended in a state the mentor was seen
    moving to from ``s``.

    The test is a confidence test: an option that never reached the mentor's successors in
    ``n`` tries reaches them with probability below ``1 − 0.05^(1/n)`` at 95 % (Clopper–Pearson
    with no success; ``n = 3``: 0.63, ``n = 10``: 0.26).

    Args:
        reached: ``[..., J]`` each option's tries at ``s`` that ended in one of the mentor's
            observed successors of ``s``; tries: ``[..., J]`` each option's tries at ``s``;
            enabled: ``[..., J]`` bool, the options the run may use; min_tries: ``n``.
    Returns ``[...]`` bool: where the mentor term stays (False: shown infeasible). A state with
    no enabled option keeps it.

    >>> import torch
    >>> feasible_mentor(
    ...     torch.tensor([[0.0, 0.0], [0.0, 1.0], [0.0, 0.0]]),  # reached
    ...     torch.tensor([[3.0, 4.0], [3.0, 4.0], [3.0, 1.0]]),  # tries
    ...     torch.tensor([[True, True], [True, True], [True, True]]),
    ...     3,
    ... ).tolist()
    [False, True, True]
    """
    _rank("feasible_mentor", "reached", reached, 1, "[..., J]")
    _same("feasible_mentor", "[..., J] as reached", reached.shape, tries=tries, enabled=enabled)
    _masks("feasible_mentor", enabled=enabled)
    tested = (~enabled | (tries >= min_tries)).all(-1) & enabled.any(-1)
    none_reached = ~((reached > 0) & enabled).any(-1)
    return ~(tested & none_reached)


def best_mentor(terms: torch.Tensor, observed: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Several mentors (``LearnerConfig.mentors``): which mentor's term enters eq. 2 at ``s``.

    Each mentor's observed move at ``s`` is one more thing the learner could do there, so the
    augmented backup takes the largest of the mentor terms, as it takes the largest own ``Q``
    (Price & Boutilier's augmented Bellman backup, JAIR 2003, with one term per mentor). Only a
    mentor seen at ``s`` (and not shown infeasible there) has a term. The chosen mentor's term
    then meets the own options as the one mentor's would: its confidence test, override and
    fading use that mentor's counts. A poor mentor's term enters only where it is the largest,
    so it cannot lower a state's value below what the other mentors give.

    Args:
        terms: ``[..., K]`` each mentor's posterior-mean term; observed: ``[..., K]`` bool, where
            each has a term.
    Returns ``(index [...], any [...])``: the mentor with the largest observed term (the first
    of equal ones, and the first observed one where a term is NaN), 0 where none is observed;
    and whether any is.

    >>> import torch
    >>> index, any_ = best_mentor(
    ...     torch.tensor([[1.0, 3.0, 2.0], [5.0, 3.0, 3.0], [9.0, 1.0, 1.0], [0.0, 0.0, 0.0]]),
    ...     torch.tensor([[True, True, True], [False, True, True], [False, False, True],
    ...                   [False, False, False]]),
    ... )
    >>> index.tolist(), any_.tolist()
    ([1, 1, 2, 0], [True, True, True, False])
    """
    if not isinstance(terms, torch.Tensor) or terms.ndim < 1 or terms.shape[-1] < 1:
        raise _refuse("best_mentor", "terms", terms, "[..., K] with K ≥ 1 (one term per mentor)")
    _same("best_mentor", "[..., K] as terms", terms.shape, observed=observed)
    _masks("best_mentor", observed=observed)
    index = torch.zeros(terms.shape[:-1], dtype=torch.int64, device=terms.device)
    best, have = terms[..., 0], observed[..., 0]
    for k in range(1, terms.shape[-1]):
        take = observed[..., k] & (~have | (terms[..., k] > best))
        index = torch.where(take, k, index)
        best = torch.where(take, terms[..., k], best)
        have = have | observed[..., k]
    return index, have


def faded_mentor_term(
    mentor_term: torch.Tensor, own_value: torch.Tensor, own_tries: torch.Tensor, fade: float
) -> torch.Tensor:
    """The mentor term weighed against the own value as ``fade`` own executions
    (``LearnerConfig.mentor_fade``): ``(k·M + n·V_own) / (k + n)`` with ``k = fade`` and
    ``n`` own options started at ``s``; the plain mentor term where no own option has a value.

    Args:
        mentor_term, own_value, own_tries: ``[...]``.
    """
    _rank("faded_mentor_term", "mentor_term", mentor_term, 0, "[...]")
    _number("faded_mentor_term", "fade", fade)
    _same(
        "faded_mentor_term",
        "[...] as mentor_term",
        mentor_term.shape,
        own_value=own_value,
        own_tries=own_tries,
    )
    k, n = fade, own_tries
    return torch.where(
        torch.isfinite(own_value), (k * mentor_term + n * own_value) / (k + n), mentor_term
    )


def trusted_augmented_backup(
    option_q: torch.Tensor,
    available: torch.Tensor,
    mentor_term: torch.Tensor,
    mentor_observed: torch.Tensor,
    own_tries: torch.Tensor | None = None,
    *,
    override_after: float | None = None,
    confidence: MentorConfidence | None = None,
    fade: float | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The paper's eq. 2 as the learner evaluates it: :func:`augmented_option_backup` with the
    mentor term available where it was observed, not yet overridden by own experience
    (:func:`mentor_override`) and, with ``confidence``, confidently better than every own option
    (:func:`confident_mentor`, Price & Boutilier 2003); with ``fade`` the term is first
    weighed against the own value (:func:`faded_mentor_term`).

    Args:
        option_q: ``[..., J]`` option values; available: ``[..., J]`` bool.
        mentor_term: ``[...]`` (:func:`mentor_backup`); mentor_observed: ``[...]`` bool.
        own_tries: ``[...]`` own options started at ``s`` (needed by ``override_after`` and
            ``fade``).
        confidence: :class:`MentorConfidence`: ``own_var [..., J]``, ``mentor_var [...]``,
            ``tested`` broadcastable to ``[...]``.
    Returns ``(V [...], mentor_won [...] bool)``; ``V`` is ``-inf`` where nothing is known.
    """
    f = "trusted_augmented_backup"
    _rank(f, "option_q", option_q, 1, "[..., J]")
    _same(f, "[..., J] as option_q", option_q.shape, available=available)
    states = option_q.shape[:-1]
    _same(f, "[...], option_q's without J", states, mentor_term=mentor_term)
    _same(f, "[...], option_q's without J", states, mentor_observed=mentor_observed)
    _masks(f, available=available, mentor_observed=mentor_observed)
    if own_tries is not None:
        _same(f, "[...], option_q's without J", states, own_tries=own_tries)
    if confidence is not None:
        _same(
            f, "[..., J] as option_q", option_q.shape, **{"confidence.own_var": confidence.own_var}
        )
        _same(
            f,
            "[...], option_q's without J",
            states,
            **{"confidence.mentor_var": confidence.mentor_var},
        )
        if not _broadcasts(getattr(confidence.tested, "shape", (None,)), states):
            raise _refuse(
                f,
                "confidence.tested",
                confidence.tested,
                f"broadcastable to [...] = {tuple(states)}",
            )
    own = options_only_backup(option_q, available)
    available_mentor = mentor_override(mentor_observed, own_tries, override_after)
    if confidence is not None:
        confident = confident_mentor(
            mentor_term,
            confidence.mentor_var,
            option_q,
            confidence.own_var,
            available,
            confidence.z,
        )
        available_mentor = available_mentor & (confident | ~confidence.tested)
    if fade is not None:
        _number(f, "fade", fade)
        if own_tries is None:
            raise ValueError("trusted_augmented_backup: fade given, so own_tries is needed")
        mentor_term = faded_mentor_term(mentor_term, own, own_tries, fade)
    return augmented_backup(own, mentor_term, available_mentor)
