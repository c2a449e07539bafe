"""Bad input on the library's families left from the last rounds: the demonstrations a learner
with several mentors is given (``transitions()``, ``durations()``, ``counts``), the backups'
tensor arguments, ``first_part``, demonstration files, the puzzle box's helpers, the stress and
baseline helpers and the exact greedy API. Each mistake is the documented exception — a
``ValueError``, or a ``TypeError`` for an argument that is no kind of the object asked for —
with a message naming the argument; never an ``AttributeError``, an ``IndexError``, a
``MemoryError``, a ``RuntimeError`` or a value silently cast (``9.5`` read as state 9).

Beside every family stands its valid neighbour (``GOOD``): the same call with good arguments
gives the right answer, so no case can pass by refusing everything.

The cases are generated (``len(CASES)`` is asserted below); the worlds are 4×4 grids and
2-skewer boxes and nothing ticks a learner, so the lot runs in seconds.
"""

from __future__ import annotations

import inspect
import io
import math
import zipfile
from functools import cached_property
from pathlib import Path

import numpy as np
import pytest
import torch

from himit_torch.exact.greedy_evaluation import (
    OptionPolicy,
    PolicyEvaluator,
    evaluate_option_choice,
    optimal_policy_evaluation,
    optimal_value,
)
from himit_torch.learner import backups
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.cloning import clone_policy, inverse_model, relabel
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.observation import CoarseDemonstrations, first_part
from himit_torch.mentor.policy import mentor_detour, mentor_policy, record_demonstrations
from himit_torch.mentor.potential import mentor_chain_value, shaping_potential
from himit_torch.mentor.puzzle_box import map_demonstrations, map_states, organisation_mentor
from himit_torch.options.builders import mentor_options, primitive_options
from himit_torch.options.puzzle_box import (
    go_to_skewer_options,
    intended_rollout,
    puzzle_box_options,
    step_options,
)
from himit_torch.worlds.multirooms import MultiRooms
from himit_torch.worlds.puzzle_box import (
    PuzzleBox,
    next_step,
    organisation_of,
    organisation_scores,
)
from tests.bad_inputs import Cases


class _Thing:
    def __repr__(self):
        return "<thing>"


CASES = Cases()
case = CASES.add
#: The valid neighbours: ``(name, check(context))``, each asserting what the good call gives.
GOOD: list = []


def good(name: str):
    def register(check):
        GOOD.append(pytest.param(check, id=name))
        return check

    return register


class Context:
    """What the cases build on, made on first use (``folder``: a scratch folder)."""

    folder: Path

    @cached_property
    def grid(self) -> MultiRooms:
        return MultiRooms(4, 2)

    @cached_property
    def learner(self) -> Learner:
        """A learner watching two mentors (the torch engine: nothing compiles)."""
        grid = self.grid
        return Learner(
            grid,
            primitive_options(grid),
            ["imitation"],
            [0],
            config=LearnerConfig(mentors=2, mentor_segments=True),
            engine="torch",
        )

    @cached_property
    def box(self) -> PuzzleBox:
        return PuzzleBox(2)

    @cached_property
    def box_options(self):
        return puzzle_box_options(self.box, "mentor")

    @cached_property
    def box_policy(self) -> torch.Tensor:
        """The skewer-by-skewer mentor's option at each state (−1 at the end)."""
        return organisation_mentor(self.box, "skewer").option

    @cached_property
    def mentor(self):
        return mentor_policy(self.grid, mentor_options(self.grid))

    @cached_property
    def inverse(self):
        """The inverse model of one own move, 0 --0--> 1."""
        return inverse_model(_ONE, _ONE, torch.tensor([1]), torch.tensor([1.0]))

    @cached_property
    def grid_options(self):
        return primitive_options(self.grid)

    @cached_property
    def evaluator(self) -> PolicyEvaluator:
        return PolicyEvaluator(self.grid, self.grid_options, 5)

    @cached_property
    def optimum(self):
        return optimal_policy_evaluation(self.grid, 5)

    @cached_property
    def box_demos(self) -> Demonstrations:
        """The first moves of the box: the hand to skewer 1, then home again."""
        box = self.box
        return Demonstrations([torch.tensor([0, box.encode([0, 0], 0), 0])], box)

    @cached_property
    def demos(self) -> Demonstrations:
        return Demonstrations([torch.tensor([0, 1, 5, 6])], self.grid)


# ====================================================================== several mentors
class _Moves:
    """A demonstrations object of one's own: ``transitions()`` (and optionally ``durations()``
    and ``counts``) as given."""

    def __init__(self, src, dst, counts=None):
        self.src, self.dst = src, dst
        if counts is not None:
            self.counts = counts

    def transitions(self):
        return self.src, self.dst


class _Timed(_Moves):
    def __init__(self, src, dst, durations):
        super().__init__(src, dst)
        self.steps = durations

    def durations(self):
        return self.steps


class _Odd:
    """``transitions()`` returns something other than a pair."""

    def __init__(self, value):
        self.value = value

    def transitions(self):
        return self.value


#: Columns that are never states of a 16-state world (fractional, bool, NaN, beyond it, no
#: numbers at all, 2-D).
NOT_STATES = [
    [9.5],
    [0.5],
    torch.tensor([2.5]),
    np.array([1.25]),
    [True],
    torch.tensor([True]),
    np.array([False]),
    [math.nan],
    [math.inf],
    torch.tensor([math.nan]),
    torch.tensor([1j]),
    ["1"],
    None,
    "01",
    {"a": 1},
    _Thing(),
    torch.tensor([[0]]),
    np.array([[1]]),
    [-1],
    [16],
    torch.tensor([2**40]),
]
for _end in ("from", "to"):
    for _value in NOT_STATES:
        _field = (
            "another world"
            if _value in ([-1], [16])
            or (
                isinstance(_value, torch.Tensor)
                and _value.dtype == torch.int64
                and _value.dim() == 1
            )
            else f"demonstrations.transitions() {_end}"
        )
        case(
            f"add_demonstrations.transitions.{_end}",
            _value,
            lambda c, e=_end, v=_value: c.learner.add_demonstrations(
                _Moves(v, [1]) if e == "from" else _Moves([0], v), mentor=1
            ),
            _field,
        )
for _pair in [([0, 1], [1]), ([0], [1, 5]), ([], [1]), (torch.tensor([0, 1]), torch.tensor([1]))]:
    case(  # an IndexError before
        "add_demonstrations.transitions.lengths",
        _pair,
        lambda c, p=_pair: c.learner.add_demonstrations(_Moves(*p), mentor=1),
        "of one length",
    )
for _value in [None, torch.tensor([0, 1]), ([0], [1], [5]), "ab", 5]:
    case(
        "add_demonstrations.transitions.pair",
        _value,
        lambda c, v=_value: c.learner.add_demonstrations(_Odd(v), mentor=1),
        "transitions() must return the pair",
        TypeError,
    )
for _value in [
    None,  # a RuntimeError before
    [True],  # a bool: accepted silently before
    torch.tensor([True]),
    [1.5],
    torch.tensor([2.5]),
    [math.nan],
    [0],
    [-2],
    ["2"],
    "2",
    [[1]],
    torch.tensor([[1]]),
    [1, 1],
    [],
    [2**40],
]:
    case(
        "add_demonstrations.durations",
        _value,
        lambda c, v=_value: c.learner.add_demonstrations(_Timed([0], [1], v), mentor=1),
        "demonstrations.durations()",
    )
for _value in [[0.0], [-1.0], [math.nan], [math.inf], [True], ["1"], [1.0, 1.0], "1", 5]:
    case(
        "add_demonstrations.counts",
        _value,
        lambda c, v=_value: c.learner.add_demonstrations(_Moves([0], [1], v), mentor=1),
        "demonstrations.counts",
    )


@good("add_demonstrations")
def _(c):
    """Whole floats, NumPy columns and a second mentor are fine; the moves land in mentor 1's
    rows (its block of states), with their durations."""
    learner = c.learner
    before = int(learner.mentor.num_edges[0])
    learner.add_demonstrations(_Timed(np.array([0.0, 1.0]), [1, 5], torch.tensor([1, 3])), mentor=1)
    assert int(learner.mentor.num_edges[0]) == before + 2
    learner.add_demonstrations(_Moves([1], [5], counts=[2.0]), mentor=0)
    learner.add_demonstrations(CoarseDemonstrations(c.demos, 2), mentor=1)
    assert int(learner.mentor.num_edges[0]) >= before + 3


# ============================================================================== backups
def _t(*shape, dtype=torch.float64):
    n = math.prod(shape)
    return (torch.arange(n, dtype=torch.float64) / 10 - 0.2).reshape(shape).to(dtype)


def _mask(*shape):
    return (torch.arange(math.prod(shape)) % 2 == 0).reshape(shape)


#: Valid arguments of each backup (batch [2], J/K 3, A 4); masks are bool.
BACKUPS = {
    "option_backup": dict(reward=_t(2), weights=_t(2, 3), successor_values=_t(2, 3)),
    "option_backup_edges": dict(
        reward=_t(1, 2),
        runs=torch.tensor([0, 0]),
        rows=torch.tensor([0, 1]),
        weights=_t(2),
        successor_values=_t(2),
    ),
    "mentor_backup_edges": dict(
        shape=(1, 2),
        runs=torch.tensor([0, 0]),
        rows=torch.tensor([0, 1]),
        counts=_t(2) + 1,
        rewards=_t(2),
        discounts=_t(2) + 0.5,
        successor_values=_t(2),
    ),
    "shaped_option_backup": dict(
        reward=_t(2),
        weights=_t(2, 3),
        successor_values=_t(2, 3),
        potential=_t(2),
        successor_potentials=_t(2, 3),
    ),
    "mentor_backup": dict(
        mentor_reward=_t(2), mentor_probs=_t(2, 3), successor_values=_t(2, 3), gamma=0.9
    ),
    "segment_reward": dict(
        last_reward=_t(2), delay=_t(2) + 0.5, unseen_step_reward=-0.01, gamma=0.9
    ),
    "segment_discount": dict(delay=_t(2), gamma=0.9),
    "segment_mentor_backup": dict(
        segment_rewards=_t(2, 3),
        segment_discounts=_t(2, 3),
        mentor_probs=_t(2, 3),
        successor_values=_t(2, 3),
    ),
    "options_only_backup": dict(option_q=_t(2, 3), available=_mask(2, 3)),
    "augmented_option_backup": dict(
        option_q=_t(2, 3), available=_mask(2, 3), mentor_term=_t(2), mentor_available=_mask(2)
    ),
    "augmented_backup": dict(own_value=_t(2), mentor_term=_t(2), mentor_available=_mask(2)),
    "primitives_only_backup": dict(
        reward=_t(2, 4), probs=_t(2, 4, 3), successor_values=_t(2, 4, 3), gamma=0.9
    ),
    "augmented_primitive_backup": dict(
        observer_reward=_t(2),
        probs=_t(2, 4, 3),
        successor_values=_t(2, 4, 3),
        mentor_probs=_t(2, 3),
        mentor_successor_values=_t(2, 3),
        mentor_available=_mask(2),
        gamma=0.9,
    ),
    "dirichlet_value_moments": dict(counts=_t(2, 3) + 1, outcome_values=_t(2, 3)),
    "dirichlet_variance": dict(mean=_t(2), second_moment=_t(2) + 1, total=_t(2) + 1),
    "confident_mentor": dict(
        mentor_mean=_t(2),
        mentor_var=_t(2) + 1,
        own_mean=_t(2, 3),
        own_var=_t(2, 3) + 1,
        own_available=_mask(2, 3),
        z=1.0,
    ),
    "mentor_override": dict(observed=_mask(2), own_tries=_t(2) + 1, override_after=3.0),
    "feasible_mentor": dict(
        reached=_t(2, 3) + 1, tries=_t(2, 3) + 3, enabled=_mask(2, 3), min_tries=3
    ),
    "best_mentor": dict(terms=_t(2, 3), observed=_mask(2, 3)),
    "faded_mentor_term": dict(mentor_term=_t(2), own_value=_t(2), own_tries=_t(2) + 1, fade=2.0),
    "trusted_augmented_backup": dict(
        option_q=_t(2, 3),
        available=_mask(2, 3),
        mentor_term=_t(2),
        mentor_observed=_mask(2),
        own_tries=_t(2) + 1,
        fade=2.0,
    ),
}
#: Number arguments each backup checks.
BACKUP_NUMBERS = {
    "segment_reward": ("unseen_step_reward", "gamma"),
    "mentor_override": ("override_after",),
    "faded_mentor_term": ("fade",),
    "trusted_augmented_backup": ("fade",),
}
for _fn, _kwargs in BACKUPS.items():
    for _arg, _valid in _kwargs.items():
        if not isinstance(_valid, torch.Tensor):
            continue
        _optional = _arg == "own_tries"  # None is its documented "not needed"
        _bads = [None] * (not _optional) + [_valid.tolist(), _valid.numpy(), "x", _Thing()]
        if _valid.dtype == torch.bool:
            _bads.append(_valid.double())  # a mask of 0/1 numbers is no mask
        for _value in _bads:
            case(  # an AttributeError or a TypeError from deep in torch before
                f"{_fn}.{_arg}",
                _value,
                lambda c, f=_fn, a=_arg, v=_value: getattr(backups, f)(**{**BACKUPS[f], a: v}),
                f"{_fn}: {_arg}",
            )
        if _fn == "segment_discount":
            continue  # any shape is its shape
        case(  # a wrong shape: refused naming the function (and the argument it disagrees with)
            f"{_fn}.{_arg}.shape",
            "[5, 5, 5, 5]",
            lambda c, f=_fn, a=_arg: getattr(backups, f)(
                **{**BACKUPS[f], a: torch.zeros(5, 5, 5, 5, dtype=BACKUPS[f][a].dtype)}
            ),
            f"{_fn}: ",
        )
for _fn, _args in BACKUP_NUMBERS.items():
    for _arg in _args:
        for _value in [None, "0.5", True, [0.5], _Thing()]:
            if _value is None and _fn in ("mentor_override", "trusted_augmented_backup"):
                continue  # None is its documented "off"
            case(
                f"{_fn}.{_arg}",
                _value,
                lambda c, f=_fn, a=_arg, v=_value: getattr(backups, f)(**{**BACKUPS[f], a: v}),
                f"{_fn}: {_arg}",
            )
for _value in [None, (2,), (1, 2, 3), "x", (1.5, 2), (True, 2)]:
    case(
        "mentor_backup_edges.shape",
        _value,
        lambda c, v=_value: backups.mentor_backup_edges(**{**BACKUPS["mentor_backup_edges"],
                                                           "shape": v}),
        "mentor_backup_edges: shape",
    )  # fmt: skip


@good("backups")
def _(c):
    """Every backup takes its valid arguments (a tensor out, of the batch shape), NumPy-typed
    numbers included; no options at all (J = 0) is "no option available": −inf, as documented."""
    for name, kwargs in BACKUPS.items():
        out = getattr(backups, name)(**kwargs)
        first = out[0] if isinstance(out, tuple) else out
        assert isinstance(first, torch.Tensor) and first.shape[0] in (1, 2), name
    assert backups.faded_mentor_term(**{**BACKUPS["faded_mentor_term"], "fade": np.float32(2)})[
        0
    ] == pytest.approx(float(backups.faded_mentor_term(**BACKUPS["faded_mentor_term"])[0]))
    none = torch.zeros(2, 0, dtype=torch.float64)
    no = torch.zeros(2, 0, dtype=torch.bool)
    assert backups.options_only_backup(none, no).tolist() == [-math.inf, -math.inf]
    value, won = backups.trusted_augmented_backup(none, no, _t(2), _mask(2))
    assert value.tolist() == [-0.2, -math.inf] and won.tolist() == [True, False]


# ============================================================================ first_part
for _value in [None, [torch.tensor([0, 1, 5])], "demos.npz", 5, _Thing(), torch.tensor([0, 1])]:
    case(  # an AttributeError before
        "first_part.demonstrations",
        _value,
        lambda c, v=_value: first_part(v, 0.5),
        "first_part: demonstrations",
        TypeError,
    )
for _value in [0, -0.5, 1.5, math.nan, "0.5", True, None]:
    case(
        "first_part.coverage",
        _value,
        lambda c, v=_value: first_part(c.demos, v),
        "first_part: coverage",
    )


@good("first_part")
def _(c):
    assert first_part(c.demos, 0.5).episodes[0].tolist() == [0, 1]
    assert first_part(c.demos, 1).episodes[0].tolist() == [0, 1, 5, 6]


# ===================================================================== demonstration files
def _npy_header(shape, descr: str = "<i8") -> bytes:
    """A version 1.0 ``.npy`` header announcing ``shape`` of ``descr`` (no data follows)."""
    out = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        out, {"descr": descr, "fortran_order": False, "shape": tuple(shape)}
    )
    return out.getvalue()


def _file_with(c, name: str, members: dict) -> Path:
    """A saved demonstrations file whose members ``members`` (name → bytes; ``None``: left
    out) replace or join the saved ones."""
    good_file = c.demos.save(c.folder / "good.npz")
    path = c.folder / name
    with zipfile.ZipFile(good_file) as src, zipfile.ZipFile(path, "w") as dst:
        for info in src.infolist():
            if info.filename not in members:
                dst.writestr(info.filename, src.read(info))
        for member, data in members.items():
            if data is not None:
                dst.writestr(member, data)
    return path


_BIG = 2**33
DAMAGED_FILES = {
    # raw bytes where an array belongs: np.load hands them back as bytes (an AttributeError)
    "raw-states": ({"states.npy": None, "states": b"\x00" * 16}, "'states' is not a NumPy"),
    "raw-world": ({"world.npy": None, "world": b'{"kind": "MultiRooms"}'}, "'world' is not"),
    "raw-extra": ({"notes.txt": b"hello"}, "'notes.txt' is not a NumPy"),
    # a few bytes announcing 2^33 elements: a MemoryError before
    "2^33-int64": ({"states.npy": _npy_header((_BIG,))}, "announces shape (8589934592,)"),
    "2^33-uint8": ({"states.npy": _npy_header((_BIG,), "|u1")}, "announces shape"),
    "2^33-starts": ({"episode_starts.npy": _npy_header((_BIG,))}, "'episode_starts.npy' announces"),
    "2^20x2^20": ({"states.npy": _npy_header((2**20, 2**20), "<f8")}, "announces shape"),
    "2^28-world": ({"world.npy": _npy_header((), "<U268435456")}, "'world.npy' announces"),
    "short-data": ({"states.npy": _npy_header((10,)) + b"\x00" * 8}, "holds 8 bytes"),
    "objects": (
        {"states.npy": _npy_header((1,), "|O") + b"\x00" * 8},
        "Object arrays cannot be loaded",
    ),
    "not-npy": ({"states.npy": b"PK not an array at all"}, "not a readable .npz"),
    "npy-v9": ({"states.npy": b"\x93NUMPY\x09\x00" + b"\x00" * 8}, "has .npy version (9, 0)"),
}
for _name, (_members, _says) in DAMAGED_FILES.items():
    case(
        "Demonstrations.load",
        _name,
        lambda c, n=_name, m=_members: Demonstrations.load(_file_with(c, f"{n}.npz", m)),
        _says,
    )
    case(  # the same file with the world given: refused before the world is compared
        "Demonstrations.load.world",
        _name,
        lambda c, n=_name, m=_members: Demonstrations.load(
            _file_with(c, f"{n}-w.npz", m), world=c.grid
        ),
        _says,
    )


@good("Demonstrations.load")
def _(c):
    """The file save writes, and one rewritten member by member as it was, read back."""
    same = _file_with(c, "same.npz", {})
    for path in (c.demos.save(c.folder / "saved.npz"), same):
        back = Demonstrations.load(path, world=c.grid)
        assert [e.tolist() for e in back.episodes] == [[0, 1, 5, 6]]


# ======================================================================== the puzzle box
_S = 175  # PuzzleBox(2): (4 + 1)² levels × 7 hand states
NOT_BOX_STATES = [
    torch.tensor([2.5]),
    [0.5],
    np.array([1.5]),
    [-1],
    [_S],
    torch.tensor([_S + 10]),
    torch.tensor([True]),
    [False],
    [math.nan],
    torch.tensor([1j]),
    None,
    "0",
    {"s": 0},
]
for _method in ("progress", "hand", "step_events", "subgoals", "grasps_used"):
    for _value in NOT_BOX_STATES + (
        [torch.tensor([[0, 1]])] if _method not in ("progress", "hand") else []
    ):
        case(  # a fractional state was truncated, a negative or too large one decoded as another
            f"PuzzleBox.{_method}",
            _value,
            lambda c, m=_method, v=_value: getattr(c.box, m)(v),
            f"PuzzleBox.{_method}: states",
        )
for _value in [2.5, -1, _S, 10**20, True, "3", None, math.nan, [0], torch.tensor([1, 2])]:
    case(
        "PuzzleBox.decode",
        _value,
        lambda c, v=_value: c.box.decode(v),
        "PuzzleBox.decode: state",
    )
    case(
        "PuzzleBox.render_ansi",
        _value,
        lambda c, v=_value: c.box.render_ansi(v),
        "PuzzleBox.decode: state",
    )
for _value in [0, 5, -1, 2.5, True, "1", None, math.nan]:
    case(
        "PuzzleBox.action_motion",
        _value,
        lambda c, v=_value: c.box.action_motion(v),
        "PuzzleBox.action_motion: step",
    )
for _value in [[0.5, 1], [-1, 0], [5, 0], [], None, "01", [True, 0], [math.nan, 0], 3]:
    case(
        "next_step.progress",
        _value,
        lambda c, v=_value: next_step(v, "skewer"),
        "next_step: progress",
    )
for _value in [1, 2.5, None, True, "4"]:
    case("next_step.steps", _value, lambda c, v=_value: next_step([0, 1], "step", v), "steps")
for _value in [None, "skewers", 5]:
    case(
        "next_step.organisation",
        _value,
        lambda c, v=_value: next_step([0, 1], v),
        "organisation",
    )
_ADVANCES = [None, 5, "ab", [(0, 1.5)], [(0,)], [(True, 1)], [(None, 1)], [(0, "1")], [3]]
for _fn in (organisation_of, organisation_scores):
    for _value in _ADVANCES:
        case(  # a TypeError, or a step 1.5 read as 1, before
            f"{_fn.__name__}.advances",
            _value,
            lambda c, f=_fn, v=_value: f(v, 1, 2),
            f"{_fn.__name__}: advances",
        )
for _field, _values in {"skewers": [0, 2.5, None, True, -1], "steps": [0, 2.5, None, "2"]}.items():
    for _value in _values:
        case(
            f"organisation_of.{_field}",
            _value,
            lambda c, f=_field, v=_value: organisation_of([(0, 1)], **{"skewers": 1, "steps": 1,
                                                                       f: v}),
            f"organisation_of: {_field}",
        )  # fmt: skip
for _fn in (go_to_skewer_options, step_options, puzzle_box_options):
    for _value in [None, "grid", 5, "box"]:
        case(  # an AttributeError before; the grid's "options" were built from a world of rooms
            f"{_fn.__name__}.box",
            _value,
            lambda c, f=_fn, v=_value: f(c.grid if v == "grid" else v),
            f"{_fn.__name__}: box",
            TypeError,
        )
for _value in [None, 1, "yes", 0, np.bool_(True)]:
    case(
        "puzzle_box_options.pinch",
        _value,
        lambda c, v=_value: puzzle_box_options(c.box, pinch=v),
        "puzzle_box_options: pinch",
    )
for _value in [None, "LEARNER", 5, ["mentor"]]:
    for _fn in (step_options, puzzle_box_options):
        case(
            f"{_fn.__name__}.style",
            _value,
            lambda c, f=_fn, v=_value: f(c.box, v),
            "style=",
        )
for _value in [None, "grid", 5, "box"]:
    case(
        "organisation_mentor.box",
        _value,
        lambda c, v=_value: organisation_mentor(c.grid if v == "grid" else v, "skewer"),
        "organisation_mentor: box",
        TypeError,
    )
for _value in [None, 5, "Skewer", ["skewer"]]:
    case(
        "organisation_mentor.organisation",
        _value,
        lambda c, v=_value: organisation_mentor(c.box, v),
        "organisation=",
    )
_OTHER_OPTIONS = {
    "grid-options": (lambda c: primitive_options(c.grid), ValueError, "another world's"),
    "bigger-box": (lambda c: puzzle_box_options(PuzzleBox(3)), ValueError, "another world's"),
    "no-layout": (lambda c: primitive_options(c.box), ValueError, "skills hold"),
    "list": (lambda c: [c.box_options], TypeError, "Options bundle"),
    "number": (lambda c: 5, TypeError, "Options bundle"),
    "string": (lambda c: "mentor", TypeError, "Options bundle"),
}
for _name, (_make, _error, _says) in _OTHER_OPTIONS.items():
    case(  # another world's options: an IndexError, or a policy over the wrong states, before
        "organisation_mentor.options",
        _name,
        lambda c, m=_make: organisation_mentor(c.box, "step", m(c)),
        "organisation_mentor: options",
        _error,
    )
    if _name != "no-layout":
        case(
            "intended_rollout.options",
            _name,
            lambda c, m=_make: intended_rollout(c.box, m(c), torch.zeros(_S, dtype=torch.int64)),
            "intended_rollout: options",
            _error,
        )
for _value in [
    torch.full((_S,), 0.5),
    torch.zeros(_S, dtype=torch.bool),
    torch.zeros(_S - 1, dtype=torch.int64),
    torch.full((_S,), -2),
    torch.full((_S,), 99),
    None,
    "0",
    torch.zeros(1, _S, dtype=torch.int64),
]:
    case(
        "intended_rollout.policy",
        _value,
        lambda c, v=_value: intended_rollout(c.box, c.box_options, v),
        "policy",
    )
for _value in [2.5, -1, "5", True, math.inf]:
    case(
        "intended_rollout.max_steps",
        _value,
        lambda c, v=_value: intended_rollout(c.box, c.box_options, c.box_policy, v),
        "intended_rollout: max_steps",
    )
for _value in [[0.5], [-1], [_S], None, torch.tensor([True]), torch.tensor([[0]])]:
    case(
        "map_states.states",
        _value,
        lambda c, v=_value: map_states(c.box, PuzzleBox(3), v, (0, 2), 0),
        "map_states: states",
    )
for _value in [None, [0.5, 1], "02", [True, 1], 5]:
    case(
        "map_states.skewers",
        _value,
        lambda c, v=_value: map_states(c.box, PuzzleBox(3), [0], v, 0),
        "map_states: skewers",
    )
for _value in [2.5, -1, 5, None, True, "0"]:
    case(
        "map_states.level",
        _value,
        lambda c, v=_value: map_states(c.box, PuzzleBox(3), [0], (0, 2), v),
        "map_states: level",
    )

for _value in [None, [torch.tensor([0, 1])], "demos.npz", 5]:
    case(  # an AttributeError before
        "map_demonstrations.demonstrations",
        _value,
        lambda c, v=_value: map_demonstrations(v, c.box, PuzzleBox(3)),
        "map_demonstrations: demonstrations",
        TypeError,
    )
for _value in [None, ["plain"], 5, "PLAIN"]:
    case(
        "map_demonstrations.mapping",
        _value,
        lambda c, v=_value: map_demonstrations(c.box_demos, c.box, PuzzleBox(3), v),
        "mapping=",
    )


@good("puzzle box")
def _(c):
    """Whole floats, NumPy and list states, a rollout and a mentor with its own options."""
    box = c.box
    state = box.encode([1, 2], skewer=1, grasp="pinch")
    assert box.decode(float(state)) == box.decode(np.int64(state)) == ((1, 2), 1, "pinch")
    assert box.progress([state, 0.0]).tolist() == [[1, 2], [0, 0]]
    assert box.hand(np.array([state])).tolist() == [1 + 3 * 1 + 2]
    assert box.action_motion(2.0) == box.action_motion(2) == 2 + 2 + 2
    one = box.encode([0, 0], 0, "power")
    after = box.encode([1, 0])
    assert box.step_events([one, after]) == [(0, 1, 1)] == [(*a, 1) for a in box.subgoals(
        torch.tensor([one, after]))]  # fmt: skip
    assert box.grasps_used([one, after]) == ["power"]
    assert next_step(np.array([4, 1]), "skewer", 4.0) == (1, 2)
    assert organisation_of([(0, 1), (0, 2)], 1.0, 2) == "skewer"
    plan, opened = intended_rollout(box, c.box_options, c.box_policy, 1000.0)
    assert opened and int(plan[-1]) in torch.nonzero(box.terminal_mask).flatten().tolist()
    mentor = organisation_mentor(box, "skewer", puzzle_box_options(box, "mentor"))
    assert torch.equal(mentor.option, organisation_mentor(box, "skewer").option)
    mapped = map_states(box, PuzzleBox(3), np.array([state]), [0.0, 2], 4.0)
    assert PuzzleBox(3).decode(int(mapped[0])) == ((1, 4, 2), 2, "pinch")
    bigger = map_demonstrations(c.box_demos, box, PuzzleBox(3), "any")
    assert len(bigger) == 3 * 5  # C(3, 2) choices of skewers × 5 levels of the third


# ============================================================== stress and baseline helpers
for _value in ["detour", 5, {"waypoint": 3}, _Thing()]:
    case(  # an AttributeError before
        "record_demonstrations.detour",
        _value,
        lambda c, v=_value: record_demonstrations(c.grid, c.mentor, 1, detour=v),
        "record_demonstrations: detour",
        TypeError,
    )
_ONE = torch.tensor([0])
_CHAIN = dict(
    sources=torch.tensor([0, 1]),
    successors=torch.tensor([1, 2]),
    counts=torch.tensor([1.0, 1.0]),
    rewards=torch.tensor([-0.01, 1.0]),
    gamma=0.9,
    terminal=torch.tensor([False, False, True, False]),
)
_TRANSITION = dict(states=_ONE, actions=_ONE, successors=torch.tensor([1]))
for _column in ("states", "actions", "successors"):
    for _value in [[0], None, "0", np.array([0]), 0]:
        case(  # an AttributeError before
            f"inverse_model.{_column}",
            _value,
            lambda c, col=_column, v=_value: inverse_model(
                **{**_TRANSITION, col: v}, counts=torch.tensor([1.0])
            ),
            f"inverse_model: {_column}",
            TypeError,
        )
    for _value in [torch.tensor([0.5]), torch.tensor([1.0]), torch.tensor([True]),
                   torch.tensor([-1]), torch.tensor([[0]])]:  # fmt: skip
        case(
            f"inverse_model.{_column}",
            _value,
            lambda c, col=_column, v=_value: inverse_model(
                **{**_TRANSITION, col: v}, counts=torch.tensor([1.0])
            ),
            "inverse_model: ",
        )
for _value in ["1", None, [math.nan], torch.tensor([True]), torch.tensor([1j]), [-1.0], [1, 1]]:
    case(
        "inverse_model.counts",
        _value,
        lambda c, v=_value: inverse_model(**_TRANSITION, counts=v),
        "inverse_model: counts",
    )
for _value in [None, "model", {"states": _ONE}, _Thing()]:
    case(
        "relabel.model",
        _value,
        lambda c, v=_value: relabel(v, _ONE, _ONE),
        "relabel: model",
        TypeError,
    )
for _column in ("states", "successors"):
    for _value in [[0], None, "0", np.array([0])]:
        case(
            f"relabel.{_column}",
            _value,
            lambda c, col=_column, v=_value: relabel(
                c.inverse, **{"states": _ONE, "successors": _ONE, col: v}
            ),
            f"relabel: {_column}",
            TypeError,
        )
    for _value in [torch.tensor([0.5]), torch.tensor([True]), torch.tensor([-1])]:
        case(
            f"relabel.{_column}",
            _value,
            lambda c, col=_column, v=_value: relabel(
                c.inverse, **{"states": _ONE, "successors": _ONE, col: v}
            ),
            f"relabel: {_column}",
        )
for _column in ("states", "labels"):
    for _value in [torch.tensor([1.0]), torch.tensor([0.5]), torch.tensor([True]),
                   torch.tensor([[0]]), torch.tensor([0, 1])]:  # fmt: skip
        case(  # float labels: an IndexError, or labels truncated, before
            f"clone_policy.{_column}",
            _value,
            lambda c, col=_column, v=_value: clone_policy(
                **{"states": _ONE, "labels": _ONE, col: v},
                weights=torch.tensor([1.0]),
                num_states=2,
                num_actions=2,
            ),
            "clone_policy: ",
        )
    for _value in [[0], None, np.array([0])]:
        case(
            f"clone_policy.{_column}",
            _value,
            lambda c, col=_column, v=_value: clone_policy(
                **{"states": _ONE, "labels": _ONE, col: v},
                weights=torch.tensor([1.0]),
                num_states=2,
                num_actions=2,
            ),
            f"clone_policy: {_column}",
            TypeError,
        )
for _value in [[math.nan], torch.tensor([math.inf]), "1", torch.tensor([True]), None]:
    case(
        "clone_policy.weights",
        _value,
        lambda c, v=_value: clone_policy(_ONE, _ONE, v, 2, 2),
        "clone_policy: weights",
    )
for _value in [math.nan, math.inf, -math.inf, None, "-1", True, [1.0], torch.tensor(1.0)]:
    case(  # a NaN potential everywhere before
        "shaping_potential.initial_value",
        _value,
        lambda c, v=_value: shaping_potential(**_CHAIN, initial_value=v),
        "shaping_potential: initial_value",
    )
    case(
        "mentor_chain_value.outside_value",
        _value,
        lambda c, v=_value: mentor_chain_value(**_CHAIN, outside_value=v),
        "mentor_chain_value: outside_value",
    )
for _value in [math.nan, 0.0, 1.5, None, "0.9", True]:
    case(
        "mentor_chain_value.gamma",
        _value,
        lambda c, v=_value: mentor_chain_value(**{**_CHAIN, "gamma": v}, outside_value=-1.0),
        "mentor_chain_value: gamma",
    )
for _column in ("counts", "rewards", "terminal"):
    for _value in [None, [1.0, 1.0], np.ones(2)]:
        case(  # an AttributeError before
            f"mentor_chain_value.{_column}",
            _value,
            lambda c, col=_column, v=_value: shaping_potential(
                **{**_CHAIN, col: v}, initial_value=-1.0
            ),
            f"mentor_chain_value: {_column}",
            TypeError,
        )


@good("stress and baseline helpers")
def _(c):
    """A detour of this world, an inverse model relabelling its own move, a cloned policy and
    the hand-solved chain's potential (module docstrings)."""
    detour = mentor_detour(c.grid)
    demos = record_demonstrations(c.grid, c.mentor, 2, detour=detour, seed=0)
    assert len(demos) == 2 and int(demos.episodes[0][0]) == c.grid.start_state
    assert relabel(c.inverse, torch.tensor([0]), torch.tensor([1])).tolist() == [0]
    assert clone_policy(_ONE, torch.tensor([1]), [2.0], 2, 2).tolist() == [1, -1]
    phi = shaping_potential(**{**_CHAIN, "gamma": np.float64(0.9)}, initial_value=np.float32(-1))
    assert [round(float(x), 4) for x in phi] == [1.89, 2.0, 0.0, 0.0]


# ============================================================================ exact greedy
_ROWS = torch.tensor([[0], [1]])
for _name, _value in {
    "numpy-option": np.array([[0], [1]]),
    "list-option": [[0], [1]],
    "none-option": None,
}.items():
    case(  # an AttributeError before
        "OptionPolicy.option",
        _name,
        lambda c, v=_value: OptionPolicy(v, torch.ones(1, 2, 1, dtype=torch.float64)),
        "OptionPolicy.option",
        TypeError,
    )
for _name, _value in {
    "numpy-probability": np.ones((1, 2, 1)),
    "list-probability": [[[1.0], [1.0]]],
    "none-probability": None,
}.items():
    case(
        "OptionPolicy.probability",
        _name,
        lambda c, v=_value: OptionPolicy(_ROWS, v),
        "OptionPolicy.probability",
        TypeError,
    )
for _value in [
    torch.ones(1, 2, 1, dtype=torch.complex128),  # a RuntimeError before
    torch.ones(1, 2, 1, dtype=torch.bool),
    torch.ones(1, 2, 1, dtype=torch.int64),
    torch.full((1, 2, 1), math.nan, dtype=torch.float64),
    torch.full((1, 2, 1), -1.0, dtype=torch.float64),
    torch.full((1, 2, 1), 0.5, dtype=torch.float64),
]:
    case(
        "OptionPolicy.probability",
        _value,
        lambda c, v=_value: OptionPolicy(_ROWS, v),
        "OptionPolicy.probability",
    )
for _value in [torch.tensor([[-2], [0]]), torch.tensor([[0], [-7]])]:
    case(  # read as "no option" before
        "OptionPolicy.option",
        _value,
        lambda c, v=_value: OptionPolicy(v, torch.zeros(1, 2, 1, dtype=torch.float64)),
        "OptionPolicy.option holds",
    )
for _value in [
    [0.5, 1],
    [math.nan, 0],
    torch.tensor([math.nan, 1.0]),
    np.array([-2, 0]),
    [-5, 0],
    [True, 0],
    torch.tensor([1j, 0]),
    None,
    "01",
]:
    case(  # NaN read as an option, −5 as none, before
        "OptionPolicy.deterministic",
        _value,
        lambda c, v=_value: OptionPolicy.deterministic(v),
        "OptionPolicy.deterministic: option",
    )
for _fn, _call in {
    "evaluate_option_choice": lambda w, c: evaluate_option_choice(
        w, c.grid_options, torch.zeros(16, dtype=torch.int64), 5
    ),
    "optimal_policy_evaluation": lambda w, c: optimal_policy_evaluation(w, 5),
    "optimal_value": lambda w, c: optimal_value(w),
}.items():
    for _value in [None, "MultiRooms", 5, _Thing(), "grid.json"]:
        case(  # an AttributeError before
            f"{_fn}.world",
            _value,
            lambda c, f=_call, v=_value: f(v, c),
            f"{_fn}: world",
            TypeError,
        )
for _value in [None, "options", 5, [1]]:
    case(
        "evaluate_option_choice.options",
        _value,
        lambda c, v=_value: evaluate_option_choice(
            c.grid, v, torch.zeros(16, dtype=torch.int64), 5
        ),
        "evaluate_option_choice: options",
        TypeError,
    )
for _value in [
    torch.full((16,), 0.5),
    torch.full((16,), math.nan),
    torch.full((16,), -3),
    torch.zeros(16, dtype=torch.bool),
    torch.zeros(16, dtype=torch.complex64),
    torch.zeros(1, 16, dtype=torch.int64),
    None,
    "0",
]:
    case(
        "evaluate_option_choice.option",
        _value,
        lambda c, v=_value: evaluate_option_choice(c.grid, c.grid_options, v, 5),
        "evaluate_option_choice: option",
    )
for _value in [2.5, 0, None, "5", True]:
    case(
        "optimal_policy_evaluation.window",
        _value,
        lambda c, v=_value: optimal_policy_evaluation(c.grid, v),
        "optimal_policy_evaluation: window",
    )
for _value in [None, "plan", 5, (1, 2)]:
    if _value is None:
        continue  # None: compute it
    case(
        "optimal_policy_evaluation.plan",
        _value,
        lambda c, v=_value: optimal_policy_evaluation(c.grid, 5, plan=v),
        "optimal_policy_evaluation: plan",
        TypeError,
    )
for _value in ["models", 5, (1, 2)]:
    case(  # an AttributeError deep in value iteration before
        "optimal_policy_evaluation.models",
        _value,
        lambda c, v=_value: optimal_policy_evaluation(c.grid, 5, models=v),
        "models must be the (discounted, durations) pair",
        TypeError,
    )
for _value in [None, "0", math.nan, math.inf, True, [1.0]]:
    case(
        "PolicyEvaluation.value_gap",
        _value,
        lambda c, v=_value: c.optimum.value_gap(v),
        "PolicyEvaluation.value_gap: optimal_value",
    )
for _value in [None, "3", math.nan, -1.0, True, torch.tensor([1j]), torch.tensor([True])]:
    case(
        "PolicyEvaluation.percent_of",
        _value,
        lambda c, v=_value: c.optimum.percent_of(v),
        "PolicyEvaluation.percent_of: goals_per_window",
    )
for _value in [np.zeros((16, 1), dtype=np.int64) - 2, torch.full((16, 1), 0.5), None, [[0]] * 16]:
    case(
        "PolicyEvaluator.model_rows",
        _value,
        lambda c, v=_value: c.evaluator.model_rows(v),
        "PolicyEvaluator.model_rows: option",
    )


@good("exact greedy")
def _(c):
    """The optimum's own evaluation, its value gap 0 and 100 % of itself; a NumPy choice and
    whole floats as options; model rows of a NumPy table."""
    optimum = c.optimum
    assert float(optimum.value_gap(optimal_value(c.grid))[0]) == 0.0
    assert float(optimum.percent_of(float(optimum.goals_per_window[0]))[0]) == pytest.approx(100)
    choice = OptionPolicy.deterministic(np.array([1.0] * 16))
    assert choice.option.dtype == torch.int64 and choice.batch == 1
    south = torch.where(c.grid_options.initiation[1], 1, -1)
    direct = evaluate_option_choice(c.grid, c.grid_options, south.numpy(), 5)
    assert direct.goals_per_window.shape == (1,)
    rows = c.evaluator.model_rows(np.zeros((16, 1), dtype=np.int64))
    assert (rows >= 0).sum() == int(c.grid_options.initiation[0].sum())


# =================================================================================== tests
@pytest.fixture(scope="module")
def context(tmp_path_factory) -> Context:
    c = Context()
    c.folder = tmp_path_factory.mktemp("bad-files")
    return c


@pytest.fixture(autouse=True)
def _memory_limit(monkeypatch):
    """A fixed limit, so the size checks refuse the same cases on every machine."""
    monkeypatch.setenv("HIMIT_MEMORY_LIMIT", "8GiB")


def test_the_cases_are_over_three_hundred():
    assert len(CASES) >= 300, len(CASES)


@pytest.mark.parametrize("bad", CASES)
def test_bad_input_raises_the_documented_error_naming_the_field(context, bad):
    bad.check(context)


@pytest.mark.parametrize("check", GOOD)
def test_the_valid_neighbour_is_accepted(context, check):
    check(context)


def test_every_backup_has_cases():
    """Each public backup of the module is among the generated cases (a new one joins them)."""
    public = {n for n in backups.__all__ if inspect.isfunction(getattr(backups, n))}
    assert public == set(BACKUPS), public ^ set(BACKUPS)
