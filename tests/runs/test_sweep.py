"""``himit sweep``: spec checking, the in-process and Ray runners, skip/resume, and the tables."""

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from himit_torch.cli import main
from himit_torch.runs.sweep import load_spec, run_sweep

# 16×16 world (rooms of 4 cells), 2 agents, 3000 steps: a trial runs in about a second.
TINY = """
name = "tiny"
base = "exp2"
seeds = 3
seeds_per_trial = 2
worlds = [16]
design = "{design}"
[set]
agents = ["imitation", "options"]
steps = {steps}
window = 1000
checkpoint_every = 1000
mentor_episodes = 3
engine = "{engine}"
{grid}
"""
GRID = """[grid]
learner.tie_break = ["random", "first"]
learner.untried_value = ["none", 0.0]
"""


def write_spec(
    tmp_path: Path, design="one-at-a-time", steps=3000, engine="auto", name="s.toml", grid=GRID
):
    path = tmp_path / name
    path.write_text(TINY.format(design=design, steps=steps, engine=engine, grid=grid))
    return path


def read(path: Path) -> list[dict]:
    with path.open() as f:
        return list(csv.DictReader(f))


def no_ray(monkeypatch):
    """Make ``import ray`` fail, as on a machine without it."""
    monkeypatch.setitem(sys.modules, "ray", None)


def test_designs_give_the_cells_named_by_their_settings(tmp_path):
    one = load_spec(write_spec(tmp_path))
    assert [c.slug for c in one.cells] == ["baseline", "tie_break=first", "untried_value=0.0"]
    # every cell carries every factor's level; the baseline is each factor's first level
    assert one.cells[0].levels == {"learner.tie_break": "random", "learner.untried_value": None}
    assert one.cells[2].config.learner.untried_value == 0.0
    assert one.cells[2].config.learner.tie_break == "random"
    full = load_spec(write_spec(tmp_path, design="factorial"))
    assert len(full.cells) == 4
    assert {(c.config.learner.tie_break, c.config.learner.untried_value) for c in full.cells} == {
        ("random", None),
        ("random", 0.0),
        ("first", None),
        ("first", 0.0),
    }
    trials = one.trials(tmp_path / "out")
    assert [(t.first_seed, t.seeds) for t in trials[:2]] == [(0, 2), (2, 1)]
    assert trials[0].config.sizes == (16,) and trials[0].config.agents == ("imitation", "options")
    # the base's own settings that the spec leaves alone stay
    assert trials[0].config.learner.plan_every == 4


@pytest.mark.parametrize(
    "text, message",
    [
        ("bogus = 1", "unknown keys \\['bogus'\\]"),
        ("[grid]\nlearner.nope = [1, 2]", "unknown setting 'learner.nope'"),
        ("[set]\nstepz = 10", "unknown setting 'stepz'"),
        ("[set]\nseeds = 10", "'seeds' is set by the spec's own keys"),
        ('[grid]\nlearner.tie_break = ["random", "sideways"]', "tie_break"),
        ("[grid]\nlearner.backups = []", "non-empty list of levels"),
        ("[grid]\nsteps = 100", "non-empty list of levels"),
        ('design = "latin"', "design='latin'"),
        ("seeds = 0", "seeds=0 must be ≥ 1"),
        ('base = "exp9"', "neither one of"),
        ('[set]\nagents = ["imitation", "nobody"]', "agents"),
        ('[set]\nsteps = "many"', "steps"),
        ("worlds = [41]", "multiple of room_size"),
        ("[set]\nsteps = 10\n[grid]\nsteps = [10, 20]", "both in \\[set\\] and in \\[grid\\]"),
        ("[grid]\nlearner.backups = [10, 10]", "two cells are the same"),
        ("[set]\nworld = {size = 3}", "only 'learner' settings nest"),
        ("seeds = [", "not valid TOML"),
        ("worker_niceness = 20", "worker_niceness=20 must be ≤ 19"),
        ("worker_niceness = -1", "worker_niceness=-1 must be ≥ 0"),
        ('worker_niceness = "low"', "worker_niceness must be a whole number, got 'low'"),
    ],
)
def test_bad_specs_are_refused_naming_what_is_wrong(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        load_spec(path)


#: A preset beside learner settings: each cell's learner is the preset's with the [set] or
#: level settings on top, so one that departs from the preset is refused as himit run refuses it.
PRESET_SPECS = {
    "[set] against a preset level": (
        '[set]\nlearner.mentor_fade = 5.0\n[grid]\npreset = ["none", "recommended"]',
        "cell preset=recommended: ExperimentConfig: preset='recommended' but "
        "learner.mentor_fade=5.0 (the preset: 20.0)",
    ),
    "a level against the [set] preset": (
        '[set]\npreset = "recommended"\n[grid]\nlearner.mentor_fade = [20.0, 5.0]',
        "cell mentor_fade=5.0: ExperimentConfig: preset='recommended' but learner.mentor_fade=5.0",
    ),
    "[set] against its own preset": (
        '[set]\npreset = "recommended"\nlearner.mentor_fade = 5.0',
        "[set]: ExperimentConfig: preset='recommended' but learner.mentor_fade=5.0",
    ),
}


@pytest.mark.parametrize("kind", list(PRESET_SPECS))
def test_learner_settings_that_depart_from_a_cells_preset_are_refused(tmp_path, capsys, kind):
    text, message = PRESET_SPECS[kind]
    path = tmp_path / "preset.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as err:
        load_spec(path)
    assert message in str(err.value), err.value
    with pytest.raises(SystemExit) as exit_:  # himit sweep --dry-run: one line, exit 2
        main(["sweep", str(path), "--dry-run"])
    assert exit_.value.code == 2
    out = capsys.readouterr().err
    assert out.count("\n") == 1 and out.startswith("himit: error: sweep spec") and message in out


def test_a_preset_level_keeps_the_set_settings_it_does_not_name(tmp_path):
    path = tmp_path / "preset.toml"
    path.write_text(
        "[set]\nlearner.plan_every = 7\nlearner.mentor_fade = 20.0\n"
        '[grid]\npreset = ["none", "recommended"]'
    )
    none, recommended = load_spec(path).cells
    assert none.config.preset is None and recommended.config.preset == "recommended"
    assert none.config.learner.plan_every == recommended.config.learner.plan_every == 7
    assert none.config.learner.mentor_fade == recommended.config.learner.mentor_fade == 20.0
    assert recommended.config.learner.eps_schedule != none.config.learner.eps_schedule


def test_json_specs_and_missing_files(tmp_path):
    path = tmp_path / "s.json"
    path.write_text(
        json.dumps({"base": "exp1", "seeds": 2, "grid": {"learner": {"backups": [10, 19]}}})
    )
    spec = load_spec(path)
    assert spec.name == "s" and [c.config.learner.backups for c in spec.cells] == [10, 19]
    assert spec.cells[0].config.corner_options  # exp1's settings
    with pytest.raises(ValueError, match="does not exist"):
        load_spec(tmp_path / "missing.toml")
    path.write_text("{nope")
    with pytest.raises(ValueError, match="not valid JSON"):
        load_spec(path)


def test_cli_bad_spec_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text("[grid]\nlearner.nope = [1, 2]")
    with pytest.raises(SystemExit) as exit_:
        main(["sweep", str(path)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1
        and err.startswith("himit: error: sweep spec")
        and "learner.nope" in err
    )


def test_help_documents_the_spec_file(capsys):
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    out = capsys.readouterr().out
    for needle in (
        "[grid]",
        "[set]",
        "one-at-a-time",
        "seeds_per_trial",
        "learner.<field>",
        "--address",
        "--no-ray",
        "--worker-niceness",
        "worker_niceness",
        "Ray's default is 15",
    ):
        assert needle in " ".join(out.split())


def test_worker_niceness_from_the_spec_or_the_flag_checked_like_the_other_settings(
    tmp_path, capsys, monkeypatch
):
    assert load_spec(write_spec(tmp_path)).worker_niceness == 0  # the default (module docstring)
    path = tmp_path / "nice.toml"
    path.write_text("worker_niceness = 10\n" + write_spec(tmp_path).read_text())
    assert load_spec(path).worker_niceness == 10
    for flag in ("20", "-1", "low"):
        with pytest.raises(SystemExit) as exit_:
            main(["sweep", str(path), "--worker-niceness", flag])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count("\n") == 1 and "--worker-niceness" in err
    with pytest.raises(ValueError, match="worker_niceness=25 must be ≤ 19"):
        run_sweep(path, tmp_path / "out", worker_niceness=25)
    # the flag overrides the spec, and sweep.json records what ran
    no_ray(monkeypatch)
    record = run_sweep(
        write_spec(tmp_path, steps=1000, grid=""),
        tmp_path / "out",
        worker_niceness=3,
        log=lambda line: None,
    )
    assert record["worker_niceness"] == 3
    assert json.loads((tmp_path / "out" / "sweep.json").read_text())["worker_niceness"] == 3


# (18 runs and their tables, ≈ 25 s: CI's; the fast suite runs a sweep in the niceness test)
@pytest.mark.slow
def test_in_process_sweep_without_ray_says_so_and_writes_the_tables(tmp_path, monkeypatch):
    no_ray(monkeypatch)
    lines = []
    spec = load_spec(write_spec(tmp_path))
    out = tmp_path / "out"
    record = run_sweep(spec, out, log=lines.append)
    assert sum("Ray is not installed" in line and "in this process" in line for line in lines) == 1
    rows = read(out / "results.csv")
    # one row per run and window: 3 cells × 2 agents × 3 seeds × 3 windows
    assert len(rows) == 3 * 2 * 3 * 3
    assert list(rows[0])[:4] == ["sweep", "cell", "learner.tie_break", "learner.untried_value"]
    assert {r["learner.untried_value"] for r in rows if r["cell"] == "untried_value=0.0"} == {"0.0"}
    # the table is each trial's curves.csv with the settings in front
    trial = out / "trials" / "tie_break=first" / "world16_seeds0-1" / "curves.csv"
    mine = [
        {
            k: v
            for k, v in r.items()
            if k not in ("sweep", "cell", "learner.tie_break", "learner.untried_value")
        }
        for r in rows
        if r["cell"] == "tie_break=first" and int(r["seed"]) < 2
    ]
    theirs = read(trial)
    key = lambda r: (r["agent"], int(r["seed"]), int(r["step"]))  # noqa: E731
    assert sorted(mine, key=key) == sorted(theirs, key=key)
    # the summary: mean and interval of each cell's runs, recomputed here (counts: BCa from
    # scipy.stats.bootstrap with the seed the summary uses; V(start): Student's t)
    runs = read(out / "runs.csv")
    summary = read(out / "summary.csv")
    assert len(runs) == 3 * 2 * 3 and len(summary) == 3 * 2
    for row in summary:
        goals = [
            float(r["total_goals"])
            for r in runs
            if r["cell"] == row["cell"] and r["agent"] == row["agent"]
        ]
        assert int(row["n"]) == len(goals) == 3
        assert float(row["total_goals_mean"]) == pytest.approx(np.mean(goals), rel=1e-3)
        if np.std(goals) > 0:
            low = stats.bootstrap(
                (np.array(goals),),
                np.mean,
                n_resamples=9999,
                method="BCa",
                rng=np.random.default_rng(0),
            ).confidence_interval.low
            assert float(row["total_goals_ci_low"]) == pytest.approx(low, rel=1e-3, abs=1e-3)
        values = [
            float(r["value_start"])
            for r in runs
            if r["cell"] == row["cell"] and r["agent"] == row["agent"]
        ]
        if np.std(values) > 0:
            low, _ = stats.t.interval(0.95, 2, loc=np.mean(values), scale=stats.sem(values))
            assert float(row["value_start_ci_low"]) == pytest.approx(low, rel=1e-3, abs=1e-3)
        failed = sum(
            int(r["first_goal_step"]) < 0
            for r in runs
            if r["cell"] == row["cell"] and r["agent"] == row["agent"]
        )
        assert int(row["failed"]) == failed
    page = (out / "summary.md").read_text()
    assert "95 %" in page
    assert record["engine"] == ["numba"] and record["commit"][0] != "unknown"
    assert (
        f"Runs recorded at commit `{record['commit'][0]}` (from the trials' `worlds/*.json`, as "
        f"`sweep.json` records); this page: `himit plot {out}` (from `runs.csv` and "
        f"`sweep.json`); the runs: `himit sweep {tmp_path / 's.toml'} --out {out}`."
    ) in page
    # himit plot rewrites the same tables from runs.csv and sweep.json, without the trials
    table = (out / "summary.csv").read_text()
    for name in ("summary.md", "summary.csv"):
        (out / name).unlink()
    assert main(["plot", str(out)]) == 0
    assert (out / "summary.md").read_text() == page
    assert (out / "summary.csv").read_text() == table
    assert json.loads((out / "sweep.json").read_text())["cells"][1]["cell"] == "tie_break=first"
    # a rerun skips every finished trial and rewrites the same tables
    before = (out / "results.csv").read_text()
    stamp = (out / "trials" / "baseline" / "world16_seeds0-1" / "results.md").stat().st_mtime_ns
    lines.clear()
    run_sweep(spec, out, log=lines.append)
    assert "6 finished, 0 to resume, 0 new" in lines[0] and len(lines) == 1
    assert (out / "results.csv").read_text() == before
    assert (
        out / "trials" / "baseline" / "world16_seeds0-1" / "results.md"
    ).stat().st_mtime_ns == stamp


# Two sweeps, the second resuming the first (9 s): -m slow (CI).
@pytest.mark.slow
def test_a_changed_spec_does_not_reuse_finished_trials(tmp_path, monkeypatch):
    no_ray(monkeypatch)
    out = tmp_path / "out"
    run_sweep(write_spec(tmp_path, steps=1000), out, log=lambda line: None)
    with pytest.raises(ValueError, match="another configuration"):
        run_sweep(write_spec(tmp_path, steps=2000), out, log=lambda line: None)


# (starting a local Ray takes long; the in-process sweep is in the fast suite, and CI runs the
# same comparison on a real cluster: test_sweep_cluster.py)
@pytest.mark.slow
@pytest.mark.extended
def test_tiny_sweep_on_a_local_ray_equals_the_in_process_one(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    spec = load_spec(write_spec(tmp_path, grid='[grid]\nlearner.tie_break = ["random", "first"]'))
    lines = []
    run_sweep(spec, tmp_path / "ray", workers=2, log=lines.append)
    assert any(line.startswith("himit sweep: Ray ") and "local, 2 CPUs" in line for line in lines)
    assert sum(" done (" in line for line in lines) == 4
    no_ray(monkeypatch)
    run_sweep(spec, tmp_path / "here", log=lambda line: None)
    for table in ("results.csv", "runs.csv", "summary.csv"):
        assert read(tmp_path / "ray" / table) == read(tmp_path / "here" / table)


_CHILD = """
import sys
from himit_torch.runs.sweep import run_sweep
run_sweep(sys.argv[1], sys.argv[2], use_ray=False)
"""
#: The folder holding the package under test, first on the children's path (so that a child runs
#: this checkout's code, not another installed copy).
PACKAGE_ROOT = str(Path(__file__).resolve().parents[2])


def child_env(**extra: str) -> dict:
    path = os.pathsep.join(p for p in (PACKAGE_ROOT, os.environ.get("PYTHONPATH")) if p)
    return dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=path, **extra)


def sigint_as_python_sets_it() -> None:
    """In a child: SIGINT back to its default, so that Python turns it into KeyboardInterrupt
    (a child of a shell's background job starts with SIGINT ignored, and Python leaves it so)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def session_processes(session: int) -> list[int]:
    """The live processes of ``session`` (their ids), never this one's."""
    if session == os.getsid(0):
        raise ValueError("not this process's own session")
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                if os.getsid(int(entry.name)) == session and "Z" not in _state(entry):
                    found.append(int(entry.name))
            except (ProcessLookupError, PermissionError):
                pass
    return found


def _state(entry: Path) -> str:
    try:
        return entry.joinpath("stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "Z"


def wait_until(condition, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.05)
    return condition()


def stop_session(session: int, grace: float = 5.0) -> None:
    """End every process of ``session`` (one this test started): SIGTERM, then SIGKILL."""
    for sig in (signal.SIGTERM, signal.SIGKILL, signal.SIGKILL):
        pids = session_processes(session)
        if not pids:
            return
        for pid in pids:
            try:
                os.kill(pid, sig)
            except ProcessLookupError:
                pass
        wait_until(lambda: not session_processes(session), grace)


@pytest.mark.slow  # (fast: the skip/resume of finished trials, tests above)
@pytest.mark.parametrize(
    "how",  # (CI interrupts a sweep on a real cluster: test_sweep_cluster.py)
    ["SIGKILL in-process", pytest.param("Ctrl-C on Ray", marks=pytest.mark.extended)],
)
def test_a_sweep_stopped_mid_way_and_rerun_gives_the_uninterrupted_tables(tmp_path, how):
    """Killed (SIGKILL, the in-process runner) or interrupted (SIGINT to its process group, as
    Ctrl-C in a terminal sends it, on a local Ray): a rerun resumes to the uninterrupted tables.
    On Ray the sweep ends within seconds, saying so in one line, its tasks cancelled."""
    on_ray = how == "Ctrl-C on Ray"
    if on_ray:
        pytest.importorskip("ray")
        if not sys.platform.startswith("linux"):
            pytest.skip("finds the sweep's processes in /proc")
    # the torch engine: slow enough per window to be stopped inside a trial
    spec = write_spec(tmp_path, steps=3000, engine="torch", grid="")  # one cell, two trials
    env = child_env()
    whole = subprocess.Popen(
        [sys.executable, "-c", _CHILD, str(spec), str(tmp_path / "whole")],
        env=env,
        stderr=subprocess.DEVNULL,
    )
    stopped = tmp_path / "stopped"
    if on_ray:  # one trial at a time: one CPU
        command = [sys.executable, "-m", "himit_torch.cli", "sweep", str(spec), "--out"]
        command += [str(stopped), "--workers", "1"]
    else:
        command = [sys.executable, "-c", _CHILD, str(spec), str(stopped)]
    child = subprocess.Popen(
        command,
        env=env,
        stderr=subprocess.PIPE if on_ray else subprocess.DEVNULL,
        text=True,
        start_new_session=True,  # its own process group, and Ray's processes with it
        preexec_fn=sigint_as_python_sets_it,
    )
    try:
        # stop it once a trial has saved a checkpoint but not finished: in-process, the second
        # (the first done); on Ray, whichever runs
        trials = stopped / "trials" / "baseline"
        half_way = lambda: any(  # noqa: E731
            (d / "checkpoints" / "world16.pt").exists() and not (d / "results.md").exists()
            for d in (trials.glob("world16_*") if trials.exists() else [])
            if on_ray or d.name == "world16_seeds2-2"
        )
        wait_until(lambda: child.poll() is not None or half_way(), 300)
        assert child.poll() is None, "the sweep finished before it could be stopped; lengthen it"
        if on_ray:
            signalled = time.monotonic()
            os.killpg(child.pid, signal.SIGINT)
            _, err = child.communicate(timeout=60)
            seconds = time.monotonic() - signalled
            assert child.returncode == 130 and seconds < 15, (child.returncode, seconds, err)
            last = err.strip().splitlines()[-1]
            assert last.startswith("himit: error: interrupted:") and "resumes" in last
            assert "Traceback" not in err
            # the tasks cancelled, the local Ray gone with them
            assert wait_until(lambda: not session_processes(child.pid), 10)
        else:
            child.send_signal(signal.SIGKILL)
            child.wait()
            assert (trials / "world16_seeds0-1" / "results.md").exists()
        assert not (stopped / "results.csv").exists()
        finished = sum((d / "results.md").exists() for d in trials.glob("world16_*"))
        started = sum((d / "config.json").exists() for d in trials.glob("world16_*")) - finished
        assert started >= 1, "no trial was stopped half-way"
    finally:
        if on_ray:
            stop_session(child.pid)
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    new = 2 - finished - started  # (on Ray, one CPU: the other trial may not have begun)
    assert f"{finished} finished, {started} to resume, {new} new" in done.stderr
    assert whole.wait() == 0
    for table in ("results.csv", "runs.csv", "summary.csv"):
        assert read(stopped / table) == read(tmp_path / "whole" / table)
