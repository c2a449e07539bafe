"""The runner core: one learner batch advanced window by window, the same for every experiment.

:func:`run_windows` is the loop that the paper's experiments (:func:`~himit_torch.runs.experiment.run_world`),
the Gymnasium comparison (:func:`~himit_torch.runs.gymnasium.run_task`) and the discovery
experiment (:mod:`himit_torch.runs.discovery`) share, read top to bottom::

    while learner.views.t < steps:
        advance to the end of the window (or of the run)
        log every window that ended              (on_window hooks: TensorBoard, rows, …)
        draw maps                                 (maps, into the TensorBoard logger)
        save a checkpoint                         (checkpoints; the logger is flushed first)

Around it, what every runner needs to set a batch up and keep its run directory honest: the
batch's runs (:func:`batch_runs`, :func:`run_names`), each seed's demonstrations
(:func:`watch_demonstrations`), checkpoints with resume (:class:`Checkpoints`), the run
directory's checks (:func:`check_run_dir`, :func:`clear_run_dir`), the code's commit
(:func:`source_commit`) and the threads of a world's process among others (:func:`share_cores`;
as one of a pool's lanes, :func:`join_lanes`, it takes the cores of the lanes that have ended
between its windows). What a runner measures and reports stays in its own module.
"""

from __future__ import annotations

import atexit
import gc
import os
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch

from himit_torch.learner.learner import Learner
from himit_torch.runs.checkpoints import (
    BatchShape,
    Checkpoint,
    CheckpointGenerations,
    NoGoodCheckpoint,
)
from himit_torch.state_checks import DamagedState, section
from himit_torch.validation import check_folder_path
from himit_torch.viz.tensorboard import TensorBoardLogger

__all__ = [
    "run_windows",
    "WindowHook",
    "Maps",
    "Checkpoints",
    "batch_runs",
    "run_names",
    "watch_demonstrations",
    "check_run_dir",
    "clear_run_dir",
    "source_commit",
    "state_layout_version",
    "write_atomically",
    "share_cores",
    "join_lanes",
    "take_ended_lanes_cores",
    "freeze_at_exit",
]

#: A per-window hook: ``hook(learner, index)`` with ``index`` the window's entry in
#: ``learner.metrics`` (the window ends at ``learner.metrics.steps[index]``).
WindowHook = Callable[[Learner, int], None]


# ================================================================================ the loop
@dataclass
class Maps:
    """Which runs get maps in TensorBoard, and when: every ``every`` steps and at the end."""

    runs: Sequence[int]
    every: int
    mentor_visits: Mapping[int, torch.Tensor] | torch.Tensor | None = None


def run_windows(
    learner: Learner,
    steps: int,
    *,
    on_window: Sequence[WindowHook] = (),
    logger: TensorBoardLogger | None = None,
    maps: Maps | None = None,
    checkpoints: Checkpoints | None = None,
    progress: str | None = None,
    elapsed: float = 0.0,
) -> float:
    """Advance ``learner`` to step ``steps``, one window (``learner.config.window``) at a time.

    After each window that ends, every hook of ``on_window`` is called in order; then, on their
    schedule and at the last step, the maps of ``maps`` are drawn into ``logger`` and a
    checkpoint is saved (``logger`` flushed first, so that what a checkpoint's step says was
    logged is on disk). ``progress``: the description of a progress bar (``None``: no bar).
    ``elapsed``: the wall seconds the run had used before (a resumed run's).

    Returns:
        The wall seconds of the run, ``elapsed`` included.
    """
    if maps is not None and logger is None:
        raise ValueError("run_windows: maps are drawn into a logger; pass logger=")
    window = learner.config.window
    logged = len(learner.metrics.steps)
    bar = None
    if progress is not None:
        from tqdm.auto import tqdm

        bar = tqdm(
            total=steps, initial=learner.views.t, unit="step", mininterval=1.0, desc=progress
        )
    start = time.perf_counter()
    while learner.views.t < steps:
        chunk = min(window - learner.views.t % window, steps - learner.views.t)
        learner.run(chunk)
        take_ended_lanes_cores()
        if bar is not None:
            bar.update(chunk)
        while logged < len(learner.metrics.steps):
            for hook in on_window:
                hook(learner, logged)
            logged += 1
        end = learner.views.t == steps
        if maps is not None and logger is not None and (learner.views.t % maps.every == 0 or end):
            logger.maps(learner, maps.runs, learner.views.t, maps.mentor_visits)
        if checkpoints is not None and (learner.views.t % checkpoints.every == 0 or end):
            if logger is not None:
                logger.flush()
            checkpoints.save(learner, elapsed + time.perf_counter() - start)
    if bar is not None:
        bar.close()
    return elapsed + time.perf_counter() - start


# ========================================================================= checkpoints
def state_layout_version() -> int:
    """The learner's state layout version: stored in every checkpoint so that a checkpoint of
    another layout is refused by name."""
    return Learner.STATE_LAYOUT_VERSION


@dataclass
class Checkpoints:
    """A batch's checkpoint generations (:class:`~himit_torch.runs.checkpoints.CheckpointGenerations`
    at ``path``): saved every ``every`` steps by :func:`run_windows`, restored by :meth:`start`.
    ``companions``: other state saved with the learner's (by name; objects with ``state_dict``
    and ``load_state_dict(state, learner)``, e.g. a :class:`~himit_torch.runs.greedy.GreedyTracker`):
    on resume each is given its state and the learner just restored from the same checkpoint,
    against which it checks what it reads (its batch, the step it reached); a
    :class:`~himit_torch.state_checks.DamagedState` it raises skips the generation as a damaged
    learner state does."""

    path: Path
    batch: BatchShape
    every: int
    device: str = "cpu"
    companions: Mapping[str, Any] = field(default_factory=dict)
    generations: CheckpointGenerations = field(init=False)
    layout: int = field(init=False)

    def __post_init__(self):
        self.generations = CheckpointGenerations(self.path)
        self.layout = state_layout_version()

    def start(self, learner: Learner, resume: bool) -> float:
        """Restore ``learner`` (``resume``: :meth:`resume`) or clear the generations of an
        earlier run (a fresh run: stale files must never become its "previous" one); returns the
        wall seconds the run had used."""
        if resume:
            return self.resume(learner)
        self.generations.clear()
        return 0.0

    def save(self, learner: Learner, elapsed: float) -> None:
        """Save the learner's state (its own tensors, not copies: the file is written before
        the learner runs again), ``elapsed`` and the companions' states as the newest
        generation."""
        companions = {name: c.state_dict() for name, c in self.companions.items()}
        self.generations.save(
            {"learner": learner.state_dict(copy=False), "elapsed": elapsed, **companions},
            step=learner.views.t,
            batch=self.batch,
            state_layout_version=self.layout,
        )

    def resume(self, learner: Learner) -> float:
        """Restore ``learner`` from the newest good checkpoint generation; returns the wall seconds
        the run had used. Nothing saved yet: the learner is left as it is (a run killed before its
        first checkpoint starts over). A damaged newest file: one line on stderr, then the previous
        generation — the learner then redoes the lost interval exactly as it first ran it.

        Raises:
            ValueError: no generation is good, or the checkpoint is for another state layout or
                batch, or it does not fit this learner; the message names the file.
        """
        elapsed: list[float] = []
        try:
            resumed = self.generations.load(
                map_location=self.device,
                expect_batch=self.batch,
                expect_layout=self.layout,
                restore=lambda found: elapsed.append(self._restore(learner, found)),
            )
        except NoGoodCheckpoint as err:
            raise ValueError(f"--resume: {err}; start over with --force") from None
        if resumed is None:
            return 0.0
        self._warn_skipped(resumed.checkpoint, resumed.skipped)
        return elapsed[-1]

    def _restore(self, learner: Learner, found: Checkpoint) -> float:
        """Restore ``learner`` and the companions from a verified file, its learner state checked
        in full first (a check that fails makes this generation skipped, the learner
        untouched); returns the wall seconds it records."""
        payload = section(
            found.payload, "payload", ("learner",), optional=("elapsed", *self.companions)
        )
        seconds = payload.get("elapsed", 0.0)
        if type(seconds) not in (int, float) or not 0 <= seconds < float("inf"):
            raise DamagedState("elapsed", f"{seconds!r} is not a number of seconds")
        try:
            learner.load_state_dict(payload["learner"])
        except DamagedState:
            raise
        except ValueError as err:  # another batch, configuration or state layout
            raise ValueError(f"{found.path}: {err}; start over with --force") from None
        except (KeyError, TypeError, IndexError, AttributeError, RuntimeError) as err:
            raise ValueError(
                f"{found.path} (step {found.header.step}) could not be restored into this "
                f"learner ({type(err).__name__}: {err}) although it passed every check of "
                f"state layout version {self.layout}: please report it; start over with --force"
            ) from None
        for name, companion in self.companions.items():  # (each checks what it reads)
            if name in payload:
                companion.load_state_dict(payload[name], learner)
        return float(seconds)

    def _warn_skipped(self, found: Checkpoint, skipped: Sequence[Any]) -> None:
        """One line on stderr per newer generation skipped as damaged, saying which steps the
        run will redo from ``found``."""
        for damaged in skipped:
            if damaged.step is not None and damaged.step > found.header.step:
                redo = f"{damaged.step - found.header.step} steps will be redone"
            else:
                redo = f"the steps after it (up to checkpoint_every={self.every}) will be redone"
            print(
                f"himit: warning: {damaged.path}: {damaged.reason}; resuming from "
                f"{(found.path or self.generations.newest).name} at step {found.header.step}: "
                f"{redo}",
                file=sys.stderr,
            )


# ============================================================================= the batch
def batch_runs(
    agents: Sequence[str], first_seed: int, seeds: int
) -> tuple[list[int], list[str], list[int]]:
    """``(seeds, agents, run_seeds)`` of a batch of every agent × seed: the seeds, and per run
    its agent and seed (agent-major: the runs of one agent are next to each other)."""
    seed_list = list(range(first_seed, first_seed + seeds))
    return (
        seed_list,
        [a for a in agents for _ in seed_list],
        [s for _ in agents for s in seed_list],
    )


def run_names(prefix: str, agents: Sequence[str], run_seeds: Sequence[int]) -> list[str]:
    """One TensorBoard folder name per run: ``<prefix>__<agent>__seed<k>`` (CleanRL-style)."""
    return [f"{prefix}__{a}__seed{s}" for a, s in zip(agents, run_seeds)]


def watch_demonstrations(learner: Learner, demos: Mapping[int, Any], mentor: int = 0) -> None:
    """Each seed's runs watch that seed's mentor episodes (``demos[seed]``: what
    :meth:`~himit_torch.learner.learner.Learner.add_demonstrations` takes), seed by seed, as
    mentor number ``mentor`` (``LearnerConfig.mentors``)."""
    seeds = list(learner.seeds)
    for s in sorted(set(seeds)):
        runs = [b for b, rs in enumerate(seeds) if rs == s]
        learner.add_demonstrations(demos[s], runs=runs, mentor=mentor)


# ======================================================================= the run directory
def check_run_dir(run_dir: Path, *, force: bool, resume: bool | None = None) -> None:
    """Refuse to overwrite a finished run (one with ``results.md``) unless ``force``; with
    ``resume=False``, also an unfinished one (``config.json`` without ``results.md``: resume it
    or start over). ``resume=None``: the runner cannot resume, an unfinished run starts over.
    A file where the run directory (or a folder above it) belongs is refused whatever the
    flags (:func:`~himit_torch.validation.check_folder_path`)."""
    check_folder_path("the run directory", run_dir)
    if force:
        return
    finished = (run_dir / "results.md").exists()
    started = (run_dir / "config.json").exists()
    if finished and not resume:
        raise ValueError(
            f"{run_dir} already holds a finished run; choose another --logdir or pass "
            "--force to overwrite it"
        )
    if started and not finished and resume is False:
        raise ValueError(
            f"{run_dir} holds an unfinished run; pass --resume to continue it or "
            "--force to start over"
        )


def clear_run_dir(run_dir: Path, folders: Sequence[str], files: Sequence[str] = ()) -> None:
    """Remove what an earlier run left in ``run_dir`` (``--force``): its ``folders`` and
    ``files``."""
    if not run_dir.exists():
        return
    for sub in folders:
        shutil.rmtree(run_dir / sub, ignore_errors=True)
    for f in files:
        (run_dir / f).unlink(missing_ok=True)


def source_commit() -> str:
    """The git commit of the code that runs (``+dirty`` if it has uncommitted changes), or
    ``"unknown"`` outside a git checkout: recorded with every result."""
    root = Path(__file__).resolve().parents[2]  # the checkout (himit_torch/runs/runner.py)

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", *args], cwd=root, text=True, capture_output=True, timeout=10, check=True
        ).stdout.strip()

    try:
        commit = git("rev-parse", "--short=12", "HEAD")
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", "himit_torch")
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    return commit + ("+dirty" if dirty else "")


def merge_csv(parts: Sequence[Path], out: Path, newline: str = "\r\n") -> None:
    """``out`` (e.g. a run's ``curves.csv``): the header of the first of ``parts``, then every
    part's rows, in order, each line ending with ``newline`` (``csv``'s own ``\\r\\n``, or
    ``\\n``), written atomically."""
    header: list[str] = []
    rows: list[str] = []
    for part in parts:
        lines = part.read_text().splitlines()
        header = header or lines[:1]
        rows.extend(lines[1:])
    write_atomically(out, "".join(line + newline for line in header + rows))


def write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` through a temporary file beside it and a rename, so that a
    reader (or a run killed mid-write) never sees a half-written file."""
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text, newline="")  # (the text's own line endings, on every system)
    os.replace(tmp, path)


def share_cores(threads: int) -> None:
    """Set up a process that runs one world among others on the same machine: one torch thread,
    ``threads`` for the compiled engine (capped at Numba's ``NUMBA_NUM_THREADS``; nothing to set
    without Numba). The world processes of ``run_experiments`` and a sweep's trials call it
    first. (Numba's threading layer, launched by ``set_num_threads``, resets the OpenMP thread
    count torch shares, so torch's is set after it.)"""
    try:
        import numba

        numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]
    except ImportError:
        pass
    torch.set_num_threads(1)


@dataclass
class _Lane:
    """This process as one lane of a pool (:func:`join_lanes`): the lanes still working (a
    shared ``multiprocessing.Value``), the machine's cores, and the threads it runs on now."""

    working: Any
    cores: int
    threads: int


_lane: _Lane | None = None


def join_lanes(working: Any, cores: int, threads: int) -> None:
    """Make this process one lane of a pool (:func:`~himit_torch.runs.pool.run_pool`):
    ``working`` is the count, shared by the pool's processes (a ``multiprocessing.Value``), of
    its lanes that may still take a job; ``threads`` the compiled engine's threads this lane
    runs on now (its share, :func:`share_cores`). ``working=None``: no longer a lane."""
    global _lane
    _lane = None if working is None else _Lane(working, cores, threads)


def take_ended_lanes_cores() -> None:
    """In a pool's lane (:func:`join_lanes`), between two windows of its batch
    (:func:`run_windows`): once other lanes have ended (no job was left for them), this lane's
    compiled engine runs on their cores too, ``cores // lanes still working`` threads, so that
    the pool's last world does not run on one core while the others idle. Only the time
    changes: a batch's runs give the same results on any number of threads. Nothing outside a
    pool's lane."""
    lane = _lane
    if lane is None:
        return
    threads = max(1, lane.cores // max(1, lane.working.value))
    if threads > lane.threads:
        share_cores(threads)
        lane.threads = threads


def freeze_at_exit() -> None:
    """At this process's exit, leave the objects still alive out of the interpreter's last
    garbage collections (``gc.freeze`` at exit), registered once per process.

    Those collections walk every object a run leaves behind (torch's, matplotlib's,
    TensorBoard's): ≈ 1 s at the end of a ``himit run``, and as long for each world process
    of ``himit run paper``. Nothing of ours waits on them: files and writers are closed where
    they are used, and ``weakref.finalize`` callbacks run at exit anyway (cycles the freeze
    keeps are freed with the process)."""
    atexit.unregister(gc.freeze)  # (removes an earlier registration, if any)
    atexit.register(gc.freeze)
