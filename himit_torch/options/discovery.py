"""Options discovered from the mentor's states: subgoals from state-only demonstrations, and options
to them built from the learner's own learned one-step model.

Subgoals (:func:`discover_subgoals`)
    The mentor's *state graph* has the states it visited as nodes and an undirected edge for each
    observed move ``s → s'`` (``s ≠ s'``). A bottleneck of the mentor's behaviour is a state that

    1. lies on every demonstrated episode (at least ``min_episode_share`` of them: McGovern &
       Barto's "in every successful trajectory", 2001),
    2. is a cut vertex (articulation point) of the graph: removing it separates what the mentor
       did before from what it did after — there is no demonstrated way around it (Şimşek & Barto
       2008 rank states by betweenness instead; on a mentor's graph, which is a thin tube from
       start to goal, betweenness is largest in the tube's middle, not at its narrow points, and
       found none of the doorways, so the cut-vertex test replaces it),
    3. is *narrow*: it has few demonstrated neighbours (its degree in the graph). Slips spread
       the mentor over a room's cells; a doorway's two neighbours are all it can ever have.

    Candidates passing 1–2 are taken narrowest first (ties: the one the mentor reaches first, by
    its mean first-visit time as a share of the episode) and each one taken suppresses the
    candidates within ``separation`` moves of it in the graph (non-maximum suppression). Episode
    starts and ends are never subgoals. ``separation`` is the one scale the method needs: about
    the distance between bottlenecks (MultiRooms: the room spacing − 1).

Options (:func:`learned_subgoal_options`)
    From the learner's counts of its own primitive steps (:func:`one_step_counts`), the
    maximum-likelihood one-step model ``p̂(s'|s, a)`` over the ``(s, a)`` it has tried. For each
    subgoal, the policy of fewest expected steps to it *in that model* (value iteration, untried
    actions unusable), usable where the model says the subgoal is reachable within
    ``max_steps`` expected steps (the initiation set), terminating at the subgoal or on leaving
    that set. Nothing of the world's true layout is read. Built again from newer counts, the
    options follow the evidence (:func:`learned_subgoal_options` is a pure function of them).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp
import torch

from himit_torch.options.bundle import Options
from himit_torch.validation import COUNT_MAX, as_float, as_int, as_int_array

if TYPE_CHECKING:  # (imported where a graph is built: networkx costs every process ≈ 0.2 s)
    import networkx as nx

__all__ = [
    "Subgoals",
    "mentor_graph",
    "discover_subgoals",
    "subgoal_scores",
    "one_step_counts",
    "learned_subgoal_options",
    "fewest_steps_policy",
]


def _episodes(demonstrations) -> list[np.ndarray]:
    """Each episode as int64 states ≥ 0, by :func:`~himit_torch.validation.as_int_array`'s rule
    (a NaN, a fraction or a negative state is refused, never cast)."""
    episodes = getattr(demonstrations, "episodes", demonstrations)
    if isinstance(episodes, (str, bytes, dict)) or not isinstance(episodes, Iterable):
        raise ValueError(
            "discover_subgoals: demonstrations must be Demonstrations or a list of episodes "
            f"(1-D sequences of states), got {type(demonstrations).__name__}"
        )
    out = [
        as_int_array(f"discover_subgoals: demonstrations episode {i}", e, minimum=0)
        for i, e in enumerate(episodes)
    ]
    if not out or any(e.size == 0 for e in out):
        raise ValueError(
            "discover_subgoals: demonstrations must hold at least one episode, each a "
            "non-empty 1-D sequence of states"
        )
    return out


def mentor_graph(demonstrations) -> nx.Graph:
    """The mentor's state graph: visited states, an undirected edge per observed move ``s ≠ s'``."""
    import networkx as nx

    graph = nx.Graph()
    for ep in _episodes(demonstrations):
        graph.add_nodes_from(ep.tolist())
        moves = ep[:-1] != ep[1:]
        graph.add_edges_from(zip(ep[:-1][moves].tolist(), ep[1:][moves].tolist()))
    return graph


@dataclass(frozen=True)
class Subgoals:
    """Subgoals found in demonstrations, with what the method measured.

    Attributes:
        states: the subgoal states, in the order they were taken (narrowest first).
        candidates: the states that passed the episode-share and cut-vertex tests.
        degree, episode_share, first_visit: per visited state, its degree in the mentor's graph,
            the share of episodes that visit it, its mean first-visit time (share of the episode).
        settings: the method's settings.
    """

    states: tuple[int, ...]
    candidates: tuple[int, ...]
    degree: dict = field(repr=False)
    episode_share: dict = field(repr=False)
    first_visit: dict = field(repr=False)
    settings: dict = field(default_factory=dict)

    def mask(self, num_states: int) -> torch.Tensor:
        """``[S]`` bool, True on the subgoals."""
        m = torch.zeros(num_states, dtype=torch.bool)
        m[list(self.states)] = True
        return m

    def precision_recall(self, true_states, visited_only: bool = True) -> dict:
        """Precision and recall against ``true_states`` (e.g. ``world.doorways``).

        ``visited_only``: recall counts only the true states the mentor visited (no method can
        find a bottleneck it was never shown); ``False`` counts all of them.
        """
        true = {int(s) for s in torch.as_tensor(true_states).tolist()}
        if visited_only:
            true &= set(self.degree)
        found = set(self.states)
        hits = len(found & true)
        return {
            "found": len(found),
            "true": len(true),
            "hits": hits,
            "precision": hits / len(found) if found else float("nan"),
            "recall": hits / len(true) if true else float("nan"),
        }


def subgoal_scores(demonstrations) -> tuple[nx.Graph, dict, dict, dict]:
    """The mentor graph and, per visited state, its degree, episode share and mean first-visit
    time (as a share of the episode's length)."""
    episodes = _episodes(demonstrations)
    graph = mentor_graph(episodes)
    share: dict[int, float] = {}
    first: dict[int, float] = {}
    for ep in episodes:
        states, where = np.unique(ep, return_index=True)
        length = max(1, ep.size - 1)
        for s, t in zip(states.tolist(), where.tolist()):
            share[s] = share.get(s, 0) + 1
            first[s] = first.get(s, 0.0) + t / length
    first = {s: first[s] / share[s] for s in share}
    share = {s: share[s] / len(episodes) for s in share}
    return graph, dict(graph.degree()), share, first


def discover_subgoals(
    demonstrations, separation: int = 3, min_episode_share: float = 1.0
) -> Subgoals:
    """Subgoals of the mentor's behaviour from its states alone (the module docstring's method).

    Args:
        demonstrations: :class:`~himit_torch.Demonstrations` or a list of 1-D state sequences.
        separation: subgoals are more than this many moves apart in the mentor's graph (≥ 0).
        min_episode_share: a subgoal lies on at least this share of the episodes, in (0, 1].

    Raises:
        ValueError: ``separation`` not a whole number in ``0…COUNT_MAX`` (``True``, ``2.5``,
            ``inf`` refused), ``min_episode_share`` not a real number in ``(0, 1]``, or
            demonstrations with no episode, an empty one, or a state that is negative, NaN or
            not whole.
    """
    separation = as_int("discover_subgoals: separation", separation, 0, COUNT_MAX)
    min_episode_share = as_float(
        "discover_subgoals: min_episode_share", min_episode_share, 0.0, 1.0, low_open=True
    )
    episodes = _episodes(demonstrations)
    graph, degree, share, first = subgoal_scores(episodes)
    ends = {int(e[0]) for e in episodes} | {int(e[-1]) for e in episodes}
    import networkx as nx

    cut = set(nx.articulation_points(graph))
    candidates = sorted(
        (s for s in cut if share[s] >= min_episode_share - 1e-12 and s not in ends),
        key=lambda s: (degree[s], first[s], s),
    )
    taken: list[int] = []
    near: set[int] = set()
    for s in candidates:
        if s in near:
            continue
        taken.append(s)
        near.update(nx.single_source_shortest_path_length(graph, s, cutoff=int(separation)))
    return Subgoals(
        states=tuple(taken),
        candidates=tuple(candidates),
        degree=degree,
        episode_share=share,
        first_visit=first,
        settings={
            "separation": int(separation),
            "min_episode_share": float(min_episode_share),
            "episodes": len(episodes),
        },
    )


# ================================================================= options from the learned model
def one_step_counts(learner, run: int) -> sp.csr_matrix:
    """Run ``run``'s counts of its own primitive steps: ``[A·S, S]`` sparse, row ``a·S + s``
    holding how often primitive ``a`` in ``s`` led to each successor (from its Dirichlet SMDP
    model; extended options' rows are left out)."""
    S, A = learner.num_states, learner.world.num_actions
    model, rows, options = learner.model, learner.rows, learner.options
    E = int(model.num_edges[run])
    row = model.edge_row[run, :E].cpu()
    succ = model.edge_successor[run, :E].cpu()
    count = model.edge_count[run, :E].cpu().double()
    option = rows.row_option.cpu()[row]
    state = rows.row_state.cpu()[row]
    primitive = options.is_primitive[option]
    if options.stochastic:
        action = options.policy.argmax(-1)[option, state].long()
    else:
        action = options.policy[option, state].long()  # int8 tables: widen before arithmetic
    keep = primitive & (count > 0)
    flat = (action[keep] * S + state[keep]).numpy()
    return sp.csr_matrix((count[keep].numpy(), (flat, succ[keep].numpy())), shape=(A * S, S))


def fewest_steps_policy(
    counts: sp.csr_matrix,
    num_actions: int,
    target: np.ndarray,
    terminal: np.ndarray | None = None,
    gamma: float = 0.999,
    max_sweeps: int = 100_000,
) -> tuple[np.ndarray, np.ndarray]:
    """Policy of fewest expected steps to ``target`` in the maximum-likelihood model of
    ``counts`` (``[A·S, S]``); untried ``(s, a)`` are unusable.

    Value iteration with a cost of 1 a step and discount ``gamma``, the target absorbing at 0,
    ``terminal`` states (other than targets) as bad as never arriving. Returns ``(policy [S],
    expected_steps [S])`` (``inf`` where the target cannot be reached in the model; the
    expected steps of the discounted problem, ``log(1 + V(1 − γ)) / log γ``).
    """
    A = int(num_actions)
    S = counts.shape[1]
    totals = np.asarray(counts.sum(1)).ravel()
    tried = (totals > 0).reshape(A, S)
    P = sp.diags(np.where(totals > 0, 1.0 / np.maximum(totals, 1e-300), 0.0)) @ counts
    P = P.tocsr()
    target = np.asarray(target, dtype=bool)
    terminal = np.zeros(S, bool) if terminal is None else np.asarray(terminal, dtype=bool)
    never = -1.0 / (1.0 - gamma)
    fixed = target | terminal
    fixed_value = np.where(target, 0.0, never)
    V = np.where(fixed, fixed_value, never)
    q = np.full((A, S), never)
    for _ in range(max_sweeps):
        q = np.where(tried, -1.0 + gamma * (P @ V).reshape(A, S), never)
        new = np.where(fixed, fixed_value, q.max(0))
        done = np.abs(new - V).max() < 1e-9
        V = new
        if done:
            break
    policy = q.argmax(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        steps = np.log1p(V * (1.0 - gamma)) / np.log(gamma)
    steps = np.where(V > never + 1e-6, steps, np.inf)
    steps[target] = 0.0
    return policy.astype(np.int64), steps


def learned_subgoal_options(
    counts: sp.csr_matrix,
    num_actions: int,
    subgoals,
    terminal=None,
    max_steps: float = 12.0,
    gamma: float = 0.999,
    usable=None,
) -> Options | None:
    """Options to ``subgoals`` built from a learned one-step model (the module docstring).

    Args:
        counts: ``[A·S, S]`` one-step counts (:func:`one_step_counts`).
        num_actions: ``A``.
        subgoals: subgoal states (a :class:`Subgoals` or a sequence of ints).
        terminal: ``[S]`` bool terminal states (never in an initiation set).
        max_steps: an option is usable where its subgoal lies within this many expected steps
            in the learned model (> 0).
        gamma: discount of the planning problem (close to 1: fewest expected steps).
        usable: ``[S]`` bool states where options may start at all (default: every state).

    Returns:
        One option per subgoal reachable from somewhere (kind ``"subgoal"``, named
        ``subgoal <s>``), or ``None`` if none is (e.g. nothing learned yet).
    """
    max_steps = as_float("learned_subgoal_options: max_steps", max_steps, 0.0, low_open=True)
    gamma = as_float(
        "learned_subgoal_options: gamma", gamma, 0.0, 1.0, low_open=True, high_open=True
    )
    num_actions = as_int("learned_subgoal_options: num_actions", num_actions, 1, COUNT_MAX)
    states = subgoals.states if isinstance(subgoals, Subgoals) else tuple(int(s) for s in subgoals)
    S = counts.shape[1]
    if counts.shape[0] != num_actions * S:
        raise ValueError(
            f"learned_subgoal_options: counts have shape {counts.shape}, expected "
            f"[A·S, S] = [{num_actions * S}, {S}]"
        )
    terminal = (
        np.zeros(S, bool)
        if terminal is None
        else np.asarray(torch.as_tensor(terminal).cpu(), dtype=bool)
    )
    usable = np.ones(S, bool) if usable is None else np.asarray(torch.as_tensor(usable).cpu(), bool)
    parts = []
    for g in states:
        target = np.zeros(S, bool)
        target[g] = True
        policy, steps = fewest_steps_policy(counts, num_actions, target, terminal, gamma)
        init = (steps <= max_steps) & ~target & ~terminal & usable
        if not init.any():
            continue
        parts.append(
            Options.from_policy(
                torch.from_numpy(init),
                torch.from_numpy(policy),
                name=f"subgoal {g}",
                kind="subgoal",
            )
        )
    return Options.concat(parts) if parts else None
