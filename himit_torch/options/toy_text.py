"""Options for Gymnasium's grid toy-text tasks (CliffWalking, FrozenLake 8×8): subgoal options
to single named cells, the extended options of the Gymnasium comparison
(:mod:`himit_torch.runs.gymnasium`). Taxi's are in :mod:`himit_torch.options.taxi`."""

from __future__ import annotations

import torch

from himit_torch.options.builders import subgoal_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.table_world import TableWorld

__all__ = ["cell_options", "cliff_options", "frozen_lake_options"]


def cell_options(world: TableWorld, cells: dict[str, int]) -> Options:
    """Subgoal options to single cells of a grid task, by name."""
    targets = {}
    for name, s in cells.items():
        mask = torch.zeros(world.num_states, dtype=torch.bool)
        mask[s] = True
        targets[name] = mask
    return subgoal_options(world, targets)


def cliff_options(world: TableWorld) -> Options:
    """CliffWalking (4×12, start (3, 0), goal (3, 11)): options to the two top corners, so the
    goal itself needs primitives (the "insufficient options" of the paper's experiment 2)."""
    return cell_options(world, {"to top-left (0,0)": 0, "to top-right (0,11)": 11})


def frozen_lake_options(world: TableWorld) -> Options:
    """FrozenLake 8×8: options to the two free corners (0, 7) and (7, 0), each by the policy of
    fewest expected steps on the slippery true model (holes count as never arriving)."""
    return cell_options(world, {"to top-right (0,7)": 7, "to bottom-left (7,0)": 56})
