"""Mentor-reward modules: stimulus features of the world, SalienceReward worked out by hand on a
tiny world, the learner's checks of a module (bound, NaN, shape), per-run modules in one batch,
and a learner that reaches the goal with intrinsic reward only."""

import pytest
import torch

import himit_torch as ht
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import record_demonstrations
from himit_torch.mentor.reward import SALIENCE_EVENTS, KnownReward, MentorReward, SalienceReward
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.worlds.multirooms import STIMULUS_FEATURES, MultiRooms

# ======================================================================= the tiny world by hand
#   MultiRooms(6, 2), states s = 6·row + col      rooms: 0 top-left, 1 top-right,
#        col 0 1 2 3 4 5                                2 bottom-left, 3 bottom-right
#   row 0   S . . # . .                           room feature (room + 1) / 4:
#   row 1   . . . + . .     doorways 9, 19, 23, 33     room 0 → .25, 1 → .5, 2 → .75, 3 → 1.0,
#   row 2   . . . # . .                                doorways and walls → 0
#   row 3   # + # # # +
#   row 4   . . . # . .     light = 1 on room 3 (28, 29, 34, 35); sound = 0.5 on state 16
#   row 5   . . . + . G
EPISODE_A = [0, 1, 2, 8, 9, 10, 16, 16, 17, 23, 29, 35]  # bumps at 16 (wall below)
EPISODE_B = [0, 1, 2, 8, 9, 10, 9, 10, 11, 17, 23, 29, 35]  # steps back into doorway 9


@pytest.fixture(scope="module")
def world6() -> MultiRooms:
    light = torch.zeros(36)
    light[[28, 29, 34, 35]] = 1.0
    world = MultiRooms(6, 2, stimuli={"light": light})
    sound = torch.zeros(36)
    sound[16] = 0.5
    world.set_stimulus("sound", sound)
    return world


@pytest.fixture(scope="module")
def demos6(world6):
    return ht.Demonstrations([EPISODE_A, EPISODE_B], world6)


@pytest.fixture(scope="module")
def salience6(world6, demos6) -> SalienceReward:
    return SalienceReward(world6, demos6, scale=0.1, step_cost=0.02, bound=0.8, decay=0.5)


def test_stimulus_features_of_the_tiny_world(world6):
    f = world6.stimulus_features()
    assert f.shape == (36, 4) and f.dtype == torch.float64
    assert (
        world6.stimulus_feature_names == STIMULUS_FEATURES == ("room", "doorway", "light", "sound")
    )
    assert f[0, 0] == 0.25 and f[4, 0] == 0.5 and f[24, 0] == 0.75 and f[35, 0] == 1.0
    assert f[9, 0] == 0.0 and f[3, 0] == 0.0  # doorway, wall: no room
    assert f[:, 1].nonzero().flatten().tolist() == [9, 19, 23, 33]
    assert f[:, 2].nonzero().flatten().tolist() == [28, 29, 34, 35]
    assert f[16, 3] == 0.5 and f[:, 3].sum() == 0.5
    plain = MultiRooms(6, 2)
    assert (plain.stimulus_features()[:, 2:] == 0).all()  # channels off unless set
    assert plain.describe() == world6.describe()  # stimuli are not dynamics


def test_set_stimulus_rejects_bad_channels(world6):
    with pytest.raises(ValueError, match=r"MultiRooms.set_stimulus.*expected \[S\] = \[36\]"):
        MultiRooms(6, 2).set_stimulus("light", torch.ones(35))
    with pytest.raises(ValueError, match="unknown channel 'smell'"):
        MultiRooms(6, 2).set_stimulus("smell", torch.ones(36))
    with pytest.raises(ValueError, match="NaN"):
        MultiRooms(6, 2, stimuli={"sound": torch.full((36,), float("nan"))})
    w = MultiRooms(6, 2, stimuli={"light": torch.ones(36)})
    w.set_stimulus("light", None)
    assert (w.stimulus_features()[:, 2] == 0).all()


def test_salience_reward_by_hand(salience6):
    """Settings: scale 0.1, step_cost 0.02, bound 0.8, decay 0.5, weights room 1, end 1,
    novelty 0.25, stimulus 1. r = e·0.8 + (1 − e)(0.1·σ − 0.02).

    Mentor sightings n(s): 9, 10 → 3; 11 → 1; the others on the paths → 2. Novelty
    0.5 ** (n − 1): n = 2 → 0.5, n = 3 → 0.25, n = 1 → 1; weighted by 0.25: 0.125, 0.0625, 0.25.
    Only 35 ends episodes (2 of its 2 arrivals): ε(35) = 1, e = 1.

    (9 → 10)  doorway → room 1: room 1 + novelty .0625 → σ = 1      r = 0.1 − 0.02 = 0.08
    (10 → 9)  into the doorway: novelty .0625 → σ = .0625          r = .00625 − .02 = −0.01375
    (0 → 1)   novelty .125                                         r = .0125 − .02 = −0.0075
    (10 → 16) sound 0 → .5: stimulus .5 + novelty .125 = .625      r = .0625 − .02 = 0.0425
    (16 → 16) bump: novelty .125                                   r = −0.0075
    (16 → 17) sound .5 → 0: .5 + .125                              r = 0.0425
    (10 → 11) 11 seen once: novelty .25                            r = .025 − .02 = 0.005
    (23 → 29) room 3 (1 + light 0 → 1 + .125, clipped to σ = 1)    r = 0.08
    (29 → 35) the end: e = 1                                       r = 0.8
    Transitions the mentor never made get the same formula:
    (35 → 28) same room, same light; 28 unseen: novelty 1 → .25     r = 0.005
    (33 → 34) doorway → room 3, light on, 34 unseen: σ = 1          r = 0.08
    """
    src = torch.tensor([9, 10, 0, 10, 16, 16, 10, 23, 29, 35, 33])
    dst = torch.tensor([10, 9, 1, 16, 16, 17, 11, 29, 35, 28, 34])
    expected = torch.tensor(
        [0.08, -0.01375, -0.0075, 0.0425, -0.0075, 0.0425, 0.005, 0.08, 0.8, 0.005, 0.08],
        dtype=torch.float64,
    )
    got = salience6.transition_reward(src, dst)
    torch.testing.assert_close(got, expected, atol=1e-12, rtol=0)
    assert salience6.upper_bound == 0.8
    assert not salience6.cycle_safe  # scale 0.1 > step_cost 0.02: doorway steps pay
    ev = salience6.events(torch.tensor([9, 23, 10]), torch.tensor([10, 29, 16]))
    assert ev["room"].tolist() == [1.0, 1.0, 0.0]
    assert ev["stimulus"].tolist() == [0.0, 1.0, 0.5]
    assert ev["end"].tolist() == [0.0, 0.0, 0.0]
    assert ev["novelty"].tolist() == [0.25, 0.5, 0.5]


def test_salience_map_by_hand(salience6):
    """Total salience clip(Σ w·event, 0, 1) averaged over the mentor's arrivals at each state:
    35: end 1 + .125 → 1 (twice) → 1.0;   10: three arrivals from 9, each 1 → 1.0;
    9: from 8, 8, 10, each novelty .0625 → .0625;   16: from 10 (.625) and 16 (.125) → .375;
    17: from 16 (.625) and 11 (.125) → .375;   11: .25;   0: never arrived → 0."""
    m = salience6.salience_map()
    assert m.shape == (36,)
    expected = {
        35: 1.0,
        10: 1.0,
        9: 0.0625,
        16: 0.375,
        17: 0.375,
        11: 0.25,
        1: 0.125,
        0: 0.0,
        29: 1.0,
        5: 0.0,
    }
    for s, v in expected.items():
        assert m[s].item() == pytest.approx(v, abs=1e-12), f"state {s}"
    maps = salience6.event_maps()
    assert set(maps) == set(SALIENCE_EVENTS)
    assert maps["end"][35] == 1.0 and maps["end"].sum() == 1.0
    assert maps["room"][10] == 1.0 and maps["room"][29] == 1.0 and maps["room"].sum() == 2.0


def test_salience_reward_never_reads_the_world_reward(demos6):
    """The module sees the world's features, never its reward: worlds that differ only in their
    rewards give identical intrinsic rewards."""
    src, dst = demos6.transitions()
    plain = MultiRooms(6, 2)
    other = MultiRooms(6, 2, goal_reward=5.0, step_reward=-0.5)
    a = SalienceReward(plain, list(demos6.episodes)).transition_reward(src, dst)
    b = SalienceReward(other, list(demos6.episodes)).transition_reward(src, dst)
    assert torch.equal(a, b)
    # The defaults are sound for MultiRooms' rewards: no step pays more than the real −0.01, the
    # end pays 0.5 < 1; so they are cycle-safe too (only the end pays more than 0).
    module = SalienceReward(plain, demos6)
    assert module.cycle_safe and module.upper_bound == 0.5
    assert module.step_reward_range == (-0.02, -0.01)
    r = module.transition_reward(src, dst)
    steps = r[dst != 35]
    assert (steps <= plain.step_reward + 1e-12).all() and (steps >= -0.02).all()
    assert (r[dst == 35] == 0.5).all()
    assert steps.min() < steps.max()  # salience does change the cost of a step


def test_user_features_and_channels(world6, demos6):
    S = 36
    lamp = torch.zeros(S, 1, dtype=torch.float64)
    lamp[10] = 1.0
    module = SalienceReward(world6, demos6, features=lamp, weights={"novelty": 0.0})
    assert module.feature_names == ("channel0",) and module.stimulus_channels == ("channel0",)
    r = module.transition_reward(torch.tensor([9, 10, 0]), torch.tensor([10, 11, 1]))
    # lamp on at 10: arriving and leaving are full stimulus events (σ = 1: 0.01 − 0.02); no room
    # column here, so 0 → 1 is a plain step (−0.02).
    torch.testing.assert_close(r, torch.tensor([-0.01, -0.01, -0.02], dtype=torch.float64))
    named = SalienceReward(world6, demos6, stimulus_channels=["light"], weights={"novelty": 0})
    # sound no longer counts: 10 → 16 is a plain step, 23 → 29 still a room change + light.
    r = named.transition_reward(torch.tensor([10, 23]), torch.tensor([16, 29]))
    torch.testing.assert_close(r, torch.tensor([-0.02, -0.01], dtype=torch.float64))


@pytest.mark.parametrize(
    "features, match",
    [
        (
            torch.zeros(35, 4),
            r"SalienceReward: features have shape \(35, 4\), expected \[S=36, F\]",
        ),
        (torch.zeros(36), r"SalienceReward: features have shape \(36,\), expected \[S=36, F\]"),
        (torch.zeros(36, 0), r"expected \[S=36, F\]"),
        (torch.full((36, 2), float("nan")), "SalienceReward: features hold NaN"),
    ],
)
def test_features_of_the_wrong_size_are_refused(world6, features, match):
    with pytest.raises(ValueError, match=match):
        SalienceReward(world6, features=features)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"weights": {"smell": 1.0}}, "unknown event kind 'smell'"),
        ({"weights": {"room": -1.0}}, r"weights\['room'\]"),
        ({"scale": float("nan")}, "scale"),
        ({"step_cost": -0.1}, "step_cost"),
        ({"bound": -1.0}, "bound"),
        ({"decay": 1.5}, "decay"),
        ({"decay": -0.5}, "decay"),
        ({"bound": "high"}, "bound='high'"),
        ({"stimulus_channels": ["smell"]}, "stimulus_channels"),
        ({"feature_names": ["a", "b"]}, "feature_names"),
    ],
)
def test_bad_settings_are_refused(world6, kwargs, match):
    with pytest.raises(ValueError, match=f"SalienceReward.*{match}"):
        SalienceReward(world6, **kwargs)


def test_bad_use_is_refused(world6, demos6):
    module = SalienceReward(world6)
    with pytest.raises(ValueError, match="SalienceReward: not fitted"):
        module.transition_reward(torch.tensor([0]), torch.tensor([1]))
    with pytest.raises(ValueError, match="SalienceReward.fit: .*different world"):
        module.fit(record_demonstrations(MultiRooms(8, 2), mentor_options(MultiRooms(8, 2)), 1))
    with pytest.raises(ValueError, match="SalienceReward.fit: episode 0 holds states outside"):
        module.fit([[0, 99]])
    with pytest.raises(ValueError, match="SalienceReward.fit: no episodes"):
        module.fit([])
    with pytest.raises(ValueError, match="SalienceReward.fit: episode 0 must be a non-empty 1-D"):
        module.fit([[[0, 1], [6, 7]]])
    module.fit(demos6)
    with pytest.raises(ValueError, match=r"SalienceReward.transition_reward: sources \(2,\)"):
        module.transition_reward(torch.tensor([0, 1]), torch.tensor([1]))
    with pytest.raises(ValueError, match="outside 0…35"):
        module.transition_reward(torch.tensor([0]), torch.tensor([36]))
    with pytest.raises(ValueError, match="no stimulus_features"):
        SalienceReward(type("Bare", (), {"num_states": 4})())
    assert isinstance(module, MentorReward) and isinstance(KnownReward(world6), MentorReward)


# ==================================================================== the learner's checks
class ConstantReward:
    """A reward module returning ``value`` everywhere and declaring ``upper_bound``."""

    def __init__(self, value, upper_bound, shape_offset=0):
        self.value, self.upper_bound, self.shape_offset = value, upper_bound, shape_offset

    def transition_reward(self, sources, successors):
        return torch.full((sources.numel() + self.shape_offset,), self.value, dtype=torch.float64)

    def __repr__(self):
        return f"ConstantReward({self.value}, bound={self.upper_bound})"


@pytest.fixture(scope="module")
def demos8(world8):
    return record_demonstrations(world8, mentor_options(world8), episodes=10, seed=0)


def make(world, demos, reward, check="error", agents=("imitation",)):
    return Learner(
        world,
        learner_options(world),
        list(agents),
        [0] * len(agents),
        config=LearnerConfig(reward_bound_check=check),
        demonstrations=demos,
        reward=reward,
    )


def test_bound_above_the_real_reward_is_an_error_or_a_warning(world8, demos8):
    greedy = SalienceReward(world8, demos8, bound=2.0)  # real best reward: +1.0
    with pytest.raises(
        ValueError, match=r"SalienceReward\(bound=2.*upper_bound=2.*best real reward"
    ):
        make(world8, demos8, greedy)
    with pytest.warns(UserWarning, match="upper_bound=2"):
        learner = make(world8, demos8, greedy, check="warn")
    assert learner.cache.mentor_edge_reward.max().item() == 2.0  # used as given
    make(world8, demos8, greedy, check="off")  # no error, no warning
    make(world8, demos8, SalienceReward(world8, demos8, bound=1.0))  # equal to the real best: fine


@pytest.mark.parametrize(
    "module, match",
    [
        (
            ConstantReward(0.5, 0.1),
            r"ConstantReward\(0.5, bound=0.1\) returned 0.5, above its declared upper_bound=0.1",
        ),
        (ConstantReward(float("nan"), 0.1), r"ConstantReward\(nan.*NaN"),
        (ConstantReward(float("inf"), 0.1), "NaN or infinite"),
        (
            ConstantReward(0.0, 0.1, shape_offset=1),
            r"ConstantReward\(0.0, bound=0.1\) returned shape",
        ),
    ],
)
def test_bad_module_output_is_an_error(world8, demos8, module, match):
    with pytest.raises(ValueError, match=match):
        make(world8, demos8, module)


# ================================================================ intrinsic reward in learning
def test_known_intrinsic_and_no_mentor_reward_in_one_batch(world8, demos8):
    """One batch, three runs with their own modules: known, intrinsic, none (options only).
    Each run's mentor-edge rewards come from its own module, and the intrinsic run learns
    exactly as it does alone (a run's module never leaks into another)."""
    known, intrinsic = KnownReward(world8), SalienceReward(world8, demos8)
    agents = ["imitation", "imitation", "options"]
    batch = Learner(
        world8,
        learner_options(world8),
        agents,
        [3, 3, 3],
        demonstrations=demos8,
        reward=[known, intrinsic, known],
    )
    E = int(batch.mentor.num_edges[0])  # every run watched the same demonstrations
    src, dst = batch.mentor.edge_row[0, :E], batch.mentor.edge_successor[0, :E]
    reward = batch.cache.mentor_edge_reward
    assert torch.equal(reward[0, :E], known.transition_reward(src, dst))
    assert torch.equal(reward[1, :E], intrinsic.transition_reward(src, dst))
    assert not torch.equal(reward[0, :E], reward[1, :E])
    batch.run(3000)
    alone = Learner(
        world8, learner_options(world8), ["imitation"], [3], demonstrations=demos8, reward=intrinsic
    )
    alone.run(3000)
    assert torch.equal(batch.views.state_values()[1], alone.views.state_values()[0])
    assert batch.views.goals[1] == alone.views.goals[0] and int(batch.views.goals[1]) > 0
    assert int(batch.views.goals[0]) > 0


def test_intrinsic_reward_alone_reaches_the_goal(world8, demos8):
    """The mentor term knows nothing of the goal reward: SalienceReward only. Every seed reaches
    the goal within 1500 steps and then keeps reaching it (optimal ≈ 125 goals per 2000 steps
    here; ≈ 115 when written). The same module with *paying* salient steps (scale 0.1, no step
    cost: not cycle-safe) is farmed instead: the learner steps back and forth through a doorway
    and almost stops reaching the goal (0 goals when written)."""
    seeds = [0, 1, 2, 3]
    safe = SalienceReward(world8, demos8)
    paying = SalienceReward(world8, demos8, scale=0.1, step_cost=0.0)
    assert safe.cycle_safe and not paying.cycle_safe
    learner = Learner(
        world8,
        learner_options(world8),
        ["imitation"] * 8,
        seeds * 2,
        config=LearnerConfig(window=1000),
        demonstrations=demos8,
        reward=[safe] * 4 + [paying] * 4,
    )
    learner.run(6000)
    first = learner.views.first_goal_step[:4]
    assert ((first > 0) & (first <= 1500)).all(), f"first goals: {first.tolist()}"
    last = learner.metrics.curve()[-2:].sum(0)
    assert (last[:4] >= 80).all(), f"goals in the last 2000 steps per seed: {last[:4].tolist()}"
    assert (last[4:] < 20).all(), f"farmed runs still reach the goal: {last[4:].tolist()}"
    # Its values are far above anything real (V* ≤ 1 everywhere), the cycle-safe ones are not.
    values = learner.views.state_values()
    assert (values[4:].max(1).values > 2).all() and (values[:4].max() <= 1.0)


def test_salience_refit_replaces_the_previous_fit():
    """A refit on a mentor that never moves leaves no arrivals from the earlier fit."""
    from himit_torch import (
        Demonstrations,
        MultiRooms,
        SalienceReward,
        mentor_options,
        mentor_policy,
        record_demonstrations,
    )

    world = MultiRooms(8, 2)
    demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 2, seed=0)
    module = SalienceReward(world, demos)
    assert float(module.salience_map().abs().sum()) > 0
    still = Demonstrations([torch.tensor([world.start_state])], world)
    module.fit(still)
    assert float(module.salience_map().abs().sum()) == 0.0


def test_zero_reward_and_modules_by_name(world8, demos8):
    from himit_torch.mentor.reward import MENTOR_REWARDS, ZeroReward, mentor_reward_module

    src, dst = demos8.transitions()
    zero = mentor_reward_module("none", world8)
    assert isinstance(zero, ZeroReward) and zero.upper_bound == 0.0
    r = zero.transition_reward(src, dst)
    assert r.shape == src.shape and r.dtype == torch.float64 and bool((r == 0).all())
    known = mentor_reward_module("known", world8)
    assert torch.equal(known.transition_reward(src, dst), world8.state_reward.double()[dst])
    salience = mentor_reward_module("salience", world8, demos8)
    assert salience.fitted and salience.num_episodes == demos8.num_episodes
    with pytest.raises(ValueError, match="demonstrations"):
        mentor_reward_module("salience", world8)
    with pytest.raises(ValueError, match="unknown; use one of"):
        mentor_reward_module("extrinsic", world8)
    assert MENTOR_REWARDS == ("known", "salience", "none")
    # In a learner: the world's reward carries the goal's +1 back along the mentor's path;
    # r_m = 0 carries no reward at all, so no value rises above 0.
    values = {}
    for name in ("known", "none"):
        learner = Learner(
            world8,
            ht.learner_options(world8),
            ["imitation"],
            [0],
            reward=mentor_reward_module(name, world8, demos8),
        )
        learner.add_demonstrations(demos8)
        learner.plan()
        values[name] = learner.views.state_values()[0, world8.start_state]
    assert values["known"] > 0.5 and values["none"] <= 0.0
