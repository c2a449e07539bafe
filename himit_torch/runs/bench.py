"""Throughput of the batched learner (``himit bench``; ``benchmarks/bench_learner.py`` for tables)."""

from __future__ import annotations

import resource
import time
from dataclasses import dataclass

import torch

from himit_torch.learner.agents import AGENTS
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.validation import as_device
from himit_torch.worlds.multirooms import MultiRooms

__all__ = ["BenchResult", "benchmark"]


@dataclass(frozen=True)
class BenchResult:
    size: int
    rooms: int
    corner_options: bool
    batch: int
    steps: int
    agent: str
    device: str
    seconds: float
    decisions: int
    peak_memory_mib: float
    engine: str = "torch"
    first_call_seconds: float = 0.0
    """The first (untimed) tick: for the compiled engine, loading or compiling its kernels."""

    @property
    def steps_per_second(self) -> float:
        """Primitive steps per second, summed over the batch."""
        return self.batch * self.steps / self.seconds

    @property
    def decisions_per_second(self) -> float:
        return self.decisions / self.seconds

    def line(self) -> str:
        return (
            f"{self.size}x{self.size}/{self.rooms} corners={self.corner_options} B={self.batch} "
            f"agent={self.agent} engine={self.engine} device={self.device}: "
            f"{self.steps_per_second:,.0f} steps/s, {self.decisions_per_second:,.0f} decisions/s, "
            f"peak memory {self.peak_memory_mib:,.0f} MiB ({self.seconds:.2f} s for "
            f"{self.steps} steps; first call {self.first_call_seconds:.2f} s)"
        )


def _learner(
    size: int,
    rooms: int,
    corner_options: bool,
    batch: int,
    agent: str,
    device: str,
    plan_every: int,
    engine: str,
) -> Learner:
    """The benchmark's learner: ``batch`` runs of ``agent`` (or the mix) on the world, with the
    mentor's 20 episodes."""
    world = MultiRooms(size=size, rooms=rooms)
    # the mentor's tables are freed before the learner's are built (as in the experiments)
    demos = record_demonstrations(
        world, mentor_policy(world, mentor_options(world, corner_options)), 20, seed=0
    )
    options = learner_options(world, corners=corner_options)
    mix = ["imitation", "options", "primitives"]
    agents = [mix[b % 3] if agent == "mix" else agent for b in range(batch)]
    return Learner(
        world,
        options,
        agents,
        list(range(batch)),
        demonstrations=demos,
        config=LearnerConfig(plan_every=plan_every, sweep_rounds=1),
        device=device,
        engine=engine,
    )


def benchmark(
    size: int = 40,
    rooms: int = 10,
    corner_options: bool = False,
    batch: int = 15,
    steps: int = 5000,
    agent: str = "mix",
    device: str = "cpu",
    plan_every: int = 4,
    warmup: int = 1000,
    threads: int | None = 1,
    engine: str = "auto",
) -> BenchResult:
    """Time ``steps`` ticks of a batch of ``batch`` runs after ``warmup`` untimed ticks.

    ``agent="mix"`` cycles imitation / options / primitives over the batch (as the experiments
    do). The first tick is always untimed and reported apart (``first_call_seconds``: the
    compiled engine loads, or on first use compiles, its kernels there). Peak memory is the
    process's peak resident set (CPU) or peak CUDA allocation. ``threads`` sets torch's threads;
    the compiled engine uses Numba's (``NUMBA_NUM_THREADS``, default all cores).
    """
    if agent != "mix" and agent not in AGENTS:
        raise ValueError(f"agent={agent!r}: use 'mix' or one of {sorted(AGENTS)}")
    device = str(as_device("device", device))  # refused here, before the mentor is built
    if threads is not None:
        torch.set_num_threads(threads)
    learner = _learner(size, rooms, corner_options, batch, agent, device, plan_every, engine)
    first = time.perf_counter()
    learner.run(1)
    first = time.perf_counter() - first
    learner.run(max(0, warmup - 1))
    decisions0 = int(learner.views.decisions.sum())
    cuda = device.startswith("cuda")
    if cuda:
        torch.cuda.synchronize()
        torch.cuda.reset_peak_memory_stats()
    start = time.perf_counter()
    learner.run(steps)
    if cuda:
        torch.cuda.synchronize()
    seconds = time.perf_counter() - start
    if cuda:
        peak = torch.cuda.max_memory_allocated() / 2**20
    else:
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return BenchResult(
        size,
        rooms,
        corner_options,
        batch,
        steps,
        agent,
        device,
        seconds,
        int(learner.views.decisions.sum()) - decisions0,
        peak,
        learner.engine.name,
        first,
    )
