"""The committed results are reproduced by the code as it is now (issue 11: "a short run at HEAD
reproduces the committed curves exactly for the same seeds and settings").

Each case reruns the first windows of two seeds of a committed sweep cell — with the
configuration recorded in that sweep's ``sweep.json`` — and compares every per-window number
the sweep committed (goals, ε, episodes, backups, decisions, mentor-term wins) with
``results.csv``. A change to the learner that moves any curve fails here; if the change is
meant, rerun the sweeps and commit their new tables with the commit that made them.
"""

import csv
import json
from dataclasses import replace
from pathlib import Path

import pytest

from himit_torch import LearnerConfig
from himit_torch.runs.config import ExperimentConfig
from himit_torch.runs.experiment import run_experiment

RESULTS = Path(__file__).resolve().parents[1] / "experiments" / "results"
COLUMNS = ("goals_in_window", "epsilon", "episodes", "backups", "decisions", "mentor_term_wins")


def committed_config(sweep: str, cell: str) -> ExperimentConfig:
    record = json.loads((RESULTS / sweep / "sweep.json").read_text())
    [data] = [c["config"] for c in record["cells"] if c["cell"] == cell]
    data = dict(data, learner=LearnerConfig(**data["learner"]))
    return ExperimentConfig(**data)


def curve_rows(path: Path, seeds, last_step: int, agents=None) -> dict:
    """A ``curves.csv``'s rows of ``seeds`` up to ``last_step`` (of ``agents``, all if None):
    ``(agent, seed, step)`` → the compared columns."""
    with path.open() as f:
        return {
            (r["agent"], int(r["seed"]), int(r["step"])): tuple(r[k] for k in COLUMNS)
            for r in csv.DictReader(f)
            if int(r["seed"]) in seeds
            and int(r["step"]) <= last_step
            and (agents is None or r["agent"] in agents)
        }


def short_run(tmp_path: Path, committed: ExperimentConfig, seeds, steps: int, **changes):
    """``committed`` run again for the consecutive ``seeds`` and ``steps`` steps (with
    ``changes``), in this process: ``(config, path of its curves.csv)``."""
    config = replace(committed, seeds=len(seeds), first_seed=seeds[0], steps=steps,
                     checkpoint_every=steps, **changes)  # fmt: skip
    run_experiment(config, tmp_path / "run", progress=False, workers=1)
    [curves] = (tmp_path / "run").rglob("curves.csv")
    return config, curves


def committed_rows(sweep: str, cell: str, seeds, last_step: int) -> dict:
    with (RESULTS / sweep / "results.csv").open() as f:
        return {
            (r["agent"], int(r["seed"]), int(r["step"])): tuple(r[k] for k in COLUMNS)
            for r in csv.DictReader(f)
            if r["cell"] == cell and int(r["seed"]) in seeds and int(r["step"]) <= last_step
        }


#: The cells built on exact solves (exact option models, the mentor's exact model) reproduce only
#: on a CPU whose LAPACK kernels round as those of the machine that ran the sweeps: the solves'
#: last bits change with the OpenBLAS kernel (on an AMD EPYC without AVX-512 the exact option
#: models of exp2's world and the exact mentor transitions of exp1's hash differently under
#: OPENBLAS_CORETYPE=Prescott than under the default kernel, and none of the kernels that CPU can
#: run reproduces the committed rows), and 1e6 pseudo-counts turn those bits into other decisions.
#: They still run everywhere under -m slow (CI): XPASS where they reproduce, XFAIL (not an error)
#: elsewhere.
CPU_DEPENDENT = [
    pytest.mark.xfail(
        reason="exact solves round differently under other CPUs' LAPACK kernels", strict=False
    ),
    pytest.mark.slow,
]


@pytest.mark.parametrize(
    "sweep, cell, steps",
    [
        ("sweeps/exp2_schedules", "baseline", 20_000),  # 40×40, imitation and options-only
        pytest.param(  # exact option models
            "sweeps/exp2_schedules", "option_models=exact", 10_000, marks=CPU_DEPENDENT
        ),
        pytest.param(  # 80×80 + corners, the mentor's exact model
            "sweeps/exp1_mentor_exact", "mentor_model=exact", 10_000, marks=CPU_DEPENDENT
        ),
        # posterior sampling: two seeds of a ten-seed batch, psrl runs beside mean-model runs
        ("psrl/exp2", "eps_start=0.75", 10_000),
    ],
)
def test_a_short_run_reproduces_the_committed_sweep_curves(tmp_path, sweep, cell, steps):
    seeds = (0, 1)
    config, curves = short_run(tmp_path, committed_config(sweep, cell), seeds, steps)
    ours = curve_rows(curves, seeds, steps)
    theirs = committed_rows(sweep, cell, seeds, steps)
    assert len(theirs) == len(config.agents) * len(seeds) * (steps // config.window)
    assert ours == theirs


@pytest.mark.parametrize(
    "run, steps",
    [
        ("paper-first/exp2", 20_000),  # the paper preset, first-index ties
        ("recommended-random/exp2", 20_000),  # the recommended preset, random ties
    ],
)
def test_a_short_run_reproduces_the_committed_claims_curves(tmp_path, run, steps):
    """The claims' runs (experiments/results/<preset>-<ties>/, 20 seeds): seeds 4 and 5 of the
    committed configuration, its first windows, equal the committed curves."""
    from himit_torch.runs.config import load_config

    seeds = (4, 5)
    committed = load_config(RESULTS / run / "config.json")
    config, curves = short_run(tmp_path, committed, seeds, steps)
    assert config.preset == committed.preset is not None

    theirs = curve_rows(RESULTS / run / "curves.csv", seeds, steps)
    assert len(theirs) == len(config.agents) * len(seeds) * (steps // config.window)
    assert curve_rows(curves, seeds, steps) == theirs


def test_a_short_run_reproduces_the_committed_bco_curves(tmp_path):
    """The benchmark's factorial (experiments/results/benchmark/paper/, random ties): the bco
    agent alone, seeds 4 and 5, its first windows, equal the committed curves (a run does not
    depend on the other runs of its batch). BCO's refit is compiled on the CPU; this is the
    committed records' side of its test against the torch functions."""
    from himit_torch.runs.config import load_config

    seeds, steps = (4, 5), 20_000
    committed = load_config(RESULTS / "benchmark" / "paper" / "exp2" / "config.json")
    config, curves = short_run(tmp_path, committed, seeds, steps, agents=("bco",))

    theirs = curve_rows(
        RESULTS / "benchmark" / "paper" / "exp2" / "curves.csv", seeds, steps, {"bco"}
    )
    assert len(theirs) == len(seeds) * (steps // config.window)
    assert curve_rows(curves, seeds, steps, {"bco"}) == theirs


@pytest.mark.slow
def test_a_short_run_reproduces_the_committed_discovery_curves(tmp_path):
    """``himit run discovery``'s committed run (experiments/results/discovery/, 10 seeds, the
    study's defaults): exp2's seeds 0 and 1 for 30,000 steps (the 20,000-step warm-up, then the
    discovered options swapped in), every learner's goals per window equal the committed curves."""
    from himit_torch.cli import main
    from himit_torch.runs.discovery import DiscoveryConfig

    committed = RESULTS / "discovery"
    recorded = json.loads((committed / "config.json").read_text())
    defaults = DiscoveryConfig()
    for name in ("warmup", "refresh_every", "max_steps_factor", "first_seed", "engine"):
        assert getattr(defaults, name) == recorded[name], name  # the defaults are its settings
    steps, seeds = 30_000, ("0", "1")
    main(["run", "discovery", "--worlds", "exp2", "--seeds", "2", "--steps", str(steps),
          "--logdir", str(tmp_path), "--quiet"])  # fmt: skip

    def rows(path: Path) -> dict:
        with path.open() as f:
            return {
                (r["agent"], r["seed"], int(r["step"])): r["goals_in_window"]
                for r in csv.DictReader(f)
                if r["world"] == "exp2" and r["seed"] in seeds and int(r["step"]) <= steps
            }

    [curves] = tmp_path.rglob("curves.csv")
    theirs = rows(committed / "curves.csv")
    assert len(theirs) == 6 * len(seeds) * (steps // 5_000)  # six learners, windows of 5,000
    assert rows(curves) == theirs
