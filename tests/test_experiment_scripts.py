"""The experiment scripts import what they use as modules (none loads another file by path)."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"


def test_no_experiment_script_loads_a_file_by_path():
    by_path = [
        str(p.relative_to(EXPERIMENTS))
        for p in sorted(EXPERIMENTS.rglob("*.py"))
        if "spec_from_file_location" in p.read_text() or "SourceFileLoader" in p.read_text()
    ]
    assert by_path == []


def test_the_benchmark_analysis_imports_the_claims_loader_as_a_module():
    benchmark = importlib.import_module("experiments.benchmark.analyse")
    claims = importlib.import_module("experiments.claims.analyse")
    assert benchmark.claims is claims and benchmark.load_dir is claims.load_dir
    assert benchmark.NINE == claims.WORLDS


def test_the_benchmark_times_a_slice_without_touching_the_committed_records(tmp_path, monkeypatch):
    runner = importlib.import_module("experiments.benchmark.run_benchmark")
    commands: list[tuple[str, ...]] = []
    monkeypatch.setattr(runner, "run", lambda *argv: commands.append(argv))
    committed = runner.RESULTS / "timing.json"
    before = committed.read_bytes()
    logdir = tmp_path / "bench"
    runner.main(["--timing-only", "--parts", "worlds", "puzzlebox", "minigrid", "--seeds", "2",
                 "--logdir", str(logdir)])  # fmt: skip
    assert committed.read_bytes() == before
    timing = json.loads((logdir / "timing.json").read_text())
    assert set(timing) == {"worlds", "puzzlebox", "minigrid"}
    scripts = [Path(c[0]).name if c[0] != "-m" else c[2] for c in commands]
    # the runs, and nothing that copies or analyses
    assert "collect_results.py" not in scripts
    assert "analyse.py" not in scripts and "analyse_search.py" not in scripts
    assert scripts.count("run") == 4 and scripts.count("gymnasium_worlds.py") == 4
    by_script = {Path(c[0]).name: c for c in commands}
    assert "--print-only" in by_script["puzzle_box_benchmark.py"]
    assert "--no-collect" in by_script["minigrid_benchmark.py"]
    assert all(str(logdir) in " ".join(c) for c in commands)


def test_the_benchmark_collects_and_analyses_without_timing_only(tmp_path, monkeypatch):
    runner = importlib.import_module("experiments.benchmark.run_benchmark")
    commands: list[tuple[str, ...]] = []
    monkeypatch.setattr(runner, "run", lambda *argv: commands.append(argv))
    monkeypatch.setattr(runner, "RESULTS", tmp_path / "results")
    runner.main(["--parts", "puzzlebox", "--skip-runs", "--logdir", str(tmp_path / "bench")])
    scripts = [Path(c[0]).name for c in commands]
    assert scripts == ["puzzle_box_benchmark.py", "analyse.py", "analyse_search.py"]
    assert "--print-only" not in commands[0]
