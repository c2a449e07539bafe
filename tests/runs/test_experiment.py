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

from himit_torch.cli import main
from himit_torch.runs.checkpoints import DamagedCheckpoint, read_header
from himit_torch.runs.config import EXPERIMENTS, ExperimentConfig, load_config
from himit_torch.runs.experiment import run_experiment, run_experiments


def tiny(name: str, **changes) -> ExperimentConfig:
    base = EXPERIMENTS[name]
    defaults = dict(
        seeds=1,
        steps=2000,
        window=1000,
        checkpoint_every=1000,
        mentor_episodes=3,
        sizes=base.sizes[:1],
        agents=("imitation", "options"),
    )
    defaults.update(changes)
    return replace(base, **defaults)


def read_curves(path: Path) -> list[dict]:
    with path.open() as f:
        return list(csv.DictReader(f))


# (exp3, two worlds, ≈ 3 s: CI's)
@pytest.mark.parametrize("name", ["exp1", "exp2", pytest.param("exp3", marks=pytest.mark.slow)])
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
    assert any(f.startswith("first_goal_world") for f in figures)
    from PIL import Image

    for f in (run_dir / "figures").iterdir():
        assert f.read_bytes()[:4] == b"\x89PNG"
        with Image.open(f) as image:  # readable: at least 100 dpi
            assert min(image.info["dpi"]) >= 99.9, (f.name, image.info["dpi"])


def test_the_greedy_policies_are_evaluated_on_their_schedule(tmp_path):
    """greedy_every=2000 with windows of 1000 and 3500 steps: evaluations at 2000 and at the end
    (3500, no window ends there: in world<N>.json and results.md, not curves.csv); None: no
    columns, the curves as before."""
    config = tiny("exp2", sizes=(16,), steps=3500, greedy_every=2000)
    [result] = run_experiment(config, tmp_path / "on", progress=False)
    rows = read_curves(tmp_path / "on" / "curves.csv")
    columns = ["greedy_goals_per_window", "greedy_pct_optimal", "greedy_pct_mentor"]
    for r in rows:
        evaluated = r["step"] == "2000"
        assert all((r[c] != "") == evaluated for c in [*columns, "greedy_reach_share"]), r
        if evaluated:
            rate, pct_opt, pct_mentor = (float(r[c]) for c in columns)
            assert rate >= 0 and 0 <= float(r["greedy_reach_share"]) <= 1
            assert pct_opt == pytest.approx(100 * rate / result.optimal_goals_per_window, abs=0.01)
            assert pct_mentor == pytest.approx(
                100 * rate / result.mentor_goals_per_window, abs=0.01
            )
    assert len(result.greedy_goals_per_window) == 2
    # the final policies under the "stuck" rule too: the same rate where no untried state is on
    # the way, else 0 (and in world<N>.json)
    for uniform, stuck in (
        (result.greedy_percent_of_optimal, result.greedy_percent_of_optimal_stuck),
        (result.greedy_percent_of_mentor, result.greedy_percent_of_mentor_stuck),
    ):
        assert len(stuck) == 2 and all(s in (0.0, u) for s, u in zip(stuck, uniform))
    saved = json.loads((tmp_path / "on" / "worlds" / "world16.json").read_text())
    assert saved["greedy_percent_of_mentor_stuck"] == result.greedy_percent_of_mentor_stuck
    assert 0 < result.mentor_goals_per_window <= result.optimal_goals_per_window * (1 + 1e-9)
    assert all(v <= result.true_value_start + 1e-9 for v in result.greedy_value_start)
    assert "The mentor's own policy (exact)" in (tmp_path / "on" / "results.md").read_text()
    off = replace(config, greedy_every=None)
    [plain] = run_experiment(off, tmp_path / "off", progress=False)
    rows_off = read_curves(tmp_path / "off" / "curves.csv")
    assert list(rows_off[0]) == [k for k in rows[0] if not k.startswith("greedy_")]
    assert [{k: r[k] for k in rows_off[0]} for r in rows] == rows_off  # the same runs
    assert plain.greedy_goals_per_window == [] and plain.greedy_percent_of_optimal_stuck == []


# Two worlds of exp3 to draw its scaling figure (10 s): -m slow (CI).
@pytest.mark.slow
def test_exp3_with_two_worlds_draws_the_scaling_bars(tmp_path):
    config = tiny("exp3", sizes=(16, 24), room_size=8, corner_options=False)
    results = run_experiment(config, tmp_path / "e3", progress=False)
    assert [r.size for r in results] == [16, 24]
    assert (tmp_path / "e3" / "figures" / "fig5_scaling.png").exists()
    assert "Scaling" in (tmp_path / "e3" / "results.md").read_text()


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """One tiny run on a 16×16 world (2 agents × 2 seeds, 3 windows): small enough that runs find
    the goal within the budget, so first-goal logging is exercised."""
    run_dir = tmp_path_factory.mktemp("tb") / "run"
    config = tiny("exp2", sizes=(16,), seeds=2, steps=3000)
    (result,) = run_experiment(config, run_dir, progress=False)
    return run_dir, result


def accumulate(folder: Path):
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    acc = EventAccumulator(str(folder), size_guidance={"images": 0, "scalars": 0, "tensors": 0})
    acc.Reload()
    return acc


def test_tensorboard_holds_first_goal_true_value_descriptions_and_maps(small_run):
    from himit_torch.viz.tensorboard import IMAGE_DESCRIPTIONS, SCALAR_DESCRIPTIONS

    run_dir, result = small_run
    names = [f"world16__{a}__seed{s}" for a, s in zip(result.agents, result.seeds)]
    assert sorted(p.name for p in (run_dir / "tb").iterdir()) == sorted(names)
    assert any(f >= 0 for f in result.first_goal_step), "no run found the goal: nothing checked"
    for b, name in enumerate(names):
        acc = accumulate(run_dir / "tb" / name)
        scalars = set(acc.Tags()["scalars"])
        assert [e.step for e in acc.Scalars("charts/goals_in_window")] == [1000, 2000, 3000]
        # Every scalar says what it is (TensorBoard shows the description beside the chart).
        for tag in scalars:
            assert acc.SummaryMetadata(tag).summary_description == SCALAR_DESCRIPTIONS[tag], tag
        # The first goal: one point at (step, step), or none for a run that never found it.
        first = result.first_goal_step[b]
        if first >= 0:
            assert [(e.step, e.value) for e in acc.Scalars("charts/first_goal_step")] == [
                (first, first)
            ]
        else:
            assert "charts/first_goal_step" not in scalars
        # V*(start) beside V(start), at every window.
        true_v = acc.Scalars("model/value_start_true")
        assert (
            [e.step for e in true_v]
            == [e.step for e in acc.Scalars("model/value_start")]
            == [1000, 2000, 3000]
        )
        assert all(e.value == pytest.approx(result.true_value_start, abs=1e-6) for e in true_v)
        assert acc.Scalars("model/value_start")[-1].value == pytest.approx(
            result.value_start[b], abs=1e-6
        )
        # Maps half-way and at the end, for the first seed of each agent, with colorbars or
        # legends drawn in: wide enough to read. The other seeds' runs have none.
        images = set(acc.Tags()["images"])
        if result.seeds[b] != min(result.seeds):
            assert images == set(), name
            continue
        assert images == set(IMAGE_DESCRIPTIONS)
        for tag in images:
            events = acc.Images(tag)
            assert [e.step for e in events] == [2000, 3000]
            assert events[0].width >= 400 and events[0].height >= 300
            assert acc.SummaryMetadata(tag).summary_description == IMAGE_DESCRIPTIONS[tag]
    # The options-only runs have no mentor term to log.
    assert "mentor/term_wins" not in accumulate(run_dir / "tb" / names[-1]).Tags()["scalars"]


def test_hparams_group_the_seeds_of_one_agent(small_run):
    from tensorboard.plugins.hparams.plugin_data_pb2 import HParamsPluginData

    run_dir, result = small_run
    groups = {}
    for a, s in zip(result.agents, result.seeds):
        content = accumulate(run_dir / "tb" / f"world16__{a}__seed{s}").PluginTagToContent(
            "hparams"
        )
        start = HParamsPluginData.FromString(
            content["_hparams_/session_start_info"]
        ).session_start_info
        assert "seed" not in start.hparams and start.hparams["agent"].string_value == a
        groups[a, s] = start.group_name
    # Seeds of one agent share a group; the agents' groups differ.
    assert (
        groups["imitation", 0]
        == groups["imitation", 1]
        != groups["options", 0]
        == groups["options", 1]
    )


def test_a_forced_rerun_with_another_budget_keeps_none_of_the_old_events(tmp_path):
    run_experiment(tiny("exp2", sizes=(16,)), tmp_path / "r", progress=False)
    rerun = tiny("exp2", sizes=(16,), steps=1000, window=500, checkpoint_every=500)
    run_experiment(rerun, tmp_path / "r", progress=False, force=True)
    acc = accumulate(tmp_path / "r" / "tb" / "world16__imitation__seed0")
    assert [e.step for e in acc.Scalars("charts/goals_in_window")] == [500, 1000]


def test_run_world_refuses_a_folder_with_another_runs_events(tmp_path):
    from himit_torch.runs.experiment import run_world

    config = tiny("exp2", sizes=(16,), steps=1000)
    run_world(config, 16, tmp_path, resume=False, progress=False)
    with pytest.raises(FileExistsError, match="would mix its curves"):
        run_world(config, 16, tmp_path, resume=False, progress=False)


# (three runs, ≈ 4 s: CI's; test_bad_input_cli refuses a finished run without --force, for
# every study, in the fast suite)
@pytest.mark.slow
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
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import run_experiment
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


@pytest.mark.slow  # (fast: tests/runs/test_checkpoints.py resumes a run "killed" after a checkpoint)
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
    with pytest.raises(ValueError, match="not UTF-8 text"):
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
    assert (
        main(["run", "exp2", "--config", str(cfg_path), "--logdir", str(tmp_path), "--quiet"]) == 0
    )
    assert (tmp_path / "exp2" / "results.md").exists()
    capsys.readouterr()
    page = (tmp_path / "exp2" / "results.md").read_text()
    commit = json.loads((tmp_path / "exp2" / "worlds" / "world40.json").read_text())["commit"]
    assert (
        f"Runs recorded at commit `{commit}` (from `worlds/*.json`); this page: "
        f"`himit plot {tmp_path / 'exp2'}`; the runs: `himit run exp2 --agents imitation options "
        f"--seeds 1 --steps 1000 --mentor-episodes 3 --window 1000 --logdir {tmp_path}`."
    ) in page
    (tmp_path / "exp2" / "results.md").unlink()
    # The world's process drew its figures; `himit plot` redraws them from the records.
    figures = tmp_path / "exp2" / "figures"
    drawn = {p.name: p.read_bytes() for p in figures.glob("*.png")}
    assert {"fig4_curves_world40.png", "first_goal_world40.png"} <= set(drawn)
    (figures / "fig4_curves_world40.png").write_bytes(b"stale")
    (figures / "first_goal_world40.png").unlink()
    assert main(["plot", str(tmp_path / "exp2")]) == 0
    assert "results.md" in capsys.readouterr().out
    assert (tmp_path / "exp2" / "results.md").read_text() == page  # the records redraw it
    assert {p.name: p.read_bytes() for p in figures.glob("*.png")} == drawn
    assert "finished run" in one_line_error(
        capsys, ["run", "exp2", "--config", str(cfg_path), "--logdir", str(tmp_path), "--quiet"]
    )
    assert "does not exist" in one_line_error(
        capsys, ["run", "exp1", "--config", str(tmp_path / "no.json")]
    )
    assert "is for 'exp2'" in one_line_error(capsys, ["run", "exp1", "--config", str(cfg_path)])
    if not torch.cuda.is_available():
        assert "CUDA" in one_line_error(
            capsys, ["run", "exp2", "--device", "cuda", "--logdir", str(tmp_path)]
        )
    assert "invalid choice" in one_line_error(capsys, ["run", "exp7"])
    assert "does not exist" in one_line_error(capsys, ["plot", str(tmp_path)])


def _world_record(change):
    """A damage of ``worlds/world16.json``: ``change(record)`` replaces the record (a dict)."""

    def damage(run_dir: Path) -> None:
        path = run_dir / "worlds" / "world16.json"
        path.write_text(json.dumps(change(json.loads(path.read_text()))))

    return damage


def _curves(change):
    """A damage of ``curves.csv``: ``change(rows)`` edits its rows (the header first) in place."""

    def damage(run_dir: Path) -> None:
        path = run_dir / "curves.csv"
        with path.open(newline="") as f:
            rows = list(csv.reader(f))
        change(rows)
        with path.open("w", newline="") as f:
            csv.writer(f).writerows(rows)

    return damage


def _drop_column(rows: list, name: str) -> None:
    k = rows[0].index(name)
    for row in rows:
        del row[k]


def _set_cell(rows: list, name: str, value: str) -> None:
    rows[1][rows[0].index(name)] = value


#: Damaged records of a finished run, and what ``himit plot``'s refusal must say.
PLOT_DAMAGE = {
    "a list for a world's record": (_world_record(lambda r: []), "holds a JSON list, not an"),
    "an empty world record": (_world_record(lambda r: {}), "'agents' is missing"),
    "an unknown field": (_world_record(lambda r: {**r, "bogus": 1}), "unknown fields ['bogus']"),
    "another world's record": (_world_record(lambda r: {**r, "size": 40}), "not this file's"),
    "goals not a list": (
        _world_record(lambda r: {**r, "goals": "x"}),
        "'goals' must be a list, got 'x'",
    ),
    "one run's goals short": (
        _world_record(lambda r: {**r, "goals": r["goals"][1:]}),
        "'goals' must hold one whole number per run (4)",
    ),
    "a text value start": (
        _world_record(lambda r: {**r, "value_start": ["a"] * 4}),
        "'value_start' must hold one number per run (4)",
    ),
    "a record that is not JSON": (
        lambda d: (d / "worlds" / "world16.json").write_text("{"),
        "is not valid JSON",
    ),
    "curves without goals_in_window": (
        _curves(lambda rows: _drop_column(rows, "goals_in_window")),
        "columns ['goals_in_window'] are missing",
    ),
    "a 200 kB field in curves": (
        _curves(lambda rows: _set_cell(rows, "agent", "a" * 200_000)),
        "field larger than field limit",
    ),
    "a goal count that is not a number": (
        _curves(lambda rows: _set_cell(rows, "goals_in_window", "many")),
        "goals_in_window='many' is not a whole number",
    ),
    "a short row in curves": (_curves(lambda rows: rows[1].pop()), "cells, not"),
    "no curves": (lambda d: (d / "curves.csv").unlink(), "does not exist"),
    "curves that are not text": (
        lambda d: (d / "curves.csv").write_bytes(b"\xff\xfe\x00"),
        "is not UTF-8",
    ),
}


def test_a_runs_report_draws_only_the_world_figures_not_drawn_yet(small_run, tmp_path):
    """At a run's end the report leaves each world's figures to its process (drawn as the world
    ended) and draws a world's where one is missing (a run resumed from an older version);
    ``himit plot`` redraws them all."""
    import shutil

    from himit_torch.runs.experiment import ExperimentStudy

    run_dir = tmp_path / "run"
    shutil.copytree(small_run[0], run_dir, ignore=shutil.ignore_patterns("tb", "checkpoints"))
    config = load_config(run_dir / "config.json")
    curves, first = (
        run_dir / "figures" / "fig4_curves_world16.png",
        run_dir / "figures" / "first_goal_world16.png",
    )
    drawn = curves.read_bytes(), first.read_bytes()
    curves.write_bytes(b"kept")
    ExperimentStudy().report(config, run_dir, [small_run[1]])
    assert curves.read_bytes() == b"kept"  # not redrawn
    first.unlink()
    ExperimentStudy().report(config, run_dir, [small_run[1]])
    # the world's figures drawn again, the same as its process drew them
    assert (curves.read_bytes(), first.read_bytes()) == drawn
    curves.write_bytes(b"kept")
    assert main(["plot", str(run_dir)]) == 0
    assert curves.read_bytes() == drawn[0]


@pytest.mark.parametrize("kind", list(PLOT_DAMAGE))
def test_plot_refuses_a_damaged_record_in_one_line(small_run, tmp_path, capsys, kind):
    import shutil

    run_dir = tmp_path / "run"
    shutil.copytree(small_run[0], run_dir, ignore=shutil.ignore_patterns("tb", "checkpoints"))
    damage, message = PLOT_DAMAGE[kind]
    damage(run_dir)
    err = one_line_error(capsys, ["plot", str(run_dir)])
    assert message in err, err
    assert "curves" in err or "world16.json" in err, err  # the file is named


@pytest.mark.parametrize(
    "config",
    [
        EXPERIMENTS["exp2"],
        EXPERIMENTS["exp2"].with_preset("paper"),
        replace(EXPERIMENTS["exp1"].with_preset("recommended"), seeds=20),
        replace(
            EXPERIMENTS["exp2"],
            seeds=20,
            learner=replace(EXPERIMENTS["exp2"].learner, tie_break="first"),
        ),
        replace(
            EXPERIMENTS["exp1"],
            agents=("imitation", "imitation_confident"),
            learner=replace(EXPERIMENTS["exp1"].learner, mentor_override_after=5),
        ),
        replace(EXPERIMENTS["exp2"], steps=12_000, checkpoint_every=10_000),  # as run moves it
        replace(EXPERIMENTS["exp2"], steps=12_000, checkpoint_every=5000),  # given
        replace(EXPERIMENTS["exp2"], checkpoint_every=50_000, window=2500),
        replace(EXPERIMENTS["exp1"], corner_options=False, mentor_preference=0.5, slip=0.2),
        replace(EXPERIMENTS["exp3"], sizes=(64, 80), first_seed=7, mentor_reward="none"),
    ],
)
def test_run_command_rebuilds_the_configuration(config, tmp_path):
    """The command a results page names for its runs, read by ``himit run``'s own parser,
    builds exactly the configuration the runs had."""
    import shlex

    from himit_torch.cli import build_parser, study_configs
    from himit_torch.runs.experiment import run_command

    command = run_command(config, tmp_path / "logs" / config.name)
    assert command is not None and "--config" not in command
    argv = shlex.split(command)
    assert argv[:3] == ["himit", "run", config.name]
    args = build_parser().parse_args(argv[1:])
    assert args.logdir == str(tmp_path / "logs")
    assert study_configs(args) == [config]
    assert run_command(config, Path("runs") / config.name) == command.replace(
        f" --logdir {tmp_path / 'logs'}", ""
    )


def test_run_command_where_no_flags_rebuild_it(tmp_path):
    config = EXPERIMENTS["exp2"]
    assert run_command_of(replace(config, name="mine")) is None  # not an experiment of himit run
    assert run_command_of(config, tmp_path / "elsewhere") is None  # run writes <logdir>/exp2
    # a learner departing from its recorded preset (a preset's settings changed since): no
    # flags rebuild it, its config.json does
    odd = replace(config, learner=replace(config.learner, mentor_fade=7.0))
    odd.preset = "paper"  # set after the check, as no config.json could load
    assert run_command_of(odd, tmp_path / "exp2").startswith(
        f"himit run exp2 --config {tmp_path / 'exp2' / 'config.json'}"
    )


def run_command_of(config, run_dir=None):
    from himit_torch.runs.experiment import run_command

    return run_command(config, run_dir)


def test_cli_demo_learning_run(capsys, tmp_path):
    out = tmp_path / "demo"
    assert (
        main(
            [
                "demo",
                "--out",
                str(out),
                "--episodes",
                "2",
                "--steps",
                "2000",
                "--seeds",
                "1",
                "--quiet",
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "goals in the last 2000 steps" in text and "tensorboard --logdir" in text
    assert (out / "learning" / "results.md").exists()
    assert len(list((out / "learning" / "tb").iterdir())) == 3


def test_cli_bench_prints_a_rate(capsys):
    assert (
        main(
            [
                "bench",
                "--batch",
                "2",
                "--steps",
                "50",
                "--warmup",
                "0",
                "--size",
                "12",
                "--rooms",
                "2",
            ]
        )
        == 0
    )
    line = capsys.readouterr().out
    assert "steps/s" in line and "B=2" in line
    assert "agent" in one_line_error(capsys, ["bench", "--agent", "nobody"])


# Four runs, one of them through the CLI (10 s): -m slow (CI); the reward modules' own tests
# (tests/mentor/) stay in the fast suite.
@pytest.mark.slow
def test_mentor_reward_is_a_setting_of_the_runner_and_the_cli(tmp_path, capsys):
    """``mentor_reward`` changes only the imitators: the options runs (no mentor term) are the same
    in every batch, the imitators' curves differ between the world's reward and r_m = 0."""
    with pytest.raises(ValueError, match="mentor_reward='bogus'.*known"):
        tiny("exp2", mentor_reward="bogus")
    runs = {}
    for name in ("known", "salience", "none"):
        config = tiny("exp2", mentor_reward=name, steps=3000)
        run_experiment(config, tmp_path / name, progress=False, workers=1)
        assert load_config(tmp_path / name / "config.json").mentor_reward == name
        runs[name] = {
            (r["agent"], r["step"]): r["goals_in_window"]
            for r in read_curves(tmp_path / name / "curves.csv")
        }
    own = {k: v for k, v in runs["known"].items() if k[0] == "options"}
    for name in ("salience", "none"):
        assert {k: v for k, v in runs[name].items() if k[0] == "options"} == own
    # the mentor term's values differ with its reward: compare the learners' start values
    starts = {
        n: json.loads((tmp_path / n / "worlds" / "world40.json").read_text())["value_start"][0]
        for n in runs
    }
    assert len(set(starts.values())) == 3
    assert "mentor reward `none`" in (tmp_path / "none" / "results.md").read_text()
    assert "mentor reward" not in (tmp_path / "known" / "results.md").read_text()
    # the CLI flag
    cfg = tmp_path / "cfg.json"
    cfg.write_text(tiny("exp2", steps=1000).to_json())
    assert (
        main(
            [
                "run",
                "exp2",
                "--config",
                str(cfg),
                "--mentor-reward",
                "salience",
                "--logdir",
                str(tmp_path / "cli"),
                "--quiet",
            ]
        )
        == 0
    )
    assert load_config(tmp_path / "cli" / "exp2" / "config.json").mentor_reward == "salience"
    capsys.readouterr()
    assert "invalid choice" in one_line_error(capsys, ["run", "exp2", "--mentor-reward", "x"])
    assert "no --mentor-reward" in one_line_error(
        capsys, ["run", "gymnasium", "--mentor-reward", "none"]
    )


# ------------------------------------------------------------------ several experiments at once
def without_wall_time(run_dir: Path) -> dict:
    """What a run directory says about its worlds, less the seconds they took."""
    worlds = {}
    for path in sorted((run_dir / "worlds").glob("world*.json")):
        data = json.loads(path.read_text())
        del data["wall_seconds"]
        worlds[path.name] = data
    return worlds


@pytest.mark.slow
def test_experiments_in_one_pool_end_as_each_alone(tmp_path):
    """``run_experiments`` (``himit run paper``) shares the worlds of several experiments out over
    the workers; each run directory ends as ``run_experiment`` alone leaves it."""
    plans = [
        (tiny("exp2", sizes=(16,)), "exp2"),
        (tiny("exp3", sizes=(16, 24), room_size=8, corner_options=False), "exp3"),
    ]
    together = run_experiments(
        [(config, tmp_path / "pool" / name) for config, name in plans], progress=False, workers=2
    )
    for (config, name), results in zip(plans, together):
        alone = run_experiment(config, tmp_path / "alone" / name, progress=False, workers=1)
        assert [r.size for r in results] == [r.size for r in alone] == list(config.sizes)
        pool_dir, alone_dir = tmp_path / "pool" / name, tmp_path / "alone" / name
        assert (pool_dir / "curves.csv").read_text() == (alone_dir / "curves.csv").read_text()
        assert without_wall_time(pool_dir) == without_wall_time(alone_dir)
        assert load_config(pool_dir / "config.json") == config
        assert (pool_dir / "results.md").exists()
    assert (tmp_path / "pool" / "exp3" / "figures" / "fig5_scaling.png").exists()


@pytest.mark.slow
def test_a_world_failing_in_this_process_stops_the_pool_and_restores_its_threads(
    tmp_path, monkeypatch
):
    """This process is one of the pool's lanes: a world that fails in it raises from
    ``run_experiments`` (the other lanes take no more worlds), and its thread counts are its
    own again afterwards."""
    import numba

    import himit_torch.runs.experiment as experiment

    ran = []

    def failing_world(config, size, *args, **kwargs):
        ran.append(size)
        raise RuntimeError(f"world {size} failed")

    monkeypatch.setattr(experiment, "run_world", failing_world)
    threads = numba.get_num_threads(), torch.get_num_threads()
    config = tiny("exp3", sizes=(16, 24), room_size=8, corner_options=False)
    with pytest.raises(RuntimeError, match="world 24 failed"):
        run_experiments([(config, tmp_path / "exp3")], progress=False, workers=2)
    assert ran == [24]  # the most expensive world, taken first by this process
    assert (numba.get_num_threads(), torch.get_num_threads()) == threads


def test_run_experiments_refuses_two_plans_in_one_directory(tmp_path):
    config = tiny("exp2", sizes=(16,))
    with pytest.raises(ValueError, match="two plans share a run directory"):
        run_experiments([(config, tmp_path / "r"), (config, tmp_path / "r")], progress=False)
    assert not (tmp_path / "r").exists()  # refused before anything was written


def test_cli_run_paper_runs_the_three_experiments_with_the_options_given(
    tmp_path, capsys, monkeypatch
):
    import himit_torch.runs.experiment as experiment

    seen = {}

    def fake_run_experiments(plans, **kwargs):
        seen["plans"], seen["kwargs"] = plans, kwargs
        return [[] for _ in plans]

    monkeypatch.setattr(experiment, "run_experiments", fake_run_experiments)
    argv = ["run", "paper", "--seeds", "2", "--steps", "20000", "--logdir", str(tmp_path)]
    assert main([*argv, "--workers", "2", "--quiet"]) == 0
    names = [config.name for config, _ in seen["plans"]]
    assert names == ["exp1", "exp2", "exp3"]
    assert [Path(d) for _, d in seen["plans"]] == [tmp_path / n for n in names]
    for config, _ in seen["plans"]:
        expected = replace(EXPERIMENTS[config.name], seeds=2, steps=20_000)
        assert config == replace(expected, checkpoint_every=20_000)
    assert seen["kwargs"] == {"resume": False, "force": False, "progress": False, "workers": 2}
    out = capsys.readouterr().out
    assert all(str(tmp_path / n / "results.md") in out for n in names)
    cfg = tmp_path / "cfg.json"
    cfg.write_text(tiny("exp2").to_json())
    assert "paper takes no --config" in one_line_error(
        capsys, ["run", "paper", "--config", str(cfg)]
    )
