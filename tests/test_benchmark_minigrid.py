"""The benchmark's MiniGrid part (``experiments/benchmark/``, PROTOCOL.md's amendment of
2026-11-29): its page regenerates bit for bit from the committed records, the leaderboard and
"Does the hierarchy help?" carry it, and the budgets follow the amendment's rule from the
committed calibration records."""

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHMARK = ROOT / "experiments" / "benchmark"
RESULTS = ROOT / "experiments" / "results"


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    sys.modules[name] = module  # (dataclasses look their module up)
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    return module


@pytest.fixture(scope="module")
def runner():
    return _load("minigrid_benchmark", BENCHMARK / "minigrid_benchmark.py")


@pytest.mark.slow
def test_the_minigrid_page_regenerates_from_the_committed_records():
    analyse = _load("benchmark_analyse", BENCHMARK / "analyse.py")
    sections = analyse.minigrid_sections(RESULTS)
    assert sections is not None
    page = (RESULTS / "benchmark" / "minigrid.md").read_text()
    assert analyse.minigrid_page(sections) == page
    board, hierarchy, tests = sections
    assert "\n".join(board) in (RESULTS / "benchmark" / "leaderboard.md").read_text()
    assert "\n".join(hierarchy) in (RESULTS / "benchmark" / "hierarchy.md").read_text()
    assert {t.table for t in tests} == {"minigrid leaderboard", "minigrid hierarchy"}


def test_the_budgets_follow_the_amendments_rule_from_the_calibration_records(runner):
    assert runner.budgets(list(runner.MINIGRID_BUDGETS)) == runner.MINIGRID_BUDGETS


@pytest.mark.parametrize(
    "t, budget",
    [(2_000, 100_000), (20_000, 100_000), (22_000, 150_000), (30_000, 150_000),
     (30_002, 200_000), (45_000, 200_000)],
)  # fmt: skip
def test_the_budget_rule_hand_solved(runner, t, budget):
    """5·T rounded up to a multiple of 50k, at least 100k, at most 200k."""
    assert runner.budget_rule(t) == budget


def test_plateau_step_hand_solved(runner, tmp_path):
    """Two seeds, windows of 10k over 100k steps; the last 50k steps average 100 goals per
    window, so T is the first window whose mean over the seeds reaches 90: at 30k (mean 90)."""
    goals = {10_000: (0, 20), 20_000: (100, 60), 30_000: (80, 100), 40_000: (100, 100)}
    rows = ["task,agent,seed,step,goals"]
    for step in range(10_000, 100_001, 10_000):
        a, b = goals.get(step, (100, 100))
        rows += [f"t,options,0,{step},{a}", f"t,options,1,{step},{b}"]
    path = tmp_path / "t.csv"
    path.write_text("\n".join(rows) + "\n")
    assert runner.plateau_step(path) == 30_000
