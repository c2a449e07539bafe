"""Bad input on every surface beyond the configurations' own fields (``test_bad_input.py``): spec
and config files, devices, the Gymnasium adapter, table worlds, options, learners,
``with_options``, discovery and the counts' upper bound — each mistake the documented exception
(``ValueError``, or ``TypeError`` for an argument that is no kind of the object asked for), with a
message naming the field; and the CLI's exit status for them.

The cases are generated: surfaces × bad values (``len(CASES)`` is asserted below). None ticks a
learner; the worlds are 4×4 or 3 states, so the lot runs in seconds.
"""

from __future__ import annotations

import errno
import json
import math
import pathlib
from functools import cached_property

import numpy as np
import pytest
import scipy.sparse
import torch

from himit_torch.cli import main
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.learner.option_refresh import with_options
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import MentorPolicy, mentor_policy, run_mentor
from himit_torch.options.builders import mentor_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.options.discovery import discover_subgoals, learned_subgoal_options
from himit_torch.runs.bench import benchmark
from himit_torch.runs.config import ExperimentConfig, load_config
from himit_torch.runs.discovery import DiscoveryConfig
from himit_torch.runs.gymnasium import GymExperimentConfig
from himit_torch.runs.sweep import load_spec
from himit_torch.validation import (
    COUNT_MAX,
    NESTING_MAX,
    as_device,
    as_folder_name,
    parse_document,
    settings_of,
)
from himit_torch.worlds.gymnasium import from_gymnasium
from himit_torch.worlds.multirooms import MultiRooms
from himit_torch.worlds.table_world import TableWorld
from himit_torch.worlds.tabular import DynamicsTable
from tests.bad_inputs import Cases
from tests.test_bad_input import NOT_CHOICE, NOT_FLOAT, NOT_INT, NOT_SEQUENCE

CUDA = torch.cuda.is_available()

#: Names that must never become a folder: dots, paths, hidden, empty, too long, not strings.
BAD_NAMES = [
    ".",
    "..",
    "../x",
    "a/b",
    "/abs",
    "a\\b",
    "",
    ".hidden",
    "-dash",
    "x" * 101,
    "na me",
    "a:b",
    5,
    None,
    True,
]
#: Devices the learner never runs on, whatever the machine.
BAD_DEVICES = ["meta", "mps", "xla", "gpu9", "", "cuda:x", 3, None, True, 2.5, ["cpu"]]
#: Devices that exist only on a machine with CUDA (this many of them).
UNAVAILABLE = (["cuda", "cuda:0"] if not CUDA else []) + ["cuda:99"]
#: Counts no tick can honour (the engines' int64 and products of two counts).
TOO_MANY = [COUNT_MAX + 1, 2**63, 10**30, 1e20]


class Context:
    """What the cases build on, made on first use (only the learner takes a second)."""

    def __init__(self, tmp: pathlib.Path):
        self.tmp = tmp

    @cached_property
    def world(self) -> MultiRooms:
        return MultiRooms(4, 2)

    @cached_property
    def options(self) -> Options:
        return primitive_options(self.world)

    @cached_property
    def learner(self) -> Learner:
        return Learner(self.world, self.options, ["options", "options"], [0, 1], engine="torch")

    @cached_property
    def mentor(self) -> MentorPolicy:
        return mentor_policy(self.world, mentor_options(self.world))

    @cached_property
    def demonstrations_file(self) -> pathlib.Path:
        return Demonstrations([[0, 1]], self.world).save(self.tmp / "demos.npz")

    def table(self, **change) -> DynamicsTable:
        """A 3-state, 2-action, 2-slot table with ``change``d fields."""
        parts = dict(
            successors=torch.tensor([[[1, 2]] * 2, [[2, 2]] * 2, [[2, 2]] * 2]),
            cdf=torch.tensor([[[0.5, 1.0]] * 2] * 3, dtype=torch.float64),
            rewards=torch.zeros(3, 2, 2, dtype=torch.float64),
        )
        parts.update(change)
        return DynamicsTable(**parts)

    def table_world(self, **change) -> TableWorld:
        args = dict(
            dynamics=self.table(),
            start_distribution=torch.tensor([1.0, 0.0, 0.0], dtype=torch.float64),
            terminal_mask=torch.tensor([False, False, True]),
        )
        args.update(change)
        return TableWorld(**args)

    def spec(self, name: str, text: str) -> pathlib.Path:
        path = self.tmp / name
        path.write_text(text)
        return path


CASES = Cases()
case = CASES.add


# ================================================================ configurations, generated
def _bad_values(s) -> list:
    """Bad values for a declared setting ``s`` by its kind (``None`` left out where allowed)."""
    if s.info.folder:
        values = BAD_NAMES
    elif s.name == "device":
        values = BAD_DEVICES
    elif s.kind is int:
        bound = COUNT_MAX if s.info.le is None else int(s.info.le)
        values = NOT_INT + [bound + 1, 2**63, 1e20] + ([int(s.info.ge) - 1] if s.info.ge else [])
    elif s.kind is float:
        values = NOT_FLOAT
    elif s.kind is bool:
        values = ["yes", 1, 0, None, 1.0]
    elif s.kind is str:
        values = NOT_CHOICE if s.info.choices else [5, None, True, ""]
    elif s.kind is tuple:
        item = ["nope"] if s.item is str else [1.5, True, -1, COUNT_MAX + 1]
        values = NOT_SEQUENCE + [[v] for v in item] + [[]]
    else:  # a nested configuration
        values = [5, "learner", [1]]
    return [v for v in values if not (v is None and s.optional)]


for _cls in (GymExperimentConfig, DiscoveryConfig):
    for _s in settings_of(_cls):
        for _value in _bad_values(_s):
            case(
                f"{_cls.__name__}.{_s.name}",
                _value,
                lambda c, cls=_cls, name=_s.name, v=_value: cls(**{name: v}),
                f"{_cls.__name__}.{_s.name}",
            )

# Counts above what a tick can honour, on the configurations with int64 engines behind them
# (LearnerConfig's items: mentor_fade, exact_model_count, eps_goals, the counts).
for _cls in (LearnerConfig, ExperimentConfig):
    for _s in settings_of(_cls):
        if _s.kind is not int:
            continue
        bound = COUNT_MAX if _s.info.le is None else int(_s.info.le)
        for _value in (bound + 1, 2**63, 1e20):
            case(
                f"{_cls.__name__}.{_s.name}",
                _value,
                lambda c, cls=_cls, name=_s.name, v=_value: cls(**{name: v}),
                f"{_cls.__name__}.{_s.name}",
            )
for _field, _value in [
    ("mentor_fade", math.inf),
    ("mentor_fade", True),
    ("exact_model_count", math.inf),
    ("eps_goals", 2.5),
    ("eps_goals", math.nan),
    ("eps_goals", True),
]:
    case(
        f"LearnerConfig.{_field}",
        _value,
        lambda c, f=_field, v=_value: LearnerConfig(**{f: v}),
        f"LearnerConfig.{_field}",
    )
for _value in BAD_NAMES:
    case(
        "ExperimentConfig.name",
        _value,
        lambda c, v=_value: ExperimentConfig(name=v),
        "ExperimentConfig.name",
    )

# ================================================================ spec and config files
_SPEC_WHOLE = ["seeds", "first_seed", "seeds_per_trial"]
_JSON_NOT_INT = [v for v in NOT_INT if isinstance(v, (str, int, float, list, dict, type(None)))]
for _key in _SPEC_WHOLE:
    for _value in _JSON_NOT_INT + TOO_MANY[:3] + [-1]:
        case(
            f"spec.{_key}",
            _value,
            lambda c, k=_key, v=_value: load_spec(
                c.spec("s.json", json.dumps({k: v, "worlds": [8], "set": {"room_size": 4}}))
            ),
            _key,
        )
for _value in [[], [8.5], [True], ["8"], [None], [0], [COUNT_MAX + 1], 8, "8", {"a": 8}]:
    case(
        "spec.worlds",
        _value,
        lambda c, v=_value: load_spec(c.spec("s.json", json.dumps({"worlds": v}))),
        "worlds",
    )
for _value in BAD_NAMES:
    case(
        "spec.name",
        _value,
        lambda c, v=_value: load_spec(c.spec("s.json", json.dumps({"name": v}))),
        "name=",
    )
for _value in ["latin", "", 5, None, ["factorial"]]:
    case(
        "spec.design",
        _value,
        lambda c, v=_value: load_spec(c.spec("s.json", json.dumps({"design": v}))),
        "design",
    )
for _value in ["exp9", 5, None, ["exp2"]]:
    case(
        "spec.base",
        _value,
        lambda c, v=_value: load_spec(c.spec("s.json", json.dumps({"base": v}))),
        "base",
    )

#: Deeply nested documents: (file name, text of depth n). TOML's dotted keys and table headers
#: nest without brackets (the parser does not recurse on them; what reads the result would).
_NESTED = {
    "json-list": ("n.json", lambda n: "[" * n + "]" * n),
    "json-object": ("n.json", lambda n: '{"a": ' * n + "1" + "}" * n),
    "toml-array": ("n.toml", lambda n: "a = " + "[" * n + "]" * n),
    "toml-inline-table": ("n.toml", lambda n: "a = " + "{b = " * n + "1" + "}" * n),
    "toml-dotted-key": ("n.toml", lambda n: "a" + ".b" * n + " = 1"),
    "toml-table-header": ("n.toml", lambda n: "[" + ".".join(["a"] * n) + "]\nx = 1"),
}
for _form, (_file, _text) in _NESTED.items():
    for _depth in (NESTING_MAX + 1, 1000, 100_000):
        case(
            f"spec-nested-{_form}",
            _depth,
            lambda c, f=_file, t=_text, n=_depth: load_spec(c.spec(f, t(n))),
            "sweep spec",
        )
        if _file.endswith(".json"):
            case(
                f"config-nested-{_form}",
                _depth,
                lambda c, t=_text, n=_depth: load_config(c.spec("n.json", t(n))),
                "config file",
            )

# A path that names no file: missing, a directory, under a file.
for _what, _path in [
    ("directory", lambda c: c.tmp),
    ("missing", lambda c: c.tmp / "missing.json"),
    ("under-a-file", lambda c: c.spec("plain.json", "{}") / "x.json"),
]:
    case("spec-path", _what, lambda c, p=_path: load_spec(p(c)), "sweep spec")
    case("config-path", _what, lambda c, p=_path: load_config(p(c)), "config file")

# ================================================================================== devices
for _value in BAD_DEVICES + UNAVAILABLE:
    case(
        "Learner.device",
        _value,
        lambda c, v=_value: Learner(c.world, c.options, ["options"], [0], device=v),
        "device",
    )
    case(
        "benchmark.device",
        _value,
        lambda c, v=_value: benchmark(size=4, rooms=2, batch=1, steps=1, warmup=0, device=v),
        "device",
    )
    case("as_device", _value, lambda c, v=_value: as_device("device", v), "device")
for _value in BAD_DEVICES:
    case(
        "ExperimentConfig.device",
        _value,
        lambda c, v=_value: ExperimentConfig(device=v),
        "ExperimentConfig.device",
    )

# ========================================================================== from_gymnasium
for _value in [
    "Nope-v0",
    "nomodule_xyz:Nope-v0",
    "FrozenLake-v99",
    "frozenlake-v1",
    "ALE/Nope-v5",
    " FrozenLake-v1",
    "",
]:
    case("from_gymnasium.env", _value, lambda c, v=_value: from_gymnasium(v), repr(_value))
for _kwargs in [
    {"map_name": "9x9"},
    {"map_name": ""},
    {"map_name": 5},
    {"bogus": 1},
    {"desc": 5},
]:
    case(
        "from_gymnasium.kwargs",
        _kwargs,
        lambda c, k=_kwargs: from_gymnasium("FrozenLake-v1", **k),
        next(iter(_kwargs)),
    )
for _value in NOT_FLOAT + [0, 0.0, -0.5, 1.5, "0.9"]:
    case(
        "from_gymnasium.gamma",
        _value,
        lambda c, v=_value: from_gymnasium("FrozenLake-v1", gamma=v),
        "gamma",
    )
for _value in [
    [None],
    [6.5],
    [-1],
    [16],
    [math.nan],
    [True],
    [[1, 2]],
    [1.5, 2],
    ["5"],
    "abc",
    5,
    {1, 2},
    np.array([0.5]),
    torch.tensor([2.5]),
    torch.zeros(4, 4, dtype=torch.bool),
]:
    case(
        "from_gymnasium.terminal_states",
        _value,
        lambda c, v=_value: from_gymnasium("FrozenLake-v1", terminal_states=v),
        "terminal_states",
    )
for _value in [
    "abc",
    [None] * 16,
    [True] + [False] * 15,
    [math.nan] + [0.0] * 15,
    ["1"] + [0.0] * 15,
    5,
    [1.0],
    [-1.0, 2.0] + [0.0] * 14,
]:
    case(
        "from_gymnasium.start_distribution",
        _value,
        lambda c, v=_value: from_gymnasium("FrozenLake-v1", start_distribution=v),
        "start_distribution",
    )

# ========================================================================= table worlds
_S3 = torch.tensor([[[1, 2]] * 2, [[2, 2]] * 2, [[2, 2]] * 2])
_CDF = torch.tensor([[[0.5, 1.0]] * 2] * 3, dtype=torch.float64)
for _field, _values in {
    "successors": [
        _S3.tolist(),
        _S3.numpy(),
        None,
        "s",
        _S3.double(),
        _S3.int(),
        _S3 - 2,
        _S3 + 1,
        _S3[:, :, :1],
    ],
    "cdf": [
        _CDF.tolist(),
        _CDF.numpy(),
        None,
        _CDF.long(),
        torch.where(_CDF == 0.5, -0.5, _CDF),
        torch.where(_CDF == 0.5, math.nan, _CDF),
        torch.where(_CDF == 1.0, math.nan, _CDF),
        torch.where(_CDF == 0.5, 1.5, _CDF),
        _CDF * 0.9,
        torch.where(_CDF == 0.5, -math.inf, _CDF),
    ],
    "rewards": [
        torch.zeros(3, 2, 2).tolist(),
        np.zeros((3, 2, 2)),
        None,
        torch.zeros(3, 2, 2, dtype=torch.int64),
        torch.full((3, 2, 2), math.nan, dtype=torch.float64),
        torch.full((3, 2, 2), math.inf, dtype=torch.float64),
        torch.zeros(3, 2, 3, dtype=torch.float64),
    ],
}.items():
    for _value in _values:
        case(
            f"DynamicsTable.{_field}",
            _value,
            lambda c, f=_field, v=_value: c.table(**{f: v}),
            _field,
        )
for _shape in [(0, 2, 2), (3, 0, 2), (3, 2, 0)]:
    case(
        "DynamicsTable-empty",
        _shape,
        lambda c, s=_shape: DynamicsTable(
            torch.zeros(s, dtype=torch.int64),
            torch.ones(s, dtype=torch.float64),
            torch.zeros(s, dtype=torch.float64),
        ),
        "shape",
    )
for _field, _values in {
    "dynamics": ["table", None, 5, {"successors": _S3}],
    "gamma": NOT_FLOAT + [0.0, -1.0, 1.5, "0.9"],
    "start_distribution": [
        "abc",
        None,
        5,
        [None, 0.0, 0.0],
        [True, False, False],
        ["1", 0, 0],
        [math.nan, 0.0, 0.0],
        [1.0],
        [0.5, 0.0, 0.0],
        [-1.0, 2.0, 0.0],
        [0.0, 0.0, 1.0],
        np.ones((3, 1)) / 3,
    ],
    "terminal_mask": [
        [0, 0, 1],
        torch.tensor([0, 0, 1]),
        np.array([0, 0, 1]),
        "abc",
        None,
        5,
        [True, False],
        torch.ones(3, 3, dtype=torch.bool),
    ],
    "action_names": ["ab", ["a"], 5, ["a", "b", "c"]],
    "name": [5, "", None],
    "description": ["x", 5, [1]],
}.items():
    for _value in _values:
        case(
            f"TableWorld.{_field}",
            _value,
            lambda c, f=_field, v=_value: c.table_world(**{f: v}),
            _field,
        )

# =============================================================================== options
_OPTION_FIELDS = ("initiation", "termination", "policy", "names", "kinds")
for _field in _OPTION_FIELDS:
    for _value in [None, "abcd", 5, [[True] * 16] * 4 if _field != "names" else [1, 2, 3, 4]]:
        case(
            f"Options.{_field}",
            _value,
            lambda c, f=_field, v=_value: Options(
                **{**{k: getattr(c.options, k) for k in _OPTION_FIELDS}, f: v}
            ),
            f"Options.{_field}",
        )
for _value in [
    99,
    4,
    -1,
    0.5,
    True,
    "0",
    None,
    [0.5],
    [True],
    [4],
    [-1],
    [[0]],
    {0},
    np.array([1.5]),
]:
    case("Options.select", _value, lambda c, v=_value: c.options.select(v), "index")
case(
    "Options.select",
    "bool-mask",
    lambda c: c.options.select(torch.tensor([True, False, True, False])),
    "index",
)
_TWO = torch.tensor([[0.5, 0.5]] * 16)
_THREE = torch.tensor([[0.2, 0.3, 0.5]] * 16)
for _name, _parts in {
    "2-and-3-actions": lambda c: (
        Options.from_policy(torch.ones(16, dtype=torch.bool), _TWO),
        Options.from_policy(torch.ones(16, dtype=torch.bool), _THREE),
    ),
    "3-actions-and-action-3": lambda c: (
        Options.from_policy(torch.ones(16, dtype=torch.bool), _THREE),
        c.options,
    ),
}.items():
    case("Options.concat", _name, lambda c, p=_parts: Options.concat(*p(c)), "action counts")
for _value in [5, None, "x", ()]:
    case(
        "Options.concat",
        _value,
        lambda c, v=_value: Options.concat(c.options, v) if v != () else Options.concat(),
        "Options.concat",
    )
for _field in ("initiation", "policy", "termination"):
    for _value in [None, "abc", [[1], [1, 2]]][_field == "termination" :]:  # None: the default
        case(
            f"Options.from_policy.{_field}",
            _value,
            lambda c, f=_field, v=_value: Options.from_policy(
                **{
                    "initiation": torch.ones(16, dtype=torch.bool),
                    "policy": torch.zeros(16, dtype=torch.int64),
                    f: v,
                }
            ),
            _field,
        )

# ========================================================== learners, with_options, files
for _value in [5, "demos.npz", 3.2, [(0, 1)], {"episodes": [[0, 1]]}, object()]:
    case(
        "Learner.demonstrations",
        _value,
        lambda c, v=_value: Learner(c.world, c.options, ["imitation"], [0], demonstrations=v),
        "demonstrations",
        TypeError,
    )
for _value in [5, "MultiRooms 4x4", 3.2, [1], object()]:
    case(
        "Demonstrations.load.world",
        _value,
        lambda c, v=_value: Demonstrations.load(c.demonstrations_file, v),
        "world",
        TypeError,
    )
    case(
        "Demonstrations.world",
        _value,
        lambda c, v=_value: Demonstrations([[0, 1]], v),
        "world",
        TypeError,
    )
for _value in [v for v in NOT_INT if not isinstance(v, (list, tuple))] + [-1, 2**63]:
    case(
        "Learner.seeds",
        _value,
        lambda c, v=_value: Learner(c.world, c.options, ["options"], [v]),
        "seeds",
    )
for _value in NOT_INT + [-1, COUNT_MAX + 1]:
    case("Learner.run.steps", _value, lambda c, v=_value: c.learner.run(v), "steps")
for _value in [[99], [2], [-1], [0.7], [True], "0", 5, [0, 0], [], [[0]], np.array([0.5])]:
    case(
        "with_options.runs",
        _value,
        lambda c, v=_value: with_options(c.learner, c.options, runs=v),
        "runs",
    )
for _value in ["options", 5, [5], ["nobody"], ["options", "options", "options"]]:
    case(
        "with_options.agents",
        _value,
        lambda c, v=_value: with_options(c.learner, c.options, agents=v),
        "agent",
    )

for _field, _values in {
    "episodes": NOT_INT + [0, COUNT_MAX + 1],
    "seed": [v for v in NOT_INT if v is not None] + [2**64],
    "max_steps_per_episode": [v for v in NOT_INT if v is not None] + [0, COUNT_MAX + 1],
}.items():
    for _value in _values:
        case(
            f"run_mentor.{_field}",
            _value,
            lambda c, f=_field, v=_value: run_mentor(
                c.world, c.mentor, **{"episodes": 1, "seed": 0, f: v}
            ),
            _field,
        )

# ============================================================================== discovery
for _value in [
    [[0, 1, -2, 3]],
    [[0, math.nan, 2]],
    [[0, 1.5, 2]],
    [[0, True, 2]],
    [["0", 1]],
    [[None, 1]],
    [np.array([0.0, np.nan])],
    [torch.tensor([0, -1])],
    [np.array([[0, 1]])],
    [[]],
    [],
    "abc",
    5,
]:
    case(
        "discover_subgoals.demonstrations",
        _value,
        lambda c, v=_value: discover_subgoals(v),
        "demonstrations",
    )
for _value in NOT_INT + [-1, COUNT_MAX + 1]:
    case(
        "discover_subgoals.separation",
        _value,
        lambda c, v=_value: discover_subgoals([[0, 1, 2]], separation=v),
        "separation",
    )
for _value in NOT_FLOAT + [0.0, -0.1, 1.5]:
    case(
        "discover_subgoals.min_episode_share",
        _value,
        lambda c, v=_value: discover_subgoals([[0, 1, 2]], min_episode_share=v),
        "min_episode_share",
    )
for _field, _values in {
    "max_steps": NOT_FLOAT + [0.0, -1.0],
    "gamma": NOT_FLOAT + [0.0, 1.0],
    "num_actions": NOT_INT + [0],
}.items():
    for _value in _values:
        case(
            f"learned_subgoal_options.{_field}",
            _value,
            lambda c, f=_field, v=_value: learned_subgoal_options(
                **{
                    "counts": scipy.sparse.csr_matrix((8, 4)),
                    "num_actions": 2,
                    "subgoals": [1],
                    f: v,
                }
            ),
            _field,
        )


# =================================================================================== tests
@pytest.fixture(scope="module")
def context(tmp_path_factory) -> Context:
    return Context(tmp_path_factory.mktemp("surfaces"))


def test_the_cases_are_over_five_hundred():
    assert len(CASES) >= 500, len(CASES)


@pytest.mark.parametrize("bad", CASES)
def test_bad_input_raises_the_documented_error_naming_the_field(context, bad):
    bad.check(context)


# ----------------------------------------------------------------- what is still accepted
def test_good_neighbours_of_the_bad_values_are_accepted(context):
    """The refusals are not blanket: whole floats, masks, arrays and brackets inside strings and
    comments are fine, and depth NESTING_MAX itself is."""
    assert DiscoveryConfig(seeds=2.0).seeds == 2
    assert GymExperimentConfig(window=1e3, steps=None).window == 1000
    world = from_gymnasium("FrozenLake-v1", terminal_states=np.array([5.0, 15.0]), gamma=1)
    assert world.terminal_mask.nonzero()[:, 0].tolist() == [5, 15]
    mask = torch.zeros(16, dtype=torch.bool)
    mask[15] = True
    assert bool(from_gymnasium("FrozenLake-v1", terminal_states=mask).terminal_mask[15])
    assert context.table_world(terminal_mask=[False, False, True], gamma=1).gamma == 1.0
    assert context.options.select(np.array([3, 0])).names == (
        context.options.names[3],
        context.options.names[0],
    )
    assert as_device("device", "cpu") == torch.device("cpu")
    assert ExperimentConfig(device="cuda").device == "cuda"  # written down, not run here
    assert as_folder_name("name", "exp2_ties.v1-b") == "exp2_ties.v1-b"
    text = "".join(
        f'# [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[ a.b.c\nname{i} = "a[[[[.{{{{"\n' for i in range(40)
    )
    assert parse_document("spec", text, "toml")["name39"] == "a[[[[.{{"
    deep = "[" * NESTING_MAX + "]" * NESTING_MAX
    assert parse_document("x", deep, "json") is not None
    assert discover_subgoals([np.array([0.0, 1.0, 2.0])]).settings["separation"] == 3


# ------------------------------------------------------------------------------------ CLI
def _exit(capsys, argv) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: ") and "Traceback" not in err
    return exc.value.code, err


@pytest.mark.parametrize(
    "argv, says",
    [
        (["run", "exp2", "--config", "{tmp}"], "is a directory"),
        (["sweep", "{tmp}"], "is a directory"),
        (["sweep", "{tmp}/plain.toml/x.toml"], "not a directory"),
        (["plot", "{tmp}/nothing"], "does not exist"),
        (["run", "exp2", "--device", "meta"], "device='meta'"),
        (["run", "gymnasium", "--device", "mps"], "device='mps'"),
        (["bench", "--device", "meta", "--steps", "1", "--warmup", "0"], "device='meta'"),
        (["run", "exp2", "--device", "cuda:99"], "cuda:99"),
        (["info", "--size", "8", "--rooms", "2", "--env-kwargs", "{}"], "--env-kwargs"),
        (["sweep", "{tmp}/dots.toml", "--dry-run"], "name='..'"),
        (["sweep", "{tmp}/deep.toml", "--dry-run"], "more than 32 deep"),
        (["run", "exp2", "--name", "../outside"], "ExperimentConfig.name='../outside'"),
        (["demo", "--episodes", str(COUNT_MAX + 1)], "must be ≤"),
    ],
)
def test_cli_user_mistakes_are_one_line_exit_2(capsys, tmp_path, argv, says):
    (tmp_path / "plain.toml").write_text('name = "plain"\n')
    (tmp_path / "dots.toml").write_text('name = ".."\nseeds = 1\n')
    (tmp_path / "deep.toml").write_text("a = " + "[" * 5000 + "]" * 5000)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    if argv[0] == "run":
        argv += ["--logdir", str(tmp_path / "runs")]
    status, err = _exit(capsys, argv)
    assert status == 2 and says in err, err
    assert not (tmp_path / "outside").exists() and not (tmp_path.parent / "outside").exists()


def test_cli_without_cuda_refuses_cuda_in_one_line(capsys, tmp_path):
    if CUDA:
        pytest.skip("this machine has CUDA")
    for argv in (["run", "exp2", "--device", "cuda"], ["run", "gymnasium", "--device", "cuda"]):
        status, err = _exit(capsys, argv + ["--logdir", str(tmp_path)])
        assert status == 2 and "no CUDA device is available" in err and "['cpu']" in err


@pytest.mark.parametrize(
    "fault",
    [
        OSError(errno.EACCES, "Permission denied"),
        OSError(errno.EIO, "Input/output error"),
        OSError(errno.ENOSPC, "No space left on device"),
    ],
    ids=["permissions", "io-error", "disk-full"],
)
def test_cli_genuine_io_failures_keep_exit_1_in_one_line(capsys, tmp_path, monkeypatch, fault):
    """The right file, a failing machine: exit 1 (not a user mistake), still one line."""
    config = tmp_path / "config.json"
    config.write_text(ExperimentConfig().to_json())
    real = pathlib.Path.read_text

    def failing(self, *args, **kwargs):
        if self == config:
            raise type(fault)(fault.errno, fault.strerror, str(self))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(pathlib.Path, "read_text", failing)
    status, err = _exit(capsys, ["run", "exp2", "--config", str(config), "--logdir", str(tmp_path)])
    assert status == 1 and fault.strerror in err and str(config) in err
    monkeypatch.undo()
    status, err = _exit(capsys, ["sweep", str(tmp_path), "--dry-run"])
    assert status == 2  # beside it, a directory for a file is the user's mistake
