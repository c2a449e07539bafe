"""``himit run puzzlebox``: reading a greedy policy's plan, the statistics of the report, and the
runner, its command and its script end to end on small boxes with tiny budgets."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from himit_torch.cli import main
from himit_torch.exact.planning import optimal_baseline
from himit_torch.mentor.puzzle_box import organisation_mentor
from himit_torch.options.puzzle_box import puzzle_box_options
from himit_torch.runs.puzzle_box import (
    PuzzleBoxConfig,
    greedy_plan,
    run_puzzle_box,
    watched_organisation,
)
from himit_torch.worlds.puzzle_box import PuzzleBox

ROOT = Path(__file__).resolve().parents[2]


def test_greedy_plans_of_known_policies():
    box = PuzzleBox(3)
    learner, mentor = puzzle_box_options(box, "learner"), puzzle_box_options(box, "mentor")
    plan = greedy_plan(box, learner, organisation_mentor(box, "step", learner).option, focus=2)
    assert plan["opens"] and plan["organisation"] == "step"
    assert plan["subgoals"][:4] == ["1.1", "2.1", "3.1", "1.2"]
    assert plan["scores"] == {"skewer": 0.0, "step": 1.0}
    assert plan["focus_scores"] == {"skewer": 0.0, "step": 1.0}
    assert (plan["power_steps"], plan["pinch_steps"]) == (12, 0)
    assert plan["steps_taken"] == 12 * 3  # reach, grip, motion per step: nothing slips
    theirs = greedy_plan(box, mentor, organisation_mentor(box, "skewer").option)
    assert theirs["organisation"] == "skewer" and theirs["pinch_steps"] == 12
    # a policy that withdraws again at once never opens the box: where it is stuck is named
    loop = organisation_mentor(box, "skewer", learner).option.clone()
    at = box.encode([0, 0, 0], 0, "open")
    loop[at] = box.action_withdraw
    stuck = greedy_plan(box, learner, loop)
    assert not stuck["opens"] and stuck["organisation"] == "incomplete"
    assert stuck["stuck_at"] == "[0, 0, 0], hand home: go to skewer 1"
    assert stuck["scores"] == {"skewer": None, "step": None}


def test_seeds_alternate_between_the_organisations():
    assert [watched_organisation(s, 3) for s in range(3, 7)] == ["skewer", "step"] * 2
    with pytest.raises(ValueError, match="transfer_skewers"):
        PuzzleBoxConfig(transfer_skewers=6)
    with pytest.raises(ValueError, match="variants"):
        PuzzleBoxConfig(variants=("sideways",))
    with pytest.raises(ValueError, match="eval_every"):
        PuzzleBoxConfig(eval_every=1234)


TINY = PuzzleBoxConfig(
    skewers=2,
    transfer_skewers=3,
    seeds=2,
    steps=1000,
    transfer_steps=1000,
    mentor_episodes=3,
    window=500,
    eval_every=500,
    checkpoint_every=500,
)


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """A finished tiny puzzle-box run: its directory and the summary the runner returned (tests
    that damage the directory copy it)."""
    run_dir = tmp_path_factory.mktemp("pb") / "pb"
    return run_dir, run_puzzle_box(TINY, run_dir, progress=False)


def test_runner_writes_every_result(tiny_run):
    run_dir, summary = tiny_run
    tags = [b["batch"] for b in summary["batches"]]
    assert tags == [
        "speed_imitation",
        "speed_options",
        "speed_primitives",
        "harder_pinch_imitation",
        "harder_pinch_options",
        "no_pinch_imitation",
        "no_pinch_options",
        "transfer_options",
        "transfer_plain",
        "transfer_any",
    ]
    with (run_dir / "curves.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(tags) * 2 * 2  # batches × seeds × windows
    assert {r["step"] for r in rows} == {"500", "1000"}
    # greedy policies evaluated every eval_every steps, in (c) every 3 · eval_every, and at the end
    evaluated = {(r["batch"].split("_")[0], r["step"]) for r in rows if r["greedy_value"] != ""}
    assert ("speed", "500") in evaluated and ("transfer", "500") not in evaluated
    assert all((r["batch"].split("_")[0], "1000") in evaluated for r in rows)
    speed = summary["batches"][0]
    assert speed["num_states"] == 5**2 * 7 and speed["skewers"] == 2
    # V*(start) is the optimum's (exact), and no frozen greedy policy beats it
    assert speed["value_star"] == pytest.approx(optimal_baseline(PuzzleBox(2)).value_start)
    for batch in summary["batches"]:
        assert all(r["greedy_value"] <= batch["value_star"] + 1e-9 for r in batch["runs"])
    assert [r["watched"] for r in speed["runs"]] == ["skewer", "step"]
    assert summary["batches"][1]["runs"][0]["watched"] is None  # options watched nothing
    transfer = summary["batches"][-1]
    assert transfer["num_states"] == 5**3 * 10
    assert all(r["focus_scores"] is not None for r in transfer["runs"])
    for name in ("speed.png", "organisation.png", "transfer.png"):
        assert (run_dir / "figures" / name).stat().st_size > 10_000
    text = (run_dir / "results.md").read_text()
    assert "## Beside Whiten et al. (2006)" in text
    for finding in ("| 1. Children", "| 2a.", "| 2b.", "| 3. At test"):
        assert finding in text
    assert "commit `" in text and "engine `" in text
    assert (  # TINY's settings are no flags of himit run puzzlebox (its window, its boxes)
        f"Runs recorded at commit `{summary['commit']}` (from `summary.json`); this page: "
        f"`himit plot {run_dir}`; the runs: the settings in `summary.json`'s `config`"
    ) in text
    # laid out by the shared writer (viz/results_page.py): title, provenance, then sections
    title, _, first, _, second, _, settings = text.split("\n")[:7]
    assert title == "# The puzzle box: Whiten et al.'s (2006) three findings, run on the model"
    assert first.startswith("Runs recorded at commit") and second.startswith("Produced by")
    assert settings.startswith(f"{TINY.seeds} seeds per condition")
    assert text.endswith("`tb/` (`tensorboard --logdir <run dir>/tb`).\n")
    assert len(list((run_dir / "tb").iterdir())) == len(tags) * 2


# (three more reports of the tiny run, ≈ 11 s: CI's)
@pytest.mark.slow
def test_a_finished_run_resumes_to_the_same_runs_and_redraws_the_same_page(tiny_run, tmp_path):
    import shutil

    run_dir = tmp_path / "pb"
    shutil.copytree(tiny_run[0], run_dir)
    summary = tiny_run[1]
    # a finished run is refused without --force; a resumed one reads the finished batches
    with pytest.raises(ValueError, match="finished run"):
        run_puzzle_box(TINY, run_dir, progress=False)
    again = run_puzzle_box(TINY, run_dir, resume=True, progress=False)
    assert json.dumps(again["batches"]) == json.dumps(summary["batches"])
    # a batch interrupted after its last checkpoint resumes from it to the same runs
    (run_dir / "batches" / "transfer_any.json").unlink()
    (run_dir / "results.md").unlink()
    # ...also when its config.json was saved before a learner setting existed (the setting
    # takes its declared default)
    saved = json.loads((run_dir / "config.json").read_text())
    del saved["learner"]["mentor_trial"]
    (run_dir / "config.json").write_text(json.dumps(saved))
    resumed = run_puzzle_box(TINY, run_dir, resume=True, progress=False)
    assert resumed["batches"][-1]["runs"] == summary["batches"][-1]["runs"]
    # himit plot redraws it, the same page
    text = (run_dir / "results.md").read_text()
    (run_dir / "results.md").unlink()
    assert main(["plot", str(run_dir)]) == 0
    assert (run_dir / "results.md").read_text() == text


@pytest.mark.parametrize(
    "changes", [{}, {"seeds": 10, "steps": 50_000}, {"quick": True, "engine": "torch"}]
)
def test_the_run_command_rebuilds_the_configuration(changes, tmp_path):
    """The command a puzzle-box page names for its runs, read by ``himit run``'s own parser,
    builds exactly the configuration the runs had; a setting it has no flag for, none."""
    import shlex
    from dataclasses import replace

    from himit_torch.cli import build_parser, study_configs
    from himit_torch.runs.puzzle_box import puzzle_box_run_command

    config = PuzzleBoxConfig().quick() if changes.get("quick") else PuzzleBoxConfig()
    config = replace(config, **{k: v for k, v in changes.items() if k != "quick"})
    command = puzzle_box_run_command(config, tmp_path / "puzzlebox")
    assert command is not None
    args = build_parser().parse_args(shlex.split(command)[1:])
    assert args.logdir == str(tmp_path)
    assert study_configs(args)[0] == config
    assert puzzle_box_run_command(replace(config, mentor_episodes=7)) is None
    assert puzzle_box_run_command(config, tmp_path / "elsewhere") is None


# An integration run of the command and the flat script (8 s): -m slow (CI).
@pytest.mark.slow
def test_the_command_and_the_script(capsys, tmp_path):
    assert main(["info", "--puzzle-box", "2"]) == 0
    out = capsys.readouterr().out
    assert "states     175" in out and "k=5: 50,000" in out
    rows = [line for line in out.splitlines() if "by" in line and "skills" in line]
    optimum = next(line for line in out.splitlines() if line.startswith("optimal policy"))
    assert len(rows) == 4  # both organisations, both styles: the optimum's steps and value
    assert {tuple(line.split()[-2:]) for line in rows} == {tuple(optimum.split()[-2:])}
    with pytest.raises(SystemExit) as exc:
        main(["info", "--puzzle-box", "7"])
    assert exc.value.code == 2
    assert capsys.readouterr().err.startswith("himit: error: --puzzle-box 7")
    with pytest.raises(SystemExit):
        main(["run", "puzzlebox", "--workers", "2", "--logdir", str(tmp_path)])
    assert "takes no --workers" in capsys.readouterr().err
    # the flat script, as a user runs it (tiny budget)
    done = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "puzzle_box.py"), "--quick", "--seeds", "1",
         "--logdir", str(tmp_path)],
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "puzzlebox" / "results.md").exists()
    assert "Beside Whiten et al." in done.stdout


def test_himit_run_puzzlebox_takes_a_preset_and_refuses_a_contradiction():
    from himit_torch.cli import build_parser, study_configs

    args = build_parser().parse_args(["run", "puzzlebox", "--preset", "recommended"])
    config = study_configs(args)[0]
    assert config.preset == "recommended"
    assert config.learner.mentor_fade == 20.0 and config.learner.eps_schedule == "goals"
    assert config.learner.plan_every == PuzzleBoxConfig().learner.plan_every  # (its own)
    args = build_parser().parse_args(
        ["run", "puzzlebox", "--preset", "recommended", "--mentor-fade", "3"]
    )
    with pytest.raises(ValueError, match="preset='recommended' but learner.mentor_fade=3.0"):
        study_configs(args)[0]
    with pytest.raises(ValueError, match="PuzzleBoxConfig.preset"):
        PuzzleBoxConfig(preset="best")


@pytest.fixture(scope="module")
def finished_tiny(tiny_run):
    """A finished tiny puzzle-box run directory (copied by each test that damages it)."""
    return tiny_run[0]


DAMAGED_BATCHES = [
    ("speed_options.json", "{"),
    ("speed_options.json", "[]"),
    ("speed_options.json", '{"batch": "speed_options"}'),
    (
        "speed_options.json",
        '{"batch": "other", "skewers": 2, "condition": "options", '
        '"agent": "options", "steps": 1000, "runs": []}',
    ),  # fmt: skip
    (
        "speed_options.json",
        '{"batch": "speed_options", "skewers": 2, "condition": "options", '
        '"agent": "options", "steps": 1000, "runs": [1]}',
    ),  # fmt: skip
    ("speed_options.json", "[" * 100 + "]" * 100),
]
DAMAGED_EVALUATIONS = [
    ("transfer_any.evals.json", "{"),
    ("transfer_any.evals.json", "[1]"),
    ("transfer_any.evals.json", '{"x": {}}'),
    ("transfer_any.evals.json", '{"500": {"value": [1]}}'),
    (
        "transfer_any.evals.json",
        '{"500": {"value": [1], "organisation": [1], "watched_score": [1], "pinch_steps": [1]}}',
    ),  # fmt: skip
    ("transfer_any.evals.json", '{"500": 3}'),
]


@pytest.mark.parametrize("name, text", DAMAGED_BATCHES + DAMAGED_EVALUATIONS)
def test_resume_over_a_damaged_batch_record_is_refused_naming_the_file(
    finished_tiny, tmp_path, capsys, name, text
):
    import shutil

    run_dir = tmp_path / "pb"
    shutil.copytree(finished_tiny, run_dir)
    (run_dir / "results.md").unlink()
    (run_dir / "batches" / "transfer_any.json").unlink()  # resumes this batch's evaluations
    (run_dir / "batches" / name).write_text(text)
    with pytest.raises(ValueError, match=r"--resume: .*" + name.replace(".", r"\.")):
        run_puzzle_box(TINY, run_dir, resume=True, progress=False)


_RECORDS = Path(__file__).resolve().parents[2] / "experiments" / "results"


@pytest.mark.parametrize(
    ("change", "field"),
    [
        (lambda s: {}, "config"),
        (lambda s: [], None),
        (lambda s: {**s, "commit": None}, "commit"),
        (
            lambda s: {**s, "config": {k: v for k, v in s["config"].items() if k != "window"}},
            "config.window",
        ),
        (lambda s: {**s, "batches": [{}]}, "batches[0].batch"),
        (lambda s: {**s, "mentor_plans": 3}, "mentor_plans"),
    ],
)
def test_himit_plot_refuses_a_damaged_summary_naming_the_file_and_field(
    change, field, tmp_path, capsys
):
    import shutil

    from himit_torch.cli import main

    run_dir = tmp_path / "puzzlebox"
    shutil.copytree(_RECORDS / "puzzlebox", run_dir)
    summary = json.loads((run_dir / "summary.json").read_text())
    (run_dir / "summary.json").write_text(json.dumps(change(summary)))
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(run_dir)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert str(run_dir / "summary.json") in err
    if field is not None:
        assert repr(field) in err
