"""Trial of untried own options where the mentor leads (``LearnerConfig.mentor_trial``).

The pure rule by hand, the greedy candidates it gives a live learner, its reduction (no mentor
term, or nothing untried: the greedy rule), and engine parity."""

import pytest
import torch

from himit_torch import LearnerConfig, observe_every
from himit_torch.learner.choice import greedy_rows, trial_candidates
from tests.learner.helpers import build_learner
from tests.tiers import first_fast

pytest.importorskip("numba")

AGENTS = ["imitation", "imitation_primitives", "imitation_confident", "options"]


def test_trial_candidates_by_hand():
    won = torch.tensor([True, True, True, False])
    untried = torch.tensor(
        [
            [True, True, False, True],  # the best untried score wins: row 1 (0.5)
            [True, False, True, False],  # no untried score above 0: every untried row
            [False, False, False, False],  # nothing untried: no trial
            [True, True, True, True],  # the mentor does not lead: no trial
        ]
    )
    score = torch.tensor(
        [
            [0.2, 0.5, 0.9, 0.5 - 1e-13],  # (0.9 is tried; 0.5 − 1e-13 ties with 0.5)
            [0.0, 0.7, 0.0, 0.0],
            [0.1, 0.2, 0.3, 0.4],
            [0.1, 0.2, 0.3, 0.4],
        ],
        dtype=torch.float64,
    )
    use, candidates = trial_candidates(won, untried, score)
    assert use.tolist() == [True, True, False, False]
    assert candidates.tolist() == [
        [False, True, False, True],
        [True, False, True, False],
        [False, False, False, False],
        [False, False, False, False],
    ]


def _learner(world, demos, trial, engine="numba", agents=AGENTS, **config):
    config = LearnerConfig(window=1000, mentor_trial=trial, **config)
    return build_learner(world, demos, list(agents), engine=engine, config=config)


def test_where_the_mentor_leads_the_greedy_choice_tries_an_untried_option(world12, mentor_demos12):
    learner = _learner(world12, mentor_demos12, True, agents=["imitation", "imitation_primitives"])
    learner.run(300)
    S = world12.num_states
    states = torch.arange(S)
    seen = 0
    for b in range(learner.batch):
        runs = torch.full_like(states, b)
        _, _, won = learner.cache.state_backup(runs[:, None], states[:, None])
        rows, greedy, enabled = greedy_rows(learner.cache, runs, states)
        tried = learner.model.row_count[b, rows] > 0
        untried = enabled & ~tried
        leads = won[:, 0] & untried.any(1)
        # there, every greedy candidate is untried; elsewhere the rule is the plain greedy one
        assert bool((greedy[leads] <= untried[leads]).all())
        assert bool(greedy[leads].any(1).all())
        seen += int(leads.sum())
        learner.cache.config.mentor_trial = False  # (the same state, the plain rule)
        try:
            _, plain, _ = greedy_rows(learner.cache, runs, states)
        finally:
            learner.cache.config.mentor_trial = True
        assert torch.equal(plain[~leads], greedy[~leads])
        assert not torch.equal(plain[leads], greedy[leads]) or not bool(leads.any())
    assert seen > 10


def test_without_a_mentor_trial_changes_nothing(world12):
    runs = {}
    for trial in (False, True):
        runs[trial] = _learner(world12, None, trial)
        runs[trial].run(600)
    assert torch.equal(runs[False].metrics.curve(), runs[True].metrics.curve())
    assert torch.equal(runs[False].cache.values, runs[True].cache.values)


def test_trial_changes_an_imitators_run(world12, mentor_demos12):
    runs = {}
    for trial in (False, True):
        runs[trial] = _learner(world12, mentor_demos12, trial, agents=["imitation"])
        runs[trial].run(600)
    assert not torch.equal(runs[False].model.row_count, runs[True].model.row_count)


@pytest.mark.parametrize(
    "config",
    first_fast(
        [
            {},
            {"mentor_choice": "match", "untried_value": 0.0, "initial_value": 0.0},
            {"mentor_concentration": 1.0, "concentration": 0.5, "tie_break": "first"},
            {"mentor_segments": True, "mentor_fade": 3.0},
        ],
        ids=["default", "match_optimistic", "priors_first", "segments_fade"],
    ),
)
def test_engines_agree_with_trial(world12, mentor_demos12, config):
    demos = observe_every(mentor_demos12, 2) if config.get("mentor_segments") else mentor_demos12
    numba = _learner(world12, demos, True, "numba", **config)
    torch_run = _learner(world12, demos, True, "torch", **config)
    for learner in (numba, torch_run):
        learner.run(400)  # (the torch engine's ticks are the cost)
    assert torch.equal(numba.metrics.curve(), torch_run.metrics.curve())
    assert torch.equal(numba.model.row_count, torch_run.model.row_count)
    torch.testing.assert_close(numba.cache.values, torch_run.cache.values, atol=1e-9, rtol=0)
    assert int(numba.views.decisions.min()) > 100


def test_the_frozen_greedy_policy_follows_the_trial_rule(world12, mentor_demos12):
    """The greedy policy is the run's choice at ε = 0, the trial included."""
    learner = _learner(world12, mentor_demos12, True, agents=["imitation"])
    learner.run(300)
    policy = learner.views.greedy_policy()
    S = world12.num_states
    states = torch.arange(S)
    _, greedy, _ = greedy_rows(learner.cache, torch.zeros_like(states), states)
    live = ~learner.terminal[:S]
    expected = greedy.double() / greedy.sum(1, keepdim=True).clamp(min=1)
    torch.testing.assert_close(policy.probability[0][live], expected[live])
