"""Bad input on the surfaces that were not yet held to the library's input rules: the puzzle box
(world, size, configuration, ``himit run puzzlebox`` and ``himit info --puzzle-box``), the
grid world's description, the statistics functions, the exact evaluator of frozen policies (its
window, world, options, models and policies), ``with_options``' learner, the detour's waypoint
and the BCO and shaping helpers of the mentor. Each mistake is the documented exception — a ``ValueError``, or a
``TypeError`` for an argument that is no kind of the object asked for — with a message naming
the argument; never a hang, a truncation, a ``KeyError``, a ``ZeroDivisionError`` or a NaN
answer.

The cases are generated: surfaces × bad values (``len(CASES)`` is asserted below). Nothing ticks
a learner and the worlds are at most 2-skewer boxes or 4×4 grids, so the lot runs in seconds.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
import pytest
import torch

from himit_torch.cli import main
from himit_torch.exact.greedy_evaluation import OptionPolicy, PolicyEvaluator
from himit_torch.exact.option_models import option_models_and_durations
from himit_torch.learner.option_refresh import with_options
from himit_torch.mentor.cloning import clone_policy, inverse_model
from himit_torch.mentor.potential import mentor_chain_value, shaping_potential
from himit_torch.options.builders import mentor_options, primitive_options
from himit_torch.runs.puzzle_box import PuzzleBoxConfig
from himit_torch.statistics import (
    first_goal_survival,
    holm,
    paired_comparison,
    t_interval,
)
from himit_torch.validation import COUNT_MAX
from himit_torch.worlds.multirooms import MultiRooms, detour_waypoint
from himit_torch.worlds.puzzle_box import (
    SKEWERS_MAX,
    PuzzleBox,
    organisation_of,
    organisation_scores,
    puzzle_box_size,
)
from tests.bad_inputs import Cases


class _Thing:
    def __repr__(self):
        return "<thing>"


# The bad values of ``tests/test_bad_input.py`` (kept here too, so that these cases do not
# depend on that module's generated tables of the configurations).
#: Values that are never a whole number.
NOT_INT = ["3", "0.1", 2.7, -0.5, True, False, math.nan, math.inf, -math.inf, None, [3], (3,),
           {"a": 1}, _Thing(), 1 + 2j, b"3"]  # fmt: skip
#: Values that are never a real number.
NOT_FLOAT = ["0.1", "nan", True, False, math.nan, math.inf, -math.inf, None, [0.1], {"x": 0.1},
             _Thing(), 1j, np.float64("nan")]  # fmt: skip
#: Values that are never one of a field's choices.
NOT_CHOICE = ["", "GREEDY", 1, None, True, ["greedy"], 0.5]
#: Values that are never a list of names.
NOT_SEQUENCE = ["imitation", 40, None, 4.0, {"a": 1}, _Thing()]
#: Whole numbers no count may take (the engines' int64, a tick's budget).
TOO_MANY = [COUNT_MAX + 1, 10**30, 1e20]
#: Names that never become a folder.
BAD_NAMES = [".", "..", "../x", "", "a/b", ".hidden", 5, None]


class Context:
    """What the cases build on, made on first use."""

    @cached_property
    def box(self) -> PuzzleBox:
        return PuzzleBox(2)

    @cached_property
    def grid(self) -> MultiRooms:
        return MultiRooms(4, 2)

    @cached_property
    def grid_options(self):
        return primitive_options(self.grid)

    @cached_property
    def grid_models(self):
        return option_models_and_durations(self.grid, self.grid_options)

    @cached_property
    def mentor_models(self):
        """The models of another bundle over the same world."""
        return option_models_and_durations(self.grid, mentor_options(self.grid))

    @cached_property
    def other_models(self):
        """The primitives' models in another world."""
        world = MultiRooms(6, 2)
        return option_models_and_durations(world, primitive_options(world))

    @cached_property
    def evaluator(self) -> PolicyEvaluator:
        return PolicyEvaluator(self.grid, self.grid_options, 5)


CASES = Cases()
case = CASES.add


# ============================================================================= the puzzle box
for _value in NOT_INT + [0, -1, SKEWERS_MAX + 1, 10**18, COUNT_MAX + 1]:
    case("PuzzleBox.skewers", _value, lambda c, v=_value: PuzzleBox(skewers=v), "skewers")
for _value in NOT_INT + [1, 0, 10**30]:
    case("PuzzleBox.steps", _value, lambda c, v=_value: PuzzleBox(2, steps=v), "steps")
for _skewers, _steps in [(SKEWERS_MAX, 3), (1, 10**9), (12, 10)]:
    case(  # each fits its own bound; their state space does not
        "PuzzleBox.states",
        (_skewers, _steps),
        lambda c, k=_skewers, n=_steps: PuzzleBox(k, steps=n),
        "states",
    )
for _value in [
    [0.5, 1.7],
    [1, 1.5],
    [True, 0],
    ["0", 1],
    [math.nan, 0],
    [None, 0],
    np.array([0.5, 1.0]),
    torch.tensor([0.0, 2.5]),
    "01",
    5,
]:
    case(
        "PuzzleBox.encode.progress",
        _value,
        lambda c, v=_value: c.box.encode(v),
        "progress",
    )
for _value in [0.5, "0", True, math.nan, [0], 2, -1]:
    case(
        "PuzzleBox.encode.skewer",
        _value,
        lambda c, v=_value: c.box.encode([0, 0], skewer=v),
        "skewer",
    )
for _field, _values in {
    "skewers": NOT_INT + [0, -1, SKEWERS_MAX + 1, 10**18],
    "steps": NOT_INT + [1, 0, -1, COUNT_MAX + 1],
}.items():
    for _value in _values:
        case(  # 10**18 skewers: a power that never finished
            f"puzzle_box_size.{_field}",
            _value,
            lambda c, f=_field, v=_value: puzzle_box_size(**{"skewers": 2, "steps": 4, f: v}),
            f"puzzle_box_size: {_field}",
        )
_DESCRIPTION = PuzzleBox(2).describe()
for _key in [k for k in _DESCRIPTION if k != "kind"]:
    case(
        "PuzzleBox.from_description.missing",
        _key,
        lambda c, k=_key: PuzzleBox.from_description(
            {n: v for n, v in _DESCRIPTION.items() if n != k}
        ),
        f"lacks [{_key!r}]",
    )
case(  # the case: a KeyError before
    "PuzzleBox.from_description.missing",
    "all",
    lambda c: PuzzleBox.from_description({"kind": "PuzzleBox"}),
    "lacks ['skewers', 'steps'",
)
for _value in [None, 5, "PuzzleBox", ["kind"]]:
    case(
        "PuzzleBox.from_description.desc",
        _value,
        lambda c, v=_value: PuzzleBox.from_description(v),
        "PuzzleBox.describe()",
        TypeError,
    )
_ROOMS = MultiRooms(4, 2).describe()
for _key in [k for k in _ROOMS if k != "kind"]:
    case(  # a KeyError before
        "MultiRooms.from_description.missing",
        _key,
        lambda c, k=_key: MultiRooms.from_description({n: v for n, v in _ROOMS.items() if n != k}),
        f"lacks [{_key!r}]",
    )
case(
    "MultiRooms.from_description.missing",
    "all",
    lambda c: MultiRooms.from_description({"kind": "MultiRooms"}),
    "lacks ['size', 'rooms'",
)
for _value in [None, 5, "MultiRooms", ["kind"]]:
    case(
        "MultiRooms.from_description.desc",
        _value,
        lambda c, v=_value: MultiRooms.from_description(v),
        "MultiRooms.describe()",
        TypeError,
    )
for _field, _values in {
    "steps": [1, 0, -1, 2.5, True, "4", None],
    "skewers": [0, -1, 2.5, True, SKEWERS_MAX + 1],
    "focus": [1, -1, 0.5, True, "0"],
}.items():
    for _value in _values:
        case(
            f"organisation_scores.{_field}",
            _value,
            lambda c, f=_field, v=_value: organisation_scores(
                [(0, 1)], **{"skewers": 1, "steps": 2, "focus": None, f: v}
            ),
            _field,
        )
case(  # the case: one skewer of one step, where "skewer" divided by zero
    "organisation_scores.steps",
    "one-step",
    lambda c: organisation_scores([(0, 1)], 1, 1),
    "steps",
)

# ================================================================ the puzzle box's configuration
_CONFIG_INTS = {
    "skewers": 2,
    "transfer_skewers": 2,
    "seeds": 1,
    "first_seed": 0,
    "steps": 1,
    "transfer_steps": 1,
    "mentor_episodes": 1,
    "window": 1,
    "eval_every": 1,
    "checkpoint_every": 1,
}
for _field, _minimum in _CONFIG_INTS.items():
    for _value in NOT_INT + TOO_MANY + [_minimum - 1]:
        case(
            f"PuzzleBoxConfig.{_field}",
            _value,
            lambda c, f=_field, v=_value: PuzzleBoxConfig(**{f: v}),
            f"PuzzleBoxConfig.{_field}",
        )
for _field in ("slip", "pinch_slip", "harder_pinch"):
    for _value in NOT_FLOAT + [-0.1, 1.0, 1.5]:
        if _value is None and _field == "pinch_slip":
            continue  # None is pinch_slip's documented "as slip"
        case(
            f"PuzzleBoxConfig.{_field}",
            _value,
            lambda c, f=_field, v=_value: PuzzleBoxConfig(**{f: v}),
            f"PuzzleBoxConfig.{_field}",
        )
for _value in NOT_CHOICE:
    case(
        "PuzzleBoxConfig.engine",
        _value,
        lambda c, v=_value: PuzzleBoxConfig(engine=v),
        "PuzzleBoxConfig.engine",
    )
for _value in NOT_SEQUENCE + [("sideways",), ["harder_pinch", 5], [None]]:
    case(
        "PuzzleBoxConfig.variants",
        _value,
        lambda c, v=_value: PuzzleBoxConfig(variants=v),
        "PuzzleBoxConfig.variants",
    )
for _value in BAD_NAMES:
    case(
        "PuzzleBoxConfig.name",
        _value,
        lambda c, v=_value: PuzzleBoxConfig(name=v),
        "PuzzleBoxConfig.name",
    )
for _value in ["x", 5, None, [1], {"backups": 1, "nope": 2}, {"backups": 2.5}]:
    case(
        "PuzzleBoxConfig.learner",
        _value,
        lambda c, v=_value: PuzzleBoxConfig(learner=v),
        "learner" if not isinstance(_value, dict) or "nope" in _value else "backups",
    )
for _value in [10**8, COUNT_MAX]:
    case(
        "PuzzleBoxConfig.check_size",
        _value,
        lambda c, v=_value: PuzzleBoxConfig(seeds=v).check_size(),
        "seeds",
    )

# ============================================================================== the statistics
for _value in [[-0.1, 0.01], [1.5], [0.5, math.inf], [-math.inf], [[0.1, 0.2]], ["a"]]:
    case("holm.p_values", _value, lambda c, v=_value: holm(v), "p_values")
for _value in [
    ([1, 2, math.nan], [1, 2, 3]),
    ([1, 2, 3], [1, math.inf, 3]),
    ([1, 2, -math.inf], [1, 2, 3]),
]:
    case(
        "paired_comparison",
        _value,
        lambda c, v=_value: paired_comparison(*v),
        "a[" if not np.isfinite(_value[0]).all() else "b[",
    )
for _value in [[300, -1], [101], [-2], [2.5], [math.nan], [math.inf], []]:
    case(
        "first_goal_survival.first_goal_steps",
        _value,
        lambda c, v=_value: first_goal_survival(v, budget=100),
        "first_goal_steps",
    )
for _value in [-5, 0, 2.5, True, "100", math.nan, math.inf, None]:
    case(
        "first_goal_survival.budget",
        _value,
        lambda c, v=_value: first_goal_survival([3, -1], budget=v),
        "budget",
    )
for _value in [[], [math.nan], [1.0, math.inf], [[1.0, 2.0]], ["a"]]:
    case("t_interval.values", _value, lambda c, v=_value: t_interval(v), "values")

# ================================================================= the exact policy evaluator
for _value in [2.5, "500", True, False, 0, -1, None, math.nan, COUNT_MAX + 1, [5]]:
    case(
        "PolicyEvaluator.window",
        _value,
        lambda c, v=_value: PolicyEvaluator(c.grid, c.grid_options, v),
        "window",
    )
for _value in [None, 5, "MultiRooms"]:
    case(
        "PolicyEvaluator.world",
        _value,
        lambda c, v=_value: PolicyEvaluator(v, c.grid_options, 5),
        "world",
        TypeError,
    )
    case(
        "PolicyEvaluator.options",
        _value,
        lambda c, v=_value: PolicyEvaluator(c.grid, v, 5),
        "options",
        TypeError,
    )
    case(
        "PolicyEvaluator.evaluate.policy",
        _value,
        lambda c, v=_value: c.evaluator.evaluate(v),
        "policy",
        TypeError,
    )
for _name, _models in {
    "another-world": lambda c: c.other_models,
    "another-bundle": lambda c: c.mentor_models,
    "one-of-another": lambda c: (c.mentor_models[0], c.grid_models[1]),
    "swapped-in-pair": lambda c: (c.grid_models[0], c.mentor_models[1]),
}.items():
    case(  # accepted before: the evaluation then read another bundle's rows
        "PolicyEvaluator.models",
        _name,
        lambda c, m=_models: PolicyEvaluator(c.grid, c.grid_options, 5, models=m(c)),
        "not models of these options",
    )
for _name, _models in {
    "one-model": lambda c: c.grid_models[0],
    "three": lambda c: (*c.grid_models, c.grid_models[0]),
    "not-models": lambda c: (1, 2),
    "a-string": lambda c: "models",
}.items():
    case(
        "PolicyEvaluator.models",
        _name,
        lambda c, m=_models: PolicyEvaluator(c.grid, c.grid_options, 5, models=m(c)),
        "models must be the (discounted, durations) pair",
        TypeError,
    )
case(  # a policy's raw choice table is not an OptionPolicy either
    "PolicyEvaluator.evaluate.policy",
    "tensor",
    lambda c: c.evaluator.evaluate(torch.zeros(16, dtype=torch.int64)),
    "policy",
    TypeError,
)

# ================================================================================ with_options
for _value in [None, 5, "learner", _Thing()]:
    case(  # an AttributeError before
        "with_options.learner",
        _value,
        lambda c, v=_value: with_options(v, c.grid_options),
        "with_options: learner",
        TypeError,
    )

# ============================================================== the detour, BCO and shaping
for _value in ["box", None, 5]:
    case(
        "detour_waypoint.world",
        _value,
        lambda c, v=_value: detour_waypoint(c.box if v == "box" else v),
        "world",
    )
_BIG = torch.tensor([2**33])
case(
    "inverse_model.states",
    "2**33",
    lambda c: inverse_model(_BIG, torch.tensor([0]), _BIG, torch.tensor([1.0])),
    "states",
)
case(
    "inverse_model.states",
    "2**62",
    lambda c: inverse_model(
        torch.tensor([2**62]), torch.tensor([3]), torch.tensor([0]), torch.tensor([1.0])
    ),
    "states",
)
for _column in ("states", "successors"):
    case(
        "inverse_model.num_states",
        _column,
        lambda c, col=_column: inverse_model(
            torch.tensor([0, 1 if col == "successors" else 4]),
            torch.tensor([0, 1]),
            torch.tensor([1, 4 if col == "successors" else 2]),
            torch.tensor([1.0, 1.0]),
            num_states=4,
        ),
        _column,
    )
for _value in [0, -1, 2.5, True, "4"]:
    case(
        "inverse_model.num_states",
        _value,
        lambda c, v=_value: inverse_model(
            torch.tensor([0]), torch.tensor([0]), torch.tensor([0]), torch.tensor([1.0]),
            num_states=v,
        ),
        "num_states",
    )  # fmt: skip
for _field in ("num_states", "num_actions"):
    for _value in [0, -1, 2.5, True, "2", None, math.nan]:
        case(
            f"clone_policy.{_field}",
            _value,
            lambda c, f=_field, v=_value: clone_policy(
                torch.tensor([0]),
                torch.tensor([0]),
                torch.tensor([1.0]),
                **{"num_states": 3, "num_actions": 2, f: v},
            ),
            _field,
        )
_CHAIN = dict(
    sources=torch.tensor([0, 1]),
    successors=torch.tensor([1, 2]),
    counts=torch.tensor([1.0, 1.0]),
    rewards=torch.tensor([-0.01, 1.0]),
    gamma=0.9,
    terminal=torch.tensor([False, False, True, False]),
)
for _column in ("sources", "successors"):
    for _value in [
        torch.tensor([0.5, 1.7]),
        torch.tensor([0.0, 1.0], dtype=torch.float64),
        torch.tensor([True, False]),
    ]:
        case(
            f"shaping_potential.{_column}",
            _value,
            lambda c, col=_column, v=_value: shaping_potential(
                **{**_CHAIN, col: v}, initial_value=-1.0
            ),
            _column,
        )
        case(
            f"mentor_chain_value.{_column}",
            _value,
            lambda c, col=_column, v=_value: mentor_chain_value(
                **{**_CHAIN, col: v}, outside_value=-1.0
            ),
            _column,
        )


# =================================================================================== tests
@pytest.fixture(scope="module")
def context() -> Context:
    return Context()


@pytest.fixture(autouse=True)
def _memory_limit(monkeypatch):
    """A fixed limit, so the size checks refuse the same cases on every machine."""
    monkeypatch.setenv("HIMIT_MEMORY_LIMIT", "8GiB")


def test_the_cases_are_over_four_hundred():
    assert len(CASES) >= 400, len(CASES)


@pytest.mark.parametrize("bad", CASES)
def test_bad_input_raises_the_documented_error_naming_the_field(context, bad):
    bad.check(context)


# ----------------------------------------------------------------- what is still accepted
def test_good_neighbours_of_the_bad_values_are_accepted(context):
    """The refusals are not blanket: whole floats, arrays, NaN as "no test", a first goal at
    the budget's last step, one value, and every valid box and configuration are fine."""
    box = context.box
    assert box.encode(np.array([1, 2])) == box.encode((1.0, 2.0)) == 5 * 7 * 2 + 7
    assert box.encode(torch.tensor([1, 2])) == box.encode([1, 2])
    assert box.encode([1, 2], skewer=np.int64(0), grasp="pinch") == box.encode([1, 2], 0, "pinch")
    assert PuzzleBox.from_description(box.describe()).describe() == box.describe()
    assert PuzzleBox(1, steps=2).num_states == 3 * 4 == puzzle_box_size(1.0, 2.0)
    assert puzzle_box_size(SKEWERS_MAX, COUNT_MAX) > COUNT_MAX  # a size, computed at once
    assert (
        MultiRooms.from_description(context.grid.describe()).describe() == context.grid.describe()
    )
    config = PuzzleBoxConfig(seeds=2.0, steps=1e4, slip=0, pinch_slip=None, variants=["no_pinch"])
    assert (config.seeds, config.steps, config.variants) == (2, 10_000, ("no_pinch",))
    assert config.to_json() == PuzzleBoxConfig(seeds=2, steps=10_000, slip=0.0,
                                               variants=("no_pinch",)).to_json()  # fmt: skip
    assert PuzzleBoxConfig(learner={"backups": 3}).learner.backups == 3
    PuzzleBoxConfig().check_size()  # the study's own 20 seeds fit
    scores = organisation_scores([(0, 1), (0, 2)], 1, 2)
    assert scores["skewer"] == 1.0 and math.isnan(scores["step"])
    assert organisation_of([(0, 1)], 1, 1) == "skewer"  # defined: no division there
    assert math.isnan(holm([0.01, math.nan])[1]) and holm([0.0, 1.0]) == [0.0, 1.0]
    assert first_goal_survival([100, -1], budget=100).runs == 2  # a goal at the last step
    assert first_goal_survival([3.0, -1.0], budget=100.0).never == 1
    assert t_interval([5.0]).estimate == 5.0
    assert paired_comparison([1, 2, 3], [1, 2, 4]).losses == 1
    assert PolicyEvaluator(context.grid, context.grid_options, 5.0).window == 5
    for models in (context.grid_models, list(context.grid_models)):  # its own models, any pair
        own = PolicyEvaluator(context.grid, context.grid_options, 5, models=models)
        assert np.array_equal(own.duration, context.evaluator.duration)
    south = context.grid_options.initiation[1]  # primitive 1 (S) where it is usable
    policy = OptionPolicy.deterministic(torch.where(south, 1, -1))
    assert context.evaluator.evaluate(policy, values=False).goals_per_window.shape == (1,)
    assert detour_waypoint(context.grid) == 3
    one = torch.tensor([1.0, 1.0])
    model = inverse_model(torch.tensor([0, 1]), torch.tensor([0, 1]), torch.tensor([1, 2]), one,
                          num_states=3)  # fmt: skip
    assert model.states.tolist() == [0, 1]
    cloned = clone_policy(torch.tensor([0]), torch.tensor([1]), torch.tensor([1.0]), 2, 2.0)
    assert cloned.tolist() == [1, -1]
    int32 = {**_CHAIN, "sources": torch.tensor([0, 1], dtype=torch.int32)}
    phi = shaping_potential(**int32, initial_value=-1.0)
    assert [round(float(x), 4) for x in phi] == [1.89, 2.0, 0.0, 0.0]


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
        (["run", "puzzlebox", "--quick", "--seeds", "100000000"], "use fewer seeds"),
        (["run", "puzzlebox", "--quick", "--seeds", str(COUNT_MAX + 1)], "PuzzleBoxConfig.seeds"),
        (["run", "puzzlebox", "--quick", "--steps", "1e30"], "PuzzleBoxConfig.steps"),
        (["run", "puzzlebox", "--quick", "--steps", str(10**31)], "PuzzleBoxConfig.steps"),
        (["run", "puzzlebox", "--quick", "--steps", "2.5"], "PuzzleBoxConfig.steps"),
        (["run", "puzzlebox", "--quick", "--seeds", "2.5"], "PuzzleBoxConfig.seeds"),
        (["info", "--puzzle-box", "2", "--env-kwargs", "{}"], "--env-kwargs"),
        (["info", "--pinch-slip", "0.2"], "--pinch-slip"),
        (["info", "--size", "4", "--rooms", "2", "--pinch-slip", "0.2"], "--puzzle-box"),
        (["info", "--env", "Taxi-v3", "--pinch-slip", "0.2"], "--pinch-slip"),
    ],
)
def test_cli_puzzle_box_mistakes_are_one_line_exit_2(capsys, tmp_path, argv, says):
    if argv[0] == "run":
        argv = argv + ["--logdir", str(tmp_path / "runs")]
    status, err = _exit(capsys, argv)
    assert status == 2 and says in err, err
    assert not (tmp_path / "runs").exists()  # refused before anything was written
