"""The options-only agents (``imitation_extended``, ``options_extended``): extended options, and
primitives only at states where no extended option starts."""

import pytest
import torch

from himit_torch import LearnerConfig, MultiRooms, learner_options
from himit_torch.learner.rows import RowTable
from tests.learner.helpers import build_learner

pytest.importorskip("numba")


def test_extended_rows_are_the_extended_options_and_primitives_only_where_none_starts():
    world = MultiRooms(16, 2)
    full = learner_options(world)
    # every extended option but the first two: some states are left with primitives only
    options = full.select([o for o in range(full.num_options) if full.is_primitive[o] or o > 5])
    rows = RowTable(options, 4, ["imitation_extended", "imitation", "imitation_primitives"], "cpu")
    primitive = options.is_primitive[rows.row_option[:-1]]
    states = rows.row_state[:-1]
    extended_at = torch.zeros(world.num_states, dtype=torch.bool)
    extended_at[states[~primitive]] = True
    enabled = rows.row_enabled[0, :-1]
    assert torch.equal(enabled[~primitive], torch.ones(int((~primitive).sum()), dtype=torch.bool))
    # primitives exactly at the reachable states without an extended option (the doorways)
    assert torch.equal(enabled[primitive], ~extended_at[states[primitive]])
    assert 0 < int((enabled & primitive).sum()) < int(primitive.sum())
    assert bool(rows.row_enabled[1, :-1].all())
    assert torch.equal(rows.row_enabled[2, :-1], primitive)
    # every state with a row has an enabled one: the learner is never left without a choice
    has_row = torch.zeros(world.num_states, dtype=torch.bool)
    has_row[states] = True
    has_enabled = torch.zeros(world.num_states, dtype=torch.bool)
    has_enabled[states[enabled]] = True
    assert torch.equal(has_row, has_enabled)


def test_engines_agree_on_the_extended_agents(world12, mentor_demos12):
    config = LearnerConfig(window=400, mentor_trial=True, mentor_feasibility=2)
    agents = ["imitation_extended", "options_extended"]
    runs = [build_learner(world12, mentor_demos12, agents, engine=e, config=config)
            for e in ("numba", "torch")]  # fmt: skip
    for learner in runs:
        learner.run(800)
    assert runs[0].metrics.curve().shape[0] == 2  # two windows
    assert torch.equal(runs[0].metrics.curve(), runs[1].metrics.curve())
    assert torch.equal(runs[0].model.row_count, runs[1].model.row_count)
    # no run ever executed a disabled row
    executed = runs[0].model.row_count[:, :-1] > 0
    assert not bool((executed & ~runs[0].rows.row_enabled[:, :-1]).any())
