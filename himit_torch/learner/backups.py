"""Bellman backups of the paper, as pure functions on batched tensors.

Naming follows rlax: a leading ``...`` is any batch shape (runs, states); ``K`` indexes successor
slots (padding slots carry weight 0); ``J`` indexes the options available in a state; ``A``
primitive actions. Each function cites the equation it implements. The learner evaluates the same
expressions incrementally (cached numerators); tests check it against these functions.
"""

from __future__ import annotations

import torch

__all__ = [
    "option_backup",
    "mentor_backup",
    "augmented_option_backup",
    "augmented_primitive_backup",
    "options_only_backup",
    "primitives_only_backup",
    "dirichlet_value_moments",
    "confident_mentor",
]


def option_backup(
    reward: torch.Tensor, weights: torch.Tensor, successor_values: torch.Tensor
) -> torch.Tensor:
    """Option value with a multi-time model (Sutton, Precup & Singh 1999; paper Sec. II):

        Q(s, o) = r(s, o) + Σ_{s'} p^o_{ss'} V(s')

    Args:
        reward: ``[...]`` expected discounted reward ``r(s, o)``.
        weights: ``[..., K]`` multi-time weights ``p^o_{ss'} = Σ_k p(s', k) γ^k``.
        successor_values: ``[..., K]`` ``V(s')`` of the same successors.
    """
    if weights.shape != successor_values.shape or weights.shape[:-1] != reward.shape:
        raise ValueError(
            f"option_backup: shapes reward {tuple(reward.shape)}, weights "
            f"{tuple(weights.shape)}, successor_values {tuple(successor_values.shape)} "
            "must be [...], [..., K], [..., K]"
        )
    return reward + (weights * successor_values).sum(-1)


def mentor_backup(
    mentor_reward: torch.Tensor,
    mentor_probs: torch.Tensor,
    successor_values: torch.Tensor,
    gamma: float,
) -> torch.Tensor:
    """Value of duplicating the mentor's (unseen) action (Price & Boutilier 2003; paper eq. 1–2):

        R_m(s) + γ Σ_{s'} p_m(s' | s) V(s')

    Args:
        mentor_reward: ``[...]`` ``R_m(s)``, the reward the learner assigns to the mentor.
        mentor_probs: ``[..., K]`` ``p_m(s' | s)``.
        successor_values: ``[..., K]``.
    """
    if (
        mentor_probs.shape != successor_values.shape
        or mentor_probs.shape[:-1] != mentor_reward.shape
    ):
        raise ValueError(
            "mentor_backup: mentor_reward [...], mentor_probs and successor_values "
            "[..., K] must agree"
        )
    return mentor_reward + gamma * (mentor_probs * successor_values).sum(-1)


def options_only_backup(option_q: torch.Tensor, available: torch.Tensor) -> torch.Tensor:
    """SMDP Bellman optimality (paper Sec. II): ``V(s) = max_{o ∈ O(s)} Q(s, o)``.

    Args:
        option_q: ``[..., J]``; available: ``[..., J]`` bool. States with no available option get
        ``-inf``.
    """
    neg_inf = torch.full_like(option_q, float("-inf"))
    return torch.where(available, option_q, neg_inf).max(-1).values


def augmented_option_backup(
    option_q: torch.Tensor,
    available: torch.Tensor,
    mentor_term: torch.Tensor,
    mentor_available: torch.Tensor,
) -> torch.Tensor:
    """The paper's eq. 2, the augmented Bellman equation with options:

        V(s) = max( max_{o ∈ O_obs(s)} Q(s, o),  R_m(s) + γ Σ p_m(s'|s) V(s') )

    Args:
        option_q: ``[..., J]`` option values (:func:`option_backup`).
        available: ``[..., J]`` bool.
        mentor_term: ``[...]`` (:func:`mentor_backup`).
        mentor_available: ``[...]`` bool, where the mentor was observed (and its term is trusted).
    """
    own = options_only_backup(option_q, available)
    return torch.where(mentor_available, torch.maximum(own, mentor_term), own)


def primitives_only_backup(
    reward: torch.Tensor, probs: torch.Tensor, successor_values: torch.Tensor, gamma: float
) -> torch.Tensor:
    """Bellman optimality with primitive actions (paper Sec. II, first equation):

        V(s) = max_a r(s, a) + γ Σ_{s'} p(s' | s, a) V(s')

    Args:
        reward: ``[..., A]``; probs, successor_values: ``[..., A, K]``.
    """
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
    """The paper's eq. 1 (implicit imitation, Price & Boutilier 2003), primitives only:

        V(s) = R_obs(s) + γ max( max_a Σ p_obs(s'|s,a) V(s'),  Σ p_m(s'|s) V(s') )

    Args:
        observer_reward: ``[...]`` ``R_obs(s)``.
        probs, successor_values: ``[..., A, K]`` the observer's action models.
        mentor_probs, mentor_successor_values: ``[..., K]``.
        mentor_available: ``[...]`` bool.
    """
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
    total = counts.sum(-1)
    p = counts / total.clamp(min=1e-300)[..., None]
    u = torch.where(counts > 0, outcome_values, torch.zeros_like(outcome_values))
    mean = (p * u).sum(-1)
    second = (p * u * u).sum(-1)
    var = (second - mean * mean).clamp(min=0) / (total + 1)
    return mean, torch.where(total > 0, var, torch.full_like(var, float("inf")))


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
    upper = (
        torch.where(
            own_available, own_mean + z * own_var.sqrt(), torch.full_like(own_mean, float("-inf"))
        ).amax(-1)
        if own_mean.shape[-1]
        else torch.full(own_mean.shape[:-1], float("-inf"), dtype=own_mean.dtype)
    )
    return (mentor_mean - z * mentor_var.sqrt()) > upper
