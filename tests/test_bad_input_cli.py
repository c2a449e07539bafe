"""Bad input on the run side: the studies' configurations and ``run_study``, sweep specs, resumed
runs, a file where a folder belongs, ``himit plot``'s records — each the documented exception
(``ValueError``, or ``TypeError`` for an argument that is no kind of the object asked for), its
message naming what is wrong; on the command line one ``himit: error:`` line, exit status 2.
And nothing already on disk changes when a command is refused: for every command that writes
(``himit run STUDY`` for each registered study, with ``--resume`` and ``--force``, ``himit
plot``, ``himit sweep``, ``himit demo``) a refused call leaves a directory with content byte for
byte as it was.

Beside every family stands its valid neighbour (``GOOD``), so no case can pass by refusing
everything. The cases are generated (``len(CASES)`` is asserted below); nothing runs a learner,
and the CLI is called in-process, so the lot runs in seconds.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import json
import os
import shutil
from pathlib import Path

import pytest

from himit_torch.cli import build_parser, cmd_plot, main, study_configs
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.presets import PRESETS
from himit_torch.runs.config import ExperimentConfig
from himit_torch.runs.discovery import DiscoveryConfig, run_discovery
from himit_torch.runs.experiment import read_world_result, run_experiment
from himit_torch.runs.gymnasium import (
    GymExperimentConfig,
    read_gym_curves,
    run_gym_experiment,
)
from himit_torch.runs.puzzle_box import PuzzleBoxConfig, run_puzzle_box
from himit_torch.runs.puzzle_box_report import read_summary
from himit_torch.runs.studies import STUDIES
from himit_torch.runs.study import config_differences, prepare_run_dir
from himit_torch.runs.sweep import load_spec
from himit_torch.validation import check_folder_path, settings_of
from tests.bad_inputs import Cases

CASES = Cases()
case = CASES.add
GOOD: list = []

RESULTS = Path(__file__).resolve().parents[1] / "experiments" / "results"
RECORDS = {
    "exp2": RESULTS / "paper-first" / "exp2",
    "gymnasium": RESULTS / "paper-first" / "gymnasium",
    "puzzlebox": RESULTS / "puzzlebox",
}


def good(name: str):
    def register(check):
        GOOD.append(pytest.param(check, id=name))
        return check

    return register


class _Thing:
    def __repr__(self):
        return "<thing>"


# ======================================================================== study configs
#: The configuration classes of the registered studies (one each).
CONFIG_CLASSES = list(dict.fromkeys(entry.config_class for entry in STUDIES.values()))
#: Those whose learner watches one demonstration set (``mentors`` is no derived setting).
ONE_MENTOR = [
    c
    for c in CONFIG_CLASSES
    if any(f.name == "learner" for f in dataclasses.fields(c))
    and "mentors" not in c.derived_learner
]
BAD_PRESETS = [
    None, 3, "", "nope", ["paper"], "Paper", 1.5, True, _Thing(), "paper ", " paper", "PAPER",
    "recommended\n", 0, b"paper", ("paper",), {"paper"}, -1,
]  # fmt: skip


def _config(cls, **changes):
    """A valid configuration of ``cls`` (the registered study's defaults) with ``changes``."""
    entry = next(e for e in STUDIES.values() if e.config_class is cls)
    return dataclasses.replace(entry.defaults(), **changes)


for _cls in ONE_MENTOR:
    for _n in (2, 3, 4, 5, 6, 8, 16, 32, 64):
        case(
            f"{_cls.__name__}.learner.mentors",
            _n,
            lambda c, k=_cls, n=_n: k(learner=LearnerConfig(mentors=n)),
            f"{_cls.__name__}.learner.mentors={_n}",
        )
for _cls in CONFIG_CLASSES:
    for _name in BAD_PRESETS:
        case(
            f"{_cls.__name__}.with_preset",
            _name,
            lambda c, k=_cls, n=_name: _config(k).with_preset(n),
            f"{_cls.__name__}.with_preset",
        )


@good("study configs")
def _(c):
    for cls in ONE_MENTOR:
        assert cls(learner=LearnerConfig(mentors=1)).learner.mentors == 1
    for cls in CONFIG_CLASSES:
        for name in PRESETS:
            assert _config(cls).with_preset(name).preset == name
    # the paper's experiments derive their mentors from second_mentor
    assert ExperimentConfig(second_mentor="noisy").learner.mentors == 2


# ============================================================================ run_study
RUNNERS = {
    "run_experiment": (run_experiment, ExperimentConfig),
    "run_gym_experiment": (run_gym_experiment, GymExperimentConfig),
    "run_discovery": (run_discovery, DiscoveryConfig),
    "run_puzzle_box": (run_puzzle_box, PuzzleBoxConfig),
}
for _runner, (_run, _cls) in RUNNERS.items():
    others = [k for _, k in RUNNERS.values() if not issubclass(k, _cls)]
    for _bad in [None, {}, "config", 3, {"name": "x"}, *others]:
        shown = _bad.__name__ if isinstance(_bad, type) else _bad
        case(
            f"{_runner}.config",
            shown,
            lambda c, r=_run, b=_bad: r(b() if isinstance(b, type) else b, c.folder / "never"),
            "run_study: config=",
            TypeError,
        )
    for _bad in [None, 3, [], 1.5, _Thing(), b"dir", 0, True, {"a": 1}]:
        case(
            f"{_runner}.run_dir",
            _bad,
            lambda c, r=_run, k=_cls, b=_bad: r(_config(k), b),
            "run_study: run_dir=",
            TypeError,
        )
    for _flag, _bad in [
        ("force", "yes"),
        ("force", 1),
        ("force", None),
        ("force", "false"),
        ("force", 0.0),
        ("progress", "no"),
        ("progress", 1),
        ("progress", None),
    ]:
        case(
            f"{_runner}.{_flag}",
            _bad,
            lambda c, r=_run, k=_cls, f=_flag, b=_bad: r(_config(k), c.folder / "never", **{f: b}),
            f"run_study: {_flag}=",
            TypeError,
        )


@good("run_study")
def _(c):
    """Valid arguments pass the checks and reach the run directory's own (a finished run)."""
    finished = c.folder / "finished"
    finished.mkdir(exist_ok=True)
    (finished / "results.md").write_text("done\n")
    for run, cls in RUNNERS.values():
        with pytest.raises(ValueError, match="already holds a finished run"):
            run(_config(cls), finished, force=False, progress=False)
    assert not (c.folder / "never").exists()


# ================================================================= resumes name settings
_RESUMED = {
    "seeds": 7,
    "steps": 30_000,
    "mentor_episodes": 3,
    "slip": 0.2,
    "agents": ("imitation",),
    "mentor_noise": 0.1,
    "first_seed": 4,
}
_LEARNER = {"backups": 3, "plan_every": 2, "tie_break": "first", "mentor_fade": 10.0}
for _field, _value in _RESUMED.items():
    case(
        "--resume",
        f"{_field}={_value!r}",
        lambda c, f=_field, v=_value: c.resume(dataclasses.replace(ExperimentConfig(), **{f: v})),
        f"{_field}: saved {getattr(ExperimentConfig(), _field)!r}, given {_value!r}",
    )
for _field, _value in _LEARNER.items():
    case(
        "--resume",
        f"learner.{_field}={_value!r}",
        lambda c, f=_field, v=_value: c.resume(
            ExperimentConfig(learner=dataclasses.replace(ExperimentConfig().learner, **{f: v}))
        ),
        f"learner.{_field}: saved {getattr(ExperimentConfig().learner, _field)!r}",
    )


@good("--resume")
def _(c):
    c.resume(ExperimentConfig())  # the saved one: accepted, config.json rewritten the same
    assert config_differences(ExperimentConfig(), ExperimentConfig()) == []
    two = config_differences(ExperimentConfig(), ExperimentConfig(seeds=2, steps=10_000))
    assert two == ["seeds: saved 5, given 2", "steps: saved 200000, given 10000"]


# =================================================================== a file for a folder
for _depth in range(3):
    for _where in ("the run directory", "himit demo: --out", "the sweep's folder"):
        case(
            "check_folder_path",
            f"{_where} {_depth}",
            lambda c, d=_depth, w=_where: check_folder_path(w, c.plain.joinpath(*["x"] * d)),
            f"{_where} ",
        )


@good("check_folder_path")
def _(c):
    assert check_folder_path("x", c.folder / "a" / "b") == c.folder / "a" / "b"
    assert check_folder_path("x", c.folder) == c.folder


# ========================================================================= sweep specs
#: Settings that may not be None (their "none" stays a string, which their choices refuse).
_NOT_OPTIONAL = [
    s.name
    for s in settings_of(ExperimentConfig)
    if not s.optional
    and s.kind is str
    and s.info.choices
    and "none" not in s.info.choices
    and s.name not in {"name"}
]
_NOT_OPTIONAL_LEARNER = [
    "learner." + s.name
    for s in settings_of(LearnerConfig)
    if not s.optional and s.kind is str and s.info.choices and "none" not in s.info.choices
]


def _spec(c, text: str):
    path = c.folder / "spec.toml"
    path.write_text(text)
    return load_spec(path)


def _grid_level(name: str) -> str:
    first = next(
        s.default
        for s in (*settings_of(ExperimentConfig), *settings_of(LearnerConfig))
        if s.name == name.removeprefix("learner.")
    )
    return json.dumps(first)


for _name in _NOT_OPTIONAL + _NOT_OPTIONAL_LEARNER:
    case(
        "sweep [grid] none",
        _name,
        lambda c, n=_name: _spec(c, f'[grid]\n{n} = [{_grid_level(n)}, "none"]'),
        f"cell {_name.removeprefix('learner.')}=none",
    )
for _other in ("none", "noisy", "detour"):
    for _n in (1, 2, 3):
        if (_n == 2) == (_other != "none"):
            continue  # this cell's own number: valid
        case(
            "sweep learner.mentors",
            (_n, _other),
            lambda c, n=_n, o=_other: (
                _spec(c, f'[set]\nlearner.mentors = {n}\n[grid]\nsecond_mentor = ["noisy", "{o}"]')
                if o != "noisy"
                else _spec(c, f'[set]\nlearner.mentors = {n}\n[grid]\nsecond_mentor = ["{o}"]')
            ),
            "learner.mentors",
        )
for _window in (1000, 2500):
    case(
        "sweep learner.window",
        _window,
        lambda c, w=_window: _spec(c, f"[set]\nlearner.window = {w}\n[grid]\nwindow = [5000, {w}]"),
        f"cell window=5000: learner.window={_window}",
    )


@good("sweep specs")
def _(c):
    two = _spec(c, '[set]\nlearner.mentors = 2\n[grid]\nsecond_mentor = ["noisy", "detour"]')
    assert [cell.config.learner.mentors for cell in two.cells] == [2, 2]
    mixed = _spec(
        c, '[grid]\nsecond_mentor = ["none", "noisy"]\nlearner.untried_value = ["none", 3.0]'
    )
    assert [cell.config.second_mentor for cell in mixed.cells] == ["none"] * 2 + ["noisy"] * 2
    assert [cell.config.learner.untried_value for cell in mixed.cells] == [None, 3.0] * 2
    # [set] alone would be refused (7500 is no multiple of 5000), every cell is valid
    windows = _spec(c, "[set]\ncheckpoint_every = 7500\n[grid]\nwindow = [2500, 7500]")
    assert [cell.config.window for cell in windows.cells] == [2500, 7500]
    with pytest.raises(ValueError, match=r"\[set\]: .*checkpoint_every"):
        _spec(c, "[set]\ncheckpoint_every = 7500\n[grid]\nwindow = [5000, 2000]")


# ======================================================================= plot's records
def _json(rel: str, change):
    def damage(d: Path) -> None:
        path = d / rel
        text = json.dumps(change(json.loads(path.read_text())))
        path.unlink()  # (a hard link to the pristine copy: a new file in its place)
        path.write_text(text)

    return damage


def _csv(rel: str, change):
    def damage(d: Path) -> None:
        path = d / rel
        rows = list(csv.reader(io.StringIO(path.read_text(), newline="")))
        change(rows)
        path.unlink()  # (a hard link to the pristine copy: a new file in its place)
        with path.open("w", newline="") as f:
            csv.writer(f).writerows(rows)

    return damage


def _drop(name: str):
    def change(rows):
        k = rows[0].index(name)
        for row in rows:
            del row[k]

    return change


def _cell(name: str, value: str, row: int = 1):
    return lambda rows: rows[row].__setitem__(rows[0].index(name), value)


_WORLD = "worlds/world40.json"
_PER_RUN_EXP = ("agents", "seeds", "goals", "first_goal_step", "final_window_goals")
_BOX = "summary.json"
_TAXI = "tasks/taxi.json"
_BOX_CSV = "batches/speed_imitation.csv"
_BOX_EVALS = "batches/speed_imitation.evals.json"


def _batches(change):
    return _json(_BOX, lambda r: {**r, "batches": [change(dict(b)) for b in r["batches"]]})


PLOT_DAMAGE = {
    "exp2": {
        **{
            f"optimal_steps={v}": (_json(_WORLD, lambda r, v=v: {**r, "optimal_steps": v}), v)
            for v in (0, -1, 0.0, -0.5)
        },
        **{
            f"optimal_goals_per_window={v}": (
                _json(_WORLD, lambda r, v=v: {**r, "optimal_goals_per_window": v}),
                "optimal_goals_per_window",
            )
            for v in (0, -3)
        },
        "steps=0": (
            _json(_WORLD, lambda r: {**r, "steps": 0}),
            "'steps' must be a whole number > 0, got 0",
        ),
        "steps=2.5": (
            _json(_WORLD, lambda r: {**r, "steps": 2.5}),
            "'steps' must be a whole number > 0, got 2.5",
        ),
        "rooms=0": (
            _json(_WORLD, lambda r: {**r, "rooms": 0}),
            "'rooms' must be a whole number > 0, got 0",
        ),
        "no runs": (
            _json(_WORLD, lambda r: {**r, **{k: [] for k in r if isinstance(r[k], list)}}),
            "'agents' must name one agent per run",
        ),
        "curves without step": (_csv("curves.csv", _drop("step")), "columns ['step']"),
        "curves without agent": (_csv("curves.csv", _drop("agent")), "columns ['agent']"),
        "no curve rows": (
            _csv("curves.csv", lambda rows: rows.__delitem__(slice(1, None))),
            "no rows",
        ),
        "a lost row": (_csv("curves.csv", lambda rows: rows.pop()), "other steps"),
        "a row twice": (_csv("curves.csv", lambda rows: rows.append(list(rows[1]))), "twice"),
        "a step moved": (_csv("curves.csv", _cell("step", "7")), "other steps"),
        "a seed moved": (_csv("curves.csv", _cell("seed", "-5")), "other steps"),
    },
    "gymnasium": {
        "curves without step": (_csv("curves.csv", _drop("step")), "columns ['step']"),
        "curves without task": (_csv("curves.csv", _drop("task")), "columns ['task']"),
        "curves without value_gap": (_csv("curves.csv", _drop("value_gap")), "value_gap"),
        "a step in words": (_csv("curves.csv", _cell("step", "x")), "step='x'"),
        "goals in words": (_csv("curves.csv", _cell("goals", "x")), "goals='x'"),
        "an infinite gap": (_csv("curves.csv", _cell("value_gap", "inf")), "value_gap='inf'"),
        "no curve rows": (
            _csv("curves.csv", lambda rows: rows.__delitem__(slice(1, None))),
            "no rows",
        ),
        "a short row": (_csv("curves.csv", lambda rows: rows[1].pop()), "cells, not"),
        "a lost row": (_csv("curves.csv", lambda rows: rows.pop()), "other steps"),
        "one run's goals short": (
            _json(_TAXI, lambda r: {**r, "total_goals": r["total_goals"][1:]}),
            "'total_goals' must hold one number or null per run",
        ),
        "goals in words per run": (
            _json(_TAXI, lambda r: {**r, "final_goals": ["a"] * len(r["final_goals"])}),
            "'final_goals' must hold one number or null per run",
        ),
        "nested per-run lists": (
            _json(_TAXI, lambda r: {**r, "final_value_gap": [[1]] * len(r["agents"])}),
            "'final_value_gap'",
        ),
        "no runs": (_json(_TAXI, lambda r: {**r, "agents": []}), "'agents' must name"),
        "another task's record": (
            _json(_TAXI, lambda r: {**r, "task": "frozenlake8x8"}),
            "not 'taxi'",
        ),
        "an optimum of 0": (
            _json(_TAXI, lambda r: {**r, "optimal_goals_per_window": 0}),
            "'optimal_goals_per_window' must be a number > 0",
        ),
    },
    "puzzlebox": {
        "no batches": (
            _json(_BOX, lambda r: {**r, "batches": []}),
            "'batches' must be a non-empty list of objects",
        ),
        "no transfer": (
            _json(_BOX, lambda r: {**r, "batches": r["batches"][:3]}),
            "lacks ['transfer_any'",
        ),
        "a batch of no runs": (_batches(lambda b: {**b, "runs": []}), "batches[0].runs"),
        "runs in words": (_batches(lambda b: {**b, "runs": ["x"]}), "batches[0].runs"),
        "a run without its seed": (
            _batches(
                lambda b: {
                    **b,
                    "runs": [{k: v for k, v in r.items() if k != "seed"} for r in b["runs"]],
                }
            ),
            "batches[0].runs",
        ),
        "an optimum of 0": (
            _batches(lambda b: {**b, "optimal_steps": 0}),
            "batches[0].optimal_steps",
        ),
        "steps 0": (_batches(lambda b: {**b, "steps": 0}), "batches[0].steps"),
        "states in words": (_batches(lambda b: {**b, "num_states": "x"}), "batches[0].num_states"),
        "V* in words": (_batches(lambda b: {**b, "value_star": "x"}), "batches[0].value_star"),
        "curves without step": (_csv(_BOX_CSV, _drop("step")), "columns ['step']"),
        "no curve rows": (_csv(_BOX_CSV, lambda rows: rows.__delitem__(slice(1, None))), "no rows"),
        "openings in words": (_csv(_BOX_CSV, _cell("openings", "x")), "openings='x'"),
        "a lost row": (_csv(_BOX_CSV, lambda rows: rows.pop()), "other steps"),
        "a seed too few": (
            _csv(
                _BOX_CSV,
                lambda rows: rows.__setitem__(slice(None), [r for r in rows if r[3] != "0"]),
            ),
            "runs' curves, not",
        ),
        "evaluations of one run": (
            _json(
                _BOX_EVALS, lambda r: {k: {m: v[:1] for m, v in e.items()} for k, e in r.items()}
            ),
            "for each of the batch's",
        ),
        "no evaluations": (_json(_BOX_EVALS, lambda r: {}), "not evaluations"),
        "evaluations as a list": (_json(_BOX_EVALS, lambda r: []), "not evaluations"),
        "nested evaluations": (
            _json(
                _BOX_EVALS,
                lambda r: {k: {m: [[1]] * len(v) for m, v in e.items()} for k, e in r.items()},
            ),
            "for each of the batch's",
        ),
        "a step in words": (
            _json(_BOX_EVALS, lambda r: {"x": next(iter(r.values()))}),
            "'x' is not a step",
        ),
        "no evaluations file": (lambda d: (d / _BOX_EVALS).unlink(), "does not exist"),
    },
}


class _Plot:
    """``himit plot`` (its command, without building the parser each time: main turns its
    ``ValueError`` into one line and exit 2, tested below) of a copy of a committed run
    directory damaged by ``damage``; nothing may be drawn before the refusal."""

    def __init__(self, study: str, damage):
        self.study, self.damage = study, damage

    def __call__(self, c) -> None:
        run_dir = c.copy(self.study)
        self.damage(run_dir)
        before = snapshot(run_dir)
        try:
            cmd_plot(argparse.Namespace(run_dir=str(run_dir)))
        finally:
            assert snapshot(run_dir) == before


for _study, _damages in PLOT_DAMAGE.items():
    for _kind, (_damage, _says) in _damages.items():
        case(f"himit plot {_study}", _kind, _Plot(_study, _damage), str(_says))


@good("himit plot's records")
def _(c):
    """The committed records, undamaged, are read through every check."""
    exp2 = c.copy("exp2")
    assert read_world_result(exp2 / _WORLD, 40).optimal_steps > 0
    gym = c.copy("gymnasium")
    assert set(read_gym_curves(gym)) == {"taxi", "cliffwalking", "frozenlake8x8"}
    from himit_torch.runs.puzzle_box import _check_batch_records

    box = c.copy("puzzlebox")
    _check_batch_records(box, read_summary(box))


# =================================================================================== tests
def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every file (its bytes) and folder (``None``) under ``root``, by relative path."""
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(root.rglob("*"))
    }


class Context:
    """What the cases build on: ``folder`` a scratch folder, ``plain`` a file in it."""

    folder: Path
    capsys: pytest.CaptureFixture

    @property
    def plain(self) -> Path:
        path = self.folder / "plain"
        if not path.exists():
            path.write_text("a file\n")
        return path

    def copy(self, study: str) -> Path:
        """A fresh copy of the committed run directory of ``study`` (figures left out): hard
        links to one pristine copy, which the damages replace rather than write into."""
        source = RECORDS[study]
        if not source.is_dir():
            pytest.skip("needs the committed records")
        pristine = self.folder / "pristine" / study
        if not pristine.exists():
            shutil.copytree(source, pristine, ignore=shutil.ignore_patterns("*.png", "figures"))
        target = self.folder / "plots" / study
        shutil.rmtree(target, ignore_errors=True)
        shutil.copytree(pristine, target, copy_function=os.link)
        return target

    def resume(self, config: ExperimentConfig) -> None:
        """Resume a run saved with the default configuration with ``config``."""
        run_dir = self.folder / "resumed"
        run_dir.mkdir(exist_ok=True)
        (run_dir / "config.json").write_text(ExperimentConfig().to_json())
        prepare_run_dir(run_dir, config, True, False, (), ())


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("bad-cli")


@pytest.fixture
def context(folder, capsys) -> Context:
    c = Context()
    c.folder, c.capsys = folder, capsys
    return c


def test_the_cases_are_over_three_hundred():
    assert len(CASES) >= 300, len(CASES)


@pytest.mark.parametrize("bad", CASES)
def test_bad_input_raises_the_documented_error_naming_the_field(context, bad):
    bad.check(context)


@pytest.mark.parametrize("check", GOOD)
def test_the_valid_neighbour_is_accepted(context, check):
    check(context)


# ============================================================ nothing on disk changes
def _refused(capsys, argv: list[str]) -> str:
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2, err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    return err


def _finished(logdir: Path, name: str, config_json: str) -> None:
    """A finished run's directory: its config, page, a record and a checkpoint-like file."""
    run_dir = logdir / name
    (run_dir / "worlds").mkdir(parents=True)
    (run_dir / "config.json").write_text(config_json)
    (run_dir / "results.md").write_text("# results\n")
    (run_dir / "worlds" / "record.json").write_text('{"kept": true}\n')
    (run_dir / "checkpoints").mkdir()
    (run_dir / "checkpoints" / "state.pt").write_bytes(bytes(range(256)))


def _started(study: str, argv: list[str], logdir: Path, other: dict) -> None:
    """Run directories of ``himit run study argv`` saved with ``other`` settings changed."""
    args = build_parser().parse_args(["run", study, *argv, "--logdir", str(logdir)])
    for config in study_configs(args):
        _finished(logdir, config.name, dataclasses.replace(config, **other).to_json())
        (logdir / config.name / "results.md").unlink()  # started, not finished


STUDY_NAMES = list(STUDIES)
#: Per study, a setting and a value to save a run with that the command line does not give.
OTHER = {"seeds": 3}


@pytest.mark.parametrize("study", STUDY_NAMES)
def test_a_refused_run_changes_nothing_on_disk(tmp_path, capsys, study):
    """For each registered study: a finished run without --force, --force with a value its
    configuration refuses, a file where its run directory belongs, and (where it resumes)
    --resume with other settings: each refused in one line, the folder byte for byte as it
    was."""
    entry = STUDIES[study]
    names = [config.name for config in entry.configs()]
    logdir = tmp_path / "runs"
    for name in names:
        _finished(logdir, name, '{"name": "' + name + '"}\n')
    (logdir / "stray.txt").write_text("mine\n")
    before = snapshot(tmp_path)
    base = ["run", study, "--logdir", str(logdir), "--quiet"]
    assert "finished run" in _refused(capsys, base)
    assert "seeds=0" in _refused(capsys, [*base, "--force", "--seeds", "0"])
    assert snapshot(tmp_path) == before
    for name in names:
        shutil.rmtree(logdir / name)
        (logdir / name).write_text("a file\n")
    before = snapshot(tmp_path)
    assert "is a file, not a folder" in _refused(capsys, base)
    assert "is a file, not a folder" in _refused(capsys, [*base, "--force"])
    assert snapshot(tmp_path) == before
    if "resume" in entry.run_flags:
        shutil.rmtree(logdir)
        _started(study, [], logdir, OTHER)
        before = snapshot(tmp_path)
        err = _refused(capsys, [*base, "--resume"])
        assert "seeds: saved 3, given" in err, err
        assert snapshot(tmp_path) == before


def test_a_refused_resume_of_several_experiments_changes_none_of_them(tmp_path, capsys):
    """``himit run paper --resume``: exp1 matches, exp3 does not; exp1's folder is left as it
    was too (every plan is checked before any is prepared)."""
    logdir = tmp_path / "runs"
    _started("paper", [], logdir, {})
    exp3 = logdir / "exp3" / "config.json"
    exp3.write_text(ExperimentConfig(**{**json.loads(exp3.read_text()), "learner": {}}).to_json())
    (logdir / "exp1" / "config.json").write_text(
        (logdir / "exp1" / "config.json").read_text().replace("\n", "\n ", 1)
    )
    before = snapshot(tmp_path)
    assert "exp3" in _refused(capsys, ["run", "paper", "--logdir", str(logdir), "--resume"])
    assert snapshot(tmp_path) == before


def test_a_refused_sweep_changes_nothing_on_disk(tmp_path, capsys):
    """A spec with a refused cell, a finished trial of another configuration, a file for the
    sweep's folder: refused, the folder as it was."""
    out = tmp_path / "out"
    spec = tmp_path / "spec.toml"
    spec.write_text('name = "s"\nseeds = 1\n[grid]\nmentor_goal = ["same", "none"]\n')
    _finished(out / "trials", "baseline", "{}\n")
    before = snapshot(tmp_path)
    assert "cell mentor_goal=none" in _refused(capsys, ["sweep", str(spec), "--out", str(out)])
    spec.write_text('name = "s"\nseeds = 1\nworlds = [40]\n')
    trial = out / "trials" / "baseline" / "world40_seeds0-0"
    _finished(trial.parent, trial.name, ExperimentConfig(seeds=3).to_json())
    before = snapshot(tmp_path)
    err = _refused(capsys, ["sweep", str(spec), "--out", str(out), "--no-ray"])
    assert "another configuration" in err and "seeds: saved 3, given 1" in err, err
    assert snapshot(tmp_path) == before
    plain = tmp_path / "plain"
    plain.write_text("a file\n")
    before = snapshot(tmp_path)
    assert "is a file" in _refused(capsys, ["sweep", str(spec), "--out", str(plain), "--no-ray"])
    assert snapshot(tmp_path) == before


def test_a_refused_demo_or_plot_changes_nothing_on_disk(tmp_path, capsys):
    plain = tmp_path / "plain"
    plain.write_text("a file\n")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.json").write_text('{"name": "exp2", "sizes": [12]}')
    before = snapshot(tmp_path)
    assert "is a file" in _refused(capsys, ["demo", "--out", str(plain), "--steps", "0"])
    assert "is a file" in _refused(capsys, ["demo", "--out", str(plain / "x"), "--steps", "0"])
    assert "has not finished" in _refused(capsys, ["plot", str(tmp_path / "run")])
    assert "a part of the path is a file" in _refused(capsys, ["plot", str(plain)])
    assert snapshot(tmp_path) == before
    if RECORDS["exp2"].is_dir():  # a damaged record of a finished run
        run_dir = tmp_path / "exp2"
        shutil.copytree(RECORDS["exp2"], run_dir)
        _json(_WORLD, lambda r: {**r, "optimal_steps": 0})(run_dir)
        before = snapshot(tmp_path)
        assert "'optimal_steps' must be a number > 0, got 0" in _refused(
            capsys, ["plot", str(run_dir)]
        )
        assert snapshot(tmp_path) == before


def test_mentors_on_a_one_mentor_study_exit_2(tmp_path, capsys):
    for study in ("gymnasium", "minigrid", "puzzlebox"):
        err = _refused(capsys, ["run", study, "--mentors", "2", "--logdir", str(tmp_path)])
        assert "learner.mentors=2" in err and "mentors must be 1" in err, err
    assert not any(tmp_path.iterdir())
