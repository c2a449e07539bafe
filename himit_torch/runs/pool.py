"""A pool of independent jobs over the cores, for any study (:func:`run_pool`): this process
and ``workers − 1`` others, each a lane that takes the next job when it ends its last, the
cores shared out between them; once a lane finds no job left, the lanes still working take its
cores (between their batch's windows, :func:`~himit_torch.runs.runner.take_ended_lanes_cores`).
The paper's experiments run their worlds through it.

A job's result must not depend on the process it runs in (each world of a study is
independent and seeded): the pool changes how long a run takes, never what it finds.
"""

from __future__ import annotations

import multiprocessing
import os
import queue
import threading
from collections import deque
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager, nullcontext
from typing import Any

import torch

from himit_torch.runs.runner import freeze_at_exit, join_lanes, share_cores

__all__ = ["run_pool", "workers_for", "cores_shared"]


def workers_for(jobs: int, workers: int | None) -> int:
    """The lanes a pool of ``jobs`` jobs uses: ``workers`` (default: one per core), at most
    one per job."""
    return min(jobs, os.cpu_count() or 1) if workers is None else min(int(workers), jobs)


def _pool_process(threads: int, working: Any = None, cores: int = 1) -> None:
    """Set up one of the pool's processes: its share of the cores, the count of lanes still
    working (``None``: a process of no pool's count) and an exit that skips the last garbage
    collections: the run waits for its processes to end, ≈ 1.2 s each without it, ≈ 0.25 s
    with it."""
    share_cores(threads)
    join_lanes(working, cores, threads)
    freeze_at_exit()


@contextmanager
def cores_shared(threads: int) -> Iterator[None]:
    """A block in which this process runs as one lane among others
    (:func:`~himit_torch.runs.runner.share_cores`); its thread counts are restored after."""
    try:
        from numba import get_num_threads, set_num_threads
    except ImportError:  # (no compiled engine: torch's threads only)
        numba_threads = None
    else:
        numba_threads = get_num_threads()
    torch_threads = torch.get_num_threads()
    share_cores(threads)
    try:
        yield
    finally:
        if numba_threads is not None:
            set_num_threads(numba_threads)
        torch.set_num_threads(torch_threads)


class _Lanes:
    """The jobs left, taken one at a time by every lane, and what the other lanes ended."""

    def __init__(
        self, task: Callable[..., Any], jobs: Sequence[tuple[Hashable, tuple]], working: Any
    ):
        self.task = task
        self.working = working  # the lanes that may still take a job (shared with the processes)
        self.jobs = deque(jobs)
        self.taking = threading.Lock()
        self.ended: queue.Queue = queue.Queue()  # the other lanes' (key, result), or an error
        self.failed = threading.Event()
        self.threads: list[threading.Thread] = []

    def take(self) -> tuple[Hashable, tuple] | None:
        """The next job, or ``None``: then the lane that asked has ended, and the lanes still
        working may take its cores."""
        with self.taking:
            if self.jobs and not self.failed.is_set():
                return self.jobs.popleft()
        with self.working.get_lock():
            self.working.value -= 1
        return None

    def lane(self, pool: ProcessPoolExecutor, announce: Callable[[Hashable], None]) -> None:
        """One other lane: its jobs, one at a time, each in the pool. It takes its first once
        its process has started (imported this package): it takes the most expensive job
        left then, not while its process still starts."""
        try:
            pool.submit(os.getpid).result()
            while (job := self.take()) is not None:
                key, args = job
                result = pool.submit(self.task, *args).result()
                announce(key)
                self.ended.put((key, result))
        except BaseException as err:  # (handed to the main thread, which raises it)
            self.failed.set()
            self.ended.put((None, err))

    def collect(self, done: Callable[[Hashable, Any], None], wait: bool) -> None:
        """``done`` of what the other lanes ended (``wait``: until they all stop)."""
        while True:
            try:
                key, result = self.ended.get(timeout=0.1) if wait else self.ended.get_nowait()
            except queue.Empty:
                if wait and any(t.is_alive() for t in self.threads):
                    continue
                return
            if isinstance(result, BaseException):
                raise result
            done(key, result)


def run_pool(
    task: Callable[..., Any],
    jobs: Sequence[tuple[Hashable, tuple]],
    workers: int,
    done: Callable[[Hashable, Any], None],
    announce: Callable[[Hashable], None] = lambda key: None,
    prepared: Any = None,
) -> None:
    """Run ``task(*args)`` for each job ``(key, args)`` of ``jobs`` (in this order; put the
    most expensive first) in ``workers`` lanes: this process and ``workers − 1`` others
    (``spawn``ed; ``task`` and its arguments must pickle). ``announce(key)`` as each ends (from
    any thread); ``done(key, result)`` in this thread: after each job of its own, and for the
    other lanes' jobs between its own and at the end. ``prepared``: a block the other lanes'
    processes start in (e.g. compiling the Numba kernels once, here, while they start).

    This process is a lane: it has its modules loaded and starts its first job at once, where
    a new process first spends ≈ 2.5 s importing them. A failed job stops the lanes from taking
    more; the jobs already running end first."""
    cores = os.cpu_count() or 1
    threads = max(1, cores // workers)
    # "spawn": a forked child of a process whose OpenMP threads already ran can hang.
    context = multiprocessing.get_context("spawn")
    lanes = _Lanes(task, jobs, context.Value("i", workers))
    pool = ProcessPoolExecutor(
        workers - 1,
        mp_context=context,
        initializer=_pool_process,
        initargs=(threads, lanes.working, cores),
    )
    lanes.threads = [
        threading.Thread(target=lanes.lane, args=(pool, announce), daemon=True)
        for _ in range(workers - 1)
    ]
    try:
        with prepared or nullcontext():
            for t in lanes.threads:
                t.start()
        with cores_shared(threads):
            join_lanes(lanes.working, cores, threads)
            while (job := lanes.take()) is not None:
                key, args = job
                result = task(*args)
                announce(key)
                done(key, result)
                lanes.collect(done, wait=False)
        lanes.collect(done, wait=True)
    finally:  # a failed job stops the rest instead of letting them run to the end
        join_lanes(None, cores, threads)
        lanes.failed.set()
        pool.shutdown(wait=True, cancel_futures=True)
