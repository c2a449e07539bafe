"""A batched priority queue over states for prioritized sweeping (Moore & Atkeson 1993).

Each run keeps a priority per state (``0`` = not queued) in ``priority [B, S']`` (``S'`` = states
rounded up to whole blocks of ``G``) and the maximum of every block in ``block_max [B, S'/G]``.
Popping the ``n`` highest-priority states of some runs looks at the top ``n`` blocks only — the
``n`` best states always lie in them — so a pop costs ``O(S/G + n·G)`` (times a log for the
sorts), not a scan of all ``S`` states; with ``G ≈ √(S/n)`` that is ``O(√(nS))``. Pushing is a
scatter-max. Nothing is ever evicted. Ties are broken by the lowest state, the same whatever ``n``.
"""

from __future__ import annotations

import math

import torch

from himit_torch.state_checks import in_range, private_copy, saved, section, tensor

__all__ = ["BlockPriorityQueue", "Sweeper"]


class BlockPriorityQueue:
    """Per-run max-priority queues over ``num_states`` states, batched over ``batch`` runs."""

    def __init__(
        self, batch: int, num_states: int, device, block: int | None = None, typical_pop: int = 10
    ):
        if block is None:  # minimises S/G + n·G for pops of n states
            block = 1 << max(2, round(math.log2(math.sqrt(num_states / max(1, typical_pop)))))
        self.block = int(block)
        self.num_blocks = -(-num_states // self.block)
        self.num_states = num_states
        self.priority = torch.zeros(
            batch, self.num_blocks * self.block, dtype=torch.float64, device=device
        )
        self.block_max = torch.zeros(batch, self.num_blocks, dtype=torch.float64, device=device)
        self._offsets = torch.arange(self.block, device=device)

    def push(self, runs: torch.Tensor, states: torch.Tensor, priorities: torch.Tensor) -> None:
        """Raise the priority of ``states`` in ``runs`` to at least ``priorities`` (same shapes)."""
        runs, states, priorities = runs.reshape(-1), states.reshape(-1), priorities.reshape(-1)
        flat = runs * self.priority.shape[1] + states
        self.priority.view(-1).scatter_reduce_(0, flat, priorities, "amax")
        blocks = runs * self.num_blocks + torch.div(states, self.block, rounding_mode="floor")
        self.block_max.view(-1).scatter_reduce_(0, blocks, priorities, "amax")

    def pop(
        self, runs: torch.Tensor, n: int, threshold: float, limit: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Remove and return the ``n`` highest-priority states of each of ``runs [R]``.

        Returns ``(states [R, n], valid [R, n])``; entries whose priority is not above
        ``threshold``, or beyond a run's ``limit [R]``, are invalid and stay queued.
        """
        n_blocks = min(n, self.num_blocks)
        R = runs.numel()
        width = self.priority.shape[1]
        flat = self.priority.view(-1)
        # Stable sorts give one total order — priority descending, then state ascending — so the
        # n popped states are a prefix of it whatever n is (topk's tie order depends on n, which
        # would make a run's sweep depend on its batch). The best n states lie in the best n
        # blocks under (block max descending, block ascending).
        best_blocks = (
            self.block_max.index_select(0, runs)
            .sort(dim=1, descending=True, stable=True)
            .indices[:, :n_blocks]
        )
        top_blocks = best_blocks.sort(dim=1).values  # [R, nb]
        cells = (top_blocks[:, :, None] * self.block + self._offsets).view(R, -1)  # ascending
        flat_cells = (runs[:, None] * width + cells).view(-1)
        local = flat.index_select(0, flat_cells).view(R, -1)
        values, where = local.sort(dim=1, descending=True, stable=True)
        values, where = values[:, :n], where[:, :n]
        states = cells.gather(1, where)
        valid = values > threshold
        if limit is not None:
            valid &= torch.arange(valid.shape[1], device=valid.device) < limit[:, None]
        # Clear the popped states, then refresh the maxima of the blocks they came from.
        local.scatter_(1, where, torch.where(valid, torch.zeros_like(values), values))
        flat.index_copy_(0, flat_cells, local.view(-1))
        new_max = local.view(R, n_blocks, self.block).amax(2)
        self.block_max.view(-1).index_copy_(
            0, (runs[:, None] * self.num_blocks + top_blocks).view(-1), new_max.view(-1)
        )
        return states, valid

    def refresh_block_max(self) -> None:
        """Recompute the block maxima from the priorities (after they were written elsewhere)."""
        self.block_max = self.priority.view(
            self.priority.shape[0], self.num_blocks, self.block
        ).amax(2)

    def clear(self, runs: torch.Tensor | None = None) -> None:
        if runs is None:
            self.priority.zero_()
            self.block_max.zero_()
        else:
            self.priority[runs] = 0
            self.block_max[runs] = 0


class Sweeper:
    """Prioritized sweeping's state and schedule for a batch: the queue (priorities over states
    ``[B, S + 1]``) and the decisions each run made since its last sweep (``pending [B]``).

    Per decision a run gets ``backups`` backups, in rounds of ``round_size`` states backed up
    together (the highest priorities first, ties to the lowest state); with ``plan_every > 1``
    the budget of the decisions made since the last sweep is spent every ``plan_every`` ticks.
    ``round_size`` depends on the configuration only, never on the other runs, so a run's sweep
    is the same in any batch. This class is the only one that touches the queue.
    """

    def __init__(
        self,
        batch: int,
        num_states: int,
        device,
        backups: int,
        sweep_rounds: int,
        plan_every: int,
        threshold: float,
    ):
        self.backups, self.plan_every, self.threshold = backups, plan_every, threshold
        # States backed up together per round: a decision's budget in sweep_rounds rounds; with
        # plan_every > 1, the budget of plan_every decisions in as many rounds.
        self.round_size = -(-plan_every * backups // sweep_rounds)
        self.queue = BlockPriorityQueue(
            batch, num_states + 1, device, typical_pop=max(1, backups // sweep_rounds)
        )
        self.pending = torch.zeros(batch, dtype=torch.int64, device=device)
        self.num_states = num_states

    def state_dict(self, copy: bool = True) -> dict:
        """The queue's priorities and the pending decisions; ``copy=False``: the live tensors,
        not copies (see :meth:`~himit_torch.Learner.state_dict`)."""
        return saved({"priority": self.queue.priority, "pending": self.pending}, copy)

    def check_state(self, state: dict, where: str = "sweeper") -> None:
        """Check a :meth:`state_dict` read back: the priorities of this queue's shape, ≥ 0 (``inf``
        queues a state first; NaN never) and 0 beyond the last state; the pending decisions
        ``0 … plan_every`` (a run sweeps at least every ``plan_every`` ticks, one decision a tick).

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, ("priority", "pending"))
        shape = tuple(self.queue.priority.shape)
        priority = tensor(state, "priority", where, torch.float64, shape)
        in_range(priority, f"{where}.priority", 0, float("inf"), "a priority")
        in_range(
            priority[:, self.num_states + 1 :], f"{where}.priority", 0, 0, "beyond the last state"
        )
        pending = tensor(state, "pending", where, torch.int64, (shape[0],))
        in_range(pending, f"{where}.pending", 0, self.plan_every, "decisions since the last sweep")

    def load_state_dict(
        self, state: dict, where: str = "sweeper", *, checked: bool = False
    ) -> None:
        """Restore a :meth:`state_dict`, checked first (:meth:`check_state`) unless ``checked``
        says it was."""
        if not checked:
            self.check_state(state, where)
        device = self.queue.priority.device
        self.queue.priority = private_copy(state["priority"], device)
        self.queue.refresh_block_max()
        self.pending = private_copy(state["pending"], device)

    def push(self, runs: torch.Tensor, states: torch.Tensor, priorities: torch.Tensor) -> None:
        if runs.numel():
            self.queue.push(runs, states, priorities)

    def sweep(
        self, runs: torch.Tensor, budget: torch.Tensor, backup, round_size: int | None = None
    ) -> torch.Tensor:
        """Up to ``budget [R]`` backups for each of ``runs [R]``. ``backup(runs, states [R, n],
        valid [R, n])`` backs the states up and returns the predecessors' new priorities
        ``(runs, states, priorities)``. Returns the backups done per run."""
        round_size = round_size or self.round_size
        done = torch.zeros_like(budget)
        spent = 0
        most = int(budget.max()) if budget.numel() else 0
        pad = torch.tensor(self.num_states, device=runs.device)
        while spent < most:
            states, valid = self.queue.pop(runs, round_size, self.threshold, limit=budget - spent)
            if not bool(valid.any()):
                break
            self.push(*backup(runs, torch.where(valid, states, pad), valid))
            done += valid.sum(1)
            spent += round_size
        return done
