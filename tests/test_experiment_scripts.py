"""The experiment scripts import what they use as modules (none loads another file by path)."""

from __future__ import annotations

import importlib
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
