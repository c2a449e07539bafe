"""``himit info --minigrid ID``: a MiniGrid task's summary, and its refusals on the command line."""

from __future__ import annotations

import re

import pytest

pytest.importorskip("minigrid")

import himit_torch as ht  # noqa: E402
from himit_torch.cli import main  # noqa: E402


def test_info_minigrid(capsys):
    assert main(["info", "--minigrid", "MiniGrid-DoorKey-5x5-v0"]) == 0
    out = capsys.readouterr().out
    world = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0")
    assert f"states     {world.num_states:,} reachable" in out
    assert "go to the yellow key, go to the yellow door, go to the goal" in out
    options = ht.primitive_options(world)
    plan = ht.smdp_value_iteration(ht.option_models(world, options))
    steps = ht.expected_steps(
        ht.option_durations(world, options), plan.policy, 0, world.terminal_mask
    )
    row = re.search(r"^primitives only\s+([\d.]+)\s+([\d.]+)$", out, flags=re.M)
    assert row and float(row.group(1)) == round(steps, 1)
    assert re.search(r"^mentor \(prefers its options within 0.01\)\s+[\d.]+\s+[\d.]+$", out, re.M)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--minigrid", "MiniGrid-Nope-v0"], "gymnasium.make failed"),
        (["--minigrid", "MiniGrid-Dynamic-Obstacles-5x5-v0"], "stochastic"),
        (["--minigrid", "MiniGrid-DoorKey-5x5-v0", "--env", "Taxi-v4"], "not both"),
        (["--minigrid", "MiniGrid-DoorKey-5x5-v0", "--puzzle-box", "2"], "not both"),
        (["--minigrid", "MiniGrid-DoorKey-5x5-v0", "--env-kwargs", "{}"], "is for --env"),
    ],
)
def test_info_minigrid_refused(capsys, argv, words):
    with pytest.raises(SystemExit) as exc:
        main(["info", *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("himit: error:") and words in err and err.count("\n") == 1


def test_run_minigrid_runs_doorkey_6x6_and_plot_redraws_it(tmp_path, capsys):
    """``himit run minigrid`` (the Gymnasium comparison on MiniGrid's tasks, DoorKey-6x6 by
    default) runs its batch with the MiniGrid mentor and writes the task's records; ``himit plot``
    finds its study from config.json and writes the same page again."""
    import json

    assert main(["run", "minigrid", "--quick", "--quiet", "--logdir", str(tmp_path)]) == 0
    run_dir = tmp_path / "minigrid"
    summary = json.loads((run_dir / "tasks" / "doorkey6x6.json").read_text())
    assert summary["env_id"] == "MiniGrid-DoorKey-6x6-v0"
    assert "go to the yellow key" in summary["options"]
    assert sorted(set(summary["agents"])) == ["imitation", "options", "primitives"]
    page = (run_dir / "results.md").read_text()
    assert "The mentor is optimal for its own options" in page
    assert "Produced by `himit run minigrid`" in page and "himit run gymnasium" not in page
    assert f"`himit run minigrid --quick --logdir {tmp_path}`" in page  # (its rerun command)
    # The paths figure: the mentor's first episode and each agent's greedy trajectory (seed 0),
    # kept in the task's record so that himit plot draws it again.
    assert sorted(summary["paths"]) == ["imitation", "mentor", "options", "primitives"]
    assert all(path[0] == 0 for path in summary["paths"].values())  # (from the start state)
    assert "`figures/paths_doorkey6x6.png`" in page
    figure = run_dir / "figures" / "paths_doorkey6x6.png"
    figure.unlink()
    assert main(["plot", str(run_dir)]) == 0
    assert (run_dir / "results.md").read_text() == page
    assert figure.stat().st_size > 0


def test_run_minigrid_help_lists_the_minigrid_tasks(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["run", "minigrid", "--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())  # (argparse wraps the help's lines)
    assert "doorkey6x6" in out and "(default: doorkey6x6)" in out


def _task_params():
    from himit_torch.runs.gymnasium import MINIGRID_TASKS

    # 9,210 and 17,344 states: 35-50 s each to solve on 2 cores, left to make test-all; the
    # larger of the others (2-5 s each) to CI
    large = {"doorkey8x8", "doorkey8x8_transfer", "unlockpickup"}
    medium = {"multiroomn4s5", "doorkey6x6", "doorkey6x6_transfer", "unlock"}
    return [
        pytest.param(name, marks=[pytest.mark.slow, pytest.mark.extended])
        if name in large
        else pytest.param(name, marks=pytest.mark.slow)
        if name in medium
        else name
        for name in MINIGRID_TASKS
    ]


def test_every_described_minigrid_task_is_registered_for_himit_run_minigrid():
    from himit_torch.runs.gymnasium import MINIGRID_TASKS

    assert {t.env_id for t in MINIGRID_TASKS.values()} == set(ht.MINIGRID_TASKS)


def test_run_minigrid_transfer_watches_the_mentor_of_the_moved_goal(tmp_path):
    """A transfer task: the learner is rewarded at MiniGrid's goal (3, 3) of DoorKey 5×5 and
    watches a mentor demonstrating the layout with its goal at (3, 2), carried into its states:
    the mentor's path ends on (3, 2), a floor cell of the learner's world, and the optimum is the
    learner's task's."""
    import json

    from himit_torch.runs.gymnasium import MINIGRID_TASKS

    argv = ["run", "minigrid", "--quick", "--quiet", "--logdir", str(tmp_path), "--tasks",
            "doorkey5x5_transfer", "--agents", "imitation", "options"]  # fmt: skip
    assert main(argv) == 0
    summary = json.loads((tmp_path / "minigrid" / "tasks" / "doorkey5x5_transfer.json").read_text())
    world = MINIGRID_TASKS["doorkey5x5_transfer"].world(0.99)
    assert world.goal_cells == (18,) and world.num_states == summary["num_states"]
    last = summary["paths"]["mentor"][-1]
    assert world.state_key(last)[:2] == (3, 2) and not bool(world.terminal_mask[last])
    assert summary["optimal_value"] == pytest.approx(
        float(
            ht.smdp_value_iteration(ht.option_models(world, ht.primitive_options(world))).values[0]
        )
    )


@pytest.mark.parametrize("name", _task_params())
def test_info_minigrid_answers_for_every_registered_task(capsys, name):
    """Each task of ``himit run minigrid`` (issue 54's list): ``himit info --minigrid`` prints
    its states, the learner's skills of the registered task, and a mentor that reaches success
    (finitely many steps from the start, a positive goal rate)."""
    from himit_torch.runs.gymnasium import MINIGRID_TASKS

    task = MINIGRID_TASKS[name]
    assert main(["info", "--minigrid", task.env_id]) == 0
    out = capsys.readouterr().out
    world = task.world(0.99)
    skills = [n for n, k in zip(task.options(world).names, task.options(world).kinds)
              if k != "primitive"]  # fmt: skip
    assert f"states     {world.num_states:,} reachable" in out
    assert f"subgoal: {', '.join(skills)})" in out
    row = re.search(
        r"^mentor \(prefers its options within 0.01\)\s+([\d.]+)\s+([\d.]+)$", out, re.M
    )
    assert row and 0 < float(row.group(1)) < 100 and float(row.group(2)) > 0
