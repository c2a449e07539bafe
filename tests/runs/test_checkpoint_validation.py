"""A checkpoint is validated in full before any engine touches it (issue 23).

A checksum proves nothing about a file whose checksum was recomputed after it was altered. Each
case below plants such a file — one invariant broken — and resumes it the way
``himit run exp2 … --resume`` does: it is refused naming the field, the run falls back to the
previous generation and ends with the uninterrupted curves, or, with no good generation left,
stops in one line with exit status 2. Before issue 23 the out-of-range indices crashed the
compiled kernel (SIGSEGV) and the rest ended in tracebacks.

``test_no_planted_value_reaches_the_kernel`` runs this file again with Numba's bounds checking
on (``NUMBA_BOUNDSCHECK=1``, the kernels compiled afresh): an index that reached the kernel would
raise there instead of going unnoticed.
"""

import math
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
import torch

import himit_torch.runs.checkpoints as ckpt
from himit_torch.cli import main
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.runs.experiment import run_experiment
from himit_torch.state_checks import DamagedState
from himit_torch.validation import json_depth
from tests.runs.test_checkpoints import (
    SIZE,
    newest_and_previous,
    one_line_error,
    reference,  # noqa: F401  (the module's uninterrupted run, a fixture)
    resume_argv,
    small_config,
    unfinished_copy,
)
from tests.tiers import first_fast

S = SIZE * SIZE


# ------------------------------------------------------------------------ planted damage
def put(piece: str, key: str, index, value) -> Callable[[dict], None]:
    """A change of the learner state: ``state[piece][key][index] = value``."""

    def change(state: dict) -> None:
        state[piece][key][index] = value

    return change


def swap(piece: str, key: str, make: Callable) -> Callable[[dict], None]:
    """A change of the learner state: ``state[piece][key]`` replaced by ``make`` of it."""

    def change(state: dict) -> None:
        state[piece][key] = make(state[piece][key])

    return change


#: One per invariant: the change of the learner state, and the field the refusal must name.
#: (``S`` states; the model's saved lists hold a few hundred edges, the mentor's a few dozen.)
CASES: dict[str, tuple[Callable[[dict], None], str]] = {
    "edge successor outside the states": (
        put("model", "edge_successor", (0, 0), 10**9),
        "model.edge_successor",
    ),
    "edge row outside the row table": (put("model", "edge_row", (0, 0), 10**9), "model.edge_row"),
    "mentor edge successor outside the states": (
        put("mentor", "edge_successor", (0, 0), S),
        "mentor.edge_successor",
    ),
    "num_edges beyond the capacity": (put("model", "num_edges", 0, 10**6), "model.num_edges"),
    "mentor num_edges beyond the capacity": (
        put("mentor", "num_edges", 0, 10**6),
        "mentor.num_edges",
    ),
    "negative num_edges": (put("model", "num_edges", 0, -1), "model.num_edges"),
    "position outside the states": (put("run", "position", 0, 10**9), "run.position"),
    "negative position": (put("run", "position", 1, -1), "run.position"),
    "row beyond the row table": (put("run", "row", 0, 10**9), "run.row"),
    "negative edge count": (put("model", "edge_count", (0, 0), -1.0), "model.edge_count"),
    "negative counter": (put("run", "goals", 0, -1), "run.goals"),
    "index tensor stored as float64": (
        swap("model", "edge_row", lambda t: t.double()),
        "model.edge_row",
    ),
    "metric lists of different lengths": (
        swap("metrics", "epsilon", lambda records: records[:-1]),
        "metrics.epsilon",
    ),
}


def plant(path: Path, change: Callable[[dict], None], section: str = "learner") -> None:
    """Rewrite the checkpoint at ``path`` with ``change`` applied to its ``section`` (the learner
    state by default) and the checksum recomputed: a file that verifies, as anyone can write
    one."""
    found = ckpt.read_checkpoint(path)
    change(found.payload[section])
    header = found.header
    path.write_bytes(
        ckpt.encode(
            found.payload,
            step=header.step,
            batch=header.batch,
            state_layout_version=header.state_layout_version,
        )
    )
    ckpt.read_checkpoint(path)  # it verifies


def plant_nested_header(path: Path) -> None:
    """Replace the header by 100 000 nested JSON arrays (Python's parser: ``RecursionError``)."""
    data = path.read_bytes()
    end = data.index(b"\n", len(ckpt.MAGIC))
    path.write_bytes(ckpt.MAGIC + b"[" * 100_000 + b"]" * 100_000 + data[end:])


#: Every planted file: how to plant it, and what its refusal must name.
PLANTED: dict[str, tuple[Callable[[Path], None], str]] = {
    **{
        kind: ((lambda path, change=change: plant(path, change)), field)
        for kind, (change, field) in CASES.items()
    },
    "deeply nested JSON header": (plant_nested_header, "header nests 100000 levels"),
}


# ------------------------------------------------------------------------- through the CLI
# Each case resumes the run to its end (≈ 1 s): the fast suite falls back from the first kind,
# CI from every kind; the test below refuses every kind in the fast suite.
@pytest.mark.parametrize("kind", first_fast(PLANTED, ids=list(PLANTED)))
def test_a_planted_newest_checkpoint_is_refused_by_name_and_the_run_falls_back(
    reference,  # noqa: F811
    tmp_path,
    capsys,
    kind,
):
    run_dir = unfinished_copy(reference, tmp_path)
    newest, previous = newest_and_previous(run_dir)
    make, field = PLANTED[kind]
    make(newest)
    assert main(resume_argv(run_dir)) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"himit: warning: {newest}: ") and field in err, err
    assert f"resuming from {previous.name} at step 1500" in err
    assert (run_dir / "curves.csv").read_text() == (reference / "curves.csv").read_text()


@pytest.mark.parametrize("kind", list(PLANTED))
def test_with_both_generations_planted_the_resume_stops_in_one_line_with_status_2(
    reference,  # noqa: F811
    tmp_path,
    capsys,
    kind,
):
    run_dir = unfinished_copy(reference, tmp_path)
    make, field = PLANTED[kind]
    for path in newest_and_previous(run_dir):
        make(path)
    err = one_line_error(capsys, resume_argv(run_dir))
    newest, previous = newest_and_previous(run_dir)
    assert f"{newest}: " in err and f"{previous}: " in err and "--force" in err
    assert err.count(field) == 2, err  # named for each file


def plant_greedy(path: Path, runs: int) -> None:
    """Rewrite the checkpoint at ``path`` with the greedy tracker's tensors cut to their first
    ``runs`` runs (the checksum recomputed: a file that verifies)."""

    def cut(greedy: dict) -> None:
        for name, values in greedy.items():
            if name != "steps":
                greedy[name] = [value[:runs].clone() for value in values]

    plant(path, cut, section="greedy")


def test_greedy_evaluations_of_another_batch_are_refused_on_resume(tmp_path, capsys):
    """A 4-run checkpoint whose greedy tracker holds 1 run's evaluations: refused by name in
    one line (the tracker checks them against the learner restored beside it), not an
    ``IndexError`` when the run next reads them."""
    run_dir = tmp_path / "exp2"
    run_experiment(small_config(seeds=2), run_dir, progress=False)  # 2 agents × 2 seeds
    (run_dir / "worlds" / f"world{SIZE}.json").unlink()
    (run_dir / "results.md").unlink()
    paths = newest_and_previous(run_dir)
    assert ckpt.read_checkpoint(paths[0]).payload["greedy"]["steps"]  # evaluations to cut
    for path in paths:
        plant_greedy(path, runs=1)
    err = one_line_error(capsys, resume_argv(run_dir))
    assert f"{paths[0]}: " in err and f"{paths[1]}: " in err and "--force" in err, err
    assert err.count("greedy.") == 2, err  # named for each file
    assert "IndexError" not in err


# ------------------------------------------------------------------------------ in process
@pytest.fixture(scope="module")
def saved(world8) -> tuple[Callable[[], Learner], dict]:
    """``(make, state)``: a batch of every kind of run (mentor, confidence test, posterior
    sampling, primitives), and its state after 1200 ticks (two windows and a part)."""
    options = learner_options(world8)
    demos = record_demonstrations(world8, mentor_policy(world8, mentor_options(world8)), 3, seed=0)
    agents = ["imitation", "imitation_confident", "imitation_psrl", "primitives"]

    def make() -> Learner:
        config = LearnerConfig(window=500, plan_every=4)
        return Learner(world8, options, agents, [0, 1, 2, 3], config=config, demonstrations=demos)

    learner = make()
    learner.run(1200)
    return make, learner.state_dict()


def copy_state(state):
    if isinstance(state, torch.Tensor):
        return state.clone()
    if isinstance(state, dict):
        return {k: copy_state(v) for k, v in state.items()}
    if isinstance(state, list):
        return [copy_state(v) for v in state]
    return state


def same_state(a, b) -> bool:
    if isinstance(a, torch.Tensor):  # (NaN equals NaN: a window without an episode)
        same = (a == b) | (a.isnan() & b.isnan()) if a.is_floating_point() else a == b
        return a.dtype == b.dtype and a.shape == b.shape and bool(same.all())
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same_state(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(same_state(x, y) for x, y in zip(a, b))
    return a == b


def other_state_row(learner: Learner, state: dict) -> int:
    """A row of some other state than where run 0's option started."""
    start = int(state["run"]["option_start"][0])
    return int((learner.rows.row_state[:-1] != start).nonzero()[0, 0])


def fill_an_empty_slot(state: dict) -> None:
    """An edge id in a slot beyond its run's ``num_edges`` (one of a run with fewer edges than
    the lists hold)."""
    model = state["model"]
    b = int(model["num_edges"].argmin())
    model["edge_row"][b, -1] = 0


#: Further invariants, checked in process (no run needed to show the refusal).
MORE_CASES: dict[str, tuple[Callable[[dict], None], str]] = {
    "NaN priority": (put("sweeper", "priority", (0, 0), math.nan), "sweeper.priority"),
    "priority beyond the last state": (
        put("sweeper", "priority", (0, -1), 1.0),
        "sweeper.priority",
    ),
    "pending decisions beyond plan_every": (put("sweeper", "pending", 0, 2**40), "sweeper.pending"),
    "NaN value": (put("cache", "values", (0, 3), math.nan), "cache.values"),
    "mentor edge rewards of another length": (
        swap("cache", "mentor_edge_reward", lambda t: t[:, :1]),
        "cache.mentor_edge_reward",
    ),
    "posterior draws of another length": (
        swap("sample", "option_w", lambda t: torch.cat([t, t], 1)),
        "sample.option_w",
    ),
    "negative posterior draw": (
        put("sample", "option_unseen", (2, 0), -0.5),
        "sample.option_unseen",
    ),
    "an edge listed twice": (
        lambda state: [
            state["model"][k].__setitem__((0, 1), state["model"][k][0, 0])
            for k in ("edge_row", "edge_successor")
        ],
        "model.edge_row",
    ),
    "a used slot beyond num_edges": (fill_an_empty_slot, "model.edge_row"),
    "mentor leaving the padding state": (put("mentor", "edge_row", (0, 0), 64), "mentor.edge_row"),
    "duration beyond max_option_steps": (put("run", "duration", 0, 10**9), "run.duration"),
    "epsilon above 1": (put("run", "epsilon", 0, 1.5), "run.epsilon"),
    "episode started in the future": (put("run", "episode_start", 0, 10**6), "run.episode_start"),
    "found_goal disagreeing with first_goal_step": (
        swap("run", "found_goal", lambda t: ~t),
        "run.found_goal",
    ),
    "t not a whole number": (lambda state: state["run"].__setitem__("t", 1200.0), "run.t"),
    "bool flags stored as int64": (swap("run", "found_goal", lambda t: t.long()), "run.found_goal"),
    "visits of another shape": (swap("run", "visits", lambda t: t[:, :-1]), "run.visits"),
    "a metric record of another shape": (
        lambda state: state["metrics"]["goals_in_window"].__setitem__(0, torch.zeros(9).long()),
        "metrics.goals_in_window[0]",
    ),
    "window ends that are not the windows'": (
        lambda state: state["metrics"]["steps"].__setitem__(0, 7),
        "metrics.steps",
    ),
    "a parameter, not a plain tensor": (
        swap("cache", "values", torch.nn.Parameter),
        "cache.values",
    ),
    "an unknown field": (lambda state: state["model"].__setitem__("on_grow", 1), "model"),
    "a missing piece": (lambda state: state.pop("sweeper"), "learner state: lacks ['sweeper']"),
    "identity not a dict": (lambda state: state.__setitem__("identity", [1]), "identity"),
}


@pytest.mark.parametrize("kind", [*CASES, *MORE_CASES])
def test_load_state_dict_refuses_each_broken_invariant_by_name_and_changes_nothing(saved, kind):
    make, state = saved
    learner = make()
    change, field = {**CASES, **MORE_CASES}[kind]
    broken = copy_state(state)
    change(broken)
    before = learner.state_dict()
    with pytest.raises(DamagedState) as err:
        learner.load_state_dict(broken)
    assert str(err.value).startswith(field), str(err.value)
    assert same_state(learner.state_dict(), before)  # refused before anything was restored


def test_a_row_of_another_state_than_the_option_started_in_is_refused(saved):
    make, state = saved
    learner = make()
    broken = copy_state(state)
    broken["run"]["row"][0] = other_state_row(learner, state)
    with pytest.raises(DamagedState, match="run.row: run 0 executes row"):
        learner.load_state_dict(broken)


def test_the_valid_state_still_restores_and_continues_bit_for_bit(saved):
    """The checks pass every state a run writes (every kind of run; the padding row and the
    empty slots included), and a restored learner goes on exactly as the original."""
    make, state = saved
    original = make()
    original.run(1200)
    restored = make()
    restored.load_state_dict(copy_state(state))
    original.run(600)
    restored.run(600)
    assert same_state(restored.state_dict(), original.state_dict())


def test_another_batch_is_still_an_incompatibility_not_damage(saved, world8):
    _, state = saved
    other = Learner(world8, learner_options(world8), ["options"], [0])
    with pytest.raises(ValueError, match="does not match") as err:
        other.load_state_dict(state)
    assert not isinstance(err.value, DamagedState)


def test_an_identity_holding_a_tensor_is_refused_not_compared_elementwise(saved):
    make, state = saved
    broken = copy_state(state)
    broken["identity"]["seeds"] = torch.tensor([0, 1, 2, 3])  # == would compare elementwise
    with pytest.raises(ValueError, match=r"does not match this learner: \['seeds'\] differ"):
        make().load_state_dict(broken)


@pytest.mark.parametrize(
    "text, depth",
    [
        (b"3", 0),
        (b'{"a": [1, {"b": []}]}', 4),
        (b'{"a": "[[[[{{{{", "b": ["]]]]"]}', 2),  # brackets inside strings do not count
        (rb'{"a": "\"[[[", "b": [[]]}', 3),  # nor after an escaped quote
        (b"[" * 50_000 + b"]" * 50_000, 50_000),
    ],
)
def test_json_depth_counts_nesting_outside_strings(text, depth):
    assert json_depth(text) == depth
    assert json_depth(text.decode()) == depth


# ------------------------------------------------------------------------ bounds checking
@pytest.mark.skipif(
    os.environ.get("NUMBA_BOUNDSCHECK") != "1",
    reason="only with Numba's bounds checking on (without it this would crash the process)",
)
def test_bounds_checking_is_live_in_this_process(world8):
    """Control for the run below: in this process an index that reaches the kernel raises
    ``IndexError`` — so the planted files' runs, which end normally, never passed one."""
    learner = Learner(world8, learner_options(world8), ["options"], [0], engine="numba")
    learner.run_state.position[0] = 10**6  # behind the checks' back
    with pytest.raises(IndexError):
        learner.run(1)


@pytest.mark.slow
@pytest.mark.extended  # (it compiles every kernel afresh, with bounds checks: minutes)
def test_no_planted_value_reaches_the_kernel(tmp_path):
    """This file's tests once more, in a process whose kernels are compiled afresh (a cache of
    its own) with ``NUMBA_BOUNDSCHECK=1``."""
    env = {
        **os.environ,
        "NUMBA_BOUNDSCHECK": "1",
        "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache"),
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).resolve().parents[2]), *sys.path]),
    }
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            __file__,
            "-p",
            "no:cacheprovider",
            "-n",
            "0",
            "-q",
            "-m",
            "not slow",
            "-k",
            "planted or bounds_checking",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert " passed" in done.stdout and "skipped" not in done.stdout, done.stdout[-2000:]
