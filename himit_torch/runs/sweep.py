"""Sweeps: a grid of settings × seeds × worlds, each trial a resumable run, on Ray when it is there.

A sweep is described by a spec file (TOML, or JSON with the same keys)::

    name = "exp2_ties"              # the sweep's name (default: the file's stem)
    base = "exp2"                   # exp1 | exp2 | exp3, or a config.json (relative to the spec)
    seeds = 20                      # runs per agent and cell: seeds first_seed … first_seed+seeds−1
    first_seed = 0
    seeds_per_trial = 10            # seeds run together in one batch (default: all of them)
    worlds = [40]                   # world sizes, each its own trial (default: the base's sizes)
    design = "factorial"            # or "one-at-a-time" (see below)
    worker_niceness = 0             # Ray workers' nice increment, 0–19 (default 0; see below)

    [set]                           # settings of every cell
    agents = ["imitation", "options", "primitives"]
    learner.plan_every = 4          # learner settings as learner.<field> (or a [set.learner] table)

    [grid]                          # the factors: a setting and the levels it takes
    learner.tie_break = ["random", "first"]
    mentor_episodes = [20, 200]

``design = "factorial"`` runs every combination of the levels (here 2 × 2 = 4 cells);
``"one-at-a-time"`` runs one baseline cell, every factor at its *first* level, plus one cell per
other level of each factor with the rest at baseline (here 1 + 1 + 1 = 3 cells). A setting is any
field of :class:`~himit_torch.runs.config.ExperimentConfig` but those the sweep owns (``name``,
``sizes``, ``seeds``, ``first_seed``: use the spec's own keys), or ``learner.<field>`` of
:class:`~himit_torch.LearnerConfig`. Every cell's configuration is built and checked before
anything runs: an unknown key or setting, or a value the configurations refuse, is a
``ValueError`` naming it (``himit sweep``: one line, exit status 2).

``worker_niceness`` (``himit sweep --worker-niceness``, which overrides the spec) is the niceness
Ray's workers add to their node's own (Ray's ``RAY_worker_niceness``, sent to them in the job's
``runtime_env``). Ray's default is 15 (measured on Ray 2.60: ``os.nice(0)`` in a task), chosen
to keep its own control processes responsive when workers flood the CPUs (ray-project/ray#24928).
A sweep does not flood them: one trial per CPU that Ray counts, each engine given its share of
the cores. At 15 its trials yield to every ordinary process (niceness 0) that competes for the
same cores, so where other work keeps them busy the same sweep runs far slower on Ray than
in-process (``--no-ray``) or by ``himit run``, which run at the niceness they were started with;
the default 0 runs them as those do. Set 10–19 to let other work on the machines go first. It
does not change results, nor affect the in-process runner.

A **trial** is one world × one group of seeds of one cell: one learner batch, run by
:func:`~himit_torch.runs.experiment.run_experiment` into its own run directory
``<out>/trials/<cell>/world<N>_seeds<a>-<b>/`` with its checkpoints. Rerunning the sweep skips
finished trials and resumes interrupted ones from their checkpoints, so a sweep killed mid-way and
rerun ends with exactly the tables of an uninterrupted one. At the end the sweep writes

* ``results.csv`` — the tidy table: one row per run and window (each trial's ``curves.csv``) with
  the cell's settings as columns;
* ``runs.csv`` — one row per run: total goals, goals in the last window and the last 50k steps,
  first goal step, V(start), mentor-term wins, and its greedy policy at the end evaluated exactly
  (goals per window, as % of the optimum's and of the mentor's own rate, V^π(start));
* ``summary.csv`` / ``summary.md`` — per cell, world and agent: the mean of each measure with a
  95 % confidence interval (the counts: BCa bootstrap; V(start) and greedy: Student's t), and the
  share of runs that never found the goal with its exact Clopper–Pearson 95 % interval
  (``scipy.stats.binomtest``);
* ``sweep.json`` — the spec as resolved (cells, trials), the commit and engines that ran.

**Where the trials run: Ray core, not Ray Tune.** With Ray importable, trials are Ray tasks, one
CPU each, collected as they end (a local Ray of the sweep's own; ``address=`` or ``RAY_ADDRESS``
joins a cluster, sending the token it wants: :mod:`himit_torch.runs.ray_cluster`; a cluster's
commands: ``docs/cluster.md``). Ctrl-C cancels the tasks still running (``ray.cancel(force=True)``:
their workers end at once) and returns within seconds; a rerun resumes them from their
checkpoints. Without Ray they run one after another in this process. Measured with Ray 2.60 on
Python 3.11: Ray core adds 250 MB to the environment and ``import ray`` 0.5–0.7 s; Ray Tune
another 265 MB (pandas, pyarrow, pydantic, tensorboardX) and 1.3–1.5 s to import, for search
algorithms, early-stopping schedulers and a result store that a fixed grid does not use: every
seed of every cell must run to the end (stopping poor trials early would hide failing seeds, the
very thing experiment 2 is about), and the run directories already hold the checkpoints and the
tables. Hence the ``sweep`` extra installs ``ray`` alone.
"""

from __future__ import annotations

import csv
import functools
import importlib
import itertools
import json
import math
import os
import re
import shlex
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from himit_torch.learner.config import LearnerConfig
from himit_torch.runs.config import EXPERIMENTS, ExperimentConfig, load_config
from himit_torch.runs.runner import share_cores, source_commit
from himit_torch.runs.study import config_differences, write_rows
from himit_torch.statistics import bca_interval, share_interval, t_interval
from himit_torch.validation import (
    COUNT_MAX,
    as_folder_name,
    as_int,
    as_int_array,
    check_folder_path,
    parse_document,
    read_text,
    settings_of,
)

__all__ = ["SweepSpec", "Cell", "Trial", "load_spec", "run_sweep", "summarize", "rewrite_summary"]

_SPEC_KEYS = {
    "name",
    "base",
    "seeds",
    "first_seed",
    "seeds_per_trial",
    "worlds",
    "design",
    "worker_niceness",
    "set",
    "grid",
}
_DESIGNS = ("factorial", "one-at-a-time")
#: ExperimentConfig fields the sweep owns (set through the spec's own keys).
_OWNED = {"name", "sizes", "seeds", "first_seed"}
#: Ray workers' niceness unless the spec or --worker-niceness says otherwise (module docstring).
WORKER_NICENESS = 0
#: Steps over which runs.csv sums the "late" goals (the audit's "last 50k steps").
LATE_STEPS = 50_000


@dataclass(frozen=True)
class Cell:
    """One combination of factor levels: its directory name and its settings."""

    index: int
    slug: str
    levels: dict  # factor → level (the factors of the grid only)
    config: ExperimentConfig


@dataclass(frozen=True)
class Trial:
    """One world × one group of seeds of one cell: one batch, one run directory."""

    cell: Cell
    size: int
    first_seed: int
    seeds: int
    run_dir: Path

    @property
    def config(self) -> ExperimentConfig:
        return replace(
            self.cell.config, sizes=(self.size,), first_seed=self.first_seed, seeds=self.seeds
        )


@dataclass(frozen=True)
class SweepSpec:
    """A checked sweep spec: its cells (configurations) and how seeds and worlds split."""

    name: str
    base: str
    seeds: int
    first_seed: int
    seeds_per_trial: int
    worlds: tuple[int, ...]
    design: str
    factors: dict  # factor → list of levels
    cells: tuple[Cell, ...]
    worker_niceness: int = WORKER_NICENESS
    source: str | None = None
    """The spec file it was read from (:func:`load_spec`; None: built in code), for the
    command that reruns it."""

    def trials(self, out: Path) -> list[Trial]:
        """Every trial, the largest worlds first (they take longest)."""
        out = Path(out)
        chunks = [
            (s, min(self.seeds_per_trial, self.first_seed + self.seeds - s))
            for s in range(self.first_seed, self.first_seed + self.seeds, self.seeds_per_trial)
        ]
        return [
            Trial(
                cell, size, s, n, out / "trials" / cell.slug / f"world{size}_seeds{s}-{s + n - 1}"
            )
            for size in sorted(self.worlds, reverse=True)
            for cell in self.cells
            for s, n in chunks
        ]


# ================================================================================ the spec
def _flatten(table: dict, where: str, prefix: str = "") -> dict:
    """``{"learner": {"backups": 10}}`` and ``{"learner.backups": 10}`` alike → dotted keys."""
    flat = {}
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            if name != "learner":
                raise ValueError(f"{where}: {name!r} is a table, but only 'learner' settings nest")
            flat.update(_flatten(value, where, "learner."))
        else:
            flat[name] = value
    return flat


def _check_setting(name: str, where: str) -> None:
    experiment = {f.name for f in fields(ExperimentConfig)} - _OWNED - {"learner"}
    learner = {f.name for f in fields(LearnerConfig)}
    if name.startswith("learner."):
        if name.removeprefix("learner.") not in learner:
            raise ValueError(
                f"{where}: unknown setting {name!r}; learner settings: "
                f"{sorted('learner.' + n for n in learner)}"
            )
    elif name in _OWNED:
        raise ValueError(
            f"{where}: {name!r} is set by the spec's own keys (name, worlds, seeds, "
            "first_seed), not as a setting"
        )
    elif name not in experiment:
        raise ValueError(
            f"{where}: unknown setting {name!r}; settings: {sorted(experiment)} and learner.<field>"
        )


def _apply(config: ExperimentConfig, settings: dict) -> ExperimentConfig:
    """``config`` with the dotted ``settings`` in one step the dataclasses check: a preset
    first, then the learner settings beside it (one departing from the preset is refused)."""
    top = {k: v for k, v in settings.items() if not k.startswith("learner.")}
    learner = {k[len("learner.") :]: v for k, v in settings.items() if k.startswith("learner.")}
    built = config.with_settings(top, learner)
    for key in set(learner) & set(built.derived_learner):
        # derived and recorded: a value the experiment's own settings do not give is refused,
        # not silently replaced
        if learner[key] != getattr(built.learner, key):
            raise ValueError(
                f"learner.{key}={learner[key]!r}: the experiment derives it from its own "
                f"settings (here {getattr(built.learner, key)!r}); leave learner.{key} out"
            )
    return built


def _slug(levels: dict) -> str:
    if not levels:
        return "baseline"
    parts = [f"{name.removeprefix('learner.')}={_show(value)}" for name, value in levels.items()]
    return re.sub(r"[^A-Za-z0-9_.,=+-]", "_", "__".join(parts))


def _level(name: str, value: Any) -> Any:
    """TOML has no null: "none" stands for ``None`` where setting ``name`` may be
    ``None``; elsewhere it stays the string (e.g. ``second_mentor = "none"``)."""
    if not (isinstance(value, str) and value.lower() == "none"):
        return value
    cls = LearnerConfig if name.startswith("learner.") else ExperimentConfig
    field = name.removeprefix("learner.")
    return None if next(s for s in settings_of(cls) if s.name == field).optional else value


def load_spec(path: str | os.PathLike) -> SweepSpec:
    """Read and check a sweep spec (``.toml`` or ``.json``), building every cell's
    configuration (the base with the ``[set]`` settings and the cell's levels, a preset first).

    Raises:
        ValueError: the file is missing or unreadable, a key or setting is unknown, the name is
            not a folder name, or a value is refused by the configurations; the message names
            the file and what is wrong."""
    path = Path(path)
    where = f"sweep spec {path}"
    data = parse_document(
        where, read_text(where, path), "json" if path.suffix == ".json" else "toml"
    )
    if not isinstance(data, dict):
        raise ValueError(f"{where} must hold a table of keys")
    unknown = sorted(set(data) - _SPEC_KEYS)
    if unknown:
        raise ValueError(f"{where}: unknown keys {unknown}; known: {sorted(_SPEC_KEYS)}")
    base_name, base = _spec_base(data, path, where)

    def whole(key, default, minimum, maximum=COUNT_MAX):
        return as_int(f"{where}: {key}", data.get(key, default), minimum, maximum)

    seeds = whole("seeds", base.seeds, 1)
    first_seed = whole("first_seed", base.first_seed, 0)
    per_trial = whole("seeds_per_trial", seeds, 1)
    niceness = whole("worker_niceness", WORKER_NICENESS, 0, 19)
    worlds = data.get("worlds", list(base.sizes))
    if not isinstance(worlds, list) or not worlds:
        raise ValueError(f"{where}: worlds={worlds!r} must be a non-empty list of world sizes")
    worlds = as_int_array(f"{where}: worlds", worlds, 1, COUNT_MAX).tolist()
    design = data.get("design", "factorial")
    if design not in _DESIGNS:
        raise ValueError(f"{where}: design={design!r}; use one of {list(_DESIGNS)}")
    fixed, factors = _spec_settings(data, where)
    # The sweep's folder is runs/sweeps/<name>: never ".", ".." or a path.
    name = as_folder_name(f"{where}: name", data.get("name", path.stem))
    owned = {"name": name, "sizes": tuple(worlds), "seeds": seeds, "first_seed": first_seed}
    return SweepSpec(
        name=name,
        base=base_name,
        seeds=seeds,
        first_seed=first_seed,
        seeds_per_trial=per_trial,
        worlds=tuple(worlds),
        design=design,
        factors=factors,
        cells=tuple(_cells(where, base, fixed, factors, design, owned)),
        worker_niceness=niceness,
        source=str(path),
    )


def _spec_base(data: dict, path: Path, where: str) -> tuple[str, ExperimentConfig]:
    """The spec's ``base``: its name as written, and its configuration (an experiment's, or a
    ``config.json`` relative to the spec)."""
    base_name = data.get("base", "exp2")
    if not isinstance(base_name, str):
        raise ValueError(f"{where}: base must be exp1, exp2, exp3 or a config.json path")
    if base_name in EXPERIMENTS:
        return base_name, EXPERIMENTS[base_name]
    config_path = path.parent / base_name  # (an absolute base_name stays itself)
    if not config_path.exists():
        raise ValueError(
            f"{where}: base={base_name!r} is neither one of {sorted(EXPERIMENTS)} "
            f"nor an existing config file"
        )
    return base_name, load_config(config_path)


def _spec_settings(data: dict, where: str) -> tuple[dict, dict]:
    """The spec's ``[set]`` settings (dotted name → value) and ``[grid]`` factors (dotted name
    → its levels), each setting checked by name."""
    for key in ("set", "grid"):
        if not isinstance(data.get(key, {}), dict):
            raise ValueError(f"{where}: [{key}] must be a table of settings")
    fixed = _flatten(data.get("set", {}), f"{where} [set]")
    grid = _flatten(data.get("grid", {}), f"{where} [grid]")
    for name in list(fixed) + list(grid):
        _check_setting(name, where)
    fixed = {k: _level(k, v) for k, v in fixed.items()}
    factors = {}
    for name, levels in grid.items():
        if not isinstance(levels, list) or not levels:
            raise ValueError(
                f"{where}: [grid] {name} must be a non-empty list of levels, got {levels!r}"
            )
        factors[name] = [_level(name, v) for v in levels]
    overlap = sorted(set(fixed) & set(factors))
    if overlap:
        raise ValueError(f"{where}: {overlap} both in [set] and in [grid]")
    return fixed, factors


def _cells(
    where: str, base: ExperimentConfig, fixed: dict, factors: dict, design: str, owned: dict
) -> list[Cell]:
    """The sweep's cells: per combination of the factors' levels (every one, or one
    factor at a time), the base with the ``[set]`` settings, the levels and ``owned`` applied
    together (:func:`_apply`)."""
    if design == "factorial":
        combos = [dict(zip(factors, c)) for c in itertools.product(*factors.values())]
    else:
        baseline = {n: v[0] for n, v in factors.items()}
        combos = [baseline] + [
            {**baseline, n: v} for n, levels in factors.items() for v in levels[1:]
        ]

    def refused(cell_levels: dict) -> Exception | None:
        try:
            _apply(base, {**fixed, **cell_levels, **owned})
        except (ValueError, TypeError) as error:
            return error
        return None

    cells: list[Cell] = []
    for i, levels in enumerate(combos):
        shown = (
            {n: v for n, v in levels.items() if v != factors[n][0]}
            if design == "one-at-a-time"
            else levels
        )
        try:
            config = _apply(base, {**fixed, **levels, **owned})
        except (ValueError, TypeError) as err:
            # the [set]'s refusal where [set] is refused alone and whatever the levels
            alone = refused({})
            if alone is not None and all(refused(c) for c in combos):
                raise ValueError(f"{where} [set]: {alone}") from None
            raise ValueError(f"{where}: cell {_slug(levels)}: {err}") from None
        slug = _slug(shown)
        if any(c.slug == slug for c in cells):
            raise ValueError(f"{where}: two cells are the same ({slug}); a factor repeats a level")
        cells.append(Cell(i, slug, levels, config))
    return cells


# ============================================================================= the trials
def _trial_state(trial: Trial) -> str:
    """``done``, ``started`` (resume it) or ``new``; a trial's folder that holds another
    configuration's run (finished or not), or is a file, is refused before any trial runs."""
    check_folder_path("a trial's run directory", trial.run_dir)
    finished = (trial.run_dir / "results.md").exists()
    if not finished and not (trial.run_dir / "config.json").exists():
        return "new"
    saved = load_config(trial.run_dir / "config.json")
    differences = config_differences(saved, trial.config)
    if differences:
        raise ValueError(
            f"{trial.run_dir} holds {'a finished' if finished else 'an unfinished'} trial of "
            f"another configuration ({'; '.join(differences)}): the spec changed since it "
            "ran; use another --out (or delete the folder)"
        )
    return "done" if finished else "started"


def run_trial(config_json: str, run_dir: str, resume: bool, threads: int | None = None) -> None:
    """Run (or resume) one trial; what a Ray task or the in-process loop calls."""
    from himit_torch.runs.experiment import run_experiment

    if threads is not None:
        share_cores(threads)
    config = ExperimentConfig(**json.loads(config_json))  # (its learner's dict checked too)
    run_experiment(config, run_dir, resume=resume, progress=False, workers=1)


def _execute(
    todo: list[tuple[Trial, str]],
    address: str | None,
    use_ray: bool,
    workers: int | None,
    log,
    niceness: int,
) -> None:
    """Run the unfinished trials: Ray tasks when Ray is importable (and wanted), else here."""
    try:
        ray: Any = importlib.import_module("ray") if use_ray else None
    except ImportError:
        ray = None
    if not todo:
        return
    start = time.perf_counter()
    if ray is None:
        why = (
            "--no-ray" if not use_ray else "Ray is not installed (pip install 'himit_torch[sweep]')"
        )
        log(f"himit sweep: {why}: running {len(todo)} trials in this process, one at a time")
        for k, (trial, state) in enumerate(todo, 1):
            run_trial(trial.config.to_json(), str(trial.run_dir), state == "started")
            log(
                f"[{k}/{len(todo)}] {trial.run_dir.parent.name}/{trial.run_dir.name} done "
                f"({time.perf_counter() - start:.0f} s)"
            )
        return
    _execute_on_ray(ray, todo, address, workers, log, niceness, start)


def _execute_on_ray(
    ray: Any,
    todo: list[tuple[Trial, str]],
    address: str | None,
    workers: int | None,
    log,
    niceness: int,
    start: float,
) -> None:
    """Run the trials ``todo`` as Ray tasks (a local Ray of ``workers`` CPUs, or
    the cluster at ``address``), the workers at ``niceness``; Ctrl-C or a failed trial cancels the
    tasks still running."""
    cores = os.cpu_count() or 1
    address = address or os.environ.get("RAY_ADDRESS") or None  # Ray's own variable
    where, n = _start_ray(ray, address, workers, niceness, cores)
    pending: list = []
    try:
        # each task's compiled engine gets its share of a machine's cores
        threads = max(1, cores // min(n, len(todo))) if address is None else None
        task = ray.remote(num_cpus=1, max_retries=0)(run_trial)
        refs = {
            task.remote(t.config.to_json(), str(t.run_dir), s == "started", threads): t
            for t, s in todo
        }
        log(
            f"himit sweep: Ray {ray.__version__} ({where}; workers at nice {niceness}): "
            f"{len(todo)} trials as tasks"
        )
        pending, k = list(refs), 0
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            ray.get(ready[0])  # a failed trial raises here, naming its error
            k += 1
            t = refs[ready[0]]
            log(
                f"[{k}/{len(todo)}] {t.run_dir.parent.name}/{t.run_dir.name} done "
                f"({time.perf_counter() - start:.0f} s)"
            )
    except BaseException:
        # Ctrl-C (KeyboardInterrupt) or a failed trial: end the other trials now rather than let
        # them run their batch out. force=True ends their workers at once; what a rerun resumes
        # from is each trial's last checkpoint, written whole and then renamed into place.
        for ref in pending:
            try:
                ray.cancel(ref, force=True)
            except Exception:  # already finished, or the cluster is going away: nothing to end
                pass
        raise
    finally:
        ray.shutdown()


def _start_ray(
    ray: Any, address: str | None, workers: int | None, niceness: int, cores: int
) -> tuple[str, int]:
    """Start a local Ray or join the cluster at ``address``, its workers at
    ``niceness``; returns where it runs and the tasks it runs at once."""
    # every worker of this job starts at this niceness (Ray's own job supervisor sets its
    # workers' the same way: RAY_worker_niceness in the runtime_env, ray-project/ray#34727)
    job_env = {"env_vars": {"RAY_worker_niceness": str(niceness)}}
    if address is None:
        n = workers or cores
        ray.init(
            # "local": a Ray of its own, even where `ray start` left a cluster's address in
            # /tmp/ray for a bare ray.init() to join (joining one takes --address or RAY_ADDRESS)
            address="local",
            num_cpus=n,
            include_dashboard=False,
            log_to_driver=True,
            configure_logging=False,
            runtime_env=job_env,
        )
        return f"local, {n} CPUs", n
    from himit_torch.runs.ray_cluster import prepare_to_join

    where = f"{address}, {prepare_to_join(address)}"
    ray.init(address=address, include_dashboard=False, configure_logging=False, runtime_env=job_env)
    return where, workers or int(ray.cluster_resources().get("CPU", 1))


# ============================================================================== the tables
def _read_csv(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def _show(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, (list, tuple)):
        return ",".join(map(str, value))
    return str(value)


#: The measures that are counts (skewed, bounded below): summarised with a BCa bootstrap
#: interval, which stays in the possible range where a t-interval can go below zero.
_COUNT_MEASURES = ("total_goals", "final_window_goals", "late_goals", "first_goal_step")
_MEASURES = (*_COUNT_MEASURES, "value_start")
#: The frozen greedy policies at the end (exact, ``himit_torch.runs.greedy``): blank in
#: ``runs.csv`` for trials run without them (``greedy_every = None``, or older trials).
_GREEDY_MEASURES = (
    "greedy_goals_per_window",
    "greedy_percent_of_optimal",
    "greedy_percent_of_mentor",
    "greedy_value_start",
)


def summarize(spec: SweepSpec, out: Path) -> dict:
    """Gather the finished trials into results.csv, runs.csv, summary.csv and summary.md."""
    out = Path(out)
    factor_cols = list(spec.factors)
    results: list = []
    runs: list = []
    engines: set = set()
    commits: set = set()
    for trial in spec.trials(out):
        settings = {
            "sweep": spec.name,
            "cell": trial.cell.slug,
            **{f: _show(trial.cell.levels[f]) for f in factor_cols},
        }
        curves = _read_csv(trial.run_dir / "curves.csv")
        results.extend({**settings, **row} for row in curves)
        world = json.loads((trial.run_dir / "worlds" / f"world{trial.size}.json").read_text())
        engines.add(world.get("engine", "unknown"))
        commits.add(world.get("commit", "unknown"))
        runs.extend(_run_rows(trial, settings, world, curves))
    order = {c.slug: c.index for c in spec.cells}
    agent_order = {a: i for i, a in enumerate(spec.cells[0].config.agents)}

    def key(r: dict) -> tuple:  # results.csv's rows (text) by step too, runs.csv's (numbers)
        where = (order[r["cell"]], int(r["world"]), agent_order.get(r["agent"], 99))
        return (*where, int(r["seed"]), int(r.get("step", 0)))

    results.sort(key=key)
    runs.sort(key=key)
    head = ["sweep", "cell", *factor_cols]
    write_rows(
        out / "results.csv", head + [k for k in results[0] if k not in head], results, newline="\n"
    )
    write_rows(out / "runs.csv", head + [k for k in runs[0] if k not in head], runs, newline="\n")
    summary = _summary_rows(
        spec.name, factor_cols, {c.slug: c.config.steps for c in spec.cells}, runs
    )
    provenance = {"commit": sorted(commits), "engine": sorted(engines)}
    _write_summary(_about(spec), out, summary, provenance)
    return provenance


def _run_rows(trial: Trial, settings: dict, world: dict, curves: list[dict]) -> list[dict]:
    """``runs.csv``'s rows of one trial: each run's measures, from its world record and
    curves."""
    late_windows = max(1, LATE_STEPS // trial.config.window)
    per_run: dict = {}
    for row in curves:
        per_run.setdefault((row["agent"], int(row["seed"])), []).append(int(row["goals_in_window"]))
    return [
        {
            **settings,
            "world": trial.size,
            "agent": agent,
            "seed": seed,
            "total_goals": world["goals"][b],
            "final_window_goals": world["final_window_goals"][b],
            "late_goals": sum(per_run[(agent, seed)][-late_windows:]),
            "first_goal_step": world["first_goal_step"][b],
            "value_start": f"{world['value_start'][b]:.6f}",
            "true_value_start": f"{world['true_value_start']:.6f}",
            "mentor_term_wins": f"{world['mentor_term_wins'][b]:.4f}",
            "optimal_goals_per_window": f"{world['optimal_goals_per_window']:.3f}",
            **{m: f"{world[m][b]:.6g}" if world.get(m) else "" for m in _GREEDY_MEASURES},
            "mentor_goals_per_window": (
                f"{world['mentor_goals_per_window']:.3f}"
                if world.get("greedy_goals_per_window")
                else ""
            ),
        }
        for b, (agent, seed) in enumerate(zip(world["agents"], world["seeds"]))
    ]


def _summary_rows(
    name: str, factor_cols: Sequence[str], steps_of: dict[str, int], runs: list[dict]
) -> list[dict]:
    """Per cell, world and agent (in the order of ``runs``): the mean and 95 % interval of
    each measure, and the runs that never found the goal. ``steps_of``: each cell's steps."""
    summary = []
    groups: dict = {}
    for r in runs:
        groups.setdefault((r["cell"], r["world"], r["agent"]), []).append(r)
    for (cell, size, agent), rs in groups.items():
        row = {
            "sweep": name,
            "cell": cell,
            **{f: rs[0][f] for f in factor_cols},
            "world": size,
            "agent": agent,
            "n": len(rs),
        }
        steps = steps_of[cell]
        for m in _MEASURES + _GREEDY_MEASURES:
            vals = [float(r[m]) for r in rs if r.get(m, "") != ""]  # older runs.csv: no greedy
            if m == "first_goal_step":  # a run that never found the goal: just after its end
                vals = [v if v >= 0 else steps + 1 for v in vals]
            cells: tuple[str, ...] = ("", "", "")  # greedy measures of trials without them
            if m in _MEASURES or (vals and all(math.isfinite(v) for v in vals)):
                interval = (bca_interval if m in _COUNT_MEASURES else t_interval)(vals)
                cells = tuple(f"{x:.4g}" for x in (interval.estimate, interval.low, interval.high))
            row.update({f"{m}_mean": cells[0], f"{m}_ci_low": cells[1], f"{m}_ci_high": cells[2]})
        failed = sum(int(r["first_goal_step"]) < 0 for r in rs)
        row["failed"] = failed
        share = share_interval(failed, len(rs))
        for key, x in (("share", share.estimate), ("ci_low", share.low), ("ci_high", share.high)):
            row[f"failed_{key}"] = f"{x:.3f}"
        summary.append(row)
    return summary


#: What ``summary.md`` says of the spec besides its file: the keys ``sweep.json`` records too.
_ABOUT = ("name", "base", "design", "seeds", "first_seed", "worlds")


def _about(spec: SweepSpec) -> dict:
    about = {key: getattr(spec, key) for key in _ABOUT}
    return {**about, "worlds": list(spec.worlds), "spec": spec.source}


def rewrite_summary(out: str | os.PathLike) -> None:
    """Rewrite a finished sweep's ``summary.csv`` and ``summary.md`` from its
    ``runs.csv`` and ``sweep.json`` alone (``himit plot``).

    Raises:
        ValueError: ``sweep.json`` or ``runs.csv`` is missing or not a sweep's."""
    out = Path(out)
    where = f"sweep record {out / 'sweep.json'}"
    record = parse_document(where, read_text(where, out / "sweep.json"), "json")
    try:
        steps_of = {c["cell"]: int(c["config"]["steps"]) for c in record["cells"]}
        factor_cols = list(record["factors"])
        provenance = {"commit": list(record["commit"]), "engine": list(record["engine"])}
        about = {key: record[key] for key in _ABOUT}
    except (KeyError, TypeError) as err:
        raise ValueError(f"{where} is not a sweep's record ({err!r} missing)") from None
    about["spec"] = record.get("spec")
    runs = _read_csv(out / "runs.csv")
    if not runs:
        raise ValueError(f"{out / 'runs.csv'} holds no runs")
    summary = _summary_rows(about["name"], factor_cols, steps_of, runs)
    _write_summary(about, out, summary, provenance)


def sweep_command(about: dict, out: str | os.PathLike) -> str | None:
    """``himit sweep <spec> [--out <out>]``: the command that reruns the sweep into ``out``
    (None: its spec file is not known)."""
    if not about.get("spec"):
        return None
    words = ["himit", "sweep", shlex.quote(str(about["spec"]))]
    if Path(out) != Path("runs") / "sweeps" / about["name"]:
        words += ["--out", shlex.quote(str(out))]
    return " ".join(words)


def _write_summary(about: dict, out: Path, summary: list[dict], provenance: dict) -> None:
    write_rows(out / "summary.csv", list(summary[0]), summary, newline="\n")
    command = sweep_command(about, out)
    commits = provenance["commit"]
    lines = [
        f"# Sweep {about['name']}",
        "",
        f"Runs recorded at commit{'s' if len(commits) > 1 else ''} "
        + ", ".join(f"`{c}`" for c in commits)
        + " (from the trials' `worlds/*.json`, as `sweep.json` records); this page: "
        f"`himit plot {shlex.quote(str(out))}` (from `runs.csv` and `sweep.json`); the runs: "
        + (
            f"`{command}`."
            if command
            else "`himit sweep` of the spec that `sweep.json` resolves (its file not recorded)."
        ),
        "",
        f"Base `{about['base']}`, design {about['design']}, {about['seeds']} seeds per cell "
        f"({about['first_seed']}…{about['first_seed'] + about['seeds'] - 1}), worlds "
        f"{list(about['worlds'])}; "
        f"commit {', '.join(commits)}, engine {', '.join(provenance['engine'])}.",
        "",
        "Means with 95 % confidence intervals: for the counts (total goals, last window, late, "
        "first goal) the BCa bootstrap interval (9999 resamples; a t-interval can leave the "
        "possible range on skewed counts), for V(start) and greedy Student's t (n − 1 degrees "
        "of freedom); "
        "`failed`: runs that never reached the goal, with the exact (Clopper–Pearson) 95 % "
        "interval of their share. `late`: goals in the last "
        f"{LATE_STEPS:,} steps; `first goal`: steps to the first goal (a run that never "
        "found it counts as steps + 1).",
        "",
        "`greedy`: each run's greedy policy at the end, frozen (ε = 0, ties as configured) "
        "and evaluated exactly on the true model: its long-run goals per window as a % of the "
        "mentor's own rate (also exact).",
        "",
        "| cell | world | agent | n | total goals | last window | late | first goal | "
        "V(start) | failed | greedy, % of mentor |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]

    def ci(row, m, fmt="{:.1f}"):
        if row[m + "_mean"] == "":
            return "–"
        return (
            f"{fmt.format(float(row[m + '_mean']))} [{fmt.format(float(row[m + '_ci_low']))}, "
            f"{fmt.format(float(row[m + '_ci_high']))}]"
        )

    for r in summary:
        lines.append(
            f"| {r['cell']} | {r['world']} | {r['agent']} | {r['n']} | "
            f"{ci(r, 'total_goals', '{:.0f}')} | {ci(r, 'final_window_goals')} | "
            f"{ci(r, 'late_goals', '{:.0f}')} | {ci(r, 'first_goal_step', '{:.0f}')} | "
            f"{ci(r, 'value_start', '{:.3f}')} | {r['failed']}/{r['n']} "
            f"[{float(r['failed_ci_low']):.2f}, {float(r['failed_ci_high']):.2f}] | "
            f"{ci(r, 'greedy_percent_of_mentor')} |"
        )
    (out / "summary.md").write_text("\n".join(lines) + "\n")


# ================================================================================ the sweep
def run_sweep(
    spec: SweepSpec | str | os.PathLike,
    out: str | os.PathLike,
    *,
    address: str | None = None,
    use_ray: bool = True,
    workers: int | None = None,
    worker_niceness: int | None = None,
    log=None,
) -> dict:
    """Run every unfinished trial of ``spec`` into ``out`` (skipping finished ones, resuming
    started ones), then write the tables. Returns what ``sweep.json`` holds.

    ``worker_niceness`` (0–19) overrides the spec's for Ray's workers (module docstring).

    Raises:
        ValueError: the spec is invalid, a finished trial holds another configuration, or
            ``worker_niceness`` is out of range;
            :class:`~himit_torch.runs.ray_cluster.ClusterAuthError` (a ``ValueError``): the
            cluster wants a token that is not set.
        ConnectionError: no Ray cluster answers at ``address``.
        KeyboardInterrupt: Ctrl-C; the running trials are cancelled, a rerun resumes them.
    """
    if not isinstance(spec, SweepSpec):
        spec = load_spec(spec)
    if log is None:
        log = functools.partial(print, file=sys.stderr, flush=True)
    if worker_niceness is not None:
        spec = replace(spec, worker_niceness=as_int("worker_niceness", worker_niceness, 0, 19))
    out = check_folder_path("the sweep's folder", out)
    trials = spec.trials(out)
    states = [(t, _trial_state(t)) for t in trials]
    todo = [(t, s) for t, s in states if s != "done"]
    log(
        f"himit sweep {spec.name}: {len(spec.cells)} cells × {len(spec.worlds)} worlds × "
        f"{spec.seeds} seeds = {len(trials)} trials; {len(trials) - len(todo)} finished, "
        f"{sum(s == 'started' for _, s in todo)} to resume, {sum(s == 'new' for _, s in todo)} new"
    )
    out.mkdir(parents=True, exist_ok=True)
    _execute(todo, address, use_ray, workers, log, spec.worker_niceness)
    record = _sweep_record(spec, summarize(spec, out))
    (out / "sweep.json").write_text(json.dumps(record, indent=1) + "\n")
    return record


def _sweep_record(spec: SweepSpec, provenance: dict) -> dict:
    """What ``sweep.json`` holds: the sweep, its cells' configurations and ``provenance``."""
    return {
        **_about(spec),
        "worker_niceness": spec.worker_niceness,
        "factors": {k: [_show(v) for v in vs] for k, vs in spec.factors.items()},
        "cells": [
            {
                "cell": c.slug,
                "levels": {k: _show(v) for k, v in c.levels.items()},
                "config": json.loads(c.config.to_json()),
            }
            for c in spec.cells
        ],
        **provenance,
        "sweep_commit": source_commit(),
    }
