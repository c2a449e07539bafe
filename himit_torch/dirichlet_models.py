"""Dirichlet-count models of options (SMDP) and of the mentor, for a batch of ``B`` runs.

Storage grows with the transitions actually seen, never with ``S²``:

* a batch-shared **edge index**: every ``(row, successor)`` pair that *some* run has observed gets
  one edge id ``e`` (``edge_row[e]``, ``edge_successor[e]``), listed under its row (forward table
  ``[rows, K]``) and under its successor (reverse table ``[S, P]``);
* **per-run statistics** over edge ids: ``count [B, E]`` (Dirichlet counts) and
  ``discount [B, E]`` (summed ``γ^k``, the multi-time weights), plus per-row counts and rewards.

``K`` (successors per row) and ``P`` (predecessor edges per state) start small and double when a
row or state needs more (never silently dropped); ``E`` doubles likewise.

A "row" is whatever is being modelled: an available ``(s, o)`` pair for the option model, a state
for the mentor model. Rows are shared by the batch.

The posterior over a row's successors is a Dirichlet with the observed counts plus a prior
``concentration`` placed on one lumped "unseen successor" outcome, valued at the prior value (the
learner's initial value). This is how the prior's mass on unseen successors is handled without a
dense row over ``S``.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["EdgeIndex", "SuccessorDirichlet", "DirichletSMDPModel", "DirichletMentorModel"]


class EdgeIndex:
    """Batch-shared index of observed ``(row, successor)`` edges, with growth on overflow."""

    def __init__(self, num_rows: int, num_states: int, device: torch.device,
                 width: int = 8, fan_in: int = 16, capacity: int = 4096):
        self.num_rows, self.num_states, self.device = num_rows, num_states, device
        self.num_edges = 0
        self.edge_row = torch.full((capacity,), -1, dtype=torch.int64, device=device)
        self.edge_successor = torch.full((capacity,), -1, dtype=torch.int64, device=device)
        # Forward: edges of each row (−1 = empty). One extra row (index num_rows) stays empty so
        # that padded row ids can be gathered safely.
        self.forward = torch.full((num_rows + 1, width), -1, dtype=torch.int64, device=device)
        self.forward_len = torch.zeros(num_rows + 1, dtype=torch.int64, device=device)
        # Reverse: edges ending in each state (−1 = empty); extra state for padding.
        self.reverse = torch.full((num_states + 1, fan_in), -1, dtype=torch.int64, device=device)
        self.reverse_len = torch.zeros(num_states + 1, dtype=torch.int64, device=device)
        self.on_grow = []  # callbacks(new_capacity) for per-run arrays over edges

    _STATE = ("edge_row", "edge_successor", "forward", "forward_len", "reverse", "reverse_len")

    def state_dict(self) -> dict:
        out = {name: getattr(self, name).clone() for name in self._STATE}
        out["num_edges"] = self.num_edges
        return out

    def load_state_dict(self, state: dict) -> None:
        for name in self._STATE:
            setattr(self, name, state[name].to(self.device).clone())
        self.num_edges = int(state["num_edges"])

    @property
    def capacity(self) -> int:
        return self.edge_row.shape[0]

    @property
    def width(self) -> int:
        return self.forward.shape[1]

    @property
    def fan_in(self) -> int:
        return self.reverse.shape[1]

    def incoming(self, states: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """All edges ending in ``states [n]``: ``(owner [T], edge [T])`` where ``owner`` indexes
        ``states``. Gathers only the ``Σ fan-in`` real entries, not ``n × P`` padded ones."""
        lengths = self.reverse_len.index_select(0, states)
        total = int(lengths.sum())
        owner = torch.repeat_interleave(torch.arange(states.numel(), device=states.device),
                                        lengths, output_size=total)
        ends = lengths.cumsum(0)
        offset = torch.arange(total, device=states.device) - (ends - lengths).index_select(0, owner)
        flat = states.index_select(0, owner) * self.reverse.shape[1] + offset
        return owner, self.reverse.view(-1).index_select(0, flat)

    def find(self, rows: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        """Edge ids of ``(rows[i], successors[i])``, −1 where not indexed yet."""
        cand = self.forward[rows]                                        # [n, K]
        match = (self.edge_successor[cand.clamp(min=0)] == successors[:, None]) & (cand >= 0)
        return torch.where(match.any(1), cand.gather(1, match.long().argmax(1, keepdim=True))[:, 0],
                           torch.full_like(rows, -1))

    def find_or_add(self, rows: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        """Edge ids of the pairs, adding the missing ones (shared by the whole batch)."""
        ids = self.find(rows, successors)
        missing = ids < 0
        if bool(missing.any()):
            self._add(rows[missing], successors[missing])
            ids = self.find(rows, successors)
        return ids

    def _add(self, rows: torch.Tensor, successors: torch.Tensor) -> None:
        S = self.num_states
        keys = torch.unique(rows * (S + 1) + successors)                  # sorted by row
        new_rows, new_succ = keys // (S + 1), keys % (S + 1)
        n = keys.numel()
        self._reserve(self.num_edges + n)
        ids = torch.arange(self.num_edges, self.num_edges + n, device=self.device)
        self.num_edges += n
        self.edge_row[ids] = new_rows
        self.edge_successor[ids] = new_succ
        self._append(self.forward, self.forward_len, new_rows, ids, "forward")
        order = torch.argsort(new_succ, stable=True)
        self._append(self.reverse, self.reverse_len, new_succ[order], ids[order], "reverse")

    def _append(self, table, lengths, owners, ids, which):
        # owners sorted: rank of each id within its owner group
        first = torch.ones_like(owners, dtype=torch.bool)
        first[1:] = owners[1:] != owners[:-1]
        group_start = torch.cummax(torch.where(first, torch.arange(owners.numel(), device=owners.device),
                                               torch.zeros_like(owners)), 0).values
        rank = torch.arange(owners.numel(), device=owners.device) - group_start
        pos = lengths[owners] + rank
        need = int(pos.max()) + 1
        if need > table.shape[1]:
            width = table.shape[1]
            while width < need:
                width *= 2
            grown = torch.full((table.shape[0], width), -1, dtype=table.dtype, device=table.device)
            grown[:, :table.shape[1]] = table
            table = grown
            setattr(self, which, table)
        table[owners, pos] = ids
        lengths.index_add_(0, owners, torch.ones_like(owners))

    def _reserve(self, needed: int) -> None:
        if needed <= self.capacity:
            return
        capacity = self.capacity
        while capacity < needed:
            capacity *= 2
        for name in ("edge_row", "edge_successor"):
            old = getattr(self, name)
            new = torch.full((capacity,), -1, dtype=old.dtype, device=old.device)
            new[:old.shape[0]] = old
            setattr(self, name, new)
        for callback in self.on_grow:
            callback(capacity)


def _grow_columns(tensor: torch.Tensor, capacity: int) -> torch.Tensor:
    grown = torch.zeros((tensor.shape[0], capacity), dtype=tensor.dtype, device=tensor.device)
    grown[:, :tensor.shape[1]] = tensor
    return grown


@dataclass(frozen=True)
class SuccessorDirichlet:
    """Dirichlet posterior over a row's successors, batched: ``[..., K + 1]`` categories.

    The first ``K`` categories are observed successors (``successors[..., k]``, −1 = padding, with
    zero concentration); the last is the lumped "unseen successor" carrying the prior
    concentration. Looks like NumPyro's ``Dirichlet``.
    """

    concentration: torch.Tensor
    successors: torch.Tensor

    @property
    def total(self) -> torch.Tensor:
        return self.concentration.sum(-1)

    @property
    def mean(self) -> torch.Tensor:
        """``E[p_k] = α_k / α_0`` (zeros where α_0 = 0, i.e. nothing seen and no prior)."""
        total = self.total[..., None]
        return torch.where(total > 0, self.concentration / total.clamp(min=1e-300),
                           torch.zeros_like(self.concentration))

    @property
    def variance(self) -> torch.Tensor:
        """``Var[p_k] = α_k (α_0 − α_k) / (α_0² (α_0 + 1))``."""
        a, total = self.concentration, self.total[..., None]
        return torch.where(total > 0, a * (total - a) / (total.clamp(min=1e-300) ** 2 * (total + 1)),
                           torch.zeros_like(a))

    def sample(self, generator: torch.Generator) -> torch.Tensor:
        """One draw of the probabilities per row, from ``generator`` (categories with zero
        concentration get probability 0)."""
        seed = int(torch.randint(0, 2**62, (1,), generator=generator, device=generator.device))
        devices = list(range(torch.cuda.device_count())) if torch.cuda.is_available() else []
        with torch.random.fork_rng(devices=devices):   # leaves every global RNG as it was
            torch.manual_seed(seed)
            a = self.concentration.double().cpu()
            g = torch._standard_gamma(a.clamp(min=1e-300)) * (a > 0)
        g = g.to(self.concentration.device, self.concentration.dtype)
        total = g.sum(-1, keepdim=True)
        return torch.where(total > 0, g / total.clamp(min=1e-300), torch.zeros_like(g))


class _CountModel:
    """Shared machinery: rows with per-run counts over a batch-shared edge index."""

    def __init__(self, num_rows: int, num_states: int, batch: int, device, concentration: float,
                 width: int, fan_in: int):
        if batch <= 0:
            raise ValueError(f"batch={batch}: a model needs at least one run")
        if not concentration >= 0:
            raise ValueError(f"concentration={concentration} must be ≥ 0 (the prior's Dirichlet mass "
                             "on unseen successors)")
        self.device = torch.device(device)
        self.batch, self.num_rows, self.num_states = batch, num_rows, num_states
        self.concentration = float(concentration)
        self.edges = EdgeIndex(num_rows, num_states, self.device, width=width, fan_in=fan_in)
        self.edge_count = torch.zeros(batch, self.edges.capacity, dtype=torch.float64, device=self.device)
        self.row_count = torch.zeros(batch, num_rows + 1, dtype=torch.float64, device=self.device)
        self.edges.on_grow.append(self._grow)

    def _grow(self, capacity: int) -> None:
        self.edge_count = _grow_columns(self.edge_count, capacity)

    _STATE = ("edge_count", "row_count")

    def state_dict(self) -> dict:
        out = {name: getattr(self, name).clone() for name in self._STATE}
        out["edges"] = self.edges.state_dict()
        return out

    def load_state_dict(self, state: dict) -> None:
        self.edges.load_state_dict(state["edges"])
        for name in self._STATE:
            setattr(self, name, state[name].to(self.device).clone())

    def posterior(self, runs: torch.Tensor, rows: torch.Tensor) -> SuccessorDirichlet:
        """Posterior over the successors of ``rows`` (any shape) in ``runs`` (same shape)."""
        edge = self.edges.forward[rows]                                  # [..., K]
        counts = torch.where(edge >= 0, self.edge_count[runs[..., None], edge.clamp(min=0)],
                             torch.zeros((), dtype=torch.float64, device=self.device))
        prior = torch.full(rows.shape + (1,), self.concentration, dtype=torch.float64,
                           device=self.device)
        succ = torch.where(edge >= 0, self.edges.edge_successor[edge.clamp(min=0)], edge)
        return SuccessorDirichlet(torch.cat([counts, prior], -1), succ)


class DirichletSMDPModel(_CountModel):
    """The learner's model of its own options, one per run: for every executed ``(s, o)`` row the
    count of each termination state, the summed ``γ^k`` per ``(s, o, s')`` and the summed
    discounted reward (the paper's Section II, after Sutton, Precup & Singh 1999).

    Posterior means (with prior concentration ``α`` on the unseen outcome, valued ``v0``):
    ``p^o_{ss'} = Σγ^k(s,o,s') / (n + α)`` and ``r(s, o) = Σ r / n``, so that the model's value of
    an option is ``Q = (Σ r + Σ_{s'} Σγ^k V(s') + α v0) / (n + α)``.
    """

    def __init__(self, num_rows: int, num_states: int, batch: int, device="cpu",
                 concentration: float = 0.0, width: int = 8, fan_in: int = 16):
        super().__init__(num_rows, num_states, batch, device, concentration, width, fan_in)
        self.edge_discount = torch.zeros_like(self.edge_count)
        self.row_reward = torch.zeros_like(self.row_count)

    _STATE = ("edge_count", "row_count", "edge_discount", "row_reward")

    def _grow(self, capacity: int) -> None:
        super()._grow(capacity)
        self.edge_discount = _grow_columns(self.edge_discount, capacity)

    def update(self, runs: torch.Tensor, rows: torch.Tensor, successors: torch.Tensor,
               durations: torch.Tensor, discounted_rewards: torch.Tensor, gamma: float) -> torch.Tensor:
        """Record one executed option per entry: it ran ``durations`` steps from its row and ended
        in ``successors`` having collected ``discounted_rewards``. Returns the edge ids."""
        edges = self.edges.find_or_add(rows, successors)
        discount = torch.pow(torch.as_tensor(gamma, dtype=torch.float64), durations.double())
        self.edge_count.index_put_((runs, edges), torch.ones_like(discount), accumulate=True)
        self.edge_discount.index_put_((runs, edges), discount, accumulate=True)
        self.row_count.index_put_((runs, rows), torch.ones_like(discount), accumulate=True)
        self.row_reward.index_put_((runs, rows), discounted_rewards.double(), accumulate=True)
        return edges

    def mean(self, runs: torch.Tensor, rows: torch.Tensor):
        """``(reward [...], successors [..., K], weights [..., K])``: posterior-mean reward and
        multi-time weights ``p^o_{ss'}`` of each row (zeros for untried rows)."""
        edge = self.edges.forward[rows]
        n = self.row_count[runs, rows]
        denom = (n + self.concentration)[..., None]
        g = torch.where(edge >= 0, self.edge_discount[runs[..., None], edge.clamp(min=0)],
                        torch.zeros((), dtype=torch.float64, device=self.device))
        weights = torch.where(denom > 0, g / denom.clamp(min=1e-300), torch.zeros_like(g))
        reward = torch.where(n > 0, self.row_reward[runs, rows] / n.clamp(min=1), torch.zeros_like(n))
        succ = torch.where(edge >= 0, self.edges.edge_successor[edge.clamp(min=0)], edge)
        return reward, succ, weights


class DirichletMentorModel(_CountModel):
    """The learner's model ``p_m(s' | s)`` of the mentor, from consecutive observed states only.

    Rows are states. Demonstrations can be added at any time, to all runs or to some.
    """

    def __init__(self, num_states: int, batch: int, device="cpu", concentration: float = 0.0,
                 width: int = 8, fan_in: int = 8):
        super().__init__(num_states, num_states, batch, device, concentration, width, fan_in)

    def observe(self, sources: torch.Tensor, successors: torch.Tensor,
                runs: torch.Tensor | None = None) -> torch.Tensor:
        """Count the transitions ``sources[i] → successors[i]`` for ``runs`` (all by default).
        Returns the edge ids."""
        if sources.numel() == 0:
            return sources
        edges = self.edges.find_or_add(sources, successors)
        runs = torch.arange(self.batch, device=self.device) if runs is None else runs
        R, T = runs.numel(), edges.numel()
        self.edge_count.index_put_((runs.repeat_interleave(T), edges.repeat(R)),
                                   torch.ones(R * T, dtype=torch.float64, device=self.device),
                                   accumulate=True)
        self.row_count.index_put_((runs.repeat_interleave(T), sources.repeat(R)),
                                  torch.ones(R * T, dtype=torch.float64, device=self.device),
                                  accumulate=True)
        return edges

    def observed(self) -> torch.Tensor:
        """``[B, S]`` bool: states where the mentor was seen leaving (its term exists there)."""
        return self.row_count[:, :self.num_states] > 0

    def mean(self, runs: torch.Tensor, states: torch.Tensor):
        """``(successors [..., K], probabilities [..., K])`` posterior means ``p_m(s'|s)``."""
        post = self.posterior(runs, states)
        return post.successors, post.mean[..., :-1]
