"""The experiment runner, its outputs, checkpoints and the run/plot/demo/bench commands, with tiny
budgets (window 1000 steps instead of 5000)."""

import csv
import json
import os
import pickle
import random
import signal
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import pytest
import torch

from himit_torch.checkpoints import DamagedCheckpoint, read_header
from himit_torch.cli import main
from himit_torch.experiment import EXPERIMENTS, ExperimentConfig, load_config, run_experiment


def tiny(name: str, **changes) -> ExperimentConfig:
    base = EXPERIMENTS[name]
    defaults = dict(seeds=1, steps=2000, window=1000, checkpoint_every=1000, mentor_episodes=3,
                    sizes=base.sizes[:1], agents=("imitation", "options"))
    defaults.update(changes)
    return replace(base, **defaults)


def read_curves(path: Path) -> list[dict]:
    with path.open() as f:
        return list(csv.DictReader(f))


@pytest.mark.parametrize("name", ["exp1", "exp2", "exp3"])
def test_each_experiment_runs_and_writes_its_outputs(name, tmp_path):
    config = tiny(name)
    results = run_experiment(config, tmp_path / name, progress=False)
    run_dir = tmp_path / name
    assert load_config(run_dir / "config.json") == config
    rows = read_curves(run_dir / "curves.csv")
    # 2 windows × 2 runs, for each world
    assert len(rows) == 2 * 2 * len(config.sizes)
    assert {r["agent"] for r in rows} == {"imitation", "options"}
    assert all(0 <= int(r["goals_in_window"]) <= 1000 for r in rows)
    for r in results:
        assert r.steps == 2000 and len(r.goals) == 2
        assert 10 < r.optimal_steps < 10 * r.size
    results_md = (run_dir / "results.md").read_text()
    assert "| imitation |" in results_md and "| options |" in results_md
    figures = sorted(p.name for p in (run_dir / "figures").iterdir())
    assert any(f.startswith("fig2_world") for f in figures)
    assert any("curves" in f for f in figures)
    for f in (run_dir / "figures").iterdir():
        assert f.read_bytes()[:4] == b"\x89PNG"


def test_exp3_with_two_worlds_draws_the_scaling_bars(tmp_path):
    config = tiny("exp3", sizes=(16, 24), room_size=8, corner_options=False)
    results = run_experiment(config, tmp_path / "e3", progress=False)
    assert [r.size for r in results] == [16, 24]
    assert (tmp_path / "e3" / "figures" / "fig5_scaling.png").exists()
    assert "Scaling" in (tmp_path / "e3" / "results.md").read_text()


def test_tensorboard_event_files_hold_the_scalar_tags(tmp_path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    run_experiment(tiny("exp2"), tmp_path / "tb", progress=False)
    runs = sorted((tmp_path / "tb" / "tb").iterdir())
    assert [r.name for r in runs] == ["world40__imitation__seed0", "world40__options__seed0"]
    acc = EventAccumulator(str(runs[0]), size_guidance={"images": 0})
    acc.Reload()
    scalars = set(acc.Tags()["scalars"])
    for tag in ("charts/goals_in_window", "charts/epsilon", "charts/episodes", "planner/backups",
                "planner/decisions", "model/coverage", "mentor/term_wins"):
        assert tag in scalars, (tag, scalars)
    goals = acc.Scalars("charts/goals_in_window")
    assert [e.step for e in goals] == [1000, 2000]
    assert {"values/V", "policy/greedy_option", "visits/learner_vs_mentor"} <= set(acc.Tags()["images"])
    # the options-only run has no mentor term to log
    acc2 = EventAccumulator(str(runs[1]))
    acc2.Reload()
    assert "mentor/term_wins" not in acc2.Tags()["scalars"]


def test_a_finished_run_is_not_overwritten_without_force(tmp_path):
    config = tiny("exp2", steps=1000)
    run_experiment(config, tmp_path / "r", progress=False)
    with pytest.raises(ValueError, match="already holds a finished run"):
        run_experiment(config, tmp_path / "r", progress=False)
    run_experiment(config, tmp_path / "r", progress=False, force=True)
    with pytest.raises(ValueError, match="different configuration"):
        run_experiment(replace(config, seeds=2), tmp_path / "r", progress=False, resume=True)


_CHILD = """
import sys
from dataclasses import replace
from himit_torch.experiment import EXPERIMENTS, run_experiment
# the torch engine: slow enough per window to be killed inside one (the compiled engine runs
# these 3500 steps in a blink; the state it checkpoints is the same)
config = replace(EXPERIMENTS["exp2"], sizes=(16,), seeds=1, steps=3500, window=250,
                 checkpoint_every=250, mentor_episodes=3, agents=("imitation", "primitives"),
                 engine="torch")
run_experiment(config, sys.argv[1], progress=False, resume=len(sys.argv) > 2)
"""


def checkpoint_step(path: Path) -> int:
    """The step of the newest checkpoint a running child has saved (-1: none yet)."""
    try:
        return read_header(path).step
    except (DamagedCheckpoint, OSError):
        return -1


def kill_after(child: subprocess.Popen, newest: Path, step: int, pause: float) -> None:
    """SIGKILL ``child`` ``pause`` seconds after its newest checkpoint reached ``step``: a random
    moment inside a window, now and then inside a save."""
    deadline = time.time() + 120
    while child.poll() is None and checkpoint_step(newest) < step and time.time() < deadline:
        time.sleep(0.01)
    time.sleep(pause)
    assert child.poll() is None, "the run finished before it could be killed; lengthen it"
    child.send_signal(signal.SIGKILL)
    child.wait()


def test_runs_killed_at_random_moments_resume_to_exactly_the_uninterrupted_curve(tmp_path):
    """kill -9 at three random moments, each followed by --resume; then once more with the newest
    checkpoint cut short: the resume falls back to the previous one, says so in one line, and
    every curve still equals the uninterrupted run's."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    child = [sys.executable, "-c", _CHILD, str(killed)]
    uninterrupted = subprocess.Popen([sys.executable, "-c", _CHILD, str(whole)], env=env)
    rng = random.Random(13)
    newest = killed / "checkpoints" / "world16.pt"
    for k, (low, high) in enumerate([(250, 750), (1000, 1500), (1750, 2250), (2500, 2750)]):
        run = subprocess.Popen(child + (["resume"] if k else []), env=env)
        target = max(rng.randrange(low, high + 1, 250), checkpoint_step(newest) + 250)
        kill_after(run, newest, target, rng.uniform(0.0, 0.2))
        assert not (killed / "results.md").exists()
    newest.write_bytes(newest.read_bytes()[: newest.stat().st_size // 2])
    done = subprocess.run(child + ["resume"], env=env, capture_output=True, text=True, check=True)
    assert uninterrupted.wait() == 0
    [warning] = [line for line in done.stderr.splitlines() if line.startswith("himit: ")]
    assert warning.startswith(f"himit: warning: {newest}: cut short")
    assert "resuming from world16.prev.pt at step" in warning and "will be redone" in warning
    assert read_curves(killed / "curves.csv") == read_curves(whole / "curves.csv")
    a = json.loads((whole / "worlds" / "world16.json").read_text())
    b = json.loads((killed / "worlds" / "world16.json").read_text())
    for key in ("goals", "first_goal_step", "final_window_goals", "value_start"):
        assert a[key] == b[key]
    # TensorBoard after the resumes: every window's step exactly once (nothing purged twice, no
    # duplicates from the killed processes), and the same values as the uninterrupted run.
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    def scalars(root):
        acc = EventAccumulator(str(root / "tb" / "world16__imitation__seed0"))
        acc.Reload()
        return [(e.step, e.value) for e in acc.Scalars("charts/goals_in_window")]
    assert [s for s, _ in scalars(killed)] == list(range(250, 3501, 250))
    assert scalars(killed) == scalars(whole)


def test_config_file_round_trip_and_errors(tmp_path, plants_marker):
    config = tiny("exp2")
    path = tmp_path / "c.json"
    path.write_text(config.to_json())
    assert load_config(path) == config
    path.write_text(json.dumps({"name": "exp2", "bogus": 1}))
    with pytest.raises(ValueError, match="unknown fields"):
        load_config(path)
    path.write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_config(path)
    marker = tmp_path / "marker"  # configs are JSON: a pickle in their place is never unpickled
    path.write_bytes(pickle.dumps(plants_marker(marker)))
    with pytest.raises(ValueError, match="not valid JSON"):
        load_config(path)
    assert not marker.exists()
    with pytest.raises(ValueError, match="checkpoint_every"):
        replace(config, checkpoint_every=1500)
    with pytest.raises(ValueError, match="agents"):
        replace(config, agents=("imitation", "nope"))


def one_line_error(capsys, argv) -> str:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("himit: error: ")
    return err


def test_cli_run_plot_and_errors(capsys, tmp_path):
    cfg_path = tmp_path / "cfg.json"
    cfg_path.write_text(tiny("exp2", steps=1000).to_json())
    assert main(["run", "exp2", "--config", str(cfg_path), "--logdir", str(tmp_path), "--quiet"]) == 0
    assert (tmp_path / "exp2" / "results.md").exists()
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "exp2")]) == 0
    assert "results.md" in capsys.readouterr().out
    assert "finished run" in one_line_error(capsys, ["run", "exp2", "--config", str(cfg_path),
                                                     "--logdir", str(tmp_path), "--quiet"])
    assert "does not exist" in one_line_error(capsys, ["run", "exp1", "--config", str(tmp_path / "no.json")])
    assert "is for 'exp2'" in one_line_error(capsys, ["run", "exp1", "--config", str(cfg_path)])
    if not torch.cuda.is_available():
        assert "CUDA" in one_line_error(capsys, ["run", "exp2", "--device", "cuda", "--logdir",
                                                 str(tmp_path)])
    assert "invalid choice" in one_line_error(capsys, ["run", "exp7"])
    assert "does not exist" in one_line_error(capsys, ["plot", str(tmp_path)])


def test_cli_demo_learning_run(capsys, tmp_path):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--episodes", "2", "--steps", "2000", "--seeds", "1",
                 "--quiet"]) == 0
    text = capsys.readouterr().out
    assert "goals in the last 2000 steps" in text and "tensorboard --logdir" in text
    assert (out / "learning" / "results.md").exists()
    assert len(list((out / "learning" / "tb").iterdir())) == 3


def test_cli_bench_prints_a_rate(capsys):
    assert main(["bench", "--batch", "2", "--steps", "50", "--warmup", "0", "--size", "12",
                 "--rooms", "2"]) == 0
    line = capsys.readouterr().out
    assert "steps/s" in line and "B=2" in line
    assert "agent" in one_line_error(capsys, ["bench", "--agent", "nobody"])
