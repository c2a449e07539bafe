"""Several mentors (``LearnerConfig.mentors``): each demonstration set has its own mentor model,
and eq. 2 takes the largest of the mentor terms seen at a state.

The pure rule by hand, the cache against the slow sum per mentor, the reductions (one mentor
watched by a two-mentor learner, or the same mentor twice: today's curves bit for bit), the
checks on the inputs, and engine parity."""

import pytest
import torch

from himit_torch import LearnerConfig, observe_every, record_demonstrations
from himit_torch.learner.backups import best_mentor, mentor_backup
from himit_torch.learner.models import DirichletMentorModel
from himit_torch.mentor.policy import mentor_policy
from himit_torch.options.builders import mentor_options
from tests.learner.helpers import build_learner
from tests.tiers import first_fast

pytest.importorskip("numba")

AGENTS = ["imitation", "imitation_primitives", "imitation_confident", "imitation_psrl"]


def test_best_mentor_by_hand():
    nan = float("nan")
    terms = torch.tensor(
        [
            [1.0, 3.0, 3.0],  # a tie: the first of the largest (mentor 1)
            [4.0, 3.0, -2.0],  # mentor 0 is not observed: the best observed one
            [nan, 5.0, 0.0],  # a NaN first: kept unless a later term is larger
            [7.0, 9.0, 8.0],  # nothing observed: mentor 0, none
        ],
        dtype=torch.float64,
    )
    observed = torch.tensor(
        [
            [True, True, True],
            [False, True, True],
            [True, False, True],
            [False, False, False],
        ]
    )
    index, any_observed = best_mentor(terms, observed)
    assert index.tolist() == [1, 1, 0, 0]
    assert any_observed.tolist() == [True, True, True, False]
    one_index, one_any = best_mentor(terms[:, :1], observed[:, :1])
    assert one_index.tolist() == [0, 0, 0, 0]  # one mentor: itself, where observed
    assert one_any.tolist() == [True, False, True, False]


def test_mentor_rows_are_blocks_of_states():
    model = DirichletMentorModel(5, 2, mentors=3)
    assert model.num_rows == 15
    assert model.rows_of(torch.tensor([0, 4, 5])).tolist() == [[0, 5, 10], [4, 9, 14], [15] * 3]
    assert model.row_states(torch.tensor([0, 4, 5, 9, 14])).tolist() == [0, 4, 0, 4, 4]
    model.observe(torch.tensor([7]), torch.tensor([3]))  # mentor 1 leaving state 2
    assert model.observed().tolist() == [[False, False, True, False, False]] * 2
    for bad in (0, 1.5, True, "2"):
        with pytest.raises(ValueError, match="number of mentors"):
            DirichletMentorModel(5, 2, mentors=bad)


@pytest.fixture(scope="module")
def poor_demos12(world12):
    """5 demonstrations of a mentor that errs half the time on ``world12``."""
    mentor = mentor_policy(world12, mentor_options(world12))
    return record_demonstrations(world12, mentor, 5, seed=7, noise=0.5)


def _learner(world, demos, engine="numba", agents=AGENTS, **config):
    config = LearnerConfig(window=1000, **config)
    return build_learner(world, demos, list(agents), engine=engine, config=config)


def _same_run(a, b):
    assert torch.equal(a.metrics.curve(), b.metrics.curve())
    assert torch.equal(a.model.row_count, b.model.row_count)
    assert torch.equal(a.cache.values, b.cache.values)


@pytest.mark.parametrize("engine", first_fast(["numba", "torch"], ids=["numba", "torch"]))
def test_one_mentor_watched_by_a_two_mentor_learner_is_todays_run(world12, mentor_demos12, engine):
    one = _learner(world12, mentor_demos12, engine)
    two = _learner(world12, None, engine, mentors=2)
    two.add_demonstrations(mentor_demos12, mentor=0)
    for learner in (one, two):
        learner.run(500)
    _same_run(one, two)
    assert int(two.mentor.row_count[:, world12.num_states :].sum()) == 0


def test_the_same_mentor_twice_is_one_mentor(world12, mentor_demos12):
    """Equal terms tie, and the tie goes to the first mentor: the run is the one-mentor run
    (agents that do not draw from the mentor posterior, whose draws are keyed by row)."""
    agents = AGENTS[:3]
    one = _learner(world12, mentor_demos12, agents=agents, mentor_trial=True)
    two = _learner(world12, [mentor_demos12, mentor_demos12], agents=agents, mentor_trial=True,
                   mentors=2)  # fmt: skip
    for learner in (one, two):
        learner.run(800)
    _same_run(one, two)


def test_the_cache_holds_the_largest_mentor_term(world12, mentor_demos12, poor_demos12):
    """The cached mentor term at each state is the largest of the mentors' terms, each the
    slow sum ``R_m + γ Σ p_m(s'|s) V(s')`` over that mentor's own model."""
    learner = _learner(world12, [mentor_demos12, poor_demos12], agents=["imitation"], mentors=2)
    learner.run(500)
    S, mentor, cache = world12.num_states, learner.mentor, learner.cache
    states = torch.arange(S)
    runs = torch.zeros(S, dtype=torch.int64)
    slow = torch.full((2, S), float("-inf"), dtype=torch.float64)
    E = int(mentor.num_edges[0])
    rows, succ = mentor.edge_row[0, :E], mentor.edge_successor[0, :E]
    count, reward = mentor.edge_count[0, :E], cache.mentor_edge_reward[0, :E]
    for k in range(2):
        for s in range(S):
            mine = rows == k * S + s
            if mine.any():
                p = count[mine] / count[mine].sum()
                r = (p * reward[mine]).sum()
                slow[k, s] = mentor_backup(r, p, cache.values[0, succ[mine]], learner.gamma)
    both = slow.amax(0)
    seen = torch.isfinite(both)
    assert int(seen.sum()) > 20
    assert bool((torch.isfinite(slow).all(0) & seen).any())  # states both mentors were seen in
    torch.testing.assert_close(cache.mentor_term(runs, states)[seen], both[seen], atol=1e-9, rtol=0)
    chosen = cache.mentor_rows(runs, states)
    clear = torch.isfinite(slow).all(0) & ((slow[1] - slow[0]).abs() > 1e-9)  # (no near-tie)
    assert bool(clear.any())
    assert bool(((chosen >= S) == (slow[1] > slow[0]))[clear].all())


@pytest.mark.parametrize(
    "config",
    first_fast(
        [
            {},
            {"mentor_trial": True, "mentor_choice": "match"},
            {"mentor_feasibility": 2, "mentor_fade": 3.0},
            {"mentor_concentration": 1.0, "concentration": 0.5, "mentor_segments": True},
        ],
        ids=["default", "trial_match", "feasibility_fade", "priors_segments"],
    ),
)
def test_engines_agree_with_several_mentors(world12, mentor_demos12, poor_demos12, config):
    good = mentor_demos12
    poor = observe_every(poor_demos12, 2) if config.get("mentor_segments") else poor_demos12
    numba = _learner(world12, [good, poor], "numba", mentors=2, **config)
    torch_run = _learner(world12, [good, poor], "torch", mentors=2, **config)
    for learner in (numba, torch_run):
        learner.run(400)  # (the torch engine's ticks are the cost)
    assert torch.equal(numba.metrics.curve(), torch_run.metrics.curve())
    assert torch.equal(numba.model.row_count, torch_run.model.row_count)
    torch.testing.assert_close(numba.cache.values, torch_run.cache.values, atol=1e-9, rtol=0)
    torch.testing.assert_close(numba.views.mentor_win_share(), torch_run.views.mentor_win_share())
    assert int(numba.views.decisions.min()) > 100


def test_a_second_mentor_changes_the_run(world12, mentor_demos12, poor_demos12):
    one = _learner(world12, mentor_demos12, agents=["imitation"])
    two = _learner(world12, [mentor_demos12, poor_demos12], agents=["imitation"], mentors=2)
    for learner in (one, two):
        learner.run(600)
    assert not torch.equal(one.cache.values, two.cache.values)


def test_several_mentors_resume_exactly(world12, mentor_demos12, poor_demos12):
    demos = [mentor_demos12, poor_demos12]
    whole = _learner(world12, demos, mentors=2)
    whole.run(600)
    half = _learner(world12, demos, mentors=2)
    half.run(300)
    resumed = _learner(world12, None, mentors=2)
    resumed.load_state_dict(half.state_dict())
    resumed.run(300)
    _same_run(whole, resumed)
    with pytest.raises(ValueError, match=r"config\.mentors"):
        _learner(world12, None).load_state_dict(half.state_dict())


def test_bad_mentor_inputs_are_refused(world12, mentor_demos12):
    with pytest.raises(ValueError, match="mentors"):
        LearnerConfig(mentors=0)
    learner = _learner(world12, None, agents=["imitation"], mentors=2)
    for bad in (2, -1, 1.0, True, "0"):
        with pytest.raises(ValueError, match=r"mentor=.*numbered 0…1"):
            learner.add_demonstrations(mentor_demos12, mentor=bad)
    with pytest.raises(ValueError, match="3 demonstration sets for LearnerConfig.mentors=2"):
        _learner(world12, [mentor_demos12] * 3, agents=["imitation"], mentors=2)


@pytest.mark.slow
def test_a_poor_second_mentor_does_not_drag_the_learner_below_the_good_one_alone(world12):
    """20 paired seeds: eq. 2 and eq. 1 watching the good mentor, and the good mentor with one
    that errs half the time. Goals over 15k steps; one-sided paired t-tests of (good + poor) −
    good (alternative: less), Holm over the two agents: no drag at 5 %."""
    from scipy.stats import ttest_rel

    from himit_torch import Learner, learner_options

    mentor = mentor_policy(world12, mentor_options(world12))
    seeds = list(range(20))
    agents = ["imitation"] * 20 + ["imitation_primitives"] * 20
    goals = {}
    for two in (False, True):
        learner = Learner(world12, learner_options(world12), agents, seeds + seeds,
                          config=LearnerConfig(window=1000, mentors=2 if two else 1))  # fmt: skip
        for s in seeds:
            runs = [s, 20 + s]
            learner.add_demonstrations(record_demonstrations(world12, mentor, 5, seed=s), runs)
            if two:
                poor = record_demonstrations(world12, mentor, 5, seed=s + 1000, noise=0.5)
                learner.add_demonstrations(poor, runs, mentor=1)
        learner.run(15_000)
        goals[two] = learner.views.goals.double().numpy()
    assert goals[False].min() > 0  # both learners reach the goal: the comparison means something
    for part in (slice(0, 20), slice(20, 40)):
        p = ttest_rel(goals[True][part], goals[False][part], alternative="less").pvalue
        assert 2 * p > 0.05, (part, goals[True][part].mean(), goals[False][part].mean())
