"""The benchmark scripts that reach into the package's private functions still run.

``benchmarks/bench_world_phases.py`` times a world's parts by wrapping functions of the runner
by name; a function renamed or moved stops it with an ``AttributeError``, which no other test
sees (it happened once when the mentor's episodes moved to ``runs/mentoring.py``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_world_phases_benchmark_runs_and_splits_every_part(tmp_path):
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "bench_world_phases.py"), "exp2", "40"]
        + ["--seeds", "1", "--agents", "imitation", "--logdir", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    lines = [line.strip() for line in done.stdout.splitlines()]
    groups = {line.split()[0] for line in lines if line.endswith("%)")}
    assert {"learning", "exact", "set-up", "maps", "figures", "logging", "checkpoints"} <= groups
    # each wrapped function was called: the mentor's episodes and the learner's kernel included
    parts = {line.rsplit(maxsplit=1)[0]: float(line.rsplit(maxsplit=1)[1]) for line in lines
             if line and not line.endswith("%)") and line[-1].isdigit() and "  " in line}  # fmt: skip
    assert parts["mentor's episodes"] > 0 and parts["kernel, imitation"] > 0, parts
    assert (tmp_path / "exp2" / "worlds" / "world40.json").is_file()
