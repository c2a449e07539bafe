"""Shared test set-up: one torch thread (tiny tensors; two threads only add contention on a busy
2-core machine), no disk cache of exact option models unless ``HIMIT_EXACT_CACHE`` names one
(the suite writes nothing into the user's cache; tests/exact/test_reference_cache.py turns it
on in a temporary folder), a seeded generator fixture, and a live malicious pickle for the tests
that files are read without unpickling code."""

import os
import shlex
from pathlib import Path

import pytest
import torch

from himit_torch.worlds.multirooms import MultiRooms

torch.set_num_threads(1)
os.environ.setdefault("HIMIT_EXACT_CACHE", "off")


@pytest.fixture
def generator() -> torch.Generator:
    return torch.Generator().manual_seed(1234)


@pytest.fixture(scope="module")
def world8() -> MultiRooms:
    """8×8 world, 2×2 rooms: small enough for learning tests that must finish in seconds."""
    return MultiRooms(8, 2)


class _PlantsMarker:
    """Unpickling this runs a shell command that creates ``marker`` (what a hostile file does)."""

    def __init__(self, marker: Path):
        self.marker = str(marker)

    def __reduce__(self):
        return (os.system, (f"touch {shlex.quote(self.marker)}",))


@pytest.fixture
def plants_marker():
    """``plants_marker(path)``: an object whose unpickling creates ``path``."""
    return _PlantsMarker


@pytest.fixture(scope="module")
def world12() -> MultiRooms:
    """12×12 world, 2×2 rooms."""
    return MultiRooms(12, 2)


@pytest.fixture(scope="module")
def mentor_demos12(world12):
    """5 demonstrations of the optimal mentor on ``world12`` (the engine-parity tests' batch)."""
    from himit_torch.mentor.policy import mentor_policy, record_demonstrations
    from himit_torch.options.builders import mentor_options

    return record_demonstrations(
        world12, mentor_policy(world12, mentor_options(world12)), 5, seed=0
    )


@pytest.fixture
def planned(monkeypatch):
    """``planned(argv)``: the configurations ``himit run argv`` would run (nothing runs)."""
    import himit_torch.runs.experiment as experiment_module
    from himit_torch.cli import main

    plans = []
    monkeypatch.setattr(
        experiment_module, "run_experiments", lambda p, **kwargs: plans.extend(p) or []
    )

    def run(argv):
        plans.clear()
        assert main(["run", *argv]) == 0
        return [config for config, _ in plans]

    return run
