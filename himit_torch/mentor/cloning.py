"""Behavioural cloning from observation (BCO), tabular: an inverse model from the learner's own
transitions labels the mentor's state-only transitions with actions, and a policy is cloned from
those labels.

Torabi, Warnell & Stone, *Behavioral Cloning from Observation*, IJCAI 2018. Their BCO(0) learns
an inverse dynamics model ``p(a | s, s')`` from a pre-demonstration phase of the agent's own
interaction, uses it to infer the action behind each observed demonstrator transition
``(s, s')``, and clones a policy from the inferred ``(s, a)`` pairs by maximum likelihood;
BCO(α) interleaves further own interaction, re-learning the inverse model and re-cloning. In a
tabular world each of the three steps is exact counting, one pure function each:

1. **Inverse model** (:func:`inverse_model`), from the own counts ``n(s, a, s')``:

   * ``"likelihood"`` (the learner's default) — ``p(a | s, s') ∝ n(s, a, s') / n(s, a)``, i.e.
     ``p̂(s' | s, a)`` under a uniform prior over actions: the model that BCO(0)'s uniformly
     random pre-demonstration phase estimates, without the bias of a run that takes its greedy
     action far more often than the others;
   * ``"counts"`` — ``p(a | s, s') = n(s, a, s') / Σ_a' n(s, a', s')``: the maximum-likelihood
     model of the own transitions, what BCO's classifier trained on them estimates (the own
     action frequencies at ``s`` are its prior over ``a``). With slip, ``s'`` is reachable by
     several actions and the most-taken one can win: a run acting on a wrong label takes that
     action far more often than the right one, and its slips then explain the mentor's move, so
     the wrong label confirms itself.

   ``(s, s')`` pairs never seen in own experience have no model (no prior is put on them).
2. **Relabelling** (:func:`relabel`): each observed mentor transition ``(s, s')`` gets
   ``a* = argmax_a p(a | s, s')``, ties (within ``TIE``) to the lowest action; ``−1`` where
   ``(s, s')`` was never seen in own experience (nothing explains it).
3. **Cloning** (:func:`clone_policy`): ``π_bc(s)`` = the action with the most labelled mentor
   transitions out of ``s`` (weighted by how often each was observed), ties to the lowest
   action; ``−1`` where no mentor transition out of ``s`` is labelled. Unlabelled transitions
   out of a state do not vote.

The maximum-likelihood classifier of a tabular problem is the majority label, so step 3 is BCO's
cloning step exactly; step 1 replaces its learned network by the counts it would fit. With an
observation stride (``observe_every``) the mentor's moves span several steps: one-step own
experience rarely explains them, so few transitions get labels.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import torch

from himit_torch.validation import as_float_array, as_int

__all__ = ["INVERSE_MODELS", "TIE", "InverseModel", "inverse_model", "relabel", "clone_policy"]

#: ``LearnerConfig.bco_inverse_model``: how own counts become ``p(a | s, s')`` (module docstring).
INVERSE_MODELS = ("counts", "likelihood")

#: Probabilities (or votes) within this of the best are a tie, decided for the lowest action.
TIE = 1e-12


class InverseModel(NamedTuple):
    """``p(a | s, s')`` for every own transition seen, one entry per distinct ``(s, a, s')``,
    sorted by ``(s, s', a)``: ``states``, ``successors``, ``actions`` ``[N]`` int64 and
    ``probability [N]`` float64 (summing to 1 over the actions of each ``(s, s')``)."""

    states: torch.Tensor
    successors: torch.Tensor
    actions: torch.Tensor
    probability: torch.Tensor


def _check_transitions(name: str, lowest: int = 0, **columns: Any) -> None:
    """Each of ``columns`` is a 1-D int64 tensor of one length, every entry ``≥ lowest``
    (``TypeError`` for no tensor — a list, a string —, ``ValueError`` otherwise; a float or a bool
    tensor is refused, never cast)."""
    for column, c in columns.items():
        if not isinstance(c, torch.Tensor):
            raise TypeError(
                f"{name}: {column} must be a 1-D int64 tensor, got {type(c).__name__}; give "
                "torch.tensor(...)"
            )
    shapes = [tuple(c.shape) for c in columns.values()]
    if any(len(shape) != 1 or shape != shapes[0] for shape in shapes):
        raise ValueError(
            f"{name}: give 1-D tensors of one length ({', '.join(columns)}), got {shapes}"
        )
    for column, c in columns.items():
        if c.dtype != torch.int64:
            raise ValueError(
                f"{name}: {column} must be int64 (states and actions are whole numbers), got "
                f"{c.dtype}"
            )
        if c.numel() and int(c.min()) < lowest:
            raise ValueError(f"{name}: {column} must be ≥ {lowest}, got {int(c.min())}")


def _real_column(where: str, value: Any, device: torch.device) -> torch.Tensor:
    """``value`` as a float64 tensor of finite real numbers on ``device``: a real tensor as it is
    (no round trip through the host), anything else by :func:`as_float_array`'s rule (a bool
    or complex tensor, a string, NaN are refused)."""
    if isinstance(value, torch.Tensor):
        if value.dtype == torch.bool or value.dtype.is_complex:
            raise ValueError(f"{where} must hold real numbers, got a {value.dtype} tensor")
        value = value.to(device=device, dtype=torch.float64)
        if not bool(torch.isfinite(value).all()):
            raise ValueError(f"{where} must be finite (one weight per transition)")
        return value
    return torch.from_numpy(as_float_array(where, value)).to(device)


def inverse_model(
    states: torch.Tensor,
    actions: torch.Tensor,
    successors: torch.Tensor,
    counts: torch.Tensor,
    kind: str = "likelihood",
    num_states: int | None = None,
) -> InverseModel:
    """The inverse model ``p(a | s, s')`` of the own transitions ``(states, actions,
    successors)`` seen ``counts`` times each (step 1 of the module docstring; Torabi et al. 2018,
    Sec. 4, the inverse dynamics model ``M_θ``).

    Args:
        states, actions, successors: ``[N]`` int64, the own transitions ``s --a--> s'`` (a
            triple may repeat: its counts add up).
        counts: ``[N]`` how often each was seen (≥ 0; entries of count 0 are left out).
        kind: ``"likelihood"`` (``p ∝ n(s, a, s') / n(s, a)``, a uniform prior over actions) or
            ``"counts"`` (``p ∝ n(s, a, s')``), :data:`INVERSE_MODELS`.
        num_states: ``S`` of the world, if known: ``states`` and ``successors`` must then lie in
            ``0 … S − 1``.

    Returns:
        :class:`InverseModel`, one entry per distinct ``(s, a, s')`` of positive count.

    Raises:
        TypeError: a column that is no tensor (a list, a string).
        ValueError: mismatched or non-int64 columns, a negative state or action, a state ``≥
            num_states``, counts that are not finite and ≥ 0, or states and actions so large that
            the ``(s, s', a)`` keys would not fit in int64 (``S² · A > 2⁶³``; the model is
            keyed by them).
    """
    if kind not in INVERSE_MODELS:
        raise ValueError(f"inverse model kind={kind!r}: use one of {INVERSE_MODELS}")
    _check_transitions("inverse_model", states=states, actions=actions, successors=successors)
    if num_states is not None:
        num_states = as_int("inverse_model: num_states", num_states, 1)
        for name, column in (("states", states), ("successors", successors)):
            if column.numel() and int(column.max()) >= num_states:
                raise ValueError(
                    f"inverse_model: {name} holds state {int(column.max())}; states must lie in "
                    f"0 … num_states − 1 = {num_states - 1}"
                )
    if states.numel():
        top = max(int(states.max()), int(successors.max())) + 1
        if top * top * (int(actions.max()) + 1) > 2**63:
            raise ValueError(
                f"inverse_model: states up to {top - 1} and actions up to {int(actions.max())} "
                "make (s, s', a) keys beyond int64; states must be below the world's number of "
                "states (at most about 2³¹ with few actions)"
            )
    counts = _real_column("inverse_model: counts", counts, states.device)
    if counts.shape != states.shape or bool((counts < 0).any()):
        raise ValueError("inverse_model: counts must be [N] finite and ≥ 0, one per transition")
    keep = counts > 0
    s, a, s2, n = states[keep], actions[keep], successors[keep], counts[keep]
    width = int(max(s.max(), s2.max())) + 1 if s.numel() else 1
    A = int(a.max()) + 1 if a.numel() else 1
    # distinct (s, s', a), sorted by that key
    triple, inv = torch.unique((s * width + s2) * A + a, return_inverse=True)
    n_triple = torch.zeros(triple.numel(), dtype=torch.float64, device=s.device).index_add_(
        0, inv, n
    )
    pair, action = triple // A, triple % A
    t_state, t_succ = pair // width, pair % width
    weight = n_triple
    if kind == "likelihood":  # ÷ n(s, a): p̂(s' | s, a)
        sa, sa_inv = torch.unique(t_state * A + action, return_inverse=True)
        n_sa = torch.zeros(sa.numel(), dtype=torch.float64, device=s.device).index_add_(
            0, sa_inv, n_triple
        )
        weight = n_triple / n_sa[sa_inv]
    _, pair_inv = torch.unique(pair, return_inverse=True)
    total = torch.zeros(int(pair_inv.max()) + 1 if pair.numel() else 0, dtype=torch.float64)
    total = total.to(s.device).index_add_(0, pair_inv, weight)
    return InverseModel(t_state, t_succ, action, weight / total[pair_inv])


def relabel(model: InverseModel, states: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
    """``[T]`` the action ``a* = argmax_a p(a | s, s')`` behind each observed transition
    ``(states[t], successors[t])`` (step 2 of the module docstring; Torabi et al. 2018, Alg. 1,
    "use M_θ to infer the demonstrator's actions"): ties within ``TIE`` to the lowest
    action, ``−1`` where ``(s, s')`` is not in ``model`` (own experience never explained it)."""
    if not isinstance(model, InverseModel):
        raise TypeError(
            f"relabel: model must be an InverseModel (inverse_model(...)), got "
            f"{type(model).__name__}"
        )
    _check_transitions("relabel", states=states, successors=successors)
    out = torch.full(states.shape, -1, dtype=torch.int64, device=states.device)
    if model.states.numel() == 0 or states.numel() == 0:
        return out
    width = int(max(model.states.max(), model.successors.max(), states.max(), successors.max()))
    width += 1
    pair = model.states * width + model.successors  # sorted (the model is sorted by (s, s', a))
    keys, group = torch.unique_consecutive(pair, return_inverse=True)
    best_p = torch.full((keys.numel(),), -1.0, dtype=torch.float64, device=pair.device)
    best_p = best_p.scatter_reduce(0, group, model.probability, reduce="amax")
    best = model.probability >= best_p[group] - TIE
    A = int(model.actions.max()) + 1
    lowest = torch.full((keys.numel(),), A, dtype=torch.int64, device=pair.device)
    lowest = lowest.scatter_reduce(
        0, group, torch.where(best, model.actions, torch.full_like(model.actions, A)), "amin"
    )
    query = states * width + successors
    slot = torch.searchsorted(keys, query).clamp(max=keys.numel() - 1)
    found = keys[slot] == query
    return torch.where(found, lowest[slot], out)


def clone_policy(
    states: torch.Tensor,
    labels: torch.Tensor,
    weights: torch.Tensor,
    num_states: int,
    num_actions: int,
) -> torch.Tensor:
    """``[S]`` the cloned policy ``π_bc(s)``: the label with the most weight among the labelled
    transitions out of ``s`` (step 3 of the module docstring; Torabi et al. 2018, Alg. 1, "improve
    π_φ by behavioral cloning" — for a table, the maximum-likelihood policy), ties within
    ``TIE`` to the lowest action; ``−1`` where no transition out of ``s`` is labelled.

    Args:
        states: ``[T]`` int64, where each observed mentor transition starts.
        labels: ``[T]`` int64, its inferred action (:func:`relabel`; ``−1``: none, no vote).
        weights: ``[T]`` how often it was observed (> 0).
        num_states, num_actions: ``S`` and ``A``, whole numbers ≥ 1.

    Raises:
        TypeError: ``states`` or ``labels`` is no tensor (a list, a NumPy array).
        ValueError: ``num_states`` or ``num_actions`` not a whole number ≥ 1, mismatched shapes,
            ``states`` or ``labels`` not int64 (float labels are refused, never truncated),
            weights that are not finite and positive, or states or labels out of range.
    """
    num_states = as_int("clone_policy: num_states", num_states, 1)
    num_actions = as_int("clone_policy: num_actions", num_actions, 1)
    if num_states * num_actions >= 2**63:
        raise ValueError(
            f"clone_policy: num_states · num_actions = {num_states * num_actions} is beyond int64"
        )
    _check_transitions("clone_policy", -1, states=states, labels=labels)
    weights = _real_column("clone_policy: weights", weights, states.device)
    if weights.shape != states.shape or not bool((weights > 0).all()):
        raise ValueError("clone_policy: weights must be [T] positive")
    if states.numel() and (int(states.min()) < 0 or int(states.max()) >= num_states):
        raise ValueError(f"clone_policy: states must lie in 0…{num_states - 1}")
    if labels.numel() and (int(labels.min()) < -1 or int(labels.max()) >= num_actions):
        raise ValueError(f"clone_policy: labels must lie in −1…{num_actions - 1}")
    votes = torch.zeros(num_states * num_actions, dtype=torch.float64, device=states.device)
    has = labels >= 0
    votes.index_add_(0, states[has] * num_actions + labels[has], weights[has])
    votes = votes.view(num_states, num_actions)
    top = votes.max(1, keepdim=True).values
    # the first action within TIE of the best (argmax of a bool mask: its first True)
    first = (votes >= top - TIE).long().argmax(1)
    return torch.where(top[:, 0] > 0, first, torch.full_like(first, -1))
