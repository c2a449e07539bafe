"""The mentor term over segments (``LearnerConfig.mentor_segments``): each observed mentor move
scored as the option it is, with its duration's discount and the reward of its steps.

Hand-solved values of the pure functions, the durations coarse observation gives, the
learner's cache against the from-scratch sum, the reduction to the paper's one-step term when
every move is one step, engine parity, and old checkpoints."""

import math

import pytest
import torch

from himit_torch import (
    Learner,
    LearnerConfig,
    MultiRooms,
    learner_options,
    observe_every,
)
from himit_torch.learner.backups import (
    mentor_backup,
    segment_discount,
    segment_mentor_backup,
    segment_reward,
)
from himit_torch.learner.config import CONFIG_SCHEMA_VERSION
from himit_torch.learner.models import DirichletMentorModel
from himit_torch.mentor.reward import KnownReward
from himit_torch.state_checks import DamagedState
from tests.learner.helpers import build_learner
from tests.tiers import first_fast

pytest.importorskip("numba")


def _t(x) -> torch.Tensor:
    return torch.tensor(x, dtype=torch.float64)


AGENTS = ["imitation", "imitation_primitives", "imitation_confident", "imitation_psrl"]


# ------------------------------------------------------------------------- the pure functions
def test_segment_reward_by_hand():
    # γ = 0.5; a 3-step move ending in +1, each unseen step −0.1:
    # −0.1 (1 + 0.5) + 0.25 · 1 = 0.1
    r = segment_reward(_t(1.0), _t(0.25), -0.1, 0.5)
    assert float(r) == pytest.approx(0.1, abs=1e-15)
    # an edge seen once in 1 step and once in 3 steps: mean delay (1 + 0.25) / 2 = 0.625;
    # the mean of the two segment rewards, (1 + 0.1) / 2 = 0.55
    mean = segment_reward(_t(1.0), _t(0.625), -0.1, 0.5)
    assert float(mean) == pytest.approx(0.55, abs=1e-15)


def test_segment_reward_of_one_step_moves_is_the_observed_reward_exactly():
    last = _t([-0.01, 1.0, 0.3])
    assert torch.equal(segment_reward(last, _t([1.0, 1.0, 1.0]), -5.0, 0.99), last)


@pytest.mark.parametrize("gamma", [0.0, 1.0, 1.5])
def test_segment_reward_refuses_a_discount_outside_0_1(gamma):
    with pytest.raises(ValueError, match="discount in"):
        segment_reward(torch.tensor(1.0), torch.tensor(1.0), 0.0, gamma)


def test_segment_mentor_backup_by_hand():
    # From s: to a in 1 step twice (r −0.01, V 0.5), to b in 2 steps once (r = −0.01 − 0.5·0.01
    # with γ = 0.5, V 1.0). (2/3)(−0.01 + 0.5·0.5) + (1/3)(−0.015 + 0.25·1.0) = 0.238333…
    gamma = 0.5
    r = segment_reward(_t([-0.01, -0.01]), _t([1.0, 0.5]), -0.01, gamma)
    assert r.tolist() == pytest.approx([-0.01, -0.015], abs=1e-15)
    disc = segment_discount(_t([1.0, 0.5]), gamma)
    assert disc.tolist() == [0.5, 0.25]
    m = segment_mentor_backup(r, disc, _t([2 / 3, 1 / 3]), _t([0.5, 1.0]))
    assert float(m) == pytest.approx(2 / 3 * 0.24 + 1 / 3 * 0.235, abs=1e-15)


def test_segment_mentor_backup_of_one_step_moves_is_the_papers_term():
    g = torch.Generator().manual_seed(0)
    probs = torch.rand(4, 3, generator=g, dtype=torch.float64)
    probs /= probs.sum(-1, keepdim=True)
    r = torch.rand(4, 3, generator=g, dtype=torch.float64) - 0.5
    v = torch.rand(4, 3, generator=g, dtype=torch.float64)
    ours = segment_mentor_backup(r, torch.full_like(r, 0.9), probs, v)
    papers = mentor_backup((probs * r).sum(-1), probs, v, 0.9)
    torch.testing.assert_close(ours, papers, atol=1e-15, rtol=0)


def test_segment_mentor_backup_refuses_mismatched_shapes():
    with pytest.raises(ValueError, match=r"\[\.\.\., K\]"):
        segment_mentor_backup(torch.zeros(3), torch.zeros(2), torch.zeros(3), torch.zeros(3))


# -------------------------------------------------------------------------------- durations
def test_coarse_observation_gives_each_moves_duration(world12, mentor_demos12):
    coarse = observe_every(mentor_demos12, 3)
    src, _ = coarse.transitions()
    steps = coarse.durations()
    assert steps.shape == src.shape and steps.dtype == torch.int64
    # each episode: strides of 3, its last move the rest (1…3 steps)
    start = 0
    for full, kept in zip(mentor_demos12.episodes, coarse.episodes):
        n = len(kept) - 1
        mine = steps[start : start + n]
        assert int(mine.sum()) == len(full) - 1
        assert bool((mine[:-1] == 3).all()) and 1 <= int(mine[-1]) <= 3
        start += n


def test_the_mentor_model_keeps_each_edges_delay():
    model = DirichletMentorModel(4, 2)
    # run 0 sees 0→1 in 1 step and in 3 steps (γ = 0.5: delays 1 and 0.25), 1→2 in 2 steps
    model.observe(
        torch.tensor([0, 0, 1]),
        torch.tensor([1, 1, 2]),
        torch.tensor([0]),
        delays=torch.tensor([1.0, 0.25, 0.5]),
    )
    model.observe(torch.tensor([0]), torch.tensor([1]), torch.tensor([1]))  # run 1: default 1
    E = int(model.num_edges[0])
    assert model.edge_delay[0, :E].tolist() == [1.25, 0.5]
    assert model.edge_count[0, :E].tolist() == [2.0, 1.0]
    assert model.edge_delay[1, :1].tolist() == [1.0]


def test_a_checkpoint_without_edge_delays_loads_as_one_step_moves():
    model = DirichletMentorModel(4, 1)
    model.observe(torch.tensor([0, 1]), torch.tensor([1, 2]), delays=torch.tensor([0.5, 0.5]))
    state = model.state_dict()
    del state["edge_delay"]  # written before delays were kept
    fresh = DirichletMentorModel(4, 1)
    fresh.load_state_dict(state)
    assert torch.equal(fresh.edge_delay[:, :2], fresh.edge_count[:, :2])


def test_a_delay_above_its_count_is_damage():
    model = DirichletMentorModel(4, 1)
    model.observe(torch.tensor([0]), torch.tensor([1]))
    state = model.state_dict()
    state["edge_delay"] = state["edge_delay"] * 2
    with pytest.raises(DamagedState, match="edge_delay"):
        DirichletMentorModel(4, 1).load_state_dict(state)


class _Durations:
    """Demonstrations with a given ``durations()``."""

    def __init__(self, demos, durations):
        self.demos, self._durations = demos, durations

    def transitions(self):
        return self.demos.transitions()

    def durations(self):
        return self._durations


@pytest.mark.parametrize("bad", ["zero", "float", "short"])
def test_bad_durations_are_refused(world12, mentor_demos12, bad):
    T = mentor_demos12.transitions()[0].numel()
    durations = {
        "zero": torch.zeros(T, dtype=torch.int64),
        "float": torch.full((T,), 1.5),
        "short": torch.ones(T - 1, dtype=torch.int64),
    }[bad]
    learner = Learner(world12, learner_options(world12), ["imitation"], [0])
    with pytest.raises(ValueError, match="durations"):
        learner.add_demonstrations(_Durations(mentor_demos12, durations))


def test_an_undiscounted_world_refuses_segments():
    world = MultiRooms(8, 1)
    world.gamma = 1.0
    with pytest.raises(ValueError, match="mentor_segments"):
        Learner(
            world,
            learner_options(world),
            ["imitation"],
            [0],
            config=LearnerConfig(mentor_segments=True),
        )


# ---------------------------------------------------------------------------- the learner
def _learner(world, demos, segments, engine="numba", agents=AGENTS, **config):
    config = LearnerConfig(window=1000, mentor_segments=segments, **config)
    return build_learner(world, demos, list(agents), engine=engine, config=config)


def test_one_step_segments_are_the_papers_term_bit_for_bit(world12, mentor_demos12):
    """Full demonstrations: every move one step, so the segment term is eq. 2's exactly."""
    runs = {}
    for segments in (False, True):
        runs[segments] = _learner(world12, mentor_demos12, segments)
        runs[segments].run(1000)
    off, on = runs[False], runs[True]
    assert torch.equal(off.metrics.curve(), on.metrics.curve())
    assert torch.equal(off.cache.values, on.cache.values)
    assert torch.equal(off.cache.mentor_numerator, on.cache.mentor_numerator)
    assert int(off.views.goals.sum()) > 0


def test_segments_off_ignore_the_durations(world12, mentor_demos12):
    """Without the setting, coarse demonstrations enter the mentor term as before: as one-step
    moves, whatever durations they carry."""
    coarse = observe_every(mentor_demos12, 3)
    with_durations = _learner(world12, coarse, False)
    without = _learner(world12, None, False)
    src, dst = coarse.transitions()

    class _Plain:
        def transitions(self):
            return src, dst

    without.add_demonstrations(_Plain())
    for learner in (with_durations, without):
        learner.run(600)
    assert torch.equal(with_durations.metrics.curve(), without.metrics.curve())
    assert torch.equal(with_durations.cache.values, without.cache.values)


@pytest.mark.parametrize("engine", ["numba", "torch"])
def test_the_cached_segment_term_is_the_from_scratch_sum(world12, mentor_demos12, engine):
    coarse = observe_every(mentor_demos12, 4)
    learner = _learner(world12, coarse, True, engine, agents=["imitation", "imitation_primitives"])
    learner.run(400)
    gamma, mentor, V = world12.gamma, learner.mentor, learner.cache.values
    module = KnownReward(world12)
    checked = 0
    for b in range(learner.batch):
        E = int(mentor.num_edges[b])
        src, dst = mentor.edge_row[b, :E], mentor.edge_successor[b, :E]
        count, delay = mentor.edge_count[b, :E], mentor.edge_delay[b, :E]
        r = module.transition_reward(src, dst).to(torch.float64)
        unseen = float(r.min())
        for s in torch.unique(src).tolist():
            at = src == s
            probs = count[at] / count[at].sum()
            mean_delay = delay[at] / count[at]
            expected = segment_mentor_backup(
                segment_reward(r[at], mean_delay, unseen, gamma),
                segment_discount(mean_delay, gamma),
                probs,
                V[b, dst[at]],
            )
            got = learner.cache.mentor_term(torch.tensor([b]), torch.tensor([s]))
            torch.testing.assert_close(got[0], expected, atol=1e-9, rtol=0)
            checked += 1
    assert checked > 15
    # and the stride's moves are discounted by γ^4, not once
    E = int(mentor.num_edges[0])
    discounts = learner.cache.mentor_edge_discount[0, :E].tolist()
    assert sum(math.isclose(d, gamma**4, rel_tol=1e-12) for d in discounts) > E / 2


@pytest.mark.parametrize(
    "config",
    first_fast(
        [
            {},
            {"mentor_concentration": 1.0, "concentration": 0.5, "confidence_z": 0.5},
            {"mentor_fade": 3.0, "plan_every": 3, "sweep_rounds": 3, "backups": 7},
        ],
        ids=["default", "priors_confidence", "fade_rounds"],
    ),
)
def test_engines_agree_with_segments(world12, mentor_demos12, config):
    coarse = observe_every(mentor_demos12, 3)
    numba = _learner(world12, coarse, True, "numba", **config)
    torch_run = _learner(world12, coarse, True, "torch", **config)
    for learner in (numba, torch_run):
        learner.run(400)  # (the torch engine's ticks are the cost)
    assert torch.equal(numba.metrics.curve(), torch_run.metrics.curve())
    torch.testing.assert_close(numba.cache.values, torch_run.cache.values, atol=1e-9, rtol=0)
    torch.testing.assert_close(
        numba.cache.mentor_numerator, torch_run.cache.mentor_numerator, atol=1e-9, rtol=0
    )
    assert int(numba.views.decisions.min()) > 100


def test_segments_change_the_coarse_mentor_term(world12, mentor_demos12):
    """Under coarse observation the segment term is lower than the one-step term wherever the
    successor's value is positive or a step is unseen: it is no longer optimistic."""
    coarse = observe_every(mentor_demos12, 3)
    one_step = _learner(world12, coarse, False, agents=["imitation"])
    segments = _learner(world12, coarse, True, agents=["imitation"])
    # the same values V (the initial ones) under both terms
    seen = one_step.mentor.observed()[0].nonzero()[:, 0]
    runs = torch.zeros_like(seen)
    # V = v0 = −1 at every non-goal state: a 3-step move is worth −0.01(1 + γ + γ²) − γ³ with
    # segments (the value of three steps), −0.01 − γ with one (of one step)
    gamma = world12.gamma
    three = -0.01 * (1 + gamma + gamma**2) - gamma**3
    one = -0.01 - gamma
    seg, flat = segments.cache.mentor_term(runs, seen), one_step.cache.mentor_term(runs, seen)
    assert sum(math.isclose(float(m), three, rel_tol=1e-12) for m in seg) > len(seen) / 2
    assert sum(math.isclose(float(m), one, rel_tol=1e-12) for m in flat) > len(seen) / 2


def test_the_segment_setting_survives_a_checkpoint(world12, mentor_demos12):
    coarse = observe_every(mentor_demos12, 3)
    whole = _learner(world12, coarse, True, agents=["imitation"])
    whole.run(600)
    half = _learner(world12, coarse, True, agents=["imitation"])
    half.run(300)
    resumed = _learner(world12, None, True, agents=["imitation"])
    resumed.load_state_dict(half.state_dict())
    resumed.run(300)
    assert torch.equal(whole.cache.values, resumed.cache.values)
    assert torch.equal(whole.cache.mentor_edge_discount, resumed.cache.mentor_edge_discount)


def test_options_only_world_is_unaffected():
    """A run without a mentor term reads none of it."""
    world = MultiRooms(8, 1)
    runs = {}
    for segments in (False, True):
        runs[segments] = _learner(world, None, segments, agents=["options"])
        runs[segments].run(300)
    assert torch.equal(runs[False].cache.values, runs[True].cache.values)


def test_a_checkpoint_from_before_the_new_settings_resumes(world12, mentor_demos12):
    """A checkpoint written before mentor_segments, mentor_trial, mentor_feasibility and
    mentors existed names none of them: each takes its declared default, and the run goes on
    exactly."""
    whole = _learner(world12, mentor_demos12, False, agents=["imitation"])
    whole.run(600)
    half = _learner(world12, mentor_demos12, False, agents=["imitation"])
    half.run(300)
    state = half.state_dict()
    for name in ("mentor_segments", "mentor_trial", "mentor_feasibility", "mentors"):
        del state["identity"]["config"][name]
    del state["mentor"]["edge_delay"]
    assert state.pop("config_schema") == CONFIG_SCHEMA_VERSION  # (as if written before it was)
    resumed = _learner(world12, None, False, agents=["imitation"])
    resumed.load_state_dict(state)
    resumed.run(300)
    assert torch.equal(whole.cache.values, resumed.cache.values)
    assert torch.equal(whole.metrics.curve(), resumed.metrics.curve())


def test_a_checkpoint_of_other_settings_is_refused_naming_them(world12, mentor_demos12):
    half = _learner(world12, mentor_demos12, False, agents=["imitation"])
    half.run(100)
    state = half.state_dict()
    state["identity"]["config"]["mentor_trial"] = True  # (ran with trial: not this learner)
    state["identity"]["config"]["from_the_future"] = 1  # (a setting this code does not know)
    with pytest.raises(ValueError, match=r"config\.from_the_future.*config\.mentor_trial"):
        _learner(world12, None, False, agents=["imitation"]).load_state_dict(state)
    state["identity"]["config"] = [1, 2]
    with pytest.raises(ValueError, match="identity.config"):
        _learner(world12, None, False, agents=["imitation"]).load_state_dict(state)
    good = half.state_dict()
    good["config_schema"] = CONFIG_SCHEMA_VERSION + 1
    with pytest.raises(ValueError, match="newer than this"):
        _learner(world12, None, False, agents=["imitation"]).load_state_dict(good)
    good["config_schema"] = "2"
    with pytest.raises(ValueError, match="config_schema"):
        _learner(world12, None, False, agents=["imitation"]).load_state_dict(good)
