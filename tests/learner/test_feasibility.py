"""Feasibility testing over options (``LearnerConfig.mentor_feasibility``): the mentor term at a
state is dropped once every own option there was tried enough and none reproduced the mentor's
move.

The pure rule by hand, the cached reach counts against a brute-force count, a mentor whose move
no option can reproduce (a teleport to the goal), the reduction, and engine parity."""

import pytest
import torch

from himit_torch import LearnerConfig, MultiRooms
from himit_torch.learner.backups import feasible_mentor
from tests.learner.helpers import build_learner
from tests.tiers import first_fast

pytest.importorskip("numba")


def test_feasible_mentor_by_hand():
    reached = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 2.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    tries = torch.tensor([[2.0, 5.0, 0.0], [2.0, 5.0, 9.0], [2.0, 1.0, 9.0], [0.0, 0.0, 0.0]])
    enabled = torch.tensor(
        [
            [True, True, False],  # both enabled options tried ≥ 2, none reached: dropped
            [True, True, True],  # one reached the mentor's successor: kept
            [True, True, True],  # one tried only once: not tested yet, kept
            [False, False, False],  # no option here: kept
        ]
    )
    assert feasible_mentor(reached, tries, enabled, 2).tolist() == [False, True, True, True]
    # a reach by a disabled option does not count
    assert not bool(
        feasible_mentor(
            torch.tensor([[0.0, 3.0]]),
            torch.tensor([[2.0, 2.0]]),
            torch.tensor([[True, False]]),
            2,
        )[0]
    )


class _Teleport:
    """Demonstrations of one move the learner cannot make: ``start → goal`` in one step."""

    def __init__(self, start: int, goal: int):
        self.start, self.goal = start, goal

    def transitions(self):
        return torch.tensor([self.start]), torch.tensor([self.goal])


def _learner(world, demos, feasibility, engine="numba", agents=("imitation",), **config):
    config = LearnerConfig(window=1000, mentor_feasibility=feasibility, **config)
    return build_learner(world, demos, list(agents), engine=engine, config=config)


@pytest.fixture(scope="module")
def world8():
    return MultiRooms(8, 1)


def _teleport(world):
    start = int(world.start_state)
    goal = int(world.terminal_mask.nonzero()[0, 0])
    return _Teleport(start, goal), start


# (the torch engine's run takes ~40-70 s here, the longest of CI's slow tests; engine parity with
# feasibility is tested below, so its torch run is left to make test-all)
@pytest.mark.parametrize(
    "engine",
    ["numba", pytest.param("torch", marks=[pytest.mark.slow, pytest.mark.extended])],
)
def test_a_move_no_option_reproduces_loses_its_mentor_term(world8, engine):
    demos, start = _teleport(world8)
    runs = {}
    for feasibility in (None, 2):
        learner = _learner(world8, demos, feasibility, engine, mentor_trial=True)
        learner.run(3000)
        runs[feasibility] = learner
    b, s = torch.tensor([[0]]), torch.tensor([[start]])
    rows = learner.rows.state_rows[start]
    enabled = learner.rows.row_enabled[0, rows]
    tries = runs[2].model.row_count[0, rows]
    assert bool((tries[enabled] >= 2).all())  # every option at the start was tested...
    assert float(runs[2].cache.mentor_reached(b, s, rows[None, None])[0, 0].sum()) == 0
    # ...so with the test the mentor's teleport is out of eq. 2 at the start; without, it wins
    _, _, won_tested = runs[2].cache.state_backup(b, s)
    _, _, won_plain = runs[None].cache.state_backup(b, s)
    assert not bool(won_tested) and bool(won_plain)
    assert float(runs[2].cache.values[0, start]) < float(runs[None].cache.values[0, start])


@pytest.mark.parametrize("engine", first_fast(["numba", "torch"], ids=["numba", "torch"]))
def test_the_reach_counts_are_the_brute_force_count(world12, mentor_demos12, engine):
    learner = _learner(
        world12, mentor_demos12, 1, engine, agents=("imitation", "imitation_primitives")
    )
    learner.run(600)
    model, mentor = learner.model, learner.mentor
    S = world12.num_states
    rows = learner.rows.state_rows[:S]
    checked = 0
    for b in range(learner.batch):
        got = learner.cache.mentor_reached(torch.full((S,), b), torch.arange(S), rows)
        targets: dict[int, set] = {}
        for e in range(int(mentor.num_edges[b])):
            targets.setdefault(int(mentor.edge_row[b, e]), set()).add(
                int(mentor.edge_successor[b, e])
            )
        expected = torch.zeros_like(got)
        for e in range(int(model.num_edges[b])):
            row, succ = int(model.edge_row[b, e]), int(model.edge_successor[b, e])
            if row >= learner.num_rows:
                continue
            s = int(learner.rows.row_state[row])
            j = int((rows[s] == row).nonzero()[0, 0])
            if succ in targets.get(s, ()):
                expected[s, j] += model.edge_count[b, e]
        assert torch.equal(got, expected)
        checked += int((expected > 0).sum())
    assert checked > 10


def test_feasibility_off_or_without_a_mentor_changes_nothing(world12):
    runs = {}
    for feasibility in (None, 1):
        runs[feasibility] = _learner(world12, None, feasibility, agents=("options", "primitives"))
        runs[feasibility].run(600)
    assert torch.equal(runs[None].metrics.curve(), runs[1].metrics.curve())
    assert torch.equal(runs[None].cache.values, runs[1].cache.values)


@pytest.mark.parametrize(
    "config",
    first_fast(
        [
            {"mentor_feasibility": 1},
            {"mentor_feasibility": 2, "mentor_trial": True, "mentor_choice": "match"},
            {"mentor_feasibility": 3, "mentor_concentration": 1.0, "confidence_z": 0.5},
        ],
        ids=["one_try", "trial_match", "priors_confidence"],
    ),
)
def test_engines_agree_with_feasibility(world12, mentor_demos12, config):
    agents = ("imitation", "imitation_primitives", "imitation_confident", "imitation_psrl")
    config = dict(config)  # (the parameter's dict is shared by reruns)
    feasibility = config.pop("mentor_feasibility")
    numba = _learner(world12, mentor_demos12, feasibility, "numba", agents, **config)
    torch_run = _learner(world12, mentor_demos12, feasibility, "torch", agents, **config)
    for learner in (numba, torch_run):
        learner.run(400)  # (the torch engine's ticks are the cost)
    assert torch.equal(numba.metrics.curve(), torch_run.metrics.curve())
    assert torch.equal(numba.model.row_count, torch_run.model.row_count)
    torch.testing.assert_close(numba.cache.values, torch_run.cache.values, atol=1e-9, rtol=0)
