"""The compiled engine: the learner's ticks as one Numba kernel call per run, the runs on threads.

The kernels (:mod:`himit_torch.learner.engines.kernel`) work in place on the memory of the
state's tensors (``Tensor.numpy()`` shares it), grouped by owner into the named tuples of
:mod:`~himit_torch.learner.engines.kernel.arrays`, plus two derived structures the engine owns:
linked lists over each run's model edges (rebuilt from the edge lists whenever they changed
elsewhere) and an indexed max-heap over the sweep priorities (rebuilt from them at every call).
Kernels are cached on disk (Numba ``cache=True``): a second process does not compile again, and
processes that start together compile once (each kernel's first call in a process holds the
cache's lock, :func:`cache_lock`).
"""

from __future__ import annotations

import hashlib
import tempfile
import threading
import time
from collections import deque
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numba
import numpy as np
import torch

from himit_torch.learner.engines import kernel as _kernel_package
from himit_torch.learner.engines.kernel.arrays import (
    WINDOW_COUNTS,
    CacheArrays,
    ClonedArrays,
    MentorModelArrays,
    OptionModelArrays,
    RowArrays,
    RunArrays,
    SampleArrays,
    Scratch,
    SweepArrays,
    WindowArrays,
    WorldArrays,
    map_per_run,
)
from himit_torch.learner.engines.kernel.backup import mentor_wins
from himit_torch.learner.engines.kernel.tick import link_edges, run_ticks
from himit_torch.learner.engines.settings import kernel_settings
from himit_torch.learner.state import BatchState

__all__ = ["NumbaEngine", "cache_lock"]

KERNELS = (run_ticks, link_edges, mentor_wins)  # every kernel called from Python


def _np(x: torch.Tensor) -> np.ndarray:
    return x.detach().numpy()


# ------------------------------------------------------------------------ compiling once
_holder = threading.RLock()  # this process's hold of the cache lock (re-entrant)
_held: list[IO[str]] = []  # the lock file, open while this process holds it
_depth = 0
_called: set[Any] = set()  # the kernels called once (so loaded or compiled) in this process


def _lock_path() -> Path:
    """The lock file of this kernel cache (Numba's ``NUMBA_CACHE_DIR``, or beside the kernels'
    source when that is unset): processes sharing a cache share the lock."""
    cache = numba.config.CACHE_DIR or str(Path(_kernel_package.__file__).resolve().parent)  # type: ignore[attr-defined]
    digest = hashlib.sha256(cache.encode()).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / f"himit_torch-kernels-{digest}.lock"


@contextmanager
def cache_lock() -> Iterator[None]:
    """Hold the kernel cache's lock: an ``flock`` on ``_lock_path()`` between processes, and
    re-entrant within this one (a thread already holding it goes on; other threads wait).
    Without ``fcntl`` only this process's threads are held: each process compiles on its own."""
    global _depth
    with _holder:
        if _depth == 0:
            try:
                import fcntl
            except ImportError:
                fcntl = None  # type: ignore[assignment]
            if fcntl is not None:
                f = open(_lock_path(), "a")  # noqa: SIM115 (closed when the last hold ends)
                fcntl.flock(f, fcntl.LOCK_EX)
                _held.append(f)
        _depth += 1
        try:
            yield
        finally:
            _depth -= 1
            if _depth == 0 and _held:
                import fcntl

                held = _held.pop()
                fcntl.flock(held, fcntl.LOCK_UN)
                held.close()


def _call(kernel, *args) -> None:
    """``kernel(*args)``; its first call in this process holds the cache's lock, so that a
    process which gets there while another compiles the same kernel waits for it and loads what
    it cached, instead of compiling it again on a core the other one needs."""
    if kernel in _called:
        kernel(*args)
        return
    with cache_lock():
        kernel(*args)
        _called.add(kernel)


_pool: ThreadPoolExecutor | None = None
_pool_size = 0  # its worker threads (ThreadPoolExecutor keeps the number private)


def _numba_threads() -> int:
    """``numba.get_num_threads()``, keeping torch's intra-op thread count as it was: the first
    call launches Numba's threading layer, whose OpenMP backend sets the OpenMP thread count
    that torch's pool shares (measured: ``torch.set_num_threads(1)``, one run of the compiled
    engine, then ``torch.get_num_threads()`` gave 2, and small torch ops ran ≈ 20× slower on a
    busy machine)."""
    torch_threads = torch.get_num_threads()
    threads = numba.get_num_threads()
    if torch.get_num_threads() != torch_threads:
        torch.set_num_threads(torch_threads)
    return threads


_LINE = 64  # bytes in a cache line
# A per-run array whose run rows are shorter than this travels to a batch's threads in a lined
# copy (:func:`_lined`); longer rows share a line with the next run's at their ends only.
_LINED_BELOW = 1024


def _lined(x: np.ndarray) -> np.ndarray:
    """A copy of the per-run array ``x`` (``[B, …]``) in which each run's row starts a cache line
    of its own. Threads running neighbouring runs would otherwise write the same lines (a run's
    position, its counters, its scratch rows sit 8 bytes from the next run's), and each write
    takes the line from the other core: measured, 16 mixed runs on 2 cores went from ≈ 610k to
    ≈ 880k steps/s."""
    inner = np.empty(x.shape[1:], dtype=x.dtype)  # (C strides of a run's row)
    row = -(-max(inner.nbytes, 1) // _LINE) * _LINE
    raw = np.empty(x.shape[0] * row + _LINE, dtype=np.uint8)
    start = -raw.ctypes.data % _LINE
    out = np.ndarray(x.shape, x.dtype, raw, start, (row, *inner.strides))
    out[...] = x
    return out


def _run_all(stops: list[int], args: tuple, seconds: np.ndarray) -> None:
    """Advance every run of the batch to ``stops[-1]``: ``run_ticks`` on up to
    ``numba.get_num_threads()`` threads (this one included), never more than the batch.
    ``args``: ``run_ticks``' arguments after ``t_end``, the first of them ``t_reached`` (``[B]``,
    where each run is); ``stops``: the window ends crossed, then the end; ``seconds[b]``: run
    ``b``'s time in the last call of this function (the order of the next), updated here.

    The runs are independent (each touches only its own row of every per-run array), so which
    thread runs which, and in what pieces, does not change anything. ``run_ticks`` releases the
    GIL (``nogil``). Python threads rather than a ``prange`` loop: a parallel wrapper of the loop
    took ≈ 13 s to compile, over a third of a cold start, and a call from here costs ≈ 0.1 ms
    per run. The first call in a process runs alone, under the cache's lock (:func:`_call`).

    One run goes to ``stops[-1]`` in one call. A batch's runs go from stop to stop, each thread
    taking the run at the head of a queue and putting it back at its tail, the runs that took
    longest last time first: runs differ in cost (an imitator plans more than a primitives-only
    run), and the runs end together, the threads waiting at most for the last take of one run
    (a window or a few) at the end, not a window at every window's end. A run taken goes as
    many stops as a ``2 × threads``-th of the stops the queued runs have left
    (:func:`_stops_per_take`): whole while much is left, fewer as less is, a window at a time
    at the end. A run taken back after others ran finds its rows gone from the core's caches:
    taken a window at a time throughout, 16 mixed runs on two threads ran 1.03–1.10× slower
    (``benchmarks/bench_batch_schedule.py``, medians of 9).

    A run whose edge list fills stops short of its stop (``run_ticks``); then the threads take
    runs a window at a time while some thread ends a longer take, and this returns once none is
    in a run, so that the caller grows the lists and every run goes on together, no thread idle
    while there are runs to take. Left to the end of the call instead, the runs that
    filled their lists would run alone after the others, one thread idle: measured, 2 runs on
    2 threads then took as long as on one.

    Each run of a batch gets its own call's arguments: its row of each per-run array
    (``x[b : b + 1]``, run 0 of the call), the small ones in lined copies (:func:`_lined`)
    when threads share the batch, copied back after. A run's rows are C-contiguous as a whole
    one-run batch's arrays are, so one compiled loop serves both."""
    t_reached = args[0]
    if t_reached.shape[0] == 1:
        _call(run_ticks, stops[-1], *args)
        return
    threads = min(t_reached.shape[0], _numba_threads())
    copies: list[tuple[np.ndarray, np.ndarray]] = []

    def lined(x: np.ndarray) -> np.ndarray:
        if threads == 1 or x[0].nbytes >= _LINED_BELOW:
            return x
        copy = _lined(x)
        copies.append((x, copy))
        return copy

    whole = tuple(map_per_run(arg, lined) for arg in args)
    try:
        _run_each(threads, stops if threads > 1 else stops[-1:], whole, seconds)
    finally:
        for x, copy in copies:
            x[...] = copy


def _run_each(threads: int, stops: list[int], args: tuple, seconds: np.ndarray) -> None:
    """The runs of :func:`_run_all` on ``threads`` threads, from stop to stop."""
    t_reached = args[0]
    full = False  # some run's edge list is full (the caller grows the lists once all stop)
    long_takes = 0  # threads in a take of more than one stop

    def step(b: int, take: int = 1) -> bool:
        """Run ``b`` ``take`` stops on (at most to the last); whether it is to go on."""
        nonlocal full
        t = t_reached[b]
        ahead = [s for s in stops if s > t]
        stop = ahead[min(take, len(ahead)) - 1]
        began = time.perf_counter()
        _call(run_ticks, stop, *(map_per_run(arg, lambda x: x[b : b + 1]) for arg in args))
        seconds[b] += time.perf_counter() - began
        if t_reached[b] < stop:  # (its edge list is full)
            full = True
            return False
        return stop < stops[-1]

    order = np.argsort(-seconds, kind="stable")
    queue = deque(int(b) for b in order if t_reached[b] < stops[-1])
    seconds[:] = 0.0
    if run_ticks not in _called and queue:  # (the first call alone: _call)
        b = queue.popleft()
        if step(b):
            queue.append(b)
    # the stops left to the runs not under way (a run's are its own again when it is queued)
    left = {b: sum(s > t_reached[b] for s in stops) for b in queue}
    lock = threading.Lock()

    def work() -> None:
        nonlocal long_takes
        while True:
            with lock:
                # Once a list is full, the lists grow when no thread is in a run: a thread goes
                # on a window at a time while another ends a longer take, then stops.
                if not queue or (full and long_takes == 0):
                    return
                b = queue.popleft()
                take = 1 if full else min(_stops_per_take(sum(left.values()), threads), left[b])
                del left[b]
                long_takes += take > 1
            go_on = step(b, take)
            with lock:
                long_takes -= take > 1
                if go_on:
                    queue.append(b)
                    left[b] = sum(s > t_reached[b] for s in stops)

    helpers = [_thread_pool(threads - 1).submit(work) for _ in range(threads - 1)]
    try:
        work()
    finally:
        for h in helpers:
            h.result()


def _stops_per_take(stops_left: int, threads: int) -> int:
    """How many stops a run taken from :func:`_run_each`'s queue goes (at most its own left):
    a ``2 × threads``-th of the ``stops_left`` of the runs queued, at least one ("guided"
    scheduling). The takes shrink as the work left does, the last ones a window each, so the
    threads end close together, and the first are whole runs, each one call on a core whose
    caches hold its rows."""
    return max(1, -(-stops_left // (2 * threads)))


def _thread_pool(size: int) -> ThreadPoolExecutor:
    """This process's pool of at least ``size`` worker threads (made, or made larger, here)."""
    global _pool, _pool_size
    if _pool is None or _pool_size < size:
        if _pool is not None:  # (more threads were allowed since: a larger pool)
            _pool.shutdown(wait=False)
        _pool = ThreadPoolExecutor(max(size, 1), thread_name_prefix="himit-run")
        _pool_size = max(size, 1)
    return _pool


def _row_begin(state_rows: torch.Tensor, num_rows: int) -> np.ndarray:
    """``[S + 2]``: the rows of state ``s`` are ``row_begin[s]`` … ``row_begin[s + 1] − 1``.

    :class:`~himit_torch.learner.rows.RowTable` numbers rows by state, so each state's rows are
    consecutive; the kernel loops over that range instead of reading ``state_rows`` (one
    dependent load less per row in every backup)."""
    counts = (state_rows != num_rows).sum(1)
    begin = torch.zeros(state_rows.shape[0] + 1, dtype=torch.int64)
    begin[1:] = counts.cumsum(0)
    j = torch.arange(state_rows.shape[1])
    consecutive = torch.where(j < counts[:, None], begin[:-1, None] + j, num_rows)
    if not torch.equal(consecutive, state_rows.cpu()):
        raise RuntimeError("the compiled engine needs each state's rows numbered consecutively")
    return begin.numpy()


class NumbaEngine:
    """Compiled per-run loop on the CPU (see the module docstring)."""

    name = "numba"
    #: :meth:`advance` closes the windows it crosses (``Learner.run`` does it for the torch
    #: engine, between calls).
    closes_windows = True

    def __init__(self, state: BatchState):
        L = self.state = state
        B, S = L.batch, L.tables.num_states
        self.settings = kernel_settings(L)
        tables, rows = L.tables, L.rows
        table = tables.dynamics
        assert table is not None  # (make_engine checks it)
        self.world = WorldArrays(
            _np(table.successors.contiguous()),
            _np(table.cdf.contiguous()),
            _np(table.rewards.contiguous()),
            _np(tables.terminal),
            _np(tables.start_cdf) if tables.start_cdf is not None else np.ones(1),
            _np(tables.options.termination),
            _np(tables.options.policy)
            if tables.options.policy is not None
            else np.zeros(1, dtype=np.int8),
            _np(tables.options.policy_cdf)
            if tables.options.policy_cdf is not None
            else np.ones((1, 1)),
        )
        self.row_begin = _row_begin(rows.state_rows, rows.num_rows)
        J, A, R = rows.state_rows.shape[1], table.cdf.shape[1], L.sweeper.round_size
        self.scratch = Scratch(
            np.zeros((B, R), dtype=np.int64),
            np.zeros((B, R)),
            np.zeros((B, R)),
            np.zeros((B, R)),
            np.zeros((B, J)),
            np.zeros((B, J), dtype=np.bool_),
            np.zeros((B, J), dtype=np.bool_),
            np.zeros((B, A)),
        )
        self.heap = (
            np.zeros((B, S + 1), dtype=np.int64),
            np.zeros((B, S + 1)),
            np.zeros((B, S + 1), dtype=np.int64),
            np.zeros(B, dtype=np.int64),
        )
        self._links: dict[str, tuple] = {}
        self._seconds = np.zeros(B)  # each run's time in the last advance (_run_all's order)
        # NumPy views of the state's tensors, by tensor (each call hands the kernels ~85 of
        # them; making them anew cost ≈ 0.3 ms a window, a few % of one run's time)
        self._views: dict[int, tuple[torch.Tensor, np.ndarray]] = {}

    def _rows(self) -> RowArrays:
        rows = self.state.rows
        return RowArrays(
            self.row_begin,
            self._view(rows.row_state),
            self._view(rows.row_option),
            self._view(rows.row_first_action),
            self._view(rows.primitive_rows),
            self._view(rows.row_enabled),
            self._view(rows.use_mentor),
            self._view(rows.use_confidence),
            self._view(rows.use_sampling),
        )

    def _values_and_models(self) -> tuple[CacheArrays, OptionModelArrays, MentorModelArrays]:
        """What eq. 2 reads, as the kernels take it (the models with up-to-date linked lists)."""
        L = self.state
        cache, model, mentor = L.cache, L.model, L.mentor
        cache_arrays = CacheArrays(
            self._view(cache.values),
            self._view(cache.q_numerator),
            self._view(cache.q_second),
            self._view(cache.mentor_numerator),
            self._view(cache.mentor_second),
            self._view(cache.mentor_edge_reward),
            self._view(cache.mentor_edge_discount),
        )
        model_arrays = OptionModelArrays(
            self._view(model.edge_row),
            self._view(model.edge_successor),
            self._view(model.edge_count),
            self._view(model.edge_discount),
            self._view(model.num_edges),
            self._view(model.row_count),
            self._view(model.row_reward),
            self._view(model.state_tries),
            *self._linked("model", model),
        )
        mentor_arrays = MentorModelArrays(
            self._view(mentor.edge_row),
            self._view(mentor.edge_successor),
            self._view(mentor.edge_count),
            self._view(mentor.row_count),
            *self._linked("mentor", mentor),
        )
        return cache_arrays, model_arrays, mentor_arrays

    def mentor_wins(self) -> tuple[np.ndarray, np.ndarray]:
        """``([B], [B])``: per run, how many mentor-observed states the mentor term wins eq. 2
        in, and how many states some mentor was seen leaving."""
        out = np.zeros(self.state.batch, dtype=np.int64)
        seen = np.zeros(self.state.batch, dtype=np.int64)
        args = (self.settings, self.world, self._rows(), *self._values_and_models(), out, seen)
        _call(mentor_wins, *args)
        return out, seen

    def invalidate(self) -> None:
        """The state was changed outside this engine: relink before the next call."""
        self._links.clear()
        self._views.clear()

    def _view(self, x: torch.Tensor) -> np.ndarray:
        """``x``'s memory as a NumPy array (:func:`_np`), made once per tensor: the state's
        owners replace a tensor when it grows or is read back, never resize one in place, so a
        tensor's view stays its memory. The cache holds the tensor (so its ``id`` is not
        reused) and is emptied when it outgrows what one state holds."""
        hit = self._views.get(id(x))
        if hit is not None and hit[0] is x:
            return hit[1]
        if len(self._views) > 512:  # (tensors replaced by growth: drop them all, refill)
            self._views.clear()
        view = _np(x)
        self._views[id(x)] = (x, view)
        return view

    def _linked(self, key: str, store) -> tuple:
        """Linked lists over ``store``'s edges, rebuilt when its lists changed elsewhere."""
        cached = self._links.get(key)
        if (
            cached is not None
            and cached[0] == store.version
            and cached[1][1].shape[1] == store.capacity
        ):
            return cached[1]
        B, E = store.batch, store.capacity
        lists = (
            np.empty((B, store.num_rows + 1), dtype=np.int64),
            np.empty((B, E), dtype=np.int64),
            np.empty((B, store.num_states + 1), dtype=np.int64),
            np.empty((B, E), dtype=np.int64),
        )
        _call(
            link_edges,
            _np(store.edge_row),
            _np(store.edge_successor),
            _np(store.num_edges),
            *lists,
        )
        self._links[key] = (store.version, lists)
        return lists

    def advance(self, ticks: int) -> tuple[list[int], np.ndarray, np.ndarray]:
        """Carry out ``ticks`` ticks for every run, closing each window they end (its counters
        reset). Returns the closed windows: their ends, ``[W, B, len(WINDOW_COUNTS)]`` counts
        and ``[W, B]`` ε, in ``RunMetrics``' order."""
        if mentor_wins not in _called:
            # loaded (or compiled) at the first tick, as the loop, not in the middle of a run at
            # its first window's end; it only reads the state
            self.mentor_wins()
        L = self.state
        window = L.config.window
        t0, t_end = L.run.t, L.run.t + ticks
        ends = list(range((t0 // window + 1) * window, t_end + 1, window))
        windows = WindowArrays(
            np.zeros((L.batch, len(ends), len(WINDOW_COUNTS)), dtype=np.int64),
            np.zeros((L.batch, len(ends))),
            np.zeros(L.batch, dtype=np.int64),
        )
        t_reached = np.full(L.batch, t0, dtype=np.int64)
        model = L.model
        stops = [e for e in ends if e < t_end] + [t_end]
        while True:
            args = self._arguments(t_end, t_reached, windows)
            _run_all(stops, args[1:], self._seconds)
            # The kernel kept its linked lists in step with the edges it added.
            model.version += 1
            self._links["model"] = (model.version, tuple(args[6][-4:]))
            if (t_reached == t_end).all():
                break
            model.reserve(2 * model.capacity)  # some run filled its edge list: grow, go on
        L.run.t = t_end
        L.sweeper.queue.refresh_block_max()
        return ends, windows.counts.transpose(1, 0, 2), windows.epsilon.T

    def _arguments(self, t_stop: int, t_reached: np.ndarray, windows: WindowArrays) -> tuple:
        """``run_ticks``' arguments for a call that runs each run from ``t_reached`` to ``t_stop``."""
        L = self.state
        cache_arrays, model_arrays, mentor_arrays = self._values_and_models()
        run, sweeper, sample = L.run, L.sweeper, L.sample
        return (
            t_stop,
            t_reached,
            self.settings,
            self.world,
            self._rows(),
            cache_arrays,
            model_arrays,
            mentor_arrays,
            SweepArrays(
                *self.heap, self._view(sweeper.queue.priority), self._view(sweeper.pending)
            ),
            RunArrays(
                self._view(L.keys).view(np.uint64),
                self._view(run.position),
                self._view(run.option_start),
                self._view(run.row),
                self._view(run.duration),
                self._view(run.discounted_return),
                self._view(run.discount),
                self._view(run.epsilon),
                self._view(run.found_goal),
                self._view(run.goals),
                self._view(run.window_goals),
                self._view(run.episodes),
                self._view(run.episode_start),
                self._view(run.window_episode_steps),
                self._view(run.window_episodes),
                self._view(run.backups_done),
                self._view(run.decisions),
                self._view(run.first_goal_step),
                self._view(run.visits),
            ),
            SampleArrays(
                self._view(sample.option_w),
                self._view(sample.option_unseen),
                self._view(sample.mentor_w),
                self._view(sample.mentor_unseen),
                self._view(sample.resamples),
            ),
            ClonedArrays(self._view(L.cloning.action)),
            windows,
            self.scratch,
        )
