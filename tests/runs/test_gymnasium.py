"""The Gymnasium comparison: its exact greedy-policy evaluation, its confidence intervals, and
the runner and script with tiny budgets."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from himit_torch.exact.greedy_evaluation import OptionPolicy, PolicyEvaluator, optimal_value
from himit_torch.exact.planning import value_iteration
from himit_torch.runs.gymnasium import (
    TASKS,
    GymExperimentConfig,
    neutral_value,
    optimal_goals_per_window,
    run_gym_experiment,
)
from himit_torch.worlds.table_world import world_model

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def cliff():
    world = TASKS["cliffwalking"].world(0.99)
    return world, TASKS["cliffwalking"].options(world)


def test_the_value_gap_by_hand(cliff):
    """CliffWalking (start 36, goal 47, −1 a step): V*(μ) = −(1 − γ¹³)/(1 − γ), 13 steps. The value
    gaps of deterministic policies that have an option at every state — where the merged
    evaluator and the old ``GreedyEvaluator`` (ties to the lowest option, untried states a
    uniformly random primitive) define the same policy — against the old test's hand values:
    the optimal primitive policy (gap 0), "up" forever (V = −1/(1 − γ)), and the option to the
    top-right corner from the start; and the old rule for a run that has tried nothing, written
    as the stochastic policy it was (each primitive ¼), against a dense solve."""
    world, options = cliff
    g = world.gamma
    v_star = optimal_value(world)
    assert v_star == pytest.approx(-(1 - g**13) / (1 - g))
    evaluator = PolicyEvaluator(world, options, window=100)
    best = value_iteration(*world_model(world), g)

    def gap(policy: OptionPolicy) -> float:
        return float(evaluator.evaluate(policy).value_gap(v_star)[0])

    # the optimal primitive policy as a greedy option policy (primitives are options 0…3)
    assert gap(OptionPolicy.deterministic(best.policy)) == 0.0
    # "up" forever from the start bumps at the top edge: −1 a step, never ending
    up = OptionPolicy.deterministic(torch.zeros(48, dtype=torch.int64))
    assert gap(up) == pytest.approx(v_star + 1 / (1 - g))
    # the option to the top-right corner, then primitives: 14 steps up and right, 3 down
    policy = best.policy.clone()
    policy[36] = 5
    up_right = -(1 - g**14) / (1 - g) + g**14 * float(best.values[11])
    assert gap(OptionPolicy.deterministic(policy)) == pytest.approx(v_star - up_right)
    # every primitive with probability ¼ everywhere, against a dense solve
    P, R = world_model(world)
    K = P.to_dense().mean(0)
    r = R.mean(1)
    live = ~world.terminal_mask
    K[~live] = 0
    r[~live] = 0
    V = torch.linalg.solve(torch.eye(48, dtype=torch.float64) - g * K, r)
    random = OptionPolicy(
        torch.arange(4).expand(48, 4).contiguous(),
        torch.full((1, 48, 4), 0.25, dtype=torch.float64),
    )
    assert gap(random) == pytest.approx(v_star - float(V[36]))


def test_task_settings(cliff):
    world, _ = cliff
    assert neutral_value(world) == pytest.approx(-100.0)
    assert neutral_value(TASKS["frozenlake8x8"].world(0.99)) == 0.0
    best = value_iteration(*world_model(world), world.gamma)
    assert optimal_goals_per_window(world, best.policy, 1300) == pytest.approx(100.0)
    with pytest.raises(ValueError, match="tasks"):
        GymExperimentConfig(tasks=("pong",))


@pytest.mark.parametrize(
    "changes",
    [
        {},
        {"preset": "paper", "seeds": 20, "tie_break": "first"},
        {"preset": "recommended", "first_seed": 3, "steps": 800},
        {"quick": True, "tie_break": "first"},
    ],
)
def test_the_run_command_rebuilds_the_configuration(changes, tmp_path):
    """The command a Gymnasium page names for its runs, read by ``himit run``'s own parser,
    builds exactly the configuration the runs had; a setting only the script takes has none."""
    import shlex
    from dataclasses import replace

    from himit_torch.cli import build_parser, study_configs
    from himit_torch.runs.gymnasium import gym_run_command

    config = GymExperimentConfig()
    if changes.get("quick"):
        config = config.quick()
    if "preset" in changes:
        config = config.with_preset(changes["preset"])
    config = replace(
        config,
        **{k: v for k, v in changes.items() if k not in ("quick", "preset", "tie_break")},
        learner=replace(config.learner, tie_break=changes.get("tie_break", "random")),
    )
    command = gym_run_command(config, tmp_path / "gymnasium")
    assert command is not None
    args = build_parser().parse_args(shlex.split(command)[1:])
    assert args.logdir == str(tmp_path)
    assert study_configs(args)[0] == config
    assert gym_run_command(replace(config, window=500)) is None
    assert gym_run_command(replace(config, tasks=("taxi",))) is None
    assert gym_run_command(config, tmp_path / "elsewhere") is None


# (a fresh interpreter and a study, ≈ 8 s: CI's; the fast suite runs the same study in process,
# as `himit run minigrid`, in test_cli_minigrid)
@pytest.mark.slow
def test_the_script_runs_and_writes_curves_figures_and_results(tmp_path):
    out = subprocess.run(
        [
            sys.executable,
            str(ROOT / "experiments" / "gymnasium_worlds.py"),
            "--tasks",
            "cliffwalking",
            "--seeds",
            "2",
            "--steps",
            "400",
            "--window",
            "200",
            "--logdir",
            str(tmp_path),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert out.returncode == 0, out.stderr[-2000:]
    run = tmp_path / "gymnasium"
    assert "## cliffwalking" in out.stdout and "| imitation | 2 |" in out.stdout
    with (run / "curves.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 3 * 2  # windows × agents × seeds
    assert all(float(r["value_gap"]) >= 0 and 0 <= int(r["goals"]) <= 200 for r in rows)
    summary = json.loads((run / "tasks" / "cliffwalking.json").read_text())
    assert summary["initial_value"] == pytest.approx(-100.0) and summary["steps"] == 400
    # the final greedy policies under both rules for untried states: the "stuck" rule's rate is
    # the "uniform" one's where no untried state is on the way, else 0
    for rule in ("optimal", "mentor"):
        uniform = summary[f"greedy_percent_of_{rule}"]
        stuck = summary[f"greedy_percent_of_{rule}_stuck"]
        assert len(stuck) == len(uniform) == 6
        assert all(s in (0.0, u) for s, u in zip(stuck, uniform)), (stuck, uniform)
    # the last window's value gap is the final greedy policy's, from the same evaluation
    v_star = summary["optimal_value"]
    gaps = [v_star - v for v in summary["greedy_value_start"]]
    assert summary["final_value_gap"] == pytest.approx(gaps, abs=1e-9)
    # CliffWalking ends only at its goal: the first goal is exact, inside its first goal window
    assert summary["first_goal_resolution"] == 1
    for step, window in zip(summary["first_goal_step"], summary["first_goal_window"]):
        assert (step < 0) == (window < 0) and (step < 0 or window - 200 < step <= window)
    page = (run / "results.md").read_text()
    assert "95 % BCa bootstrap interval" in page
    assert (
        f"Runs recorded at commit `{summary['commit']}` (from `tasks/*.json`), engine "
        f"`{summary['engine']}`; this page: `himit plot {run}`; the runs: the settings in "
        "`config.json`"  # --tasks and --window: the script's settings, not himit run's flags
    ) in page
    assert (run / "figures" / "curves_cliffwalking.png").read_bytes()[:4] == b"\x89PNG"
    # himit plot redraws the same results.md from the run's records (its commit kept)
    from himit_torch.cli import main

    before = (run / "results.md").read_text()
    (run / "results.md").unlink()
    assert main(["plot", str(run)]) == 0
    assert (run / "results.md").read_text() == before
    assert len(list((run / "tb").iterdir())) == 6
    config = GymExperimentConfig(tasks=("cliffwalking",))
    with pytest.raises(ValueError, match="already holds a finished run"):
        run_gym_experiment(config, run, progress=False)


_RECORDS = Path(__file__).resolve().parents[2] / "experiments" / "results"


@pytest.mark.parametrize(
    ("record", "field"),
    [
        ({}, "agents"),
        ({"task": "taxi", "agents": ["imitation"]}, "about"),
        ({"task": "taxi", "about": "x", "agents": "imitation"}, "agents"),
        ([], None),
    ],
)
def test_himit_plot_refuses_a_damaged_task_record_naming_the_file_and_field(
    record, field, tmp_path, capsys
):
    import shutil

    from himit_torch.cli import main

    run_dir = tmp_path / "gymnasium"
    shutil.copytree(_RECORDS / "paper-first" / "gymnasium", run_dir)
    (run_dir / "tasks" / "taxi.json").write_text(json.dumps(record))
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(run_dir)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert str(run_dir / "tasks" / "taxi.json") in err
    if field is not None:
        assert repr(field) in err


@pytest.mark.parametrize(
    ("paths", "words"),
    [
        ({"mentor": [0, 1.5]}, "field 'paths' must map each path's name to its states"),
        ([[0, 1]], "field 'paths' must"),
        ({"mentor": [0, 1]}, "only MiniGrid's tasks draw"),  # (a Taxi record)
    ],
)
def test_himit_plot_refuses_damaged_paths_in_a_task_record(paths, words, tmp_path, capsys):
    import shutil

    from himit_torch.cli import main

    run_dir = tmp_path / "gymnasium"
    shutil.copytree(_RECORDS / "paper-first" / "gymnasium", run_dir)
    path = run_dir / "tasks" / "taxi.json"
    path.write_text(json.dumps(dict(json.loads(path.read_text()), paths=paths)))
    with pytest.raises(SystemExit) as exc:
        main(["plot", str(run_dir)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: "), err
    assert "tasks/taxi.json" in err and words in err


@pytest.mark.slow
def test_the_script_runs_the_three_gymnasium_tasks_by_default(tmp_path):
    """``experiments/gymnasium_worlds.py`` (the benchmark's worlds part runs it per preset)
    runs Taxi, CliffWalking and FrozenLake, not MiniGrid's tasks, which are in ``TASKS`` too
    and are the benchmark's own part: with them it ran 12 tasks, ≈ 30× the work."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "experiments" / "gymnasium_worlds.py"), "--seeds", "1",
         "--agents", "primitives", "--steps", "200", "--window", "200", "--logdir", str(tmp_path)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr[-2000:]
    config = json.loads((tmp_path / "gymnasium" / "config.json").read_text())
    assert tuple(config["tasks"]) == GymExperimentConfig().tasks
    assert config["tasks"] == ["taxi", "cliffwalking", "frozenlake8x8"]
    assert sorted(p.stem for p in (tmp_path / "gymnasium" / "tasks").glob("*.json")) == sorted(
        config["tasks"]
    )
