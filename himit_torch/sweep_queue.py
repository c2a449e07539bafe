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

__all__ = ["BlockPriorityQueue"]


class BlockPriorityQueue:
    """Per-run max-priority queues over ``num_states`` states, batched over ``batch`` runs."""

    def __init__(self, batch: int, num_states: int, device, block: int | None = None,
                 typical_pop: int = 10):
        if block is None:  # minimises S/G + n·G for pops of n states
            block = 1 << max(2, round(math.log2(math.sqrt(num_states / max(1, typical_pop)))))
        self.block = int(block)
        self.num_blocks = -(-num_states // self.block)
        self.num_states = num_states
        self.priority = torch.zeros(batch, self.num_blocks * self.block, dtype=torch.float64,
                                    device=device)
        self.block_max = torch.zeros(batch, self.num_blocks, dtype=torch.float64, device=device)
        self._offsets = torch.arange(self.block, device=device)

    def push(self, runs: torch.Tensor, states: torch.Tensor, priorities: torch.Tensor) -> None:
        """Raise the priority of ``states`` in ``runs`` to at least ``priorities`` (same shapes)."""
        runs, states, priorities = runs.reshape(-1), states.reshape(-1), priorities.reshape(-1)
        flat = runs * self.priority.shape[1] + states
        self.priority.view(-1).scatter_reduce_(0, flat, priorities, "amax")
        blocks = runs * self.num_blocks + torch.div(states, self.block, rounding_mode="floor")
        self.block_max.view(-1).scatter_reduce_(0, blocks, priorities, "amax")

    def pop(self, runs: torch.Tensor, n: int, threshold: float,
            limit: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
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
        best_blocks = self.block_max.index_select(0, runs).sort(
            dim=1, descending=True, stable=True).indices[:, :n_blocks]
        top_blocks = best_blocks.sort(dim=1).values                               # [R, nb]
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
        self.block_max.view(-1).index_copy_(0, (runs[:, None] * self.num_blocks + top_blocks).view(-1),
                                            new_max.view(-1))
        return states, valid

    def clear(self, runs: torch.Tensor | None = None) -> None:
        if runs is None:
            self.priority.zero_()
            self.block_max.zero_()
        else:
            self.priority[runs] = 0
            self.block_max[runs] = 0
