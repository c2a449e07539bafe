"""Exact planning for known models: value iteration for MDPs and option SMDPs.

Used for ground truth (tests, ``himit info``, experiment 3's optimal baseline) and by the mentor.
The learner plans with prioritized sweeping on its own estimated models instead.

Stopping rule (both planners): iterate until the sup-norm change of ``V`` between sweeps is below
``tol``; then ``‖V − V*‖∞ ≤ tol · γ / (1 − γ)`` for an MDP (Puterman 1994, Thm. 6.3.1). For an
SMDP the contraction factor is the largest row sum of ``P^o`` (≤ γ) instead of γ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.csgraph as csgraph
import scipy.sparse.linalg as spla
import torch

from himit_torch.exact import reference_cache
from himit_torch.exact.option_models import OptionModels, option_durations, option_models
from himit_torch.options.builders import primitive_options

__all__ = [
    "value_iteration",
    "smdp_value_iteration",
    "PlanResult",
    "expected_steps",
    "greedy_option_policy",
    "OptimalBaseline",
    "optimal_baseline",
]


@dataclass(frozen=True)
class PlanResult:
    """Values ``V [S]``, greedy ``policy [S]`` (action or option index; −1 where none is
    available), action/option values ``q`` and the number of sweeps done."""

    values: torch.Tensor
    policy: torch.Tensor
    q: torch.Tensor
    iterations: int


def value_iteration(
    P: torch.Tensor, R: torch.Tensor, gamma: float, tol: float = 1e-10, max_iter: int = 100_000
) -> PlanResult:
    """Value iteration for a tabular MDP (MDP-toolbox convention).

    Args:
        P: ``[A, S, S]`` transition probabilities ``P[a, s, s']``, dense or sparse COO.
        R: ``[S, A]`` expected reward of taking ``a`` in ``s``.
        gamma: discount in ``[0, 1)``.
        tol: stop when ``max_s |V_{n+1}(s) − V_n(s)| < tol``.

    Returns:
        :class:`PlanResult` with ``q [S, A]``; ties in the greedy policy go to the lowest action.
    """
    if P.dim() != 3 or P.shape[1] != P.shape[2]:
        raise ValueError(f"P must be [A, S, S], got {tuple(P.shape)}")
    A, S, _ = P.shape
    if tuple(R.shape) != (S, A):
        raise ValueError(f"R must be [S, A] = [{S}, {A}], got {tuple(R.shape)}")
    if not 0.0 <= gamma < 1.0:
        raise ValueError(f"gamma={gamma} must lie in [0, 1) for value iteration to converge")
    if not torch.isfinite(R).all():
        raise ValueError("R holds NaN or infinite rewards")
    flat = P.coalesce() if P.is_sparse else P.to_sparse().coalesce()
    idx = flat.indices()
    rows = (idx[0] * S + idx[1]).numpy()
    stacked = sp.csr_matrix(
        (flat.values().double().numpy(), (rows, idx[2].numpy())), shape=(A * S, S)
    )
    Rn = R.double().numpy()
    V = np.zeros(S)
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is returned)
        q = Rn + gamma * (stacked @ V).reshape(A, S).T
        new = q.max(1)
        delta = np.abs(new - V).max()
        V = new
        if delta < tol:
            break
    q = Rn + gamma * (stacked @ V).reshape(A, S).T
    return PlanResult(
        values=torch.from_numpy(V),
        policy=torch.from_numpy(q.argmax(1)),
        q=torch.from_numpy(q),
        iterations=it,
    )


def smdp_value_iteration(
    models: OptionModels, tol: float = 1e-10, max_iter: int = 100_000
) -> PlanResult:
    """Value iteration with option models: ``V(s) = max_o r(s, o) + Σ P^o[s, s'] V(s')``.

    States with no available option (walls, terminal states) keep ``V = 0``. Returns ``q [M]``
    per model row and the greedy option per state (ties → lowest option index).

    Models kept by content (:mod:`~himit_torch.exact.reference_cache`: those of
    :func:`~himit_torch.exact.option_models.option_models`) have their result kept there too,
    the same to the bit: the mentor's policy and the optimum are solved once per world, options
    and setting, not once per batch and process.
    """
    models_key = reference_cache.key_of(models)
    if models_key is None:
        return _smdp_value_iteration(models, tol, max_iter)
    key = reference_cache.plan_key(
        models_key, "smdp_value_iteration", tol=float(tol).hex(), max_iter=int(max_iter)
    )
    kept = reference_cache.load_plan(key, models.num_states, models.num_rows, models.num_options)
    if kept is not None:
        arrays, iterations = kept
        return PlanResult(
            values=torch.from_numpy(arrays["values"]),
            policy=torch.from_numpy(arrays["policy"]),
            q=torch.from_numpy(arrays["q"]),
            iterations=iterations,
        )
    plan = _smdp_value_iteration(models, tol, max_iter)
    reference_cache.store_plan(key, plan.values, plan.policy, plan.q, plan.iterations)
    return plan


def _smdp_value_iteration(models: OptionModels, tol: float, max_iter: int) -> PlanResult:
    """:func:`smdp_value_iteration`, computed."""
    S = models.num_states
    T = models.transition.to_sparse_coo().coalesce()
    idx = T.indices().numpy()
    Tm = sp.csr_matrix((T.values().numpy(), (idx[0], idx[1])), shape=tuple(T.shape))
    r = models.reward.numpy()
    row_state = models.row_state.numpy()
    # Rows sorted by state, so a state's best option is one reduceat over its block.
    order = np.argsort(row_state, kind="stable")
    Tm, r, row_state = Tm[order], r[order], row_state[order]
    block_states, block_starts = np.unique(row_state, return_index=True)
    V = np.zeros(S)
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is returned)
        q = r + Tm @ V
        new = np.zeros(S)
        new[block_states] = np.maximum.reduceat(q, block_starts)
        delta = np.abs(new - V).max()
        V = new
        if delta < tol:
            break
    q = torch.empty(order.size, dtype=torch.float64)
    q[torch.from_numpy(order)] = torch.from_numpy(r + Tm @ V)
    values = torch.from_numpy(V)
    return PlanResult(
        values=values, policy=greedy_option_policy(models, q, values), q=q, iterations=it
    )


def greedy_option_policy(
    models: OptionModels,
    q: torch.Tensor,
    values: torch.Tensor,
    preferred: torch.Tensor | None = None,
    tolerance: float = 0.0,
) -> torch.Tensor:
    """Greedy option per state from row values ``q [M]``: ``[S]`` int64, −1 where none.

    With ``preferred [O]`` bool and ``tolerance > 0``, a preferred option whose value is within
    ``tolerance`` of the state's best value wins over a better non-preferred one (the mentor uses
    this to favour its extended options over primitives that are better only by a hair); the best
    of those preferred options is taken. Remaining ties go to the lowest option index.
    """
    S = models.num_states
    row_state, row_option = models.row_state, models.row_option
    score = q.clone()
    if preferred is not None and tolerance > 0:
        # Preferred options within tolerance of the best outrank the rest, and keep their order.
        ok = preferred[row_option] & (q >= values[row_state] - tolerance)
        score = torch.where(ok, q + 1e9, score)
    # Lexicographic argmax: highest score, then lowest option index.
    order = np.lexsort((row_option.numpy(), -score.numpy(), row_state.numpy()))
    first = np.ones(order.size, dtype=bool)
    first[1:] = row_state.numpy()[order][1:] != row_state.numpy()[order][:-1]
    policy = torch.full((S,), -1, dtype=torch.int64)
    chosen = order[first]
    policy[row_state[chosen]] = row_option[chosen]
    return policy


def expected_steps(
    durations: OptionModels, policy: torch.Tensor, start: int, terminal: torch.Tensor
) -> float:
    """Expected primitive steps from ``start`` until a terminal state, following ``policy [S]``.

    Args:
        durations: undiscounted models from :func:`himit_torch.option_durations` (termination
            probabilities and expected durations).
        policy: option per state (−1 where none; such states must be unreachable).
        terminal: ``[S]`` bool.

    Solves ``t(s) = D(s, π(s)) + Σ_{s'} Pr(s' | s, π(s)) t(s')``, ``t = 0`` at terminal states,
    over the states reachable from ``start``. Returns ``inf`` if the goal is not reached with
    probability 1.
    """
    S = durations.num_states
    term = terminal.numpy()
    if term[int(start)]:
        return 0.0
    T = durations.transition.to_sparse_coo().coalesce()
    idx = T.indices().numpy()
    Tm = sp.csr_matrix((T.values().numpy(), (idx[0], idx[1])), shape=tuple(T.shape))
    # The model row of (s, π(s)) at each state (−1: no option there, or no row for it).
    pol = policy.numpy()
    row_state, row_option = durations.row_state.numpy(), durations.row_option.numpy()
    used = (pol[row_state] >= 0) & (row_option == pol[row_state])
    row_of = np.full(S, -1, dtype=np.int64)
    row_of[row_state[used]] = np.flatnonzero(used)
    # Reachable states under the policy: along every stored entry of the chosen rows.
    acting = np.flatnonzero((row_of >= 0) & ~term)
    reach = reachable(_rows_graph(Tm[row_of[acting]], acting, S), np.array([int(start)]))
    if (row_of[reach & ~term] < 0).any():
        return float("inf")  # a reachable state where the policy has no option
    # The goal is reached with probability 1 iff every reachable state can reach a terminal one;
    # otherwise the system below is singular (a closed loop), so answer before solving it.
    states = np.flatnonzero(reach & ~term)
    chosen = Tm[row_of[states]]  # (the chosen rows of the states the system is over)
    back = _rows_graph(chosen, states, S).T.tocsr()
    if not reachable(back, np.flatnonzero(reach & term))[reach].all():
        return float("inf")
    n = states.size
    index = np.full(S, -1, dtype=np.int64)
    index[states] = np.arange(n)
    sub = chosen.tocoo()
    keep = np.isin(sub.col, states)
    system = sp.identity(n, format="csr") - sp.csr_matrix(
        (sub.data[keep], (sub.row[keep], index[sub.col[keep]])), shape=(n, n)
    )
    t = spla.spsolve(system.tocsc(), durations.reward.numpy()[row_of[states]])
    value = float(np.atleast_1d(t)[index[int(start)]])
    return value if np.isfinite(value) and value > 0 else float("inf")


def _rows_graph(rows: sp.csr_matrix, states: np.ndarray, S: int) -> sp.csr_matrix:
    """``[S, S]``: state ``states[i]`` (sorted) linked to every state stored in ``rows[i]``
    (zeros stored included); the other states to none."""
    counts = np.zeros(S, dtype=np.int64)
    counts[states] = np.diff(rows.indptr)
    indptr = np.concatenate([[0], np.cumsum(counts)])
    return sp.csr_matrix((np.ones(rows.indices.size), rows.indices, indptr), shape=(S, S))


def reachable(graph: sp.csr_matrix, sources: np.ndarray) -> np.ndarray:
    """``[n]`` bool: the states reachable from ``sources`` (themselves included) along the
    stored entries of ``graph [n, n]`` (one breadth-first search from an added root)."""
    n = graph.shape[0]
    if sources.size == 0:
        return np.zeros(n, dtype=bool)
    indptr = np.append(graph.indptr, graph.indptr[-1] + sources.size)
    indices = np.concatenate([graph.indices, sources])
    rooted = sp.csr_matrix((np.ones(indices.size), indices, indptr), shape=(n + 1, n + 1))
    seen = np.zeros(n + 1, dtype=bool)
    seen[csgraph.breadth_first_order(rooted, n, directed=True, return_predecessors=False)] = True
    return seen[:n]


@dataclass(frozen=True)
class OptimalBaseline:
    """What the optimal policy of a world achieves from its start state, exact (true model,
    primitive actions): the reference line of learning curves and of ``V(start)``."""

    steps_to_goal: float
    """Expected primitive steps from the start to a terminal state (slips included)."""
    value_start: float
    """``V*(start)``, the optimal value of the start state."""

    def goals_per(self, steps: int) -> float:
        """Goals the optimal policy reaches in ``steps`` primitive steps (restarting at the start
        after each goal), e.g. ``goals_per(5000)`` ≈ 54.7 on experiment 2's 40×40 world."""
        return steps / self.steps_to_goal


def optimal_baseline(world) -> OptimalBaseline:
    """:class:`OptimalBaseline` of ``world`` (a :class:`~himit_torch.MultiRooms`, or any world
    that :func:`~himit_torch.primitive_options` accepts), by value iteration on the primitive
    options' exact models."""
    prims = primitive_options(world)
    plan = smdp_value_iteration(option_models(world, prims))
    steps = expected_steps(
        option_durations(world, prims), plan.policy, world.start_state, world.terminal_mask
    )
    return OptimalBaseline(
        steps_to_goal=float(steps), value_start=float(plan.values[world.start_state])
    )
