"""The two engines carry out one algorithm: same seeds → the same decisions, goals and values.

The compiled engine follows the torch engine operation for operation, so equality is checked
exactly (values to 1e-9 is what is promised; bit-for-bit is what holds on a CPU).

Each parity run is about 1000 ticks. The fast suite runs one setting of each family (the first
of :data:`CONFIGS`, :data:`BCO_CONFIGS`, …); the others' 1000-tick runs are left to
``make test-all``, and every setting is checked by CI through its long run. A long run
(3000–5000 ticks, and the 40×40 world) is checked in two ways: under ``-m slow`` (CI) its last
300 ticks on both engines, the torch engine starting from the compiled engine's state
(:func:`fast_and_long`); under ``-m extended`` (``make test-all``) all its ticks on both engines
from tick 0."""

import numpy as np
import pytest
import scipy.stats
import torch

from himit_torch import (
    Learner,
    LearnerConfig,
    MultiRooms,
    Options,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)
from himit_torch.learner.engines import make_engine

pytest.importorskip("numba")

#: The fast suite's parity runs (about 1000 ticks), the long ones (marked slow), and the ticks
#: of a long run that CI checks on both engines (its late part, :func:`fast_and_long`).
FAST, LONG, LATE = 1000, 5000, 300


#: The marks that put a case in each tier: the fast suite, ``-m slow`` (CI), ``make test-all``.
TIERS = {
    "fast": (),
    "slow": (pytest.mark.slow,),
    "all": (pytest.mark.slow, pytest.mark.extended),
}


def fast_and_long(long: int = LONG, fast: str = "fast") -> list:
    """Tick counts to parametrize a parity run with: ``FAST``, in the tier ``fast`` names (a key
    of :data:`TIERS`); under ``-m slow`` (CI) the late part of a ``long`` run,
    ``("late", long)``: the compiled engine runs the first ``long − LATE`` ticks, hands its
    state to the torch engine, and both engines run the last ``LATE`` — the regime of grown
    edge lists, decayed ε and many goals, at a small part of the torch engine's cost (its late
    ticks cost ≈ 3× its first ones); and under ``-m extended`` (``make test-all``) all ``long``
    ticks on both engines from tick 0."""
    return [
        pytest.param(FAST, marks=TIERS[fast], id=f"{FAST}"),
        pytest.param(("late", long), marks=TIERS["slow"], id=f"late{long}"),
        pytest.param(long, marks=TIERS["all"], id=f"{long}"),
    ]


def settings_and_ticks(names, long: int = LONG) -> list:
    """``(name, ticks)`` for every setting in ``names`` and every tick count of
    :func:`fast_and_long`: the first setting's ``FAST`` run in the fast suite, the others' in
    ``make test-all`` (CI checks each through its late part)."""
    return [
        pytest.param(name, ticks.values[0], marks=ticks.marks, id=f"{name}-{ticks.id}")
        for i, name in enumerate(names)
        for ticks in fast_and_long(long, fast="fast" if i == 0 else "all")
    ]


def length(ticks) -> int:
    """The tick a parity run ends at (``ticks`` as :func:`fast_and_long` gives it)."""
    return ticks[1] if isinstance(ticks, tuple) else ticks


def advance(make, engine: str, ticks) -> Learner:
    """``make(engine)`` run to :func:`length` ``(ticks)``: from tick 0 on ``engine``, or for
    ``("late", n)`` on the torch engine, from the compiled engine's state at ``n − LATE`` (a
    ``state_dict``, as :func:`test_state_dict_moves_between_engines` checks)."""
    if isinstance(ticks, tuple) and engine == "torch":
        early = make("numba")
        early.run(length(ticks) - LATE)
        learner = make("torch")
        learner.load_state_dict(early.state_dict())
        learner.run(LATE)
        return learner
    learner = make(engine)
    learner.run(length(ticks))
    return learner


def both_engines(make, ticks) -> tuple[Learner, Learner]:
    """``(numba, torch)``: ``make(engine)`` advanced on each engine (:func:`advance`)."""
    return advance(make, "numba", ticks), advance(make, "torch", ticks)


AGENT_MIX = ["imitation", "options", "primitives", "imitation_confident", "imitation_primitives"]

CONFIGS = {
    "default": LearnerConfig(window=1000),
    "plan_every4_one_round": LearnerConfig(window=1000, plan_every=4, sweep_rounds=1),
    "plan_every3_rounds3": LearnerConfig(window=1000, plan_every=3, sweep_rounds=3, backups=7),
    "priors_override_first": LearnerConfig(
        window=1000,
        concentration=0.5,
        mentor_concentration=1.0,
        untried_value=0.0,
        mentor_override_after=4,
        tie_break="first",
        confidence_z=0.5,
    ),
    "match_optimistic": LearnerConfig(
        window=1000,
        mentor_choice="match",
        initial_value=0.0,
        untried_value=0.0,
        max_option_steps=30,
    ),
    # settings of issue 11's factorial studies
    "eps_step": LearnerConfig(window=1000, eps_schedule="step", eps_decay=0.9995),
    "eps_goals_fade": LearnerConfig(
        window=1000, eps_schedule="goals", eps_goals=3, mentor_fade=3.0
    ),
    "eps_paper_exact_models": LearnerConfig(
        window=1000,
        eps_schedule="paper",
        eps_decay=0.9,
        option_models="exact",
        exact_model_count=50.0,
    ),
}


def _state(learner: Learner) -> dict[str, torch.Tensor]:
    run, cache, sample = learner.run_state, learner.cache, learner.sample
    E, Em = learner.model.used, learner.mentor.used
    return {
        # posterior sampling (the …_psrl agents): the draws and how many were made
        "option_w": sample.option_w[:, :E],
        "option_unseen": sample.option_unseen,
        "mentor_w": sample.mentor_w[:, :Em],
        "mentor_unseen": sample.mentor_unseen,
        "resamples": sample.resamples,
        "position": run.position,
        "row": run.row,
        "decisions": run.decisions,
        "goals": run.goals,
        "first_goal_step": run.first_goal_step,
        "epsilon": run.epsilon,
        "backups_done": run.backups_done,
        "visits": run.visits,
        "values": cache.values,
        "q_numerator": cache.q_numerator,
        "q_second": cache.q_second,
        "mentor_numerator": cache.mentor_numerator,
        "priority": learner.sweeper.queue.priority,
        "row_count": learner.model.row_count,
        "state_tries": learner.model.state_tries,
    }


def assert_same_run(a: Learner, b: Learner, values_atol: float = 1e-9) -> None:
    """Same decisions and goals exactly; values and caches to ``values_atol``."""
    assert a.views.t == b.views.t
    sa, sb = _state(a), _state(b)
    for name in sa:
        if sa[name].dtype == torch.float64 and name != "epsilon":
            torch.testing.assert_close(
                sa[name],
                sb[name],
                atol=values_atol,
                rtol=0,
                msg=lambda m, name=name: f"{name}: {m}",
            )
        else:
            assert torch.equal(sa[name], sb[name]), name
    assert_same_metrics(a, b)
    for store_a, store_b in ((a.model, b.model), (a.mentor, b.mentor)):
        assert torch.equal(store_a.num_edges, store_b.num_edges)
        E = int(store_a.num_edges.max())
        for name in ("edge_row", "edge_successor", "edge_count"):
            assert torch.equal(getattr(store_a, name)[:, :E], getattr(store_b, name)[:, :E]), name


def assert_same_metrics(a: Learner, b: Learner) -> None:
    """Every per-window record the same (NaN where the other has NaN): the compiled engine
    closes its windows inside the kernel, the torch engine's are closed by ``Learner.run``."""
    ma, mb = a.metrics.state_dict(), b.metrics.state_dict()
    assert ma["steps"] == mb["steps"]
    for name, records in ma.items():
        if name != "steps" and records:
            torch.testing.assert_close(
                torch.stack(records), torch.stack(mb[name]), rtol=0, atol=0, equal_nan=True,
                msg=lambda m, name=name: f"metrics.{name}: {m}",
            )  # fmt: skip


@pytest.mark.parametrize("name, ticks", settings_and_ticks(CONFIGS))
def test_engines_agree_on_the_small_world(world12, mentor_demos12, name, ticks):
    """Every agent variant under every setting family: identical on both engines."""
    options = learner_options(world12)
    seeds = list(range(len(AGENT_MIX)))
    numba, torch_run = both_engines(
        lambda engine: Learner(
            world12,
            options,
            AGENT_MIX,
            seeds,
            config=CONFIGS[name],
            demonstrations=mentor_demos12,
            engine=engine,
        ),
        ticks,
    )
    runs = {"numba": numba, "torch": torch_run}
    assert_same_run(runs["numba"], runs["torch"])
    assert int(runs["numba"].views.decisions.min()) > 300
    # The edge lists outgrew their first capacity on the way (the compiled engine stops, grows
    # them and goes on); the 40×40 run checks the same at the paper's size (-m slow).
    assert runs["numba"].model.capacity > 256
    # (priors_override_first's first goal comes after 2000 ticks)
    if length(ticks) >= LONG or name != "priors_override_first":
        assert int(runs["numba"].views.goals.sum()) > 0


#: Mean-model and posterior-sampling runs in one batch (issue 9, part 2).
PSRL_MIX = [
    "imitation",
    "imitation_psrl",
    "options_psrl",
    "primitives_psrl",
    "imitation_primitives_psrl",
]
PSRL_CONFIGS = {
    "episodes": LearnerConfig(window=1000, plan_every=4, sweep_rounds=1),
    "priors_every7": LearnerConfig(
        window=1000,
        concentration=0.5,
        mentor_concentration=1.0,
        resample_every=7,
        mentor_fade=3.0,
    ),
}


# A draw every 7 decisions rebuilds every row's cache: the torch engine's eager ops make
# "priors_every7" the slowest parity case (≈ 30 ms a tick, 10 s for the fast run), so it is
# checked under -m slow (CI), and "episodes" keeps sampling in the fast suite.
@pytest.mark.parametrize("ticks", fast_and_long())
@pytest.mark.parametrize(
    "name", ["episodes", pytest.param("priors_every7", marks=pytest.mark.slow)]
)
def test_engines_agree_with_posterior_sampling(world12, mentor_demos12, name, ticks):
    """Mean and sampling runs together: the same draws (bit for bit), decisions, goals and
    values on both engines."""
    runs = both_engines(
        lambda engine: Learner(
            world12,
            learner_options(world12),
            PSRL_MIX,
            range(len(PSRL_MIX)),
            config=PSRL_CONFIGS[name],
            demonstrations=mentor_demos12,
            engine=engine,
        ),
        ticks,
    )
    assert_same_run(*runs)
    assert int(runs[0].sample.resamples[1:].max()) > length(ticks) // 250
    assert int(runs[0].views.goals[1:].sum()) > 0
    for name in ("option_w", "mentor_w"):
        assert torch.equal(_state(runs[0])[name], _state(runs[1])[name]), name


#: Potential-based shaping from the demonstrations (issue 26) beside its unshaped twins.
PBRS_MIX = ["pbrs", "pbrs_primitives", "options", "primitives", "imitation"]


@pytest.mark.parametrize(
    "name, ticks", settings_and_ticks(["default", "plan_every3_rounds3"], 3000)
)
def test_engines_agree_with_shaping(world12, mentor_demos12, name, ticks):
    """The ``pbrs`` agents (their V starts at v0 + Φ): identical on both engines."""
    runs = both_engines(
        lambda engine: Learner(
            world12,
            learner_options(world12),
            PBRS_MIX,
            range(len(PBRS_MIX)),
            config=CONFIGS[name],
            demonstrations=mentor_demos12,
            engine=engine,
        ),
        ticks,
    )
    assert_same_run(*runs)
    assert torch.equal(runs[0].cache.potential, runs[1].cache.potential)
    assert int((runs[0].cache.potential[:2] > 0).sum()) > 10  # the potential is there
    assert int(runs[0].views.decisions[:2].min()) > 300
    if length(ticks) >= 3000:
        assert int(runs[0].views.goals[:2].sum()) > 0


#: Behavioural cloning from observation (issue 26) beside the agents it is compared with.
BCO_MIX = ["bco", "primitives", "imitation", "bco", "options"]
BCO_CONFIGS = {
    "every150": LearnerConfig(window=1000, bco_every=150),
    "counts_every40_first": LearnerConfig(
        window=1000, bco_every=40, bco_inverse_model="counts", tie_break="first"
    ),
}


@pytest.mark.parametrize("name, ticks", settings_and_ticks(BCO_CONFIGS, 3000))
def test_engines_agree_with_behavioural_cloning(world12, mentor_demos12, name, ticks):
    """The ``bco`` agent (greedy choice = the cloned action where there is one, refitted every
    ``bco_every`` ticks between the engine's calls): identical on both engines."""
    runs = both_engines(
        lambda engine: Learner(
            world12,
            learner_options(world12),
            BCO_MIX,
            range(len(BCO_MIX)),
            config=BCO_CONFIGS[name],
            demonstrations=mentor_demos12,
            engine=engine,
        ),
        ticks,
    )
    assert_same_run(*runs)
    assert torch.equal(runs[0].cloning.action, runs[1].cloning.action)
    cloned = (runs[0].cloning.action >= 0).sum(1)
    assert int(cloned[0]) > 10 and int(cloned[3]) > 10  # the cloned policy is there
    assert int(cloned[[1, 2, 4]].sum()) == 0
    assert int(runs[0].views.decisions[[0, 3]].min()) == length(ticks)  # (one primitive per tick)


# (its fast run, ≈ 14 s on the torch engine, is CI's; the fast suite runs the sampling path in
# test_learner's test_stochastic_policy_options_run_match_and_draw)
@pytest.mark.parametrize("ticks", fast_and_long(3000, fast="slow"))
def test_engines_agree_with_stochastic_option_policies(world12, mentor_demos12, ticks):
    """Options with ``[O, S, A]`` policies go through the sampling path of both engines."""
    usable = world12.free_mask & ~world12.terminal_mask
    walk = Options.from_policy(
        usable,
        torch.full((world12.num_states, 4), 0.25),
        termination=torch.full((world12.num_states,), 0.5),
        name="random walk",
    )
    options = learner_options(world12) + walk
    config = LearnerConfig(window=1000, mentor_choice="match")
    runs = both_engines(
        lambda engine: Learner(
            world12,
            options,
            ["imitation", "options"],
            [0, 1],
            config=config,
            demonstrations=mentor_demos12,
            engine=engine,
        ),
        ticks,
    )
    assert_same_run(*runs)


@pytest.mark.slow
@pytest.mark.parametrize(
    "ticks",
    [("late", LONG), pytest.param(LONG, marks=pytest.mark.extended, id=f"{LONG}")],
    ids=lambda t: f"late{t[1]}" if isinstance(t, tuple) else None,
)
def test_engines_agree_on_the_paper_40x40_world(ticks):
    """Experiment 2's world and settings: the edge lists outgrow their first capacity on the way
    (the compiled engine stops, grows them and goes on)."""
    world = MultiRooms(40, 10)
    demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 20, seed=0)
    config = LearnerConfig(plan_every=4, sweep_rounds=1)
    runs = both_engines(
        lambda engine: Learner(
            world,
            learner_options(world),
            ["imitation", "options", "primitives"],
            [0, 1, 2],
            config=config,
            demonstrations=demos,
            engine=engine,
        ),
        ticks,
    )
    assert runs[0].model.capacity > 256  # grew at least once
    assert_same_run(*runs)


# The torch twin (9 s) under -m slow (CI); the fast suite checks the compiled engine, and the
# parity tests check that the torch engine equals it.
@pytest.mark.parametrize("ticks", fast_and_long(3000))
@pytest.mark.parametrize("engine", ["numba", pytest.param("torch", marks=pytest.mark.slow)])
def test_run_in_a_batch_equals_run_alone(world12, mentor_demos12, engine, ticks):
    """Run b inside a batch is bit for bit the same run alone, on each engine."""
    config = CONFIGS["plan_every3_rounds3"]
    options = learner_options(world12)
    agents = ["imitation_confident", "options", "imitation", "imitation_psrl", "options_psrl"]
    seeds = [11, 12, 13, 14, 15]
    batch = advance(
        lambda e: Learner(
            world12, options, agents, seeds, config=config, demonstrations=mentor_demos12, engine=e
        ),
        engine,
        ticks,
    )
    for b, (agent, seed) in enumerate(zip(agents, seeds)):
        alone = advance(
            lambda e, agent=agent, seed=seed: Learner(
                world12,
                options,
                [agent],
                [seed],
                config=config,
                demonstrations=mentor_demos12,
                engine=e,
            ),
            engine,
            ticks,
        )
        for name, value in _state(alone).items():
            mine = _state(batch)[name][b]
            if name in ("option_w", "mentor_w"):  # per-edge: as wide as the batch's fullest run
                k = int((alone.model if name == "option_w" else alone.mentor).num_edges[0])
                mine, value = mine[:k], value[:, :k]
            assert torch.equal(mine, value[0]), (b, name)


@pytest.mark.parametrize("third", [500, pytest.param(1500, marks=pytest.mark.slow, id="1500")])
def test_switching_engines_mid_run_changes_nothing(world12, mentor_demos12, third):
    """The state is shared: numba → torch → numba gives the run that one engine gives."""
    config = CONFIGS["plan_every4_one_round"]
    options = learner_options(world12)
    make = lambda: Learner(
        world12,
        options,
        AGENT_MIX,
        range(5),
        config=config,  # noqa: E731
        demonstrations=mentor_demos12,
        engine="numba",
    )
    straight, switched = make(), make()
    straight.run(3 * third)
    switched.run(third)
    switched.use_engine("torch")
    switched.run(third + 1)
    switched.use_engine("numba")
    switched.run(third - 1)
    assert switched.engine.name == "numba"
    assert_same_run(straight, switched, values_atol=0.0)


@pytest.mark.parametrize(
    "ticks", [500, pytest.param(3000, marks=[pytest.mark.slow, pytest.mark.extended], id="3000")]
)
def test_state_dict_moves_between_engines(world12, mentor_demos12, ticks):
    """A checkpoint of a numba run resumes on the torch engine to the same run."""
    config = CONFIGS["default"]
    options = learner_options(world12)
    make = lambda engine: Learner(
        world12,
        options,
        AGENT_MIX,
        range(5),
        config=config,  # noqa: E731
        demonstrations=mentor_demos12,
        engine=engine,
    )
    straight, first = make("numba"), make("numba")
    straight.run(ticks)
    first.run(ticks * 2 // 5)
    second = make("torch")
    second.load_state_dict(first.state_dict())
    second.run(ticks - ticks * 2 // 5)
    assert_same_run(straight, second)


def test_engine_choice_is_explained():
    class CorridorWorld:  # the TabularWorld protocol without a dynamics table
        num_states, num_actions, start_state, gamma = 3, 2, 0, 0.9
        terminal_mask = torch.tensor([False, False, True])

        def step(self, positions, actions, uniforms):
            nxt = (positions + torch.where(actions == 1, 1, -1)).clamp(0, 2)
            return nxt, torch.where(nxt == 2, 1.0, -0.1).double()

    options = Options(
        initiation=torch.tensor([[True, True, False]] * 2),
        termination=torch.ones(2, 3),
        policy=torch.tensor([[0] * 3, [1] * 3]),
        names=("left", "right"),
        kinds=("primitive", "primitive"),
    )
    learner = Learner(CorridorWorld(), options, ["options"], [0])
    assert learner.engine.name == "torch"  # auto: no table, so the torch engine
    with pytest.raises(ValueError, match="dynamics_table"):
        Learner(CorridorWorld(), options, ["options"], [0], engine="numba")
    with pytest.raises(ValueError, match="engine='fast'"):
        make_engine("fast", learner)
    world = MultiRooms(8, 2)
    assert Learner(world, learner_options(world), ["options"], [0]).engine.name == "numba"


@pytest.mark.slow
@pytest.mark.statistical
@pytest.mark.timeout(3600)
def test_engine_curves_agree_statistically_over_20_seeds():
    """Experiment 2 (40×40), 20 seeds × 3 agents, 30k steps: per agent, the goals of the two
    engines' runs come from one distribution (two-sample KS test) — and in fact are equal."""
    world = MultiRooms(40, 10)
    demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 20, seed=0)
    config = LearnerConfig(plan_every=4, sweep_rounds=1)
    agents = ["imitation", "options", "primitives"] * 20
    seeds = [s for s in range(20) for _ in range(3)]
    totals = {}
    for engine in ("numba", "torch"):
        learner = Learner(
            world,
            learner_options(world),
            agents,
            seeds,
            config=config,
            demonstrations=demos,
            engine=engine,
        )
        learner.run(30_000)
        totals[engine] = learner.views.goals.numpy()
    for k in range(3):
        a, b = totals["numba"][k::3], totals["torch"][k::3]
        assert scipy.stats.ks_2samp(a, b).pvalue > 0.05
    np.testing.assert_array_equal(totals["numba"], totals["torch"])


def test_mentor_win_share_is_the_same_from_either_engine(world12, mentor_demos12):
    """The compiled count of states where the mentor term wins equals the batched one."""
    learner = Learner(
        world12,
        learner_options(world12),
        AGENT_MIX,
        range(5),
        config=CONFIGS["priors_override_first"],
        demonstrations=mentor_demos12,
    )
    learner.run(2000)
    compiled = learner.views.mentor_win_share()
    learner.use_engine("torch")
    batched = learner.views.mentor_win_share()
    assert torch.equal(compiled.isnan(), ~learner.rows.use_mentor)
    torch.testing.assert_close(compiled, batched, equal_nan=True, rtol=0, atol=0)
    assert float(compiled.nan_to_num(0).max()) > 0


# (its fast run, ≈ 20 s on the torch engine, is CI's)
@pytest.mark.parametrize("ticks", fast_and_long(3000, fast="slow"))
def test_engines_agree_with_the_exact_mentor_model(world12, ticks):
    """The mentor's exact transition model (fractional counts) on both engines: the same run."""
    from himit_torch import exact_mentor_transitions

    exact = exact_mentor_transitions(world12, mentor_policy(world12, mentor_options(world12)), 5.0)
    runs = both_engines(
        lambda engine: Learner(
            world12,
            learner_options(world12),
            AGENT_MIX,
            range(5),
            config=CONFIGS["default"],
            demonstrations=exact,
            engine=engine,
        ),
        ticks,
    )
    assert_same_run(*runs)
    assert int(runs[0].views.goals.sum()) > 0
