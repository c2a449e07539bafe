"""Worlds given by their tabular model, and what the library reads from any world's model.

:class:`TableWorld` is a world defined by a :class:`~himit_torch.DynamicsTable` (successors,
cdf and rewards per transition ``(s, a, s')``), a start distribution, the terminal states and a
discount: everything the learner, the exact planners, the mentor and the demonstrations need.
:func:`~himit_torch.from_gymnasium` builds one from a Gymnasium toy-text environment.

The helpers read the model of *any* world, MultiRooms and hand-written ones included:

* :func:`world_model` — the true model ``(P [A, S, S] sparse, R [S, A])`` with terminal states
  absorbing at reward 0 (from ``transition_model()``/``reward_model()``, or derived from
  ``dynamics_table()``);
* :func:`transition_support` — which one-step moves ``s → s'`` are possible;
* :func:`describe_world` — a JSON-able description that identifies a world (saved with
  demonstrations).

The wider world protocol (optional members beyond :class:`~himit_torch.TabularWorld`):

* ``start_distribution`` — ``[S]`` float64 probabilities summing to 1; episodes start from a
  draw of it (the learner draws it from each run's own random stream). ``None`` or absent:
  every episode starts at ``start_state``.
* ``dynamics_table()`` — the :class:`~himit_torch.DynamicsTable` that ``step`` uses; rewards per
  transition ``(s, a, s')``.
* ``transition_model(sparse=True)`` / ``reward_model()`` — the true model for exact planning.
* ``state_reward`` — ``[S]`` reward for *entering* each state, only where that is the whole
  reward (MultiRooms; a TableWorld whose rewards depend on ``s'`` alone).
* ``describe()`` — the world's identity for saved demonstrations.
"""

from __future__ import annotations

import hashlib
import json

import numpy as np
import scipy.sparse as sp
import torch

from himit_torch.validation import as_float, as_float_array, as_tuple, bool_vector
from himit_torch.worlds.tabular import DynamicsTable

__all__ = [
    "TableWorld",
    "world_model",
    "transition_support",
    "transition_support_matrix",
    "describe_world",
    "model_from_table",
    "table_probabilities",
]


def _shape_of(value) -> str:
    shape = getattr(value, "shape", None)
    if shape is None:
        return repr(value)[:40]
    return f"shape {tuple(shape)} dtype {getattr(value, 'dtype', '?')}"


def table_probabilities(table: DynamicsTable) -> torch.Tensor:
    """``[S, A, K]`` float64 probability of each slot (the cdf's increments)."""
    return torch.diff(table.cdf, dim=-1, prepend=torch.zeros_like(table.cdf[..., :1]))


def model_from_table(
    table: DynamicsTable, terminal_mask: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """The true model of a dynamics table: ``P [A, S, S]`` float64 sparse COO and the expected
    reward ``R [S, A]`` float64. Terminal states are absorbing with reward 0 (the convention of
    the exact planners: a terminal state's value is 0), whatever the table says about leaving
    them; slots of probability 0 are left out."""
    succ, rew = table.successors.cpu(), table.rewards.cpu()
    prob = table_probabilities(table).cpu()
    S, A, K = succ.shape
    terminal = torch.as_tensor(terminal_mask, dtype=torch.bool).cpu()
    s_idx = torch.arange(S)[:, None, None].expand(S, A, K)
    a_idx = torch.arange(A)[None, :, None].expand(S, A, K)
    live = (prob > 0) & ~terminal[:, None, None]
    idx = torch.stack([a_idx[live], s_idx[live], succ[live]])
    vals = prob[live]
    term = terminal.nonzero()[:, 0]
    if term.numel():  # absorbing: P[a, t, t] = 1 for every action
        ta = torch.arange(A).repeat_interleave(term.numel())
        tt = term.repeat(A)
        idx = torch.cat([idx, torch.stack([ta, tt, tt])], 1)
        vals = torch.cat([vals, torch.ones(tt.numel(), dtype=torch.float64)])
    P = torch.sparse_coo_tensor(idx, vals, (A, S, S), check_invariants=False).coalesce()
    R = (prob * rew).sum(-1)
    R[terminal] = 0.0
    return P, R


def world_model(world) -> tuple[torch.Tensor, torch.Tensor]:
    """``(P [A, S, S] sparse COO float64, R [S, A] float64)`` of any world: its own
    ``transition_model()`` and ``reward_model()`` where it has them, else derived from its
    ``dynamics_table()`` (:func:`model_from_table`).

    Raises:
        ValueError: the world has neither (a world with only ``step`` has no model to read).
    """
    if hasattr(world, "transition_model") and hasattr(world, "reward_model"):
        P = world.transition_model(sparse=True)
        P = (P if P.is_sparse else P.to_sparse()).coalesce()
        return P.double(), world.reward_model().double()
    if hasattr(world, "dynamics_table"):
        return model_from_table(world.dynamics_table(), world.terminal_mask)
    raise ValueError(
        f"{type(world).__name__} has no true model to read: give it a "
        "dynamics_table() (a DynamicsTable; see TableWorld) or "
        "transition_model(sparse=True) [A, S, S] and reward_model() [S, A]"
    )


def transition_support(world) -> torch.Tensor:
    """``[S, S]`` bool, True where ``s → s'`` is possible in one primitive step (some action
    reaches ``s'`` with positive probability), from the world's ``dynamics_table()`` where it
    has one (the table ``step`` uses), else its ``transition_model()``.

    Rows of terminal states are left empty: an episode ends there, so no step leaves them.
    Dense: ``S²`` bytes; :func:`transition_support_matrix` holds the same sparsely.
    """
    return torch.from_numpy(transition_support_matrix(world).toarray())


def transition_support_matrix(world) -> sp.csr_matrix:
    """:func:`transition_support` as a scipy CSR bool matrix: memory grows with the possible
    moves, not with ``S²`` (a 50,000-state world's dense support is 2.5 GB)."""
    S = int(world.num_states)
    terminal = torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu().numpy()
    if hasattr(world, "dynamics_table"):
        table = world.dynamics_table()
        prob = table_probabilities(table).cpu().numpy()
        s_idx = np.broadcast_to(np.arange(S)[:, None, None], prob.shape)
        live = prob > 0
        rows, cols = s_idx[live], table.successors.cpu().numpy()[live]
    elif hasattr(world, "transition_model"):
        P = world.transition_model(sparse=True)
        P = (P if P.is_sparse else P.to_sparse()).coalesce()
        _, s, t = P.indices().numpy()
        keep = P.values().numpy() > 0
        rows, cols = s[keep], t[keep]
    else:
        raise ValueError(
            f"{type(world).__name__} has neither dynamics_table() nor "
            "transition_model(): its transition support (which moves are possible) "
            "is unknown, so demonstrations cannot be checked against it"
        )
    keep = ~terminal[rows]
    support = sp.csr_matrix(
        (np.ones(int(keep.sum()), dtype=bool), (rows[keep], cols[keep])), shape=(S, S)
    )
    support.sum_duplicates()
    return support


def _fingerprint(*tensors: torch.Tensor) -> str:
    """A short hash of tensors' values (their float64/int64 bytes): the same model, the same
    fingerprint, on every machine."""
    h = hashlib.sha256()
    for t in tensors:
        t = t.detach().cpu().contiguous()
        t = t.double() if t.is_floating_point() else t.to(torch.int64)
        h.update(str(tuple(t.shape)).encode())
        h.update(t.numpy().tobytes())
    return h.hexdigest()[:16]


def table_fingerprint(table: DynamicsTable, terminal_mask, start) -> str:
    """A hash of a dynamics table, the terminal states and the start (distribution or state)."""
    return _fingerprint(
        table.successors,
        table.cdf,
        table.rewards,
        torch.as_tensor(terminal_mask, dtype=torch.bool),
        torch.as_tensor(start),
    )


def model_fingerprint(world) -> str:
    """A hash of a world's dynamics, terminal states and start distribution."""
    terminal = torch.as_tensor(world.terminal_mask, dtype=torch.bool)
    start = getattr(world, "start_distribution", None)
    start = torch.tensor([float(world.start_state)]) if start is None else torch.as_tensor(start)
    if hasattr(world, "dynamics_table"):
        return table_fingerprint(world.dynamics_table(), terminal, start)
    P, R = world_model(world)
    return _fingerprint(P.indices(), P.values(), R, terminal, start)


def describe_world(world) -> dict:
    """A JSON-able description identifying ``world``: its own ``describe()`` where it has one,
    else ``{"kind": "custom", "class", "num_states", "num_actions", "gamma", "fingerprint"}`` —
    the fingerprint hashes the dynamics, so demonstrations saved in one world are refused in a
    world with other dynamics."""
    if hasattr(world, "describe"):
        return json.loads(json.dumps(world.describe()))
    cls = type(world)
    return {
        "kind": "custom",
        "class": f"{cls.__module__}.{cls.__qualname__}",
        "num_states": int(world.num_states),
        "num_actions": int(world.num_actions),
        "gamma": float(world.gamma),
        "fingerprint": model_fingerprint(world),
    }


class TableWorld:
    """A tabular world defined by its model: a :class:`~himit_torch.DynamicsTable`, a start
    distribution, terminal states and a discount.

    Description
        ``S`` states and ``A`` actions. Executing ``a`` in ``s`` with the uniform ``u`` leads to
        ``dynamics.successors[s, a, k]`` with reward ``dynamics.rewards[s, a, k]`` for the first
        slot ``k`` with ``u < dynamics.cdf[s, a, k]`` (:meth:`DynamicsTable.step`).

    Start
        Every episode starts in a state drawn from ``start_distribution`` (the learner draws it
        from each run's own random stream, so runs stay reproducible). ``start_state`` is its
        most likely state (the lowest of ties): the one state used where a single start is
        needed (greedy trajectories, probes).

    Rewards
        Per transition ``(s, a, s')``, read from the table. ``state_reward`` (reward for
        entering ``s'``) exists only when every transition into a state from a non-terminal
        state pays the same: then it is the whole reward.

    Termination
        Entering a state of ``terminal_mask`` ends the episode. In the true model
        (:meth:`transition_model`, :meth:`reward_model`) terminal states are absorbing with
        reward 0, as in MultiRooms.

    Args:
        dynamics: the :class:`~himit_torch.DynamicsTable`, ``[S, A, K]`` (tensors; it checks
            them).
        start_distribution: ``[S]`` probabilities (≥ 0, summing to 1, none on a terminal state):
            a tensor, array or list of real numbers (bools and strings are refused).
        terminal_mask: ``[S]`` bools: a bool tensor, array or list (0/1 numbers are refused:
            a list of state indices is not a mask).
        gamma: discount in ``(0, 1]`` (value iteration needs ``< 1``), a real number.
        action_names: optional ``A`` names (for option names and printing).
        description: the dict :meth:`describe` returns; by default ``{"kind": "TableWorld",
            "num_states", "num_actions", "gamma", "fingerprint"}``.
        name: a short label for ``repr``.

    Raises:
        ValueError: any argument outside what is said above, naming it.
    """

    def __init__(
        self,
        dynamics: DynamicsTable,
        start_distribution,
        terminal_mask,
        gamma: float = 0.99,
        action_names=None,
        description: dict | None = None,
        name: str = "TableWorld",
    ):
        if not isinstance(dynamics, DynamicsTable):  # which checks its own tensors
            raise ValueError(
                f"TableWorld: dynamics must be a DynamicsTable, got {type(dynamics).__name__}"
            )
        S, A, _ = dynamics.successors.shape
        self._table = DynamicsTable(
            dynamics.successors.cpu().contiguous(),
            dynamics.cdf.cpu().double().contiguous(),
            dynamics.rewards.cpu().double().contiguous(),
        )
        self._tables: dict[torch.device, DynamicsTable] = {torch.device("cpu"): self._table}
        self.num_states, self.num_actions = int(S), int(A)
        self.gamma = as_float("TableWorld: gamma", gamma, 0.0, 1.0, low_open=True)
        terminal = bool_vector(terminal_mask)
        if terminal is None or terminal.shape != (S,):
            raise ValueError(
                f"TableWorld: terminal_mask must be a [S] = [{S}] bool tensor (or a bool array or "
                f"list; 0/1 numbers are not bools), got {_shape_of(terminal_mask)}"
            )
        self._terminal = terminal.clone()
        start = torch.from_numpy(
            as_float_array("TableWorld: start_distribution", start_distribution)
        )
        if start.shape != (S,):
            raise ValueError(
                f"TableWorld: start_distribution must be [S] = [{S}], got {tuple(start.shape)}"
            )
        if bool((start < 0).any()) or abs(float(start.sum()) - 1.0) > 1e-9:
            raise ValueError(
                "TableWorld: start_distribution must hold probabilities ≥ 0 summing to 1 "
                f"(sum {float(start.sum())!r})"
            )
        on_terminal = (start > 0) & terminal
        if bool(on_terminal.any()):
            raise ValueError(
                f"TableWorld: start_distribution puts weight on terminal states "
                f"{on_terminal.nonzero()[:, 0].tolist()[:5]}; an episode cannot start "
                "where it ends"
            )
        self.start_distribution = start
        self.start_state = int(torch.argmax(start))  # first of the most likely starts
        if action_names is not None:
            action_names = tuple(str(n) for n in as_tuple("TableWorld: action_names", action_names))
            if len(action_names) != A:
                raise ValueError(f"TableWorld: {len(action_names)} action_names for {A} actions")
        self.action_names = action_names or tuple(str(a) for a in range(A))
        if not isinstance(name, str) or not name:
            raise ValueError(f"TableWorld: name must be a non-empty string, got {name!r}")
        if description is not None and not isinstance(description, dict):
            raise ValueError(
                f"TableWorld: description must be a dict (or None), got {type(description).__name__}"
            )
        self.name = name
        self._description = description
        self._transition: torch.Tensor | None = None
        self._reward: torch.Tensor | None = None
        self.state_reward = self._entering_reward()

    # ----------------------------------------------------------------------------- protocol
    @property
    def terminal_mask(self) -> torch.Tensor:
        """``[S]`` bool: entering one of these states ends the episode."""
        return self._terminal.clone()

    def dynamics_table(self) -> DynamicsTable:
        """The :class:`~himit_torch.DynamicsTable` that :meth:`step` uses (on the CPU)."""
        return self._table

    def step(
        self,
        positions: torch.Tensor,
        actions: torch.Tensor,
        uniforms: torch.Tensor | None = None,
        generator: torch.Generator | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """``positions [B], actions [B], uniforms [B] in [0, 1)`` → ``(next [B] int64, reward [B]
        float64)`` by :meth:`dynamics_table` (``uniforms`` drawn from ``generator`` if omitted)."""
        if uniforms is None:
            uniforms = torch.rand(
                positions.shape, generator=generator, device=positions.device, dtype=torch.float64
            )
        table = self._tables.get(positions.device)
        if table is None:
            table = self._tables[positions.device] = self._table.to(positions.device)
        return table.step(positions, actions, uniforms)

    # ----------------------------------------------------------------------------- true model
    def transition_model(self, sparse: bool = True) -> torch.Tensor:
        """The true dynamics ``P [A, S, S]`` float64 (``P[a, s, s']``); terminal states absorbing.
        Sparse COO unless ``sparse=False``; each call returns a fresh copy."""
        if self._transition is None:
            self._transition, self._reward = model_from_table(self._table, self._terminal)
        P = self._transition.clone()
        return P if sparse else P.to_dense()

    def reward_model(self) -> torch.Tensor:
        """Expected reward ``R [S, A]`` float64 of each action; 0 at terminal states."""
        if self._reward is None:
            self._transition, self._reward = model_from_table(self._table, self._terminal)
        return self._reward.clone()

    def describe(self) -> dict:
        """A JSON-able description identifying the world (saved with demonstrations)."""
        if self._description is not None:
            return json.loads(json.dumps(self._description))
        return {
            "kind": "TableWorld",
            "num_states": self.num_states,
            "num_actions": self.num_actions,
            "gamma": self.gamma,
            "fingerprint": model_fingerprint(self),
        }

    # ----------------------------------------------------------------------------- queries
    def _entering_reward(self) -> torch.Tensor | None:
        """``[S]`` reward for entering each state if that is the whole reward (every possible
        transition into ``s'`` from a non-terminal state pays the same), else ``None``."""
        table = self._table
        live = (table_probabilities(table) > 0) & ~self._terminal[:, None, None]
        succ, rew = table.successors[live], table.rewards[live]
        S = self.num_states
        high = torch.full((S,), -float("inf"), dtype=torch.float64).scatter_reduce(
            0, succ, rew, "amax"
        )
        low = torch.full((S,), float("inf"), dtype=torch.float64).scatter_reduce(
            0, succ, rew, "amin"
        )
        entered = torch.isfinite(high)
        if bool((high[entered] != low[entered]).any()):
            return None
        # States never entered get the least reward of the world: never used, and never raises
        # the learner's bound on its best real reward.
        return torch.where(
            entered,
            high,
            low[entered].min() if bool(entered.any()) else torch.zeros((), dtype=torch.float64),
        )

    @property
    def goal_mask(self) -> torch.Tensor:
        """``[S]`` bool: the terminal states that count as *success* — those entered with the
        highest reward among all transitions into terminal states (FrozenLake's goal, not its
        holes; every delivery in Taxi; CliffWalking's goal)."""
        table = self._table
        live = (table_probabilities(table) > 0) & ~self._terminal[:, None, None]
        succ, rew = table.successors[live], table.rewards[live]
        into = self._terminal[succ]
        goal = torch.zeros(self.num_states, dtype=torch.bool)
        if bool(into.any()):
            best = torch.full(
                (self.num_states,), -float("inf"), dtype=torch.float64
            ).scatter_reduce(0, succ[into], rew[into], "amax")
            goal = self._terminal & (best >= float(rew[into].max()))
        return goal

    def __repr__(self) -> str:
        starts = int((self.start_distribution > 0).sum())
        return (
            f"{self.name}(S={self.num_states}, A={self.num_actions}, start states={starts}, "
            f"terminal states={int(self._terminal.sum())}, gamma={self.gamma})"
        )
