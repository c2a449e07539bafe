"""``himit plot`` tells the study a run directory belongs to, and says in one line what it
cannot redraw (a discovery run, a puzzle-box run without its batch records) instead of reading
it as an experiment's."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "experiments" / "results"


def _plot(run_dir: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "himit_torch.cli", "plot", str(run_dir)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )


def _one_line_error(done: subprocess.CompletedProcess, *words: str) -> None:
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("himit: error:"), done.stderr
    for word in words:
        assert word in lines[0]
    assert "Traceback" not in done.stderr


@pytest.mark.slow  # (a fresh interpreter, ≈ 4 s: CI's; the experiment directory's runs in the fast suite)
@pytest.mark.skipif(not (RESULTS / "discovery").is_dir(), reason="needs the committed records")
def test_a_discovery_run_is_named_not_read_as_an_experiment(tmp_path):
    run = tmp_path / "discovery"
    run.mkdir()
    shutil.copy(RESULTS / "discovery" / "config.json", run / "config.json")
    _one_line_error(_plot(run), "discovery", "does not redraw")


@pytest.mark.slow  # (≈ 3 s: CI's; test_bad_input_cli refuses damaged puzzle-box runs in the fast suite)
@pytest.mark.skipif(not (RESULTS / "puzzlebox").is_dir(), reason="needs the committed records")
def test_a_puzzle_box_run_without_its_batches_says_so(tmp_path):
    run = tmp_path / "box"
    run.mkdir()
    for name in ("config.json", "summary.json"):
        shutil.copy(RESULTS / "puzzlebox" / name, run / name)
    _one_line_error(_plot(run), "batches/", "puzzle-box")


def test_an_experiment_directory_is_still_read_as_one(tmp_path):
    """A folder whose config is an experiment's (and no world finished) gets the experiment
    reader's own message, not the discovery one."""
    run = tmp_path / "exp"
    run.mkdir()
    (run / "config.json").write_text(json.dumps({"name": "exp2", "sizes": [12]}))
    done = _plot(run)
    assert done.returncode == 2 and "discovery" not in done.stderr, done.stderr
