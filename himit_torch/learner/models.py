"""Dirichlet-count models of options (SMDP) and of the mentor, one per run of a batch of ``B``.

Storage grows with the transitions each run has seen, never with ``S²``. Each run keeps a list of
the ``(row, successor)`` **edges** it has observed — ``edge_row [B, E]``, ``edge_successor [B, E]``
and the Dirichlet counts ``edge_count [B, E]`` (plus, for options, the summed ``γ^k`` per edge,
the multi-time weights) — with edge ids ``0 … num_edges[b] − 1`` given in the order run ``b``
first saw them. So a run's model, and every number computed from it, is the same in any batch.
The capacity ``E`` doubles when a run needs more (nothing is ever dropped).

A "row" is whatever is being modelled: an available ``(s, o)`` pair for the option model, a state
for the mentor model. Rows are numbered by the learner's row table and shared by the batch.

The edge lists are the state. Lookups go through an index derived from them:
:class:`DenseEdgeIndex` (padded per-run forward and reverse tables, for batched tensor ops) here;
the compiled engine builds linked lists of its own. An index rebuilds itself when the lists
changed under it (``EdgeStore.version``).

The posterior over a row's successors is a Dirichlet with the observed counts plus a prior
``concentration`` placed on one lumped "unseen successor" outcome, valued at the prior value (the
learner's initial value). This is how the prior's mass on unseen successors is handled without a
dense row over ``S``.
"""

from __future__ import annotations

import numpy as np
import torch

from himit_torch.state_checks import (
    DamagedState,
    all_finite,
    in_range,
    private_copy,
    saved,
    section,
    tensor,
)

__all__ = [
    "EdgeStore",
    "DenseEdgeIndex",
    "SuccessorDirichlet",
    "DirichletSMDPModel",
    "DirichletMentorModel",
]


def _grow_columns(tensor: torch.Tensor, capacity: int, fill=0) -> torch.Tensor:
    grown = torch.full((tensor.shape[0], capacity), fill, dtype=tensor.dtype, device=tensor.device)
    grown[:, : tensor.shape[1]] = tensor
    return grown


def _nonzero(total: torch.Tensor) -> torch.Tensor:
    """``total`` where it is positive, 1 elsewhere: a divisor for the branch of a
    ``torch.where(total > 0, …)`` that is taken. (Clamping at a tiny floor instead would divide a
    subnormal total — a subnormal prior concentration, say 5e-324 — by the floor, not by itself:
    posterior means summing to 1e-24.)"""
    return torch.where(total > 0, total, torch.ones_like(total))


def _has_repeats(keys: torch.Tensor) -> bool:
    """Whether some value occurs twice in the 1-D ``keys`` (sorted, neighbours compared; on a
    CPU by NumPy's sort, several times faster here than ``unique``'s hashing)."""
    if keys.device.type == "cpu":
        ordered = np.sort(keys.numpy())
        return bool(np.any(ordered[1:] == ordered[:-1]))
    on_device = keys.sort().values
    return bool((on_device[1:] == on_device[:-1]).any())


class DenseEdgeIndex:
    """Per-run forward (edges of each row) and reverse (edges into each state) tables of an
    :class:`EdgeStore`, padded with −1: ``forward [B, R + 1, K]``, ``reverse [B, S + 1, P]``.
    ``K`` and ``P`` double when a row or a state needs more room. Derived: never saved."""

    def __init__(self, store: EdgeStore, width: int = 8, fan_in: int = 16):
        B, dev = store.batch, store.device
        self.store = store
        self.forward = torch.full((B, store.num_rows + 1, width), -1, dtype=torch.int64, device=dev)
        self.forward_len = torch.zeros(B, store.num_rows + 1, dtype=torch.int64, device=dev)
        self.reverse = torch.full(
            (B, store.num_states + 1, fan_in), -1, dtype=torch.int64, device=dev
        )
        self.reverse_len = torch.zeros(B, store.num_states + 1, dtype=torch.int64, device=dev)
        runs = torch.arange(B, device=dev)[:, None].expand(-1, store.capacity)
        valid = torch.arange(store.capacity, device=dev) < store.num_edges[:, None]
        self.append(runs[valid], torch.arange(store.capacity, device=dev).expand(B, -1)[valid])
        self.version = store.version

    def append(self, runs: torch.Tensor, edges: torch.Tensor) -> None:
        """List new edges ``(runs[i], edges[i])`` (ascending ids within a run) in both tables."""
        if edges.numel() == 0:
            return
        st = self.store
        rows = st.edge_row[runs, edges]
        succ = st.edge_successor[runs, edges]
        self.forward = self._append(self.forward, self.forward_len, runs, rows, edges)
        self.reverse = self._append(self.reverse, self.reverse_len, runs, succ, edges)

    @staticmethod
    def _append(table, lengths, runs, owners, ids):
        # Rank of each id within its (run, owner) group, groups in id order.
        key = runs * table.shape[1] + owners
        order = torch.argsort(key * (ids.max() + 1) + ids)
        key, ids_sorted = key[order], ids[order]
        first = torch.ones_like(key, dtype=torch.bool)
        first[1:] = key[1:] != key[:-1]
        idx = torch.arange(key.numel(), device=key.device)
        rank = idx - torch.cummax(torch.where(first, idx, torch.zeros_like(idx)), 0).values
        flat_len = lengths.view(-1)
        pos = flat_len.index_select(0, key) + rank
        need = int(pos.max()) + 1
        if need > table.shape[2]:
            width = table.shape[2]
            while width < need:
                width *= 2
            grown = torch.full(
                table.shape[:2] + (width,), -1, dtype=table.dtype, device=table.device
            )
            grown[:, :, : table.shape[2]] = table
            table = grown
        table.view(-1).index_put_((key * table.shape[2] + pos,), ids_sorted)
        flat_len.index_add_(0, key, torch.ones_like(key))
        return table

    def find(
        self, runs: torch.Tensor, rows: torch.Tensor, successors: torch.Tensor
    ) -> torch.Tensor:
        """Edge ids of ``(runs[i], rows[i], successors[i])``, −1 where not seen."""
        cand = self.forward[runs, rows]  # [n, K]
        succ = self.store.edge_successor[runs[:, None], cand.clamp(min=0)]
        match = (succ == successors[:, None]) & (cand >= 0)
        return torch.where(
            match.any(1),
            cand.gather(1, match.long().argmax(1, keepdim=True))[:, 0],
            torch.full_like(rows, -1),
        )

    def incoming(
        self, runs: torch.Tensor, states: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """All edges of ``runs[i]`` ending in ``states[i]``: ``(owner [T], edge [T])`` where
        ``owner`` indexes the inputs, in input order and, within one input, ascending edge ids.
        Gathers only the ``Σ fan-in`` real entries, not ``n × P`` padded ones."""
        flat = runs * self.reverse.shape[1] + states
        lengths = self.reverse_len.view(-1).index_select(0, flat)
        total = int(lengths.sum())
        owner = torch.repeat_interleave(
            torch.arange(states.numel(), device=states.device), lengths, output_size=total
        )
        ends = lengths.cumsum(0)
        offset = torch.arange(total, device=states.device) - (ends - lengths).index_select(0, owner)
        cells = flat.index_select(0, owner) * self.reverse.shape[2] + offset
        return owner, self.reverse.view(-1).index_select(0, cells)


class EdgeStore:
    """Per-run lists of observed ``(row, successor)`` edges with their Dirichlet counts.

    Shapes: ``edge_row``, ``edge_successor`` (−1 = unused) and ``edge_count`` ``[B, E]``;
    ``num_edges [B]``; ``row_count [B, R + 1]`` (the extra row is padding, always 0).
    Subclasses name further per-edge arrays in ``_EDGE_FLOATS``; ``on_grow`` callbacks let
    owners of other per-edge arrays grow with the store.
    """

    _EDGE_FLOATS: tuple[str, ...] = ("edge_count",)
    _ROW_FLOATS: tuple[str, ...] = ("row_count",)
    # Set by name in __init__ from _EDGE_FLOATS / _ROW_FLOATS.
    edge_count: torch.Tensor
    row_count: torch.Tensor

    def __init__(
        self,
        num_rows: int,
        num_states: int,
        batch: int,
        device,
        concentration: float,
        capacity: int = 256,
    ):
        if batch <= 0:
            raise ValueError(f"batch={batch}: a model needs at least one run")
        if not concentration >= 0:
            raise ValueError(
                f"concentration={concentration} must be ≥ 0 (the prior's Dirichlet mass "
                "on unseen successors)"
            )
        self.device = dev = torch.device(device)
        self.batch, self.num_rows, self.num_states = batch, num_rows, num_states
        self.concentration = float(concentration)
        self.edge_row = torch.full((batch, capacity), -1, dtype=torch.int64, device=dev)
        self.edge_successor = torch.full((batch, capacity), -1, dtype=torch.int64, device=dev)
        for name in self._EDGE_FLOATS:
            setattr(self, name, torch.zeros(batch, capacity, dtype=torch.float64, device=dev))
        for name in self._ROW_FLOATS:
            setattr(self, name, torch.zeros(batch, num_rows + 1, dtype=torch.float64, device=dev))
        self.num_edges = torch.zeros(batch, dtype=torch.int64, device=dev)
        self.version = 0  # bumped by every change to the edge lists
        self.on_grow: list = []  # callbacks(new_capacity)
        self._index: DenseEdgeIndex | None = None

    @property
    def capacity(self) -> int:
        return self.edge_row.shape[1]

    def reserve(self, needed: int) -> None:
        """Make room for ``needed`` edges per run (capacity doubles)."""
        if needed <= self.capacity:
            return
        capacity = self.capacity
        while capacity < needed:
            capacity *= 2
        self.edge_row = _grow_columns(self.edge_row, capacity, -1)
        self.edge_successor = _grow_columns(self.edge_successor, capacity, -1)
        for name in self._EDGE_FLOATS:
            setattr(self, name, _grow_columns(getattr(self, name), capacity))
        for callback in self.on_grow:
            callback(capacity)

    def index(self) -> DenseEdgeIndex:
        """The dense lookup tables, rebuilt if the edge lists changed without them."""
        if self._index is None or self._index.version != self.version:
            self._index = DenseEdgeIndex(self)
        return self._index

    def find_or_add(
        self, runs: torch.Tensor, rows: torch.Tensor, successors: torch.Tensor
    ) -> torch.Tensor:
        """Edge ids of ``(runs[i], rows[i], successors[i])``, adding the unseen pairs to their
        run's list (new ids in order of first appearance within each run, by sorted key)."""
        index = self.index()
        ids = index.find(runs, rows, successors)
        missing = ids < 0
        if bool(missing.any()):
            S1, R1 = self.num_states + 1, self.num_rows + 1
            keys = torch.unique((runs[missing] * R1 + rows[missing]) * S1 + successors[missing])
            new_runs, rest = keys // (R1 * S1), keys % (R1 * S1)
            new_rows, new_succ = rest // S1, rest % S1
            first = torch.ones_like(new_runs, dtype=torch.bool)
            first[1:] = new_runs[1:] != new_runs[:-1]
            idx = torch.arange(keys.numel(), device=keys.device)
            rank = idx - torch.cummax(torch.where(first, idx, torch.zeros_like(idx)), 0).values
            new_ids = self.num_edges.index_select(0, new_runs) + rank
            self.reserve(int(new_ids.max()) + 1)
            self.edge_row[new_runs, new_ids] = new_rows
            self.edge_successor[new_runs, new_ids] = new_succ
            self.num_edges.index_add_(0, new_runs, torch.ones_like(new_runs))
            self.version += 1
            index.version = self.version
            index.append(new_runs, new_ids)
            ids = index.find(runs, rows, successors)
        return ids

    @property
    def used(self) -> int:
        """Edge slots in use by the fullest run (what a checkpoint keeps of the lists)."""
        return max(1, int(self.num_edges.max()))

    def state_dict(self, copy: bool = True) -> dict:
        """The edge lists (only the slots in use), counts and per-row sums; ``copy=False``: the
        live tensors and views of them, not copies (see :meth:`~himit_torch.Learner.state_dict`)."""
        used = self.used
        out = {
            name: getattr(self, name)[:, :used]
            for name in ("edge_row", "edge_successor") + self._EDGE_FLOATS
        }
        out.update({name: getattr(self, name) for name in ("num_edges",) + self._ROW_FLOATS})
        return saved(out, copy)

    #: Whether an edge may start at the padding row ``num_rows`` (an option executed at a state
    #: without rows is counted there, as both engines do), or only at a real row.
    _PADDING_ROW_EDGES = True

    def _state_keys(self) -> tuple[str, ...]:
        return ("edge_row", "edge_successor", *self._EDGE_FLOATS, "num_edges", *self._ROW_FLOATS)

    def check_state(self, state: dict, where: str = "model") -> int:
        """Check a :meth:`state_dict` read back (``where``: its name, for the messages) against
        this store's shapes and invariants, before anything reads it: the edge lists' ids in
        range — rows within the row table, successors states — ``0 ≤ num_edges ≤`` the lists'
        length, empty slots empty, one edge per ``(row, successor)``, counts finite and ≥ 0.
        Returns the saved lists' length.

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, self._state_keys())
        B = self.batch
        E = tensor(state, "edge_row", where, torch.int64, (B, None)).shape[1]
        if E < 1:
            raise DamagedState(f"{where}.edge_row", "has no edge slot (a state_dict keeps ≥ 1)")
        rows = state["edge_row"]
        successors = tensor(state, "edge_successor", where, torch.int64, (B, E))
        num_edges = tensor(state, "num_edges", where, torch.int64, (B,))
        in_range(num_edges, f"{where}.num_edges", 0, E, f"edges held; the lists hold {E} slots")
        used = torch.arange(E, device=num_edges.device) < num_edges[:, None]
        last_row = self.num_rows if self._PADDING_ROW_EDGES else self.num_rows - 1
        in_range(rows, f"{where}.edge_row", 0, last_row, "a row of the table", used)
        in_range(successors, f"{where}.edge_successor", 0, self.num_states - 1, "a state", used)
        in_range(rows, f"{where}.edge_row", -1, -1, "an empty slot beyond num_edges", ~used)
        in_range(
            successors, f"{where}.edge_successor", -1, -1, "an empty slot beyond num_edges", ~used
        )
        for name in self._EDGE_FLOATS:
            value = tensor(state, name, where, torch.float64, (B, E))
            all_finite(value, f"{where}.{name}", minimum=0.0)
            in_range(value, f"{where}.{name}", 0, 0, "an empty slot beyond num_edges", ~used)
        # one edge per (run, row, successor): both engines look an outcome's edge up by it
        runs = torch.arange(B, device=rows.device)[:, None].expand(B, E)
        keys = ((runs * (self.num_rows + 1) + rows) * (self.num_states + 1) + successors)[used]
        if _has_repeats(keys):
            raise DamagedState(
                f"{where}.edge_row", "lists some (row, successor) edge twice in one run"
            )
        for name in self._ROW_FLOATS:
            value = tensor(state, name, where, torch.float64, (B, self.num_rows + 1))
            if name == "row_count":
                all_finite(value, f"{where}.{name}", minimum=0.0)
            else:  # (summed rewards: any sign)
                all_finite(value, f"{where}.{name}")
        return E

    def load_state_dict(self, state: dict, where: str = "model", *, checked: bool = False) -> None:
        """Restore a :meth:`state_dict`, checked first (:meth:`check_state`) unless ``checked``
        says it was (the learner checks every piece before it restores any)."""
        if not checked:
            self.check_state(state, where)
        for name in self._state_keys():
            setattr(self, name, private_copy(state[name], self.device))
        saved = self.edge_row.shape[1]
        capacity = 256
        while capacity < saved:
            capacity *= 2
        self.edge_row = _grow_columns(self.edge_row, capacity, -1)
        self.edge_successor = _grow_columns(self.edge_successor, capacity, -1)
        for name in self._EDGE_FLOATS:
            setattr(self, name, _grow_columns(getattr(self, name), capacity))
        self.version += 1
        for callback in self.on_grow:
            callback(capacity)

    def posterior(self, runs: torch.Tensor, rows: torch.Tensor) -> SuccessorDirichlet:
        """Posterior over the successors of ``rows`` (any shape) in ``runs`` (same shape)."""
        edge = self.index().forward[runs, rows]  # [..., K]
        r = runs[..., None].expand_as(edge)
        counts = torch.where(
            edge >= 0,
            self.edge_count[r, edge.clamp(min=0)],
            torch.zeros((), dtype=torch.float64, device=self.device),
        )
        prior = torch.full(
            rows.shape + (1,), self.concentration, dtype=torch.float64, device=self.device
        )
        succ = torch.where(edge >= 0, self.edge_successor[r, edge.clamp(min=0)], edge)
        return SuccessorDirichlet(torch.cat([counts, prior], -1), succ)


class SuccessorDirichlet(torch.distributions.Dirichlet):
    """Dirichlet posterior over a row's successors, batched: a real
    :class:`torch.distributions.Dirichlet` with ``batch_shape = [...]`` (one per row) and
    ``event_shape = [K + 1]`` categories.

    The first ``K`` categories are observed successors (``successors[..., k]``, −1 = padding, with
    zero concentration); the last is the lumped "unseen successor" carrying the prior
    concentration.

    Categories with concentration 0 (padding, or the unseen outcome without a prior) are the
    degenerate limit ``α_k → 0``: their probability is 0 with certainty, and the rest is the
    Dirichlet of the positive categories alone (so :attr:`mean`, :attr:`variance`,
    :meth:`log_prob` and :meth:`entropy` equal ``scipy.stats.dirichlet``'s over those). A row with
    no mass at all (an untried row, no prior) has mean and variance 0, draws all zeros, and
    ``log_prob`` 0 at the zero vector (−∞ elsewhere).
    """

    has_rsample = False

    def __init__(
        self,
        concentration: torch.Tensor,
        successors: torch.Tensor,
        validate_args: bool | None = None,
    ):
        concentration = torch.as_tensor(concentration)
        if not concentration.is_floating_point():
            concentration = concentration.double()
        if concentration.dim() < 1:
            raise ValueError(
                "SuccessorDirichlet: concentration must have a category axis [..., K + 1]"
            )
        if tuple(successors.shape) != tuple(concentration.shape[:-1]) + (
            concentration.shape[-1] - 1,
        ):
            raise ValueError(
                f"SuccessorDirichlet: successors {tuple(successors.shape)} must be "
                f"[..., K] for concentration {tuple(concentration.shape)} = [..., K + 1]"
            )
        if validate_args is not False and not bool(
            (torch.isfinite(concentration) & (concentration >= 0)).all()
        ):
            raise ValueError("SuccessorDirichlet: concentrations must be finite and ≥ 0")
        self.successors = successors
        # The parent's positivity constraint does not hold for zero (padding) categories: the
        # checks above replace it.
        super().__init__(concentration, validate_args=False)

    def expand(self, batch_shape, _instance=None):
        new = self._get_checked_instance(SuccessorDirichlet, _instance)
        new = super().expand(batch_shape, _instance=new)
        new.successors = self.successors.expand(
            torch.Size(batch_shape) + self.successors.shape[-1:]
        )
        return new

    @property
    def total(self) -> torch.Tensor:
        """``α_0 = Σ_k α_k``, ``[...]``."""
        return self.concentration.sum(-1)

    @property
    def mean(self) -> torch.Tensor:
        """``E[p_k] = α_k / α_0`` (zeros where α_0 = 0, i.e. nothing seen and no prior)."""
        total = self.total[..., None]
        return torch.where(
            total > 0,
            self.concentration / _nonzero(total),
            torch.zeros_like(self.concentration),
        )

    @property
    def variance(self) -> torch.Tensor:
        """``Var[p_k] = α_k (α_0 − α_k) / (α_0² (α_0 + 1)) = m_k (1 − m_k) / (α_0 + 1)`` with
        ``m`` the :attr:`mean` (the second form: ``α_0²`` underflows for a tiny total)."""
        m, total = self.mean, self.total[..., None]
        return torch.where(total > 0, m * (1.0 - m) / (total + 1), torch.zeros_like(m))

    @property
    def mode(self) -> torch.Tensor:
        raise NotImplementedError("SuccessorDirichlet.mode is not defined (zero-mass categories)")

    def log_prob(self, value: torch.Tensor) -> torch.Tensor:
        """Log density of ``value [..., K + 1]`` over the simplex of the positive categories
        (−∞ where a zero-concentration category gets a non-zero probability)."""
        value = torch.as_tensor(
            value, dtype=self.concentration.dtype, device=self.concentration.device
        )
        a = self.concentration
        pos = a > 0
        safe = torch.where(pos, a, torch.ones_like(a))
        term = torch.where(
            pos, torch.xlogy(a - 1.0, value) - torch.lgamma(safe), torch.zeros_like(a)
        ).sum(-1)
        total = self.total
        norm = torch.where(total > 0, torch.lgamma(_nonzero(total)), torch.zeros_like(total))
        outside = ((~pos) & (value != 0)).any(-1)
        return torch.where(outside, torch.full_like(term, float("-inf")), term + norm)

    def entropy(self) -> torch.Tensor:
        """Differential entropy over the simplex of the positive categories."""
        a = self.concentration
        pos = a > 0
        safe = torch.where(pos, a, torch.ones_like(a))
        k = pos.sum(-1).to(a.dtype)
        total = self.total
        safe_total = torch.where(total > 0, total, torch.ones_like(total))
        per = torch.where(
            pos, torch.lgamma(safe) - (safe - 1.0) * torch.digamma(safe), torch.zeros_like(a)
        ).sum(-1)
        out = per - torch.lgamma(safe_total) - (k - safe_total) * torch.digamma(safe_total)
        return torch.where(k > 1, out, torch.zeros_like(out))

    # Adds ``generator``, and takes one in place of the shape (the old ``sample(generator)``).
    def sample(
        self,
        sample_shape: torch.Size | list[int] | tuple[int, ...] | torch.Generator = (),
        generator: torch.Generator | None = None,
    ) -> torch.Tensor:
        """Draws of the probabilities, ``sample_shape + batch_shape + [K + 1]``, from
        ``generator`` (a ``torch.Generator``; the global torch random state when omitted, as in
        every ``torch.distributions`` object). Categories with zero concentration get
        probability 0. ``sample(generator)`` (the generator alone) also works.

        The gamma variates come from NumPy's ``Generator.standard_gamma`` seeded by one draw
        from ``generator``, so the global random state of torch and NumPy is left alone and the
        same generator state always gives the same draws (on any device)."""
        if isinstance(sample_shape, torch.Generator):  # sample(generator), the old call
            generator = sample_shape
            sample_shape = ()
        shape = self._extended_shape(torch.Size(sample_shape))
        device = generator.device if generator is not None else torch.device("cpu")
        seed = int(torch.randint(0, 2**63 - 1, (1,), generator=generator, device=device))
        a = self.concentration.detach().double().cpu().expand(shape).numpy()
        g = torch.from_numpy(np.random.default_rng(seed).standard_gamma(a))
        g = g.to(self.concentration.device, self.concentration.dtype)
        total = g.sum(-1, keepdim=True)
        return torch.where(total > 0, g / _nonzero(total), torch.zeros_like(g))

    def rsample(self, sample_shape: torch.Size | list[int] | tuple[int, ...] = ()) -> torch.Tensor:
        raise NotImplementedError(
            "SuccessorDirichlet has no reparameterized sample (posteriors "
            "of counts need no gradient); use sample(generator=…)"
        )

    def __repr__(self) -> str:
        return (
            f"SuccessorDirichlet(batch_shape={tuple(self.batch_shape)}, "
            f"event_shape={tuple(self.event_shape)})"
        )


class DirichletSMDPModel(EdgeStore):
    """The learner's model of its own options, one per run: for every executed ``(s, o)`` row the
    count of each termination state, the summed ``γ^k`` per ``(s, o, s')`` and the summed
    discounted reward (the paper's Section II, after Sutton, Precup & Singh 1999), and how often
    each state started an own option (``state_tries [B, S + 1]``).

    Posterior means (with prior concentration ``α`` on the unseen outcome, valued ``v0``):
    ``p^o_{ss'} = Σγ^k(s,o,s') / (n + α)`` and ``r(s, o) = Σ r / n``, so that the model's value of
    an option is ``Q = (Σ r + Σ_{s'} Σγ^k V(s') + α v0) / (n + α)``.
    """

    _EDGE_FLOATS = ("edge_count", "edge_discount")
    _ROW_FLOATS = ("row_count", "row_reward")
    edge_discount: torch.Tensor
    row_reward: torch.Tensor

    def __init__(
        self,
        num_rows: int,
        num_states: int,
        batch: int,
        device="cpu",
        concentration: float = 0.0,
        capacity: int = 256,
    ):
        super().__init__(num_rows, num_states, batch, device, concentration, capacity)
        self.state_tries = torch.zeros(
            batch, num_states + 1, dtype=torch.float64, device=self.device
        )

    def state_dict(self, copy: bool = True) -> dict:
        return {**super().state_dict(copy), **saved({"state_tries": self.state_tries}, copy)}

    def _state_keys(self) -> tuple[str, ...]:
        return (*super()._state_keys(), "state_tries")

    def check_state(self, state: dict, where: str = "model") -> int:
        E = super().check_state(state, where)
        tries = tensor(
            state, "state_tries", where, torch.float64, (self.batch, self.num_states + 1)
        )
        all_finite(tries, f"{where}.state_tries", minimum=0.0)
        return E

    def update(
        self,
        runs: torch.Tensor,
        rows: torch.Tensor,
        starts: torch.Tensor,
        successors: torch.Tensor,
        discounts: torch.Tensor,
        discounted_rewards: torch.Tensor,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Record one executed option per run (``runs`` distinct): it started in ``starts`` from
        ``rows``, ended in ``successors`` after ``γ^k = discounts`` having collected
        ``discounted_rewards``. Returns ``(edge ids, counts before, summed γ^k before)``."""
        e = self.find_or_add(runs, rows, successors)
        c_old, g_old = self.edge_count[runs, e], self.edge_discount[runs, e]
        self.edge_count[runs, e] = c_old + 1
        self.edge_discount[runs, e] = g_old + discounts
        self.row_count[runs, rows] += 1
        self.row_reward[runs, rows] += discounted_rewards
        self.state_tries[runs, starts] += 1
        return e, c_old, g_old

    def preload(
        self,
        run: int,
        rows: torch.Tensor,
        successors: torch.Tensor,
        counts: torch.Tensor,
        discounts: torch.Tensor,
        counted_rows: torch.Tensor,
        row_counts: float,
        row_rewards: torch.Tensor,
    ) -> None:
        """Replace run ``run``'s option model wholesale (exact models as pseudo-counts,
        ``LearnerConfig.option_models = "exact"``): edge ``i`` is ``rows[i] → successors[i]``
        with count ``counts[i]`` and summed ``γ^k`` ``discounts[i]``; each of ``counted_rows``
        was executed ``row_counts`` times and collected ``row_rewards`` in total. The value
        cache's ``Q`` numerators must be rebuilt afterwards (``ValueCache.rebuild_options``)."""
        E = rows.numel()
        if not (successors.numel() == counts.numel() == discounts.numel() == E):
            raise ValueError(
                f"preload: rows, successors, counts and discounts must all be [E], got "
                f"{rows.numel()}, {successors.numel()}, {counts.numel()}, {discounts.numel()}"
            )
        if counted_rows.shape != row_rewards.shape:
            raise ValueError(
                f"preload: counted_rows {tuple(counted_rows.shape)} and row_rewards "
                f"{tuple(row_rewards.shape)} must have the same shape"
            )
        self.reserve(E)
        self.edge_row[run, :E] = rows
        self.edge_successor[run, :E] = successors
        self.edge_count[run, :E] = counts
        self.edge_discount[run, :E] = discounts
        self.num_edges[run] = E
        self.row_count[run, counted_rows] = row_counts
        self.row_reward[run, counted_rows] = row_rewards
        self.version += 1

    def mean(self, runs: torch.Tensor, rows: torch.Tensor):
        """``(reward [...], successors [..., K], weights [..., K])``: posterior-mean reward and
        multi-time weights ``p^o_{ss'}`` of each row (zeros for untried rows)."""
        edge = self.index().forward[runs, rows]
        r = runs[..., None].expand_as(edge)
        n = self.row_count[runs, rows]
        denom = (n + self.concentration)[..., None]
        g = torch.where(
            edge >= 0,
            self.edge_discount[r, edge.clamp(min=0)],
            torch.zeros((), dtype=torch.float64, device=self.device),
        )
        weights = torch.where(denom > 0, g / _nonzero(denom), torch.zeros_like(g))
        reward = torch.where(
            n > 0, self.row_reward[runs, rows] / n.clamp(min=1), torch.zeros_like(n)
        )
        succ = torch.where(edge >= 0, self.edge_successor[r, edge.clamp(min=0)], edge)
        return reward, succ, weights


class DirichletMentorModel(EdgeStore):
    """The learner's model ``p_m(s' | s)`` of the mentor, from consecutive observed states only.

    Rows are states. Demonstrations can be added at any time, to all runs or to some.

    Besides the counts, each edge keeps ``edge_delay``: the summed ``γ^(k−1)`` of its
    observations, ``k`` the primitive steps the observed move took (1 when every state is seen,
    so ``edge_delay = edge_count``; more under coarse observation). The segment term
    (``LearnerConfig.mentor_segments``, :func:`~himit_torch.learner.backups.segment_reward`)
    reads it; the paper's one-step term does not.

    Several mentors (``LearnerConfig.mentors``) share the store, one block of rows each: mentor
    ``k``'s model of state ``s`` is row ``k·S + s`` (:meth:`rows_of`), so each mentor keeps its
    own counts, edges and posterior, and one mentor is rows ``0 … S − 1`` exactly as before.
    """

    _PADDING_ROW_EDGES = False  # the mentor is only ever seen leaving a real state
    _EDGE_FLOATS = ("edge_count", "edge_delay")
    edge_delay: torch.Tensor

    def __init__(
        self,
        num_states: int,
        batch: int,
        device="cpu",
        concentration: float = 0.0,
        capacity: int = 256,
        mentors: int = 1,
    ):
        if isinstance(mentors, bool) or not isinstance(mentors, int) or mentors < 1:
            raise ValueError(f"mentors={mentors!r}: the number of mentors must be an int ≥ 1")
        self.mentors = mentors
        super().__init__(mentors * num_states, num_states, batch, device, concentration, capacity)

    def rows_of(self, states: torch.Tensor) -> torch.Tensor:
        """``[..., mentors]`` each mentor's row of ``states`` (the padding state ``S`` maps to
        the padding row, for every mentor)."""
        S = self.num_states
        k = torch.arange(self.mentors, device=states.device) * S
        rows = states[..., None] + k
        return torch.where(states[..., None] >= S, torch.full_like(rows, self.num_rows), rows)

    def row_states(self, rows: torch.Tensor) -> torch.Tensor:
        """The state each mentor row models (``row mod S``)."""
        return rows % self.num_states if self.mentors > 1 else rows

    def observe(
        self,
        sources: torch.Tensor,
        successors: torch.Tensor,
        runs: torch.Tensor | None = None,
        counts: torch.Tensor | None = None,
        delays: torch.Tensor | None = None,
    ) -> None:
        """Count the transitions ``sources[i] → successors[i]`` for ``runs`` (all by default),
        each once, or ``counts[i]`` times (any positive weight: expected counts of an exact
        model, :class:`~himit_torch.mentor.policy.ExactMentorTransitions`). ``delays[i]`` is
        ``γ^(k_i − 1)`` for a move of ``k_i`` primitive steps (default 1: one step each)."""
        if sources.numel() == 0:
            return
        runs = torch.arange(self.batch, device=self.device) if runs is None else runs
        R, T = runs.numel(), sources.numel()
        rr, src, dst = runs.repeat_interleave(T), sources.repeat(R), successors.repeat(R)
        e = self.find_or_add(rr, src, dst)
        if counts is None:
            ones = torch.ones(R * T, dtype=torch.float64, device=self.device)
        else:
            ones = torch.as_tensor(counts, dtype=torch.float64, device=self.device).repeat(R)
        self.edge_count.index_put_((rr, e), ones, accumulate=True)
        self.row_count.index_put_((rr, src), ones, accumulate=True)
        if delays is None:
            self.edge_delay.index_put_((rr, e), ones, accumulate=True)
        else:
            d = torch.as_tensor(delays, dtype=torch.float64, device=self.device).repeat(R)
            self.edge_delay.index_put_((rr, e), ones * d, accumulate=True)

    @staticmethod
    def _with_delay(state: dict) -> dict:
        """A checkpoint written before ``edge_delay`` was kept: every move it counted was taken
        as one step then, so its delay is its count."""
        if isinstance(state, dict) and "edge_delay" not in state and "edge_count" in state:
            return {**state, "edge_delay": state["edge_count"]}
        return state

    def check_state(self, state: dict, where: str = "model") -> int:
        """:meth:`EdgeStore.check_state`, and each edge's delay at most its count; a state
        without ``edge_delay`` (saved before delays were kept) is read as one-step moves."""
        state = self._with_delay(state)
        E = super().check_state(state, where)
        if bool((state["edge_delay"] > state["edge_count"] * (1 + 1e-12)).any()):
            raise DamagedState(
                f"{where}.edge_delay", "exceeds edge_count (each observation adds γ^(k−1) ≤ 1)"
            )
        return E

    def load_state_dict(self, state: dict, where: str = "model", *, checked: bool = False) -> None:
        """:meth:`EdgeStore.load_state_dict`, a state without ``edge_delay`` read as one-step
        moves."""
        super().load_state_dict(self._with_delay(state), where, checked=checked)

    def observed(self) -> torch.Tensor:
        """``[B, S]`` bool: states where a mentor was seen leaving (a mentor term exists there)."""
        S = self.num_states
        seen = self.row_count[:, : self.num_rows] > 0
        return seen if self.mentors == 1 else seen.view(self.batch, self.mentors, S).any(1)

    def mean(self, runs: torch.Tensor, states: torch.Tensor):
        """``(successors [..., K], probabilities [..., K])`` posterior means ``p_m(s'|s)``."""
        post = self.posterior(runs, states)
        return post.successors, post.mean[..., :-1]
