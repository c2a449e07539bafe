"""The Gymnasium adapter against Gymnasium's own ``step``, and worlds with rewards per
transition, start distributions and per-transition termination."""

import gymnasium
import numpy as np
import pytest
import torch
from scipy import stats

import himit_torch as ht
from himit_torch.options.taxi import taxi_navigation_options
from himit_torch.worlds.gymnasium import from_gymnasium
from himit_torch.worlds.table_world import TableWorld, transition_support, world_model
from himit_torch.worlds.tabular import DynamicsTable

ENVS = {
    "taxi": ("Taxi-v4", {}),
    "cliff": ("CliffWalking-v1", {}),
    "frozen8": ("FrozenLake-v1", {"map_name": "8x8", "is_slippery": True}),
}


@pytest.fixture(scope="module")
def worlds():
    return {k: from_gymnasium(i, **kw) for k, (i, kw) in ENVS.items()}


def raw_env(key, seed=0):
    env_id, kwargs = ENVS[key]
    env = gymnasium.make(env_id, **kwargs).unwrapped
    env.reset(seed=seed)
    return env


def gym_outcomes(env, s, a):
    """Gymnasium's own model of ``(s, a)``: successor → (probability, reward, terminated)."""
    out = {}
    for p, t, r, term in env.P[s][a]:
        if p > 0:
            q, r0, t0 = out.get(t, (0.0, r, term))
            assert (r0, t0) == (r, term) or t not in out  # one reward per successor here
            out[t] = (q + p, r, term)
    return out


# ------------------------------------------------------------------------------- the model
def reachable(world) -> torch.Tensor:
    """``[S]`` bool: states an episode can visit (from the starts, through non-terminal states)."""
    support = transition_support(world)
    seen = world.start_distribution > 0
    while True:
        grown = seen | support[seen].any(0)
        if torch.equal(grown, seen):
            return seen
        seen = grown


@pytest.mark.parametrize("key", ENVS)
def test_every_deterministic_transition_equals_gymnasiums_step(worlds, key):
    """Successor and reward of every deterministic ``(s, a)`` — all states, as the table keeps
    ``P`` whole — and termination on the states an episode can visit (Taxi's states with the
    passenger at its destination but the taxi elsewhere come only after a delivery)."""
    world, env = worlds[key], raw_env(key)
    terminal, visitable = world.terminal_mask, reachable(world)
    checked = flags = 0
    for s in range(world.num_states):
        for a in range(world.num_actions):
            if len(gym_outcomes(env, s, a)) != 1:
                continue
            env.s = s
            nxt, reward, term, _, _ = env.step(a)
            for u in (0.0, 0.5, 0.999):
                got, r = world.step(torch.tensor([s]), torch.tensor([a]), torch.tensor([u]))
                assert (int(got), float(r)) == (nxt, reward), (key, s, a, u)
            checked += 1
            if visitable[s] and not terminal[s]:
                assert bool(terminal[nxt]) == term, (key, s, a)
                flags += 1
    assert (checked, flags) == {"taxi": (3000, 2400), "cliff": (192, 148), "frozen8": (44, 0)}[key]


@pytest.mark.parametrize("key", ["frozen8", "cliff"])
def test_same_uniforms_give_gymnasiums_transitions(worlds, key):
    """Gymnasium draws one ``np_random.random()`` per step and takes the first outcome whose
    cumulative probability exceeds it — the DynamicsTable rule — so with the same uniforms the
    adapter makes exactly Gymnasium's transitions."""
    world = worlds[key] if key == "frozen8" else from_gymnasium("CliffWalking-v1", is_slippery=True)
    env = (
        raw_env(key)
        if key == "frozen8"
        else gymnasium.make("CliffWalking-v1", is_slippery=True).unwrapped
    )
    env.reset(seed=0)
    env.np_random = np.random.default_rng(11)
    uniforms = np.random.default_rng(11)
    pick = np.random.default_rng(3)
    live = np.flatnonzero(~world.terminal_mask.numpy())
    states = pick.choice(live, 3000)
    actions = pick.integers(0, world.num_actions, 3000)
    gym_next, gym_reward, u = [], [], []
    for s, a in zip(states, actions):
        env.s = int(s)
        nxt, r, _, _, _ = env.step(int(a))
        gym_next.append(nxt)
        gym_reward.append(r)
        u.append(uniforms.random())
    got, rewards = world.step(
        torch.from_numpy(states), torch.from_numpy(actions), torch.tensor(u, dtype=torch.float64)
    )
    assert got.tolist() == gym_next
    assert rewards.tolist() == [float(r) for r in gym_reward]
    assert len(set(zip(states.tolist(), actions.tolist(), got.tolist()))) > 400  # stochastic


def test_successor_distribution_matches_gymnasium_statistically(worlds):
    """FrozenLake 8×8 slippery: the table's probabilities are P's (exactly), and samples of the
    adapter's step and of Gymnasium's step agree (χ² homogeneity over every stochastic pair)."""
    world, env = worlds["frozen8"], raw_env("frozen8", seed=5)
    table = world.dynamics_table()
    prob = torch.diff(table.cdf, dim=-1, prepend=torch.zeros_like(table.cdf[..., :1]))
    gen = torch.Generator().manual_seed(0)
    chi2, dof, n = 0.0, 0, 200
    for s in np.flatnonzero(~world.terminal_mask.numpy()):
        for a in range(4):
            truth = gym_outcomes(env, int(s), a)
            mine = {}
            for k in range(table.successors.shape[2]):
                t = int(table.successors[s, a, k])
                mine[t] = mine.get(t, 0.0) + float(prob[s, a, k])
            mine = {t: p for t, p in mine.items() if p > 0}
            assert mine.keys() == truth.keys()
            for t, (p, _r, _) in truth.items():
                assert mine[t] == pytest.approx(p, abs=1e-12)
            got, _ = world.step(
                torch.full((n,), int(s)),
                torch.full((n,), a),
                torch.rand(n, generator=gen, dtype=torch.float64),
            )
            theirs = []
            for _ in range(n):
                env.s = int(s)
                theirs.append(env.step(a)[0])
            succ = sorted(truth)
            if len(succ) < 2:
                continue
            table_counts = np.array(
                [[int((got == t).sum()) for t in succ], [theirs.count(t) for t in succ]]
            )
            keep = table_counts.sum(0) > 0
            c, _, d, _ = stats.chi2_contingency(table_counts[:, keep], correction=False)
            chi2, dof = chi2 + c, dof + d
    assert dof > 100
    assert stats.chi2.sf(chi2, dof) > 1e-3, (chi2, dof)


def test_start_distribution_terminal_and_goal_states(worlds):
    taxi, cliff, frozen = worlds["taxi"], worlds["cliff"], worlds["frozen8"]
    env = raw_env("taxi")
    assert torch.equal(taxi.start_distribution, torch.from_numpy(env.initial_state_distrib))
    assert int((taxi.start_distribution > 0).sum()) == 300
    # Taxi ends on a delivery: the taxi, the passenger and the destination at one landmark.
    delivered = [env.encode(*loc, i, i) for i, loc in enumerate(env.locs)]
    assert taxi.terminal_mask.nonzero()[:, 0].tolist() == sorted(delivered)
    assert torch.equal(taxi.goal_mask, taxi.terminal_mask)
    assert cliff.terminal_mask.nonzero()[:, 0].tolist() == [47] and cliff.start_state == 36
    holes = np.flatnonzero(raw_env("frozen8").desc.ravel() == b"H").tolist()
    assert frozen.terminal_mask.nonzero()[:, 0].tolist() == sorted(holes + [63])
    assert frozen.goal_mask.nonzero()[:, 0].tolist() == [63]  # holes are not goals
    # rewards for entering a state: only where that is the whole reward
    assert taxi.state_reward is None and cliff.state_reward is None
    assert frozen.state_reward[63] == 1.0 and float(frozen.state_reward[:63].abs().sum()) == 0.0


def test_true_model_value_iteration_and_option_models(worlds):
    """CliffWalking's optimum is the 13-step path along the cliff: V* = −Σ_{k<13} γ^k; terminal
    states are absorbing at 0 in the true model."""
    cliff = worlds["cliff"]
    P, R = world_model(cliff)
    plan = ht.value_iteration(P, R, cliff.gamma)
    g = cliff.gamma
    assert float(plan.values[36]) == pytest.approx(-(1 - g**13) / (1 - g), abs=1e-8)
    dense = cliff.transition_model(sparse=False)
    assert torch.allclose(dense.sum(-1), torch.ones(4, 48, dtype=torch.float64))
    assert float(dense[:, 47, 47].min()) == 1.0 and float(cliff.reward_model()[47].abs().max()) == 0
    # the exact option model of a subgoal option: "to top-right" from the start takes 14 steps
    opts = ht.subgoal_options(cliff, {"to (0,11)": torch.arange(48) == 11})
    dur = ht.option_durations(cliff, opts)
    row = int(((dur.row_state == 36) & (dur.row_option == 0)).nonzero()[0, 0])
    assert float(dur.reward[row]) == pytest.approx(14.0)
    assert dur.transition.to_dense()[row, 11] == pytest.approx(1.0)


def test_taxi_navigation_options_drive_by_shortest_paths(worlds):
    taxi = worlds["taxi"]
    env = raw_env("taxi")
    nav = taxi_navigation_options(taxi)
    assert nav.names == ("drive to R", "drive to G", "drive to Y", "drive to B")
    assert set(nav.kinds) == {"subgoal"}
    assert int(nav.policy.max()) <= 3  # moves only; pickup/dropoff stay primitive
    dur = ht.option_durations(taxi, nav)
    # from (row 4, col 4): to R (0, 0) the taxi goes up to row 0 then west past the walls: 8 steps
    s = env.encode(4, 4, 0, 1)
    row = int(((dur.row_state == s) & (dur.row_option == 0)).nonzero()[0, 0])
    assert float(dur.reward[row]) == pytest.approx(8.0)
    target = env.encode(0, 0, 0, 1)
    assert float(dur.transition.to_dense()[row, target]) == pytest.approx(1.0)
    # not usable where the taxi already is at the landmark, nor in terminal states
    assert not bool(nav.initiation[0, target]) and not bool(
        (nav.initiation & taxi.terminal_mask).any()
    )


# ------------------------------------------------------------------------------- refusals
class TinyEnv(gymnasium.Env):
    """A two-state Gymnasium env with a tabular model, for the refusals."""

    def __init__(self, P, observation_space=None):
        self.observation_space = observation_space or gymnasium.spaces.Discrete(3)
        self.action_space = gymnasium.spaces.Discrete(2)
        if P is not None:
            self.P = P
        self.initial_state_distrib = np.array([1.0, 0.0, 0.0])


def test_termination_per_transition_is_refused_and_terminal_states_can_be_given():
    # 0 -a0-> 1 ends the episode, 0 -a1-> 1 does not: not expressible as terminal states.
    P = {
        0: {0: [(1.0, 1, 1.0, True)], 1: [(1.0, 1, 0.0, False)]},
        1: {0: [(1.0, 2, 0.0, False)], 1: [(1.0, 2, 0.0, False)]},
        2: {0: [(1.0, 2, 0.0, True)], 1: [(1.0, 2, 0.0, True)]},
    }
    with pytest.raises(
        ValueError,
        match=r"per transition.*0 -\(0\)-> 1 ends the episode but "
        r"0 -\(1\)-> 1.*terminal_states=",
    ):
        from_gymnasium(TinyEnv(P))
    world = from_gymnasium(TinyEnv(P), terminal_states=[2])
    assert world.terminal_mask.tolist() == [False, False, True]


@pytest.mark.parametrize(
    "env, match",
    [
        (TinyEnv(None), "has no tabular model"),
        (TinyEnv({0: {0: [(1.0, 0, 0.0, False)]}}), r"P\[0\]\[a\] is missing"),
        (
            TinyEnv({s: {a: [(0.5, 0, 0.0, False)] for a in range(2)} for s in range(3)}),
            "sum to 0.5",
        ),
        (
            TinyEnv({s: {a: [(1.0, 7, 0.0, False)] for a in range(2)} for s in range(3)}),
            "outside 0…2",
        ),
        (TinyEnv({s: {a: [(1.0, 0, 0.0)] for a in range(2)} for s in range(3)}), "entries must be"),
        (TinyEnv(None, gymnasium.spaces.Box(0, 1, (2,))), "Discrete observation and action spaces"),
    ],
)
def test_environments_without_a_usable_model_are_refused(env, match):
    with pytest.raises(ValueError, match=match):
        from_gymnasium(env)


def test_other_refusals():
    with pytest.raises(ValueError, match="Discrete"):
        from_gymnasium("CartPole-v1")
    with pytest.raises(ValueError, match="fickle_passenger"):
        from_gymnasium("Taxi-v4", fickle_passenger=True)
    with pytest.raises(ValueError, match="need an environment id"):
        from_gymnasium(gymnasium.make("Taxi-v4"), is_rainy=True)


def test_description_identifies_the_world(worlds):
    frozen = worlds["frozen8"]
    d = frozen.describe()
    assert (d["kind"], d["id"], d["kwargs"]) == (
        "gymnasium",
        "FrozenLake-v1",
        {"map_name": "8x8", "is_slippery": True},
    )
    assert (
        d
        == from_gymnasium(
            gymnasium.make("FrozenLake-v1", map_name="8x8", is_slippery=True)
        ).describe()
    )
    # the kwargs as given: the defaults left out describe the same model, but not the same way
    default = from_gymnasium("FrozenLake-v1", map_name="8x8").describe()
    assert default["kwargs"] == {"map_name": "8x8"} and default["fingerprint"] == d["fingerprint"]
    assert (
        d["fingerprint"]
        != from_gymnasium("FrozenLake-v1", map_name="8x8", is_slippery=False).describe()[
            "fingerprint"
        ]
    )


# ------------------------------------------------------------------- rewards per transition
def tiny_world(start=None) -> TableWorld:
    """States 0, 1, 2 (terminal), 3. From 0 both actions lead to 1, paying −1 (a0) or −5 (a1):
    the reward of 0 → 1 depends on the unseen action. From 1 both lead to 2 paying +10. From 3
    both lead to 0 paying 0. Start: state 3 (or ``start``)."""
    succ = torch.tensor([[[1], [1]], [[2], [2]], [[2], [2]], [[0], [0]]])
    rewards = torch.tensor(
        [[[-1.0], [-5.0]], [[10.0], [10.0]], [[0.0], [0.0]], [[0.0], [0.0]]], dtype=torch.float64
    )
    table = DynamicsTable(succ, torch.ones(4, 2, 1, dtype=torch.float64), rewards)
    start = torch.tensor([0.0, 0.0, 0.0, 1.0]) if start is None else start
    return TableWorld(table, start, torch.tensor([False, False, True, False]), gamma=0.9)


def test_known_reward_of_transitions_takes_the_least_where_the_action_matters():
    world = tiny_world()
    assert world.state_reward is None
    known = ht.KnownReward(world)
    assert known.ambiguous_pairs == 1 and "least reward" in known.note and "1 of 3" in repr(known)
    r = known.transition_reward(torch.tensor([0, 1, 3]), torch.tensor([1, 2, 0]))
    assert r.tolist() == [-5.0, 10.0, 0.0]
    assert known.upper_bound == 10.0
    with pytest.raises(ValueError, match="mentor move 0 → 2 is impossible"):
        known.transition_reward(torch.tensor([0]), torch.tensor([2]))


def test_transition_rewards_in_the_mentor_term_by_hand():
    """Mentor states 3 → 0 → 1 → 2, no own experience: the mentor term alone gives
    V(1) = 10, V(0) = −5 + 0.9·10 = 4 (the least reward of 0 → 1), V(3) = 0 + 0.9·4 = 3.6."""
    world = tiny_world()
    demos = ht.Demonstrations([[3, 0, 1, 2]], world)
    options = ht.primitive_options(world)
    learner = ht.Learner(
        world, options, ["imitation"], [0], demonstrations=demos, reward=ht.KnownReward(world)
    )
    learner.plan()
    v = learner.views.state_values()[0]
    assert v[[1, 0, 3]].tolist() == pytest.approx([10.0, 4.0, 3.6])
    assert float(v[2]) == 0.0


# ------------------------------------------------------------------- start distributions
def test_learner_starts_are_drawn_per_run_and_reproducible():
    """Every step of ``tiny_world`` from 1 ends the episode and 3 → 0 → 1 never does; with a
    start distribution over {0, 1, 3} each episode starts at a fresh draw from lane 5 of the
    run's own stream: the same seed gives the same starts, in any batch, and the starts follow
    the distribution."""
    start = torch.tensor([0.2, 0.5, 0.0, 0.3], dtype=torch.float64)
    world = tiny_world(start)
    options = ht.primitive_options(world)

    def starts(seeds, steps=300):
        learner = ht.Learner(
            world,
            options,
            ["primitives"] * len(seeds),
            seeds,
            config=ht.LearnerConfig(window=steps),
        )
        firsts, restarts = learner.run_state.position.clone(), []
        for _ in range(steps):
            learner.step()
            restarts.append(learner.run_state.position.clone())
        return firsts, torch.stack(restarts, 1)

    firsts, path = starts([0, 1, 0, 2])
    assert firsts[0] == firsts[2] and torch.equal(path[0], path[2])
    alone_first, alone_path = starts([1])
    assert torch.equal(alone_path[0], path[1]) and alone_first[0] == firsts[1]
    assert not torch.equal(path[0], path[1])
    # After a goal (arrival at 2) the run restarts: those positions are the drawn starts.
    seen = torch.cat([path[b][1:][path[b][:-1] == 1] for b in range(4)])
    counts = torch.bincount(seen, minlength=4).double()
    assert counts[2] == 0 and counts.sum() > 500
    expected = start * counts.sum()
    chi2 = float(((counts - expected)[[0, 1, 3]] ** 2 / expected[[0, 1, 3]]).sum())
    assert stats.chi2.sf(chi2, 2) > 1e-3, counts
    many = ht.Learner(world, options, ["primitives"] * 400, list(range(400))).run_state.position
    assert set(many.tolist()) == {0, 1, 3}


def test_mentor_episodes_start_from_the_distribution(worlds):
    taxi = worlds["taxi"]
    mentor = ht.mentor_policy(taxi, ht.primitive_options(taxi))
    a = ht.run_mentor(taxi, mentor, 40, seed=3)
    b = ht.run_mentor(taxi, mentor, 40, seed=3)
    firsts = [int(e[0]) for e in a.states]
    assert firsts == [int(e[0]) for e in b.states] and len(set(firsts)) > 20
    assert all(taxi.start_distribution[s] > 0 for s in firsts)
    assert all(bool(taxi.goal_mask[int(e[-1])]) for e in a.states)  # every episode delivers


def test_transition_support(worlds):
    support = transition_support(worlds["cliff"])
    assert support[36].nonzero()[:, 0].tolist() == [
        24,
        36,
    ]  # up, or stay (down/left bump, the cliff)
    assert not bool(support[47].any())  # nothing leaves the terminal state


def test_table_world_validates_its_parts():
    world = tiny_world()
    table = world.dynamics_table()
    terminal = world.terminal_mask
    with pytest.raises(ValueError, match="weight on terminal states"):
        TableWorld(table, torch.tensor([0.0, 0.0, 1.0, 0.0]), terminal)
    with pytest.raises(ValueError, match="summing to 1"):
        TableWorld(table, torch.tensor([0.5, 0.0, 0.0, 0.0]), terminal)
    with pytest.raises(ValueError, match=r"terminal_mask must be a \[S\] = \[4\] bool"):
        TableWorld(table, world.start_distribution, torch.tensor([0, 0, 1, 0]))
    with pytest.raises(ValueError, match="must be a DynamicsTable"):
        TableWorld("table", world.start_distribution, terminal)
    # the description hashes the model: another start distribution is another world
    other = tiny_world(torch.tensor([1.0, 0.0, 0.0, 0.0]))
    assert world.describe()["kind"] == "TableWorld"
    assert world.describe()["fingerprint"] != other.describe()["fingerprint"]
    assert world.start_state == 3 and other.start_state == 0
