"""The learner's settings (LearnerConfig): their checks, and what each setting of the factorial
studies (issue 11) does: ε schedules, the mentor's exact transition model, exact option models, the
mentor fade. Engine parity of each is in tests/learner/engines/test_parity.py."""

import math

import pytest
import torch

from himit_torch import (
    Learner,
    LearnerConfig,
    exact_mentor_transitions,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)
from himit_torch.exact.option_models import option_models
from himit_torch.runs.config import ExperimentConfig


@pytest.mark.parametrize(
    "field, value, allowed",
    [
        ("eps_schedule", "linear", "decision"),
        ("eps_goals", 0, "≥ 1"),
        ("option_models", "given", "exact"),
        ("exact_model_count", 0.0, "> 0"),
    ],
)
def test_learner_settings_are_checked(field, value, allowed):
    with pytest.raises(ValueError, match=f"LearnerConfig.{field}=.*{allowed}"):
        LearnerConfig(**{field: value})


def test_mentor_model_is_checked():
    with pytest.raises(ValueError, match="ExperimentConfig.mentor_model='counts'.*'exact'"):
        ExperimentConfig(mentor_model="counts")


def _run(
    world,
    config,
    steps,
    engine="numba",
    agents=("options", "primitives", "imitation"),
    demonstrations=None,
):
    learner = Learner(
        world,
        learner_options(world),
        list(agents),
        range(len(agents)),
        config=config,
        demonstrations=demonstrations,
        engine=engine,
    )
    learner.run(steps)
    return learner


@pytest.mark.parametrize("engine", ["numba"])  # the torch engine: parity, engines/test_parity.py
def test_goals_schedule_explores_until_n_goals_then_drops_to_the_floor(world8, engine):
    config = LearnerConfig(window=500, eps_schedule="goals", eps_goals=4, eps_min=0.05)
    learner = _run(world8, config, 3000, engine)
    goals, eps = learner.views.goals, learner.views.epsilon
    assert bool((goals >= 4).any())
    expected = torch.where(
        goals >= 4, torch.tensor(0.05, dtype=torch.float64), torch.tensor(0.75, dtype=torch.float64)
    )
    assert torch.equal(eps, expected)


@pytest.mark.parametrize("engine", ["numba"])  # the torch engine: parity, engines/test_parity.py
def test_paper_schedule_decays_once_per_goal(world8, engine):
    config = LearnerConfig(window=500, eps_schedule="paper", eps_decay=0.9, eps_min=0.01)
    learner = _run(world8, config, 2000, engine)
    for g, e in zip(learner.views.goals.tolist(), learner.views.epsilon.tolist()):
        assert e == pytest.approx(max(0.75 * 0.9**g, 0.01), rel=1e-12)
    assert int(learner.views.goals.max()) > 0


@pytest.mark.parametrize("engine", ["numba"])  # the torch engine: parity, engines/test_parity.py
def test_step_schedule_decays_once_per_step_from_the_first_goal(world8, engine):
    config = LearnerConfig(window=500, eps_schedule="step", eps_decay=0.999, eps_min=0.001)
    learner = _run(world8, config, 2000, engine)
    for first, e in zip(learner.views.first_goal_step.tolist(), learner.views.epsilon.tolist()):
        # decayed at the first goal's step and every step after it
        steps = 0 if first < 0 else learner.views.t - first + 1
        assert e == pytest.approx(max(0.75 * 0.999**steps, 0.001), rel=1e-9)
    assert int((learner.views.first_goal_step >= 0).sum()) > 0


def test_decision_schedule_is_todays_default(world8):
    """The default is the per-decision rule: ε = 0.75 · 0.999^(decisions after the first goal)."""
    learner = _run(world8, LearnerConfig(window=500), 1500, agents=("primitives",))
    assert learner.config.eps_schedule == "decision"
    assert float(learner.views.epsilon[0]) < 0.75 * 0.999**10 and int(learner.views.goals[0]) > 0


def test_exact_mentor_model_matches_many_demonstrations(world8):
    """Expected counts per episode and p_m(s'|s) agree with 3000 recorded episodes."""
    mentor = mentor_policy(world8, mentor_options(world8))
    exact = exact_mentor_transitions(world8, mentor, 1.0)
    demos = record_demonstrations(world8, mentor, 3000, seed=1)
    src, dst = demos.transitions()
    S = world8.num_states
    seen = (
        torch.zeros(S, S, dtype=torch.float64).index_put_(
            (src, dst), torch.ones(len(src), dtype=torch.float64), accumulate=True
        )
        / 3000
    )
    model = torch.zeros(S, S, dtype=torch.float64)
    model[exact.sources, exact.successors] = exact.counts
    # expected steps per episode: the sum of all expected counts
    assert float(model.sum()) == pytest.approx(float(seen.sum()), rel=0.03)
    busy = seen.sum(1) > 0.5  # states the mentor passes about every other episode
    p_seen = seen[busy] / seen[busy].sum(1, keepdim=True)
    p_model = model[busy] / model[busy].sum(1, keepdim=True)
    assert float((p_seen - p_model).abs().max()) < 0.05
    # every transition ever seen is possible under the exact model
    assert bool((model[seen > 0] > 0).all())
    assert float(exact_mentor_transitions(world8, mentor, 20.0).counts.sum()) == pytest.approx(
        20 * float(model.sum())
    )


def test_exact_mentor_counts_go_into_the_mentor_model(world8):
    mentor = mentor_policy(world8, mentor_options(world8))
    exact = exact_mentor_transitions(world8, mentor, 20.0)
    learner = Learner(world8, learner_options(world8), ["imitation"], [0], demonstrations=exact)
    total = learner.mentor.row_count[0, : world8.num_states]
    expected = torch.zeros(world8.num_states, dtype=torch.float64).index_add_(
        0, exact.sources, exact.counts
    )
    torch.testing.assert_close(total, expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="counts"):
        bad = type(
            "Bad",
            (),
            {
                "transitions": lambda self: (exact.sources, exact.successors),
                "counts": -exact.counts,
            },
        )()
        learner.add_demonstrations(bad)


def test_exact_option_models_give_the_exact_option_values(world8):
    """Preloaded rows: Q = r(s,o) + Σ P^o V for the initial V, for every enabled row; disabled
    rows (options for the primitives-only run) are left untried; the queue holds exactly the
    states whose backup changes V."""
    options = learner_options(world8)
    learner = Learner(
        world8,
        options,
        ["options", "primitives"],
        [0, 1],
        config=LearnerConfig(option_models="exact", exact_model_count=1e6),
    )
    exact = option_models(world8, options)
    v = torch.full((world8.num_states,), -1.0, dtype=torch.float64)
    v[world8.terminal_mask] = 0.0
    O = options.num_options
    key = learner.rows.row_state[:-1] * O + learner.rows.row_option[:-1]
    order = torch.argsort(key)
    rows = order[torch.searchsorted(key[order], exact.row_state * O + exact.row_option)]
    q = learner.cache.row_q(torch.zeros_like(rows), rows)
    torch.testing.assert_close(q, exact.q_values(v), rtol=0, atol=1e-12)
    enabled = learner.rows.row_enabled[1, rows]
    assert bool((learner.model.row_count[1, rows[~enabled]] == 0).all())
    assert bool((learner.model.row_count[1, rows[enabled]] == 1e6).all())
    assert not bool(learner.model.state_tries.any())
    queued = learner.sweeper.queue.priority[0, : world8.num_states] > 0
    best, has_value, _ = learner.cache.state_backup(
        torch.zeros(1, 1, dtype=torch.int64), torch.arange(world8.num_states)[None]
    )
    changes = has_value[0] & ((best[0] - v).abs() > learner.config.priority_threshold)
    assert torch.equal(queued, changes) and bool(changes.any())


def test_exact_option_models_plan_to_the_optimum(world8):
    """With exact models and exhaustive planning the options run's V(start) is the optimal SMDP
    value of its options."""
    from himit_torch.exact.planning import smdp_value_iteration

    options = learner_options(world8)
    learner = Learner(
        world8,
        options,
        ["options"],
        [0],
        config=LearnerConfig(option_models="exact", exact_model_count=1e9),
    )
    learner.plan()
    optimum = smdp_value_iteration(option_models(world8, options)).values
    start = world8.start_state
    assert float(learner.views.state_values()[0, start]) == pytest.approx(
        float(optimum[start]), abs=1e-4
    )
    assert not math.isclose(float(optimum[start]), -1.0)


def test_mentor_fade_mixes_the_mentor_term_with_own_experience(world8):
    """Eq. 2 with mentor_fade = k at each mentor state: max(own, (k·m + n·own) / (k + n)) where
    own options were tried (n own executions), m itself where none was; and the diagnostics
    report the raw margin m − own."""
    from himit_torch.mentor.diagnostics import mentor_margin_summary, mentor_margins

    mentor = mentor_policy(world8, mentor_options(world8))
    demos = record_demonstrations(world8, mentor, 5, seed=0)
    learner = _run(
        world8,
        LearnerConfig(window=500, mentor_fade=4.0),
        1500,
        agents=("imitation",),
        demonstrations=demos,
    )
    d = mentor_margins(learner)
    obs = ~d["mentor"][0].isnan()
    states = obs.nonzero()[:, 0]
    best, _, _ = learner.cache.state_backup(torch.zeros(1, 1, dtype=torch.int64), states[None])
    n = learner.model.state_tries[0, states]
    m, own = d["mentor"][0, states], d["own"][0, states]
    mixed = torch.where(torch.isfinite(own), (4.0 * m + n * own) / (4.0 + n), m)
    torch.testing.assert_close(best[0], torch.maximum(own, mixed), rtol=0, atol=1e-12)
    assert bool((n[torch.isfinite(own)] > 0).any())
    torch.testing.assert_close(d["margin"][0, states], m - own)
    summary = mentor_margin_summary(learner)
    assert summary["observed"] == [float(obs.sum())] and 0 <= summary["win_share"][0] <= 1
