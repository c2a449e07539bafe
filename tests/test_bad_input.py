"""Bad input, tried as a new user would: every mistake is a ``ValueError`` naming the field (the
CLI: one line on stderr, exit status 2), never another exception, never a silent truncation.

A generated sweep (several hundred cases: every numeric, choice and sequence field of
``MultiRooms``, ``LearnerConfig`` and ``ExperimentConfig`` × wrong types, non-whole and
non-finite numbers), hypothesis property tests (random valid configurations build and step, random
invalid ones raise ``ValueError``, model invariants after random runs), the up-front size checks
and the CLI."""

import json
import math

import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from himit_torch.cli import main
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.options.builders import learner_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.runs.config import ExperimentConfig, load_config
from himit_torch.runs.experiment import run_experiment
from himit_torch.validation import as_float, as_int, memory_limit, settings_of
from himit_torch.worlds.multirooms import MultiRooms

FAST = settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)


class _Thing:
    def __repr__(self):
        return "<thing>"


#: Values that are never a whole number.
NOT_INT = [
    "3",
    "0.1",
    2.7,
    -0.5,
    True,
    False,
    math.nan,
    math.inf,
    -math.inf,
    None,
    [3],
    (3,),
    {"a": 1},
    _Thing(),
    1 + 2j,
    b"3",
]
#: Values that are never a real number.
NOT_FLOAT = [
    "0.1",
    "nan",
    True,
    False,
    math.nan,
    math.inf,
    -math.inf,
    None,
    [0.1],
    {"x": 0.1},
    _Thing(),
    1j,
    np.float64("nan"),
]
#: Values that are never one of a field's choices.
NOT_CHOICE = ["", "GREEDY", 1, None, True, ["greedy"], 0.5]
#: Values that are never a list of names / sizes.
NOT_SEQUENCE = ["imitation", 40, None, 4.0, {"a": 1}, _Thing()]

MULTIROOMS = {
    "size": "int",
    "rooms": "int",
    "slip": "float",
    "gamma": "float",
    "step_reward": "float",
    "goal_reward": "float",
    "start": "cell",
    "goal": "cell",
}
#: Every declared field of LearnerConfig, by the kind of value it takes.
LEARNER = {
    s.name: {int: "int", float: "float", str: "choice", bool: "bool"}[s.kind]
    for s in settings_of(LearnerConfig)
}
EXPERIMENT = {
    "seeds": "int",
    "first_seed": "int",
    "steps": "int",
    "mentor_episodes": "int",
    "window": "int",
    "checkpoint_every": "int",
    "room_size": "int",
    "slip": "float",
    "mentor_preference": "float",
    "engine": "choice",
    "sizes": "sequence",
    "agents": "sequence",
    "corner_options": "bool",
    "device": "device",
}

BAD = {
    "int": NOT_INT,
    "float": NOT_FLOAT,
    "choice": NOT_CHOICE,
    "sequence": NOT_SEQUENCE,
    "cell": ["0", 2.5, True, None, (0.5, 1), (True, 0), (0, 1, 2), [1.5, 0], math.nan, "top"],
    "bool": ["yes", 1, 0, None, 1.0],
    "device": ["gpu9", 3, None, "", "cuda:x"],
}


def _nullable(kind_map, field):
    """None is the field's documented "off": the learner's optional settings (from the schema)
    and these few."""
    optional = {s.name for s in settings_of(LearnerConfig) if s.optional}
    return field in optional or field in ("mentor_preference", "start", "goal")


def _cases(target, spec):
    for field, kind in spec.items():
        for value in BAD[kind]:
            if value is None and _nullable(spec, field):
                continue  # None is these fields' documented "off"
            yield pytest.param(target, field, value, id=f"{target}-{field}-{value!r}")


SWEEP = (
    list(_cases("MultiRooms", MULTIROOMS))
    + list(_cases("LearnerConfig", LEARNER))
    + list(_cases("ExperimentConfig", EXPERIMENT))
)


def _build(target, field, value):
    if target == "MultiRooms":
        return MultiRooms(**{"size": 8, "rooms": 2, field: value})
    if target == "LearnerConfig":
        return LearnerConfig(**{field: value})
    return ExperimentConfig(**{"sizes": (8,), "seeds": 1, "steps": 10, field: value})


def test_the_sweep_is_several_hundred_cases():
    assert len(SWEEP) >= 300


@pytest.mark.parametrize("target, field, value", SWEEP)
def test_bad_input_sweep_raises_value_error_naming_the_field(target, field, value):
    with pytest.raises(ValueError) as err:
        _build(target, field, value)
    message = str(err.value)
    assert field.split("_")[0] in message or "cell" in message or "device" in message, message
    assert "\n" not in message.strip()


def _in_json(case) -> bool:
    target, _, value = case.values
    return target != "MultiRooms" and isinstance(value, (str, int, float, list, dict, type(None)))


@pytest.mark.parametrize("target, field, value", [c.values for c in SWEEP[::3] if _in_json(c)])
def test_bad_config_file_fields_are_one_line_exit_2(tmp_path, capsys, target, field, value):
    """The same values through ``himit run --config file.json`` (those JSON can hold)."""
    data = json.loads(ExperimentConfig(sizes=(8,), seeds=1, steps=10).to_json())
    if target == "LearnerConfig":
        data["learner"][field] = value
    else:
        data[field] = value
    path = tmp_path / "config.json"
    path.write_text(json.dumps(data))
    with pytest.raises(SystemExit) as exc:
        main(["run", "exp2", "--config", str(path), "--logdir", str(tmp_path / "runs")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: ") and "Traceback" not in err


# ------------------------------------------------------------------ conversion rules, by rule
def test_whole_floats_convert_and_fractions_are_never_truncated():
    assert as_int("x", 1e6) == 1_000_000 and isinstance(as_int("x", 1e6), int)
    assert as_int("x", np.int32(4)) == 4
    with pytest.raises(ValueError, match="not a whole number"):
        as_int("x", 2.7)
    assert LearnerConfig(backups=12.0).backups == 12
    assert ExperimentConfig(steps=2e4, sizes=[8.0], agents=["imitation"]).steps == 20_000
    config = ExperimentConfig(sizes=[8], agents=["imitation"])
    assert config.sizes == (8,) and config.agents == ("imitation",)  # lists become tuples
    assert as_float("x", 3) == 3.0 and as_float("x", np.float32(0.5)) == 0.5


def test_cells_must_be_whole_numbers():
    world = MultiRooms(8, 2, start=[1, 1])
    assert world.start_state == 9
    with pytest.raises(ValueError, match="whole number"):
        MultiRooms(8, 2, start=(1.7, 1))
    with pytest.raises(ValueError, match="cell"):
        MultiRooms(8, 2, closed_doorways=5)


def test_options_refuse_strings_and_non_boolean_initiation():
    opts = primitive_options(MultiRooms(8, 2))
    with pytest.raises(ValueError, match="names"):
        Options(opts.initiation, opts.termination, opts.policy, "abcd", opts.kinds)
    listed = Options(
        opts.initiation, opts.termination, opts.policy, list(opts.names), list(opts.kinds)
    )
    assert isinstance(listed.names, tuple)
    with pytest.raises(ValueError, match="torch.Tensor"):
        Options(opts.initiation.tolist(), opts.termination, opts.policy, opts.names, opts.kinds)
    with pytest.raises(ValueError, match="bools"):
        Options.from_policy(torch.tensor([0.5, 1.0]), torch.tensor([0, 1]))
    assert (
        Options.from_policy(torch.tensor([0, 1]), torch.tensor([0, 1])).initiation.dtype
        == torch.bool
    )


def test_learner_refuses_bad_seeds_agents_device_and_out_of_range_actions(world8):
    opts = primitive_options(world8)
    for kwargs, match in [
        (dict(seeds=[1.5]), "whole number"),
        (dict(seeds=[True]), "whole number"),
        (dict(agents="imitation", seeds=[0]), "list"),
        (dict(device="gpu9"), "torch device"),
        (dict(engine="fast"), "engine"),
        (dict(config={"backups": 3}), "LearnerConfig"),
    ]:
        args = {"agents": ["options"], "seeds": [0], **kwargs}
        with pytest.raises(ValueError, match=match):
            Learner(world8, opts, **args)
    bad = Options(opts.initiation, opts.termination, opts.policy + 4, opts.names, opts.kinds)
    with pytest.raises(ValueError, match="action 7"):
        Learner(world8, bad, ["options"], [0])


# --------------------------------------------------------------------------- size checks
def test_sizes_that_cannot_fit_are_refused_up_front_with_estimate_and_limit(
    monkeypatch, world8, tmp_path
):
    with pytest.raises(ValueError, match=r"would need about .*more than the limit"):
        MultiRooms(size=200_000, rooms=1000)
    monkeypatch.setenv("HIMIT_MEMORY_LIMIT", "2MiB")
    assert memory_limit() == 2 * 2**20
    with pytest.raises(ValueError, match=r"options over .* states"):
        learner_options(MultiRooms(48, 6), corners=True)
    with pytest.raises(ValueError, match="a batch of 4000 runs"):
        Learner(world8, primitive_options(world8), ["options"] * 4000, list(range(4000)))
    with pytest.raises(ValueError, match="ExperimentConfig: world 400×400"):
        ExperimentConfig(sizes=(400,), room_size=8).check_size()
    with pytest.raises(ValueError, match="ExperimentConfig: world 400×400"):
        run_experiment(ExperimentConfig(sizes=(400,), room_size=8), tmp_path / "run")
    assert not (tmp_path / "run" / "config.json").exists()  # refused before anything was written
    monkeypatch.setenv("HIMIT_MEMORY_LIMIT", "off")
    assert memory_limit() is None
    monkeypatch.setenv("HIMIT_MEMORY_LIMIT", "lots")
    with pytest.raises(ValueError, match="HIMIT_MEMORY_LIMIT"):
        memory_limit()


# ---------------------------------------------------------------------------- demonstrations
def test_demonstrations_are_checked_in_the_world_object_they_are_used_with(world8):
    """A world whose description matches but whose cells differ (here a subclass that walls off
    a cell the mentor passed): the learner's world object, not the rebuilt one, decides."""
    episode = [0, 1, 2, 10, 18, 19]

    class Walled(MultiRooms):
        @property
        def wall_mask(self):
            mask = super().wall_mask
            mask[10] = True
            return mask

    demos = Demonstrations([episode], MultiRooms(8, 2).describe())  # checked in a rebuilt world
    walled = Walled(8, 2)
    assert walled.describe() == world8.describe()
    demos.check_world(world8)
    with pytest.raises(ValueError, match="wall cell"):
        demos.check_world(walled)
    with pytest.raises(ValueError, match="wall cell"):
        Learner(walled, primitive_options(world8), ["imitation"], [0], demonstrations=demos)


# ---------------------------------------------------------------------------- the CLI
@pytest.mark.parametrize(
    "argv",
    [
        ["info", "--size", "2.5"],
        ["info", "--slip", "nan"],
        ["info", "--slip", "0.1x"],
        ["info", "--slip", "inf"],
        ["info", "--gamma", "-1", "--env", "Taxi-v3"],
        ["info", "--size", "-8"],
        ["info", "--size", "7", "--rooms", "2"],
        ["bench", "--batch", "0"],
        ["bench", "--device", "gpu9", "--steps", "1", "--warmup", "0"],
        ["run", "exp2", "--seeds", "1.5"],
        ["run", "exp2", "--steps", "true"],
        ["run", "exp2", "--config", "/nonexistent.json"],
        ["run", "exp2", "--device", "gpu9"],
    ],
)
def test_cli_bad_arguments_are_one_line_exit_2(capsys, tmp_path, argv):
    if argv[0] == "run":
        argv = argv + ["--logdir", str(tmp_path)]
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: ") and "Traceback" not in err


def test_cli_bad_thread_count_is_one_line_exit_2(capsys, monkeypatch):
    monkeypatch.setenv("HIMIT_THREADS", "two")
    with pytest.raises(SystemExit) as exc:
        main(["info", "--size", "8", "--rooms", "2"])
    assert exc.value.code == 2 and "HIMIT_THREADS" in capsys.readouterr().err


# ---------------------------------------------------------------------------- hypothesis
@st.composite
def valid_worlds(draw):
    rooms = draw(st.integers(1, 3))
    room_size = draw(st.integers(2, 4))
    return dict(
        size=rooms * room_size,
        rooms=rooms,
        slip=draw(st.floats(0.0, 0.3)),
        # a step cost, so that the mentor's optimal policy heads for the goal
        gamma=draw(st.floats(0.5, 0.999)),
        step_reward=draw(st.floats(-1.0, -0.01)),
        goal_reward=draw(st.floats(0.0, 2.0)),
    )


@st.composite
def valid_learner_configs(draw):
    backups = draw(st.integers(1, 12))
    return LearnerConfig(
        backups=backups,
        sweep_rounds=draw(st.integers(1, backups)),
        plan_every=draw(st.integers(1, 5)),
        rng_chunk=draw(st.integers(1, 64)),
        concentration=draw(st.floats(0.0, 3.0)),
        mentor_concentration=draw(st.floats(0.0, 3.0)),
        initial_value=draw(st.floats(-2.0, 0.0)),
        untried_value=draw(st.none() | st.floats(-1.0, 0.0)),
        eps_start=draw(st.floats(0.1, 1.0)),
        eps_min=0.0,
        window=draw(st.integers(10, 200)),
        mentor_choice=draw(st.sampled_from(["greedy", "match"])),
        tie_break=draw(st.sampled_from(["random", "first"])),
        mentor_override_after=draw(st.none() | st.integers(0, 5)),
        reward_bound_check="off",
    )


@settings(max_examples=10, deadline=None, derandomize=True)
@given(
    world=valid_worlds(),
    config=valid_learner_configs(),
    seed=st.integers(0, 2**31),
    steps=st.integers(1, 200),
    engine=st.sampled_from(["numba", "torch"]),
)
def test_random_valid_configurations_build_step_and_keep_the_model_invariants(
    world, config, seed, steps, engine
):
    from himit_torch.mentor.policy import mentor_policy, record_demonstrations
    from himit_torch.options.builders import mentor_options

    w = MultiRooms(**world)
    opts = learner_options(w)
    agents = ["imitation", "options", "primitives", "imitation_confident"]
    # prefer_extended_within=0: the default tolerance, one step's cost |step_reward|, can exceed
    # the whole spread of discounted values in the generated worlds (e.g. γ = 0.5 with −1 a step:
    # every value lies in [−2, 0]), and a mentor that takes any extended option within it may
    # loop and never reach the goal. This test is about the learner's invariants.
    mentor = mentor_policy(w, mentor_options(w), prefer_extended_within=0.0)
    demos = record_demonstrations(w, mentor, 2, seed=seed % 100)
    learner = Learner(
        w,
        opts,
        agents,
        [seed % 1000 + i for i in range(4)],
        config=config,
        demonstrations=demos,
        engine=engine,
    )
    learner.run(steps)
    assert learner.views.t == steps
    # counts are non-negative, in both models
    for model in (learner.model, learner.mentor):
        assert bool((model.edge_count >= 0).all()) and bool((model.row_count >= 0).all())
    # the posterior means of every tried row sum to 1
    B, M = learner.batch, learner.num_rows
    runs = torch.arange(B)[:, None].expand(B, M)
    rows = torch.arange(M)[None].expand(B, M)
    post = learner.model.posterior(runs, rows)
    tried = post.total > 0
    sums = post.mean.sum(-1)[tried]
    assert torch.allclose(sums, torch.ones_like(sums))
    mentor_post = learner.mentor.posterior(
        runs[:, : w.num_states]
        if M >= w.num_states
        else torch.arange(B)[:, None].expand(B, w.num_states),
        torch.arange(w.num_states)[None].expand(B, -1),
    )
    msums = mentor_post.mean.sum(-1)[mentor_post.total > 0]
    assert torch.allclose(msums, torch.ones_like(msums))
    # V of the terminal state is 0
    assert bool((learner.views.state_values()[:, w.terminal_mask] == 0).all())
    assert bool(torch.isfinite(learner.views.state_values()).all())


_NONFINITE = st.sampled_from([math.nan, math.inf, -math.inf])
_FRACTION = st.floats(-1e6, 1e6).filter(lambda x: x != int(x))


def _junk(kind):
    """Values that are invalid for a field of ``kind`` whatever their draw."""
    base = [
        st.text(max_size=4),
        st.none(),
        _NONFINITE,
        st.dictionaries(st.text(max_size=2), st.integers(), max_size=1),
    ]
    if kind == "bool":
        return st.one_of(*base, st.integers(), _FRACTION)
    base.append(st.booleans())
    if kind in ("int", "cell"):
        return st.one_of(*base, _FRACTION, st.lists(st.text(max_size=2), min_size=1, max_size=3))
    if kind == "sequence":
        return st.one_of(
            *base, st.lists(st.one_of(st.none(), _NONFINITE, _FRACTION), min_size=1, max_size=2)
        )
    if kind == "device":
        return st.one_of(*base).filter(lambda v: not (isinstance(v, str) and _is_device(v)))
    if kind == "choice":
        valid = {
            "greedy",
            "match",
            "random",
            "first",
            "error",
            "warn",
            "off",
            "auto",
            "numba",
            "torch",
            "decision",
            "step",
            "goals",
            "paper",
            "learned",
            "exact",
            "known",
            "salience",
            "none",
        }
        return st.one_of(*base).filter(lambda v: not (isinstance(v, str) and v in valid))
    return st.one_of(*base, st.lists(st.floats(), max_size=2))  # float


def _is_device(text):
    try:
        torch.device(text)
        return True
    except RuntimeError:
        return False


@FAST
@given(target=st.sampled_from(["MultiRooms", "LearnerConfig", "ExperimentConfig"]), data=st.data())
def test_random_invalid_values_raise_value_error_and_nothing_else(target, data):
    spec = {"MultiRooms": MULTIROOMS, "LearnerConfig": LEARNER, "ExperimentConfig": EXPERIMENT}[
        target
    ]
    field = data.draw(st.sampled_from(sorted(spec)))
    value = data.draw(_junk(spec[field]))
    if value is None and _nullable(spec, field):
        return
    with pytest.raises(ValueError):
        _build(target, field, value)


@FAST
@given(
    data=st.dictionaries(
        st.sampled_from(["seeds", "steps", "window", "first_seed", "mentor_episodes", "bogus"]),
        _junk("int"),
        min_size=1,
        max_size=3,
    )
)
def test_random_bad_config_files_raise_value_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("cfg") / "config.json"
    path.write_text(json.dumps(data, allow_nan=True))
    with pytest.raises(ValueError):
        load_config(path)
