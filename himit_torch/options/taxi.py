"""Navigation options for Gymnasium's Taxi: walk to each landmark, the skills a mentor
and a learner of the Taxi world share."""

from __future__ import annotations

import numpy as np
import torch

from himit_torch.options.builders import subgoal_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.table_world import TableWorld

__all__ = ["TAXI_LANDMARKS", "taxi_navigation_options"]


# ------------------------------------------------------------------------------------ Taxi
#: Taxi's four landmarks in the order of its ``locs``.
TAXI_LANDMARKS = ("R", "G", "Y", "B")


def taxi_navigation_options(world: TableWorld) -> Options:
    """Dietterich's navigation subtasks for Gymnasium's Taxi: four options "drive to R / G / Y /
    B", each moving the taxi (actions south, north, east, west only) by a shortest path to that
    landmark, whatever the passenger and destination; usable in every non-terminal state where
    the taxi is elsewhere, terminating on arrival. Pick-up and drop-off stay primitive
    (:func:`~himit_torch.primitive_options`)."""
    raw = getattr(world, "env", None)
    if raw is None or type(raw).__name__ != "TaxiEnv":
        raise ValueError("taxi_navigation_options needs a world made by from_gymnasium('Taxi-v4')")
    rows_cols = np.array([raw.decode(s)[:2] for s in range(world.num_states)])
    targets = {}
    for name, loc in zip(TAXI_LANDMARKS, raw.locs):
        targets[f"drive to {name}"] = torch.from_numpy((rows_cols == np.array(loc)).all(1))
    return subgoal_options(world, targets, actions=[0, 1, 2, 3])
