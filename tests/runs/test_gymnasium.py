"""The Gymnasium comparison: its exact greedy-policy evaluation, its confidence intervals, and
the runner and script with tiny budgets."""

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from himit_torch.runs.gymnasium import (
    TASKS,
    GreedyEvaluator,
    GymExperimentConfig,
    mean_ci,
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


def test_greedy_evaluation_is_exact(cliff):
    world, options = cliff
    ev = GreedyEvaluator(world, options)
    g = world.gamma
    assert ev.optimal_value == pytest.approx(-(1 - g**13) / (1 - g))
    # the optimal primitive policy as a greedy option policy (primitives are options 0…3)
    assert ev.value(ev.optimal.policy) == pytest.approx(ev.optimal_value, abs=1e-9)
    # "up" forever from the start bumps at the top edge: −1 a step, never ending
    assert ev.value(torch.zeros(48, dtype=torch.int64)) == pytest.approx(-1 / (1 - g))
    # the option to the top-right corner, then primitives: 14 steps up and right, 3 down
    policy = ev.optimal.policy.clone()
    policy[36] = 5
    up_right = -(1 - g**14) / (1 - g) + g**14 * float(ev.optimal.values[11])
    assert ev.value(policy) == pytest.approx(up_right)
    # nothing tried anywhere: a uniformly random primitive, against a dense solve
    P, R = world_model(world)
    K = P.to_dense().mean(0)
    r = R.mean(1)
    live = ~world.terminal_mask
    K[~live] = 0
    r[~live] = 0
    V = torch.linalg.solve(torch.eye(48, dtype=torch.float64) - g * K, r)
    assert ev.value(torch.full((48,), -1)) == pytest.approx(float(V[36]))


def test_mean_ci_by_hand():
    mean, half, n = mean_ci([1.0, 2.0, 3.0])
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.302653 / np.sqrt(3), rel=1e-6)
    assert mean_ci([5.0])[:1] == (5.0,) and np.isnan(mean_ci([5.0])[1])
    assert mean_ci([])[2] == 0


def test_task_settings(cliff):
    world, _ = cliff
    assert neutral_value(world) == pytest.approx(-100.0)
    assert neutral_value(TASKS["frozenlake8x8"].world(0.99)) == 0.0
    ev = GreedyEvaluator(world, cliff[1])
    assert optimal_goals_per_window(world, ev.optimal.policy, 1300) == pytest.approx(100.0)
    with pytest.raises(ValueError, match="tasks"):
        GymExperimentConfig(tasks=("pong",))


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
    # CliffWalking ends only at its goal: the first goal is exact, inside its first goal window
    assert summary["first_goal_resolution"] == 1
    for step, window in zip(summary["first_goal_step"], summary["first_goal_window"]):
        assert (step < 0) == (window < 0) and (step < 0 or window - 200 < step <= window)
    assert "95 % BCa bootstrap interval" in (run / "results.md").read_text()
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
