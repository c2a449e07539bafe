"""The kernels' arguments, grouped by the object that owns them: one named tuple type each.

Numba passes a named tuple of arrays as one argument and reads its fields by name. Inside the
tick loop (where the hot phases are inlined) the grouping costs nothing at run time; a call to a
phase compiled on its own passes every field of every array of its tuples (:mod:`.jit`, which
says which phases are inlined and why). Per-run arrays have the
run as their first axis; shared ones (world, options, row table) have none.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

__all__ = [
    "WorldArrays",
    "RowArrays",
    "CacheArrays",
    "OptionModelArrays",
    "MentorModelArrays",
    "SweepArrays",
    "RunArrays",
    "SampleArrays",
    "ClonedArrays",
    "WindowArrays",
    "WINDOW_COUNTS",
    "Scratch",
    "SHARED_FIELDS",
    "map_per_run",
]


class WorldArrays(NamedTuple):
    """The world and the options (shared, read only): ``WorldTables``."""

    dyn_succ: np.ndarray  # [S, A, K] successors of (state, action)
    dyn_cdf: np.ndarray  # [S, A, K] their cumulative probabilities
    dyn_rew: np.ndarray  # [S, A, K] their rewards
    terminal: np.ndarray  # [S + 1] goal states
    start_cdf: np.ndarray  # [S] start distribution's cdf (unused with a fixed start state)
    termination: np.ndarray  # [O · S] each option's termination probability
    policy: np.ndarray  # [O · S] deterministic options' actions (unused when stochastic)
    policy_cdf: np.ndarray  # [O · S, A] stochastic options' action cdfs (else unused)


class RowArrays(NamedTuple):
    """The row table (shared, read only, except the per-run masks): ``RowTable``."""

    row_begin: np.ndarray  # [S + 2] the rows of s are row_begin[s] … row_begin[s + 1] − 1
    row_state: np.ndarray  # [M] a row's state
    row_option: np.ndarray  # [M] a row's option
    row_first_action: np.ndarray  # [M] a row's option's first action
    primitive_rows: np.ndarray  # [S, A] the row of each primitive option
    row_enabled: np.ndarray  # [B, M] the run may choose the row
    use_mentor: np.ndarray  # [B] the run uses the mentor term
    use_conf: np.ndarray  # [B] the run tests the mentor term's confidence
    use_sampling: np.ndarray  # [B] the run plans on a posterior sample


class CacheArrays(NamedTuple):
    """The value cache (``ValueCache``)."""

    values: np.ndarray  # [B, S + 1] V
    q_num: np.ndarray  # [B, M + 1] each row's Q numerator
    q_sec: np.ndarray  # [B, M + 1] its second moment's (confidence runs)
    m_num: np.ndarray  # [B, R_m + 1] the mentor term's numerator, per mentor row (K·S rows)
    m_sec: np.ndarray  # [B, R_m + 1] its second moment's
    m_edge_reward: np.ndarray  # [B, E_m] the mentor's mean reward on each edge
    m_edge_disc: np.ndarray  # [B, E_m] its E[γ^k] (γ: one-step moves)


class OptionModelArrays(NamedTuple):
    """The option model (``DirichletSMDPModel``) and the engine's linked lists over its edges."""

    edge_row: np.ndarray  # [B, E]
    edge_succ: np.ndarray  # [B, E]
    edge_count: np.ndarray  # [B, E]
    edge_disc: np.ndarray  # [B, E] Σ γ^k over the edge's outcomes
    num_edges: np.ndarray  # [B]
    row_count: np.ndarray  # [B, M + 1]
    row_reward: np.ndarray  # [B, M + 1] Σ discounted return
    state_tries: np.ndarray  # [B, S + 1] own options executed from each state
    row_head: np.ndarray  # [B, M + 1] first edge of each row (−1: none)
    row_next: np.ndarray  # [B, E] next edge of the same row
    succ_head: np.ndarray  # [B, S + 1] first edge into each state
    succ_next: np.ndarray  # [B, E] next edge into the same state


class MentorModelArrays(NamedTuple):
    """The mentor model (``DirichletMentorModel``, read only) and its linked lists."""

    edge_row: np.ndarray  # [B, E_m] the mentor row (k·S + state) the mentor left
    edge_succ: np.ndarray  # [B, E_m]
    edge_count: np.ndarray  # [B, E_m]
    row_count: np.ndarray  # [B, R_m + 1] (R_m = K·S: a row per mentor and state)
    row_head: np.ndarray
    row_next: np.ndarray
    succ_head: np.ndarray
    succ_next: np.ndarray


class SweepArrays(NamedTuple):
    """Prioritized sweeping (``Sweeper``) and the engine's indexed max-heap over its priorities:
    ``heap[b, i]`` the state in slot i, ``hkey[b, i]`` its priority (kept beside it, so that
    comparisons read the heap's own memory), ``hpos[b, s]`` the slot of state s (−1: not
    queued), ``hsize[b]``; ``prio[b, s]`` is the sweeper's priority array, kept equal."""

    heap: np.ndarray
    hkey: np.ndarray
    hpos: np.ndarray
    hsize: np.ndarray
    prio: np.ndarray
    pending: np.ndarray  # [B] decisions whose backups are still to do


class RunArrays(NamedTuple):
    """The run state (``RunState``) and each run's random stream key."""

    keys: np.ndarray  # [B] uint64
    position: np.ndarray
    option_start: np.ndarray
    row_of: np.ndarray  # the row being executed
    duration: np.ndarray
    disc_return: np.ndarray
    discount: np.ndarray
    epsilon: np.ndarray
    found_goal: np.ndarray
    goals: np.ndarray
    window_goals: np.ndarray
    episodes: np.ndarray
    episode_start: np.ndarray
    window_episode_steps: np.ndarray
    window_episodes: np.ndarray
    backups_done: np.ndarray
    decisions: np.ndarray
    first_goal_step: np.ndarray
    visits: np.ndarray  # [B, S + 1]


class SampleArrays(NamedTuple):
    """The posterior sample (``PosteriorSample``)."""

    w_opt: np.ndarray  # [B, E] each option-model edge's sampled weight
    wu_opt: np.ndarray  # [B, M + 1] each row's weight on the unseen successor
    w_m: np.ndarray  # [B, E_m] the same for the mentor model
    wu_m: np.ndarray  # [B, S + 1]
    resamples: np.ndarray  # [B] draws so far (the event counter of the sample keys)


class ClonedArrays(NamedTuple):
    """The cloned policy of the ``bco`` runs (``ClonedPolicy``, read only)."""

    action: np.ndarray  # [B, S + 1] the cloned action at each state (−1: none)


#: The counts a window's record holds, in the order of ``WindowArrays.counts``' last axis: the
#: run state's counters (named as its fields) and the mentor term's wins and observed states.
WINDOW_COUNTS = (
    "window_goals",
    "episodes",
    "window_episode_steps",
    "window_episodes",
    "backups_done",
    "decisions",
    "mentor_wins",
    "mentor_seen",
)


class WindowArrays(NamedTuple):
    """The windows the tick loop closes in one call (``RunMetrics``' records, filled in by the
    kernel at every ``window``-th tick: the Python side reads them after the call)."""

    counts: np.ndarray  # [B, W, len(WINDOW_COUNTS)] int64
    epsilon: np.ndarray  # [B, W] each run's ε at the window's end
    closed: np.ndarray  # [B] windows closed so far in this call


class Scratch(NamedTuple):
    """Per-run work space (the loop allocates nothing)."""

    round_states: np.ndarray  # [B, R] the states of a sweep round
    round_best: np.ndarray  # [B, R] their new values
    round_old: np.ndarray  # [B, R] their old values
    round_delta: np.ndarray  # [B, R] the change (0: none)
    q_buf: np.ndarray  # [B, J] Q of the rows of the state a choice is made in
    usable_buf: np.ndarray  # [B, J] usable, then the candidates
    enabled_buf: np.ndarray  # [B, J]
    score_buf: np.ndarray  # [B, A] the "match" rule's score of each first action


#: The arrays every run shares (no run axis), by group; every other array of a group has the run
#: as its first axis.
SHARED_FIELDS: dict[type, frozenset[str]] = {
    WorldArrays: frozenset(WorldArrays._fields),
    RowArrays: frozenset(
        ("row_begin", "row_state", "row_option", "row_first_action", "primitive_rows")
    ),
}


def map_per_run(arg: Any, f: Callable[[np.ndarray], np.ndarray]) -> Any:
    """``arg`` (a kernel argument: an array, a group of them, or anything else) with ``f``
    applied to each of its per-run arrays: an array is per-run, a group's array is unless
    :data:`SHARED_FIELDS` names it, and anything else (scalars, the settings) is left alone."""
    if isinstance(arg, np.ndarray):
        return f(arg)
    if not (isinstance(arg, tuple) and hasattr(arg, "_fields")):
        return arg
    shared = SHARED_FIELDS.get(type(arg), frozenset())
    return type(arg)(
        *(
            f(x) if isinstance(x, np.ndarray) and name not in shared else x
            for name, x in zip(arg._fields, arg)
        )
    )
