"""The compiled engine: the learner's ticks as one Numba kernel per run, the runs on threads.

The kernel (:mod:`himit_torch.learner.engines._kernel`) works in place on the memory of the learner's
tensors (``Tensor.numpy()`` shares it), plus two derived structures the engine owns: linked lists
over each run's model edges (rebuilt from the edge lists whenever they changed elsewhere) and an
indexed max-heap over the sweep priorities (rebuilt from them at every call). Kernels are cached
on disk (Numba ``cache=True``): a second process does not compile again, and processes that
start together compile once (:func:`prepare_kernels`).
"""

from __future__ import annotations

import hashlib
import tempfile
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from pathlib import Path

import numba
import numpy as np
import torch

from himit_torch.learner.engines import _kernel
from himit_torch.learner.state import BatchState

__all__ = ["NumbaEngine", "prepare_kernels", "kernels_prepared_here"]


def _np(x: torch.Tensor) -> np.ndarray:
    return x.detach().numpy()


_pool: ThreadPoolExecutor | None = None
_pool_size = 0  # its worker threads (ThreadPoolExecutor keeps the number private)


def _run_all(batch: int, args: tuple) -> None:
    """``_kernel._run(b, *args)`` for every run ``b`` of the batch, on up to
    ``numba.get_num_threads()`` threads (this one included), never more than ``batch``.

    The runs are independent (each touches only its own row of every per-run array), so which
    thread runs which does not change anything. ``_run`` releases the GIL (``nogil``); threads
    take the next run as they finish one (runs differ in cost: an imitator plans more than a
    primitives-only run). Python threads rather than a ``prange`` loop around ``_run``: the
    parallel wrapper of a function with ≈ 90 array arguments took ≈ 13 s to compile, over a
    third of a cold start, and a call from here costs ≈ 0.1 ms per run."""
    global _pool, _pool_size
    threads = max(1, min(batch, numba.get_num_threads()))
    if threads == 1:  # (B = 1: no thread to wait for)
        for b in range(batch):
            _kernel._run(b, *args)
        return
    runs = iter(range(batch))
    lock = threading.Lock()

    def work() -> None:
        while True:
            with lock:
                b = next(runs, None)
            if b is None:
                return
            _kernel._run(b, *args)

    if _pool is None or _pool_size < threads - 1:
        if _pool is not None:  # (more threads were allowed since: a larger pool)
            _pool.shutdown(wait=False)
        _pool = ThreadPoolExecutor(threads - 1, thread_name_prefix="himit-run")
        _pool_size = threads - 1
    helpers = [_pool.submit(work) for _ in range(threads - 1)]
    try:
        work()
    finally:
        for h in helpers:
            h.result()


# ------------------------------------------------------------------------ compiling once
_kernels_ready = False
_kernels_guard = threading.Lock()


def _lock_path() -> Path:
    """The lock file of this kernel cache (Numba's ``NUMBA_CACHE_DIR``, or beside the kernel's
    source when that is unset): processes sharing a cache share the lock."""
    cache = numba.config.CACHE_DIR or str(Path(_kernel.__file__).resolve().parent)  # type: ignore[attr-defined]
    digest = hashlib.sha256(cache.encode()).hexdigest()[:16]
    return Path(tempfile.gettempdir()) / f"himit_torch-kernels-{digest}.lock"


@contextmanager
def _cache_lock() -> Iterator[None]:
    """Hold the kernel cache's lock (an ``flock`` on :func:`_lock_path`; no lock where ``fcntl``
    does not exist: there each process compiles on its own, as before)."""
    try:
        import fcntl
    except ImportError:
        yield
        return
    with open(_lock_path(), "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _run_tiny_learner() -> None:
    """Call every kernel once, with the argument types every learner passes: a few hundred ticks
    of an imitator and a posterior-sampling imitator on an 8×8 world, to a window's end."""
    from himit_torch.learner.config import LearnerConfig
    from himit_torch.learner.learner import Learner
    from himit_torch.mentor.policy import mentor_policy, record_demonstrations
    from himit_torch.options.builders import learner_options, mentor_options
    from himit_torch.worlds.multirooms import MultiRooms

    world = MultiRooms(8, 2)
    demonstrations = record_demonstrations(
        world, mentor_policy(world, mentor_options(world)), 1, seed=0
    )
    learner = Learner(
        world,
        learner_options(world),
        ["imitation", "imitation_psrl"],
        [0, 0],
        LearnerConfig(window=200),
        demonstrations=demonstrations,
        engine="numba",
    )
    learner.run(200)


def _prepare_locked() -> None:
    global _kernels_ready
    with _kernels_guard:
        if _kernels_ready:
            return
        _kernels_ready = True  # (the tiny learner's own calls must not come back here)
        try:
            _run_tiny_learner()
        except BaseException:
            _kernels_ready = False
            raise


def prepare_kernels() -> float:
    """Load the compiled kernels into this process — compiling them first if Numba's disk cache
    has none — and return the seconds it took (0 once they are loaded).

    One process compiles at a time per cache: another process that gets here meanwhile waits
    for it, then loads what it cached, instead of compiling the same kernels on a core the
    first one needs (a cold start of two world processes compiles once, not twice). The engine
    calls this at its first tick; :func:`kernels_prepared_here` lets a parent process compile
    while the processes it starts set up."""
    if _kernels_ready:
        return 0.0
    start = time.perf_counter()
    with _cache_lock():
        _prepare_locked()
    return time.perf_counter() - start


@contextmanager
def kernels_prepared_here() -> Iterator[None]:
    """Take the kernel cache's lock now, and at the end of the block load (or compile) the
    kernels in this process before letting it go. Processes started inside the block wait at
    their first tick until then, and load the kernels from the cache instead of compiling them
    too (``run_experiments`` starts its world processes this way)."""
    with _cache_lock():
        yield
        _prepare_locked()


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

    def __init__(self, state: BatchState):
        L = self.state = state
        cfg = L.config
        B, S = L.batch, L.tables.num_states
        cfg_f = np.zeros(_kernel.N_CFG_F)
        cfg_f[_kernel.F_GAMMA] = L.tables.gamma
        cfg_f[_kernel.F_EPS_DECAY] = cfg.eps_decay
        cfg_f[_kernel.F_EPS_MIN] = cfg.eps_min
        cfg_f[_kernel.F_THRESHOLD] = cfg.priority_threshold
        cfg_f[_kernel.F_V0] = cfg.initial_value
        cfg_f[_kernel.F_CONC] = cfg.concentration
        cfg_f[_kernel.F_MCONC] = cfg.mentor_concentration
        cfg_f[_kernel.F_UNTRIED] = 0.0 if cfg.untried_value is None else cfg.untried_value
        cfg_f[_kernel.F_Z] = cfg.confidence_z
        cfg_i = np.zeros(_kernel.N_CFG_I, dtype=np.int64)
        cfg_i[_kernel.I_BACKUPS] = cfg.backups
        cfg_i[_kernel.I_ROUND] = L.sweeper.round_size
        cfg_i[_kernel.I_PLAN_EVERY] = cfg.plan_every
        cfg_i[_kernel.I_MAX_STEPS] = cfg.max_option_steps
        cfg_i[_kernel.I_UNTRIED_MODE] = (
            0 if cfg.concentration > 0 else (1 if cfg.untried_value is None else 2)
        )
        cfg_i[_kernel.I_OVERRIDE] = (
            -1 if cfg.mentor_override_after is None else cfg.mentor_override_after
        )
        cfg_i[_kernel.I_MATCH] = cfg.mentor_choice == "match"
        cfg_i[_kernel.I_TIE_FIRST] = cfg.tie_break == "first"
        cfg_i[_kernel.I_ANY_CONF] = L.cache.any_confidence
        cfg_i[_kernel.I_ANY_MENTOR] = L.cache.any_mentor
        cfg_i[_kernel.I_STOCHASTIC] = L.tables.policy is None
        cfg_i[_kernel.I_START] = -1 if L.tables.start_cdf is not None else L.tables.start_state
        from himit_torch.learner.config import EPS_SCHEDULES

        cfg_i[_kernel.I_EPS_SCHEDULE] = EPS_SCHEDULES.index(cfg.eps_schedule)
        cfg_i[_kernel.I_EPS_GOALS] = cfg.eps_goals
        cfg_f[_kernel.F_FADE] = 0.0 if cfg.mentor_fade is None else cfg.mentor_fade
        cfg_i[_kernel.I_RESAMPLE_EVERY] = cfg.resample_every
        self.cfg_f, self.cfg_i = cfg_f, cfg_i

        table = L.tables.dynamics
        rows = L.rows
        self.row_begin = _row_begin(rows.state_rows, rows.num_rows)
        self.static = (
            _np(table.successors.contiguous()),
            _np(table.cdf.contiguous()),
            _np(table.rewards.contiguous()),
            _np(L.tables.terminal),
            _np(L.tables.start_cdf) if L.tables.start_cdf is not None else np.ones(1),
            _np(L.tables.termination),
            _np(L.tables.policy) if L.tables.policy is not None else np.zeros(1, dtype=np.int8),
            _np(L.tables.policy_cdf) if L.tables.policy_cdf is not None else np.ones((1, 1)),
            self.row_begin,
            _np(rows.row_state),
            _np(rows.row_option),
            _np(rows.row_first_action),
            _np(rows.primitive_rows),
            _np(rows.row_enabled),
            _np(rows.use_mentor),
            _np(rows.use_confidence),
        )
        self.keys = _np(L.keys).view(np.uint64)
        J, A, R = rows.state_rows.shape[1], table.cdf.shape[1], L.sweeper.round_size
        self.scratch = (
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

    def mentor_wins(self) -> torch.Tensor:
        """``[B]`` how many mentor-observed states the mentor term wins eq. 2 in, per run."""
        prepare_kernels()
        L = self.state
        cache, model, rows = L.cache, L.model, L.rows
        out = np.zeros(L.batch, dtype=np.int64)
        _kernel.mentor_wins(
            self.cfg_f,
            self.cfg_i,
            self.row_begin,
            _np(L.tables.terminal),
            _np(rows.use_mentor),
            _np(rows.use_confidence),
            _np(cache.q_numerator),
            _np(cache.q_second),
            _np(model.row_count),
            _np(model.row_reward),
            _np(rows.row_enabled),
            _np(model.state_tries),
            _np(cache.mentor_numerator),
            _np(cache.mentor_second),
            _np(L.mentor.row_count),
            out,
        )
        return torch.from_numpy(out)

    def invalidate(self) -> None:
        """The state was changed outside this engine: relink before the next call."""
        self._links.clear()

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
        _kernel.link_edges(
            _np(store.edge_row), _np(store.edge_successor), _np(store.num_edges), *lists
        )
        self._links[key] = (store.version, lists)
        return lists

    def advance(self, ticks: int) -> None:
        """Carry out ``ticks`` ticks for every run (no window boundary inside)."""
        prepare_kernels()
        L = self.state
        t_end = L.run.t + ticks
        t_reached = np.full(L.batch, L.run.t, dtype=np.int64)
        model, mentor, cache, run, sweeper = L.model, L.mentor, L.cache, L.run, L.sweeper
        while True:
            option_links = self._linked("model", model)
            mentor_links = self._linked("mentor", mentor)
            _run_all(
                L.batch,
                (
                    t_end,
                    t_reached,
                    self.keys,
                    self.cfg_f,
                    self.cfg_i,
                    *self.static,
                    _np(cache.values),
                    _np(cache.q_numerator),
                    _np(cache.q_second),
                    _np(cache.mentor_numerator),
                    _np(cache.mentor_second),
                    _np(cache.mentor_edge_reward),
                    _np(model.edge_row),
                    _np(model.edge_successor),
                    _np(model.edge_count),
                    _np(model.edge_discount),
                    _np(model.num_edges),
                    _np(model.row_count),
                    _np(model.row_reward),
                    _np(model.state_tries),
                    *option_links,
                    _np(mentor.edge_row),
                    _np(mentor.edge_successor),
                    _np(mentor.edge_count),
                    _np(mentor.row_count),
                    *mentor_links,
                    _np(sweeper.pending),
                    *self.heap,
                    _np(sweeper.queue.priority),
                    _np(run.position),
                    _np(run.option_start),
                    _np(run.row),
                    _np(run.duration),
                    _np(run.discounted_return),
                    _np(run.discount),
                    _np(run.epsilon),
                    _np(run.found_goal),
                    _np(run.goals),
                    _np(run.window_goals),
                    _np(run.episodes),
                    _np(run.episode_start),
                    _np(run.window_episode_steps),
                    _np(run.window_episodes),
                    _np(run.backups_done),
                    _np(run.decisions),
                    _np(run.first_goal_step),
                    _np(run.visits),
                    _np(L.rows.use_sampling),
                    _np(L.sample.option_w),
                    _np(L.sample.option_unseen),
                    _np(L.sample.mentor_w),
                    _np(L.sample.mentor_unseen),
                    _np(L.sample.resamples),
                    *self.scratch,
                ),
            )
            # The kernel kept its linked lists in step with the edges it added.
            model.version += 1
            self._links["model"] = (model.version, option_links)
            if (t_reached == t_end).all():
                break
            model.reserve(2 * model.capacity)  # some run filled its edge list: grow, go on
        run.t = t_end
        sweeper.queue.refresh_block_max()
