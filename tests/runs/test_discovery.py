"""The discovery experiment (himit_torch.runs.discovery) with a tiny budget: its command, its
outputs and its option refreshes. Discovery itself: tests/options/test_discovery.py."""

import pytest


def test_himit_run_discovery_quick(tmp_path, capsys):
    import csv

    from himit_torch.cli import main
    from himit_torch.runs.discovery import DISCOVERY_AGENTS, DiscoveryConfig, _fmt

    assert (
        main(
            [
                "run",
                "discovery",
                "--quick",
                "--seeds",
                "2",
                "--steps",
                "10000",
                "--logdir",
                str(tmp_path),
                "--quiet",
            ]
        )
        == 0
    )
    run = tmp_path / "discovery"
    text = (run / "results.md").read_text()
    assert (
        "this page: written by the runs themselves (no command redraws it from its records); "
        f"the runs: `himit run discovery --quick --steps 10000 --logdir {tmp_path}`."
    ) in text
    for agent in DISCOVERY_AGENTS:
        assert f"| {agent} |" in text
    with (run / "curves.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == len(DISCOVERY_AGENTS) * 2 * 2  # 2 seeds × 2 windows of 5000
    assert {r["agent"] for r in rows} == set(DISCOVERY_AGENTS)
    assert (run / "figures" / "subgoals_exp2.png").exists() and (run / "subgoals.csv").exists()
    # runs.csv: one row per run, its goals those of its curve, its greedy policy a percentage,
    # discovered options counted for the discovered runs only
    with (run / "runs.csv").open() as f:
        runs = list(csv.DictReader(f))
    assert len(runs) == len(DISCOVERY_AGENTS) * 2
    for r in runs:
        curve = [
            int(c["goals_in_window"])
            for c in rows
            if (c["agent"], c["seed"]) == (r["agent"], r["seed"])
        ]
        assert int(r["total_goals"]) == sum(curve)
        assert (int(r["first_goal_step"]) >= 0) == (sum(curve) > 0)
        assert 0.0 <= float(r["greedy_percent_of_optimal"]) <= 100.0 + 1e-6
        assert (r["discovered_options"] != "") == r["agent"].startswith("discovered")
    assert "% of optimum |" in text
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["run", "discovery", "--quick", "--mentor-reward", "none", "--logdir", str(tmp_path)])
    assert "takes no --mentor-reward" in capsys.readouterr().err
    with pytest.raises(ValueError, match="warmup"):
        DiscoveryConfig(steps=20_000, warmup=20_000)
    with pytest.raises(ValueError, match="refresh_every"):
        DiscoveryConfig(refresh_every=3000)  # not a multiple of the window (5000)
    # t(0.975, 2) = 4.303, sd = 1: half-width 4.302653 / √3 = 2.484
    assert _fmt([1.0, 2.0, 3.0], 3) == "2.000 ± 2.484"
    # the page's own conventions around statistics.t_interval: the mean alone for one value,
    # and a NaN (a seed whose discovery found nothing: precision 0/0) shown, not left out
    assert _fmt([5.0]) == "5.0"
    assert _fmt([0.5, float("nan")]) == "nan ± nan"


def test_discovered_runs_continue_the_primitives_runs_and_refresh(tmp_path):
    """The discovered-options runs are the primitives runs up to the warm-up (the same curve), then
    go on with options rebuilt every ``refresh_every`` steps."""
    from dataclasses import replace

    from himit_torch.runs.discovery import DiscoveryConfig, run_discovery

    config = replace(DiscoveryConfig().quick(), seeds=1, steps=15_000, refresh_every=5000)
    (result,) = run_discovery(config, tmp_path / "d", progress=False)
    goals, window = result["goals"], config.warmup // 5000
    for variant, source in (
        ("discovered_options", "primitives"),
        ("discovered_imitation", "imitation_primitives"),
    ):
        assert len(goals[variant][0]) == 3
        assert list(goals[variant][0][:window]) == list(goals[source][0][:window])
    assert result["refreshes"] == [1, 1]  # at 10,000 steps (the warm-up build is not counted)
    text = (tmp_path / "d" / "results.md").read_text()
    assert "rebuilt from its latest counts every 5,000 steps" in text
    # refresh_every is no flag of himit run discovery (and "d" no run directory it writes)
    assert "the runs: the settings in `config.json` (not all of them flags" in text


def test_a_moved_goals_mentor_shows_its_walk_and_the_subgoals_come_from_it():
    """``mentor_goal = "top-right"``: on exp2's 40×40 world (rooms of 4, start (0, 0), the
    learner's goal (39, 39)) the mentor walks to the top-right corner cell (0, 39). Its shortest
    way runs along the top row of rooms (rows 0–3), so each episode starts at (0, 0), ends at
    (0, 39), never enters the learner's goal, and every subgoal found is a state of the
    demonstrations in rows 0–3 (most of them doorways) — where the learner's own task's mentor ends at
    (39, 39) and leaves the top row."""
    from himit_torch.runs.discovery import DiscoveryConfig, _find_subgoals, _world_setting

    moved = DiscoveryConfig(worlds=("exp2",), seeds=2, mentor_goal="top-right",
                            demonstrations_needed=(2,))  # fmt: skip
    w = _world_setting(moved, "exp2", progress=False)
    world = w.world
    assert world.coords(world.start_state) == (0, 0)
    assert world.coords(world.goal_state) == (39, 39)
    doorways = set(world.doorways.tolist())
    _find_subgoals(moved, w)
    for seed in (0, 1):
        episodes = w.demos[seed].episodes
        assert len(episodes) == 20
        for episode in episodes:
            cells = [world.coords(int(s)) for s in episode]
            assert cells[0] == (0, 0) and cells[-1] == (0, 39)
            assert world.goal_state not in episode.tolist()
        visited = {int(s) for e in episodes for s in e}
        found = [int(s) for s in w.found[seed].states]
        assert found, "no subgoal found in the moved goal's demonstrations"
        assert set(found) <= visited and set(found) & doorways
        assert all(world.coords(s)[0] <= 3 for s in found)
    same = _world_setting(DiscoveryConfig(worlds=("exp2",), seeds=1), "exp2", progress=False)
    assert all(
        world.coords(int(e[-1])) == (39, 39) and max(world.coords(int(s))[0] for s in e) == 39
        for e in same.demos[0].episodes
    )
