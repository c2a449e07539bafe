"""A batch on the compiled engine's threads: each run gets its own rows of the per-run arrays,
the small ones in copies whose rows start cache lines of their own, and the runs advance from
a shared queue, several windows a take while much is left and one at the end, stopping for a
full edge list. None of that may change a number."""

import numba
import numpy as np
import pytest
import torch

from himit_torch import Learner, LearnerConfig, learner_options
from himit_torch.learner.engines import numba_engine
from himit_torch.learner.engines.kernel.arrays import RowArrays, WorldArrays, map_per_run

AGENTS = ["imitation", "primitives", "options", "imitation_confident", "imitation"]


@pytest.mark.parametrize(
    ("shape", "dtype"),
    [((5,), np.int64), ((3,), np.bool_), ((4, 3), np.float64), ((3, 2, 9), np.int64),
     ((2, 17), np.bool_)],
)  # fmt: skip
def test_lined_copy_puts_each_runs_row_on_its_own_cache_lines(shape, dtype):
    x = (np.arange(np.prod(shape)) % 7).astype(dtype).reshape(shape)
    lined = numba_engine._lined(x)
    np.testing.assert_array_equal(lined, x)
    assert lined.dtype == x.dtype and lined.shape == x.shape
    starts = [lined[b:].ctypes.data for b in range(shape[0])]
    assert all(a % 64 == 0 for a in starts), starts
    # rows of different runs share no line: each ends before the next one's line begins
    assert all(b - a >= max(x[0].nbytes, 1) for a, b in zip(starts, starts[1:]))
    for b in range(shape[0]):  # one run's rows: contiguous, as a one-run batch's arrays
        assert lined[b : b + 1].flags.c_contiguous
    lined[-1] = 1  # a copy: the original is untouched
    assert not np.shares_memory(lined, x)


def test_map_per_run_cuts_the_per_run_arrays_and_leaves_the_shared_ones():
    world = WorldArrays(*(np.zeros(3) for _ in WorldArrays._fields))
    rows = RowArrays(*(np.zeros((2, 4)) for _ in RowArrays._fields))
    assert all(a is b for a, b in zip(map_per_run(world, lambda x: x[1:2]), world))
    cut = map_per_run(rows, lambda x: x[1:2])
    shared = {"row_begin", "row_state", "row_option", "row_first_action", "primitive_rows"}
    for name, before, after in zip(RowArrays._fields, rows, cut):
        assert (after is before) == (name in shared), name
        assert after.shape == ((2, 4) if name in shared else (1, 4))
    assert map_per_run(7, lambda x: x[1:2]) == 7
    np.testing.assert_array_equal(map_per_run(np.arange(4), lambda x: x[1:2]), [1])


def _learner(world, demos, agents, seeds) -> Learner:
    return Learner(
        world, learner_options(world), agents, seeds, config=LearnerConfig(window=500),
        demonstrations=demos, engine="numba",
    )  # fmt: skip


def _state(learner: Learner) -> dict:
    flat = {}

    def walk(prefix, value):
        if isinstance(value, dict):
            for k, v in value.items():
                walk(f"{prefix}.{k}", v)
        elif isinstance(value, torch.Tensor):
            flat[prefix] = value

    walk("", learner.state_dict())
    return flat


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two Numba threads")
def test_a_batch_on_two_threads_equals_one_thread_and_each_run_alone(world12, mentor_demos12):
    seeds = [3, 0, 1, 2, 3]
    before = numba.get_num_threads()
    try:
        runs = {}
        for threads in (1, 2):
            numba.set_num_threads(threads)
            learner = _learner(world12, mentor_demos12, AGENTS, seeds)
            for ticks in (1700, 2300):  # (a window's end inside a call, and between calls)
                learner.run(ticks)
            runs[threads] = learner
    finally:
        numba.set_num_threads(before)
    one, two = _state(runs[1]), _state(runs[2])
    assert one.keys() == two.keys() and len(one) > 20
    for name in one:
        torch.testing.assert_close(one[name], two[name], rtol=0, atol=0, equal_nan=True)
    assert int(runs[2].run_state.goals.sum()) > 0  # (the runs got somewhere)
    # (the edge lists grew on the way: some run stopped short for it, on two threads too)
    assert runs[2].model.capacity > 256
    # the batch's first run is the same as that run alone (no batch: whole arrays, one call)
    alone = _learner(world12, mentor_demos12, AGENTS[:1], seeds[:1])
    alone.run(4000)
    for field in ("position", "goals", "decisions", "backups_done", "epsilon"):
        got = getattr(runs[2].run_state, field)[0]
        torch.testing.assert_close(got, getattr(alone.run_state, field)[0], rtol=0, atol=0)
    torch.testing.assert_close(runs[2].cache.values[0], alone.cache.values[0], rtol=0, atol=0)


@pytest.mark.skipif(numba.config.NUMBA_NUM_THREADS < 2, reason="needs two Numba threads")
def test_a_batch_taking_a_second_thread_mid_run_equals_one_thread_throughout(
    world12, mentor_demos12
):
    """A pool's lane takes the cores of lanes that ended between two windows of its batch
    (``runs.runner.take_ended_lanes_cores``): the batch goes on from one thread to two."""
    seeds = [3, 0, 1, 2, 3]
    before = numba.get_num_threads()
    try:
        runs = {}
        for switch in (False, True):
            numba.set_num_threads(1)
            learner = _learner(world12, mentor_demos12, AGENTS, seeds)
            learner.run(1500)  # (three windows of 500)
            numba.set_num_threads(2 if switch else 1)
            learner.run(2500)
            runs[switch] = learner
    finally:
        numba.set_num_threads(before)
    one, switched = _state(runs[False]), _state(runs[True])
    assert one.keys() == switched.keys() and len(one) > 20
    for name in one:
        torch.testing.assert_close(one[name], switched[name], rtol=0, atol=0, equal_nan=True)
    assert int(runs[True].run_state.goals.sum()) > 0


@pytest.mark.parametrize(
    ("left", "threads", "take"),
    [(40, 1, 20), (41, 1, 21), (40, 2, 10), (3, 2, 1), (4, 2, 1), (5, 2, 2), (1, 4, 1), (0, 2, 1)],
)
def test_stops_per_take_is_a_2_threads_th_of_the_stops_left_at_least_one(left, threads, take):
    assert numba_engine._stops_per_take(left, threads) == take


def _scheduled(monkeypatch, stops, batch, short=None):
    """``_run_each`` on one thread (a fixed order) with a kernel that records each call as
    ``(run, from, to)`` and goes to its stop, or, for ``short = (run, tick)``, stops that run's
    first call at ``tick`` as a full edge list does. Returns the calls and where each run is."""
    calls = []

    def kernel(stop, t_reached, run):
        b, t = int(run[0, 0]), int(t_reached[0])
        end = short[1] if short is not None and b == short[0] and not calls_of(b) else stop
        calls.append((b, t, end))
        t_reached[0] = end

    def calls_of(b):
        return [c for c in calls if c[0] == b]

    monkeypatch.setattr(numba_engine, "run_ticks", kernel)
    monkeypatch.setattr(numba_engine, "_called", {kernel})
    t_reached = np.zeros(batch, dtype=np.int64)
    numba_engine._run_each(1, stops, (t_reached, np.arange(batch)[:, None]), np.zeros(batch))
    return calls, t_reached.tolist()


def test_runs_go_whole_while_much_is_left_and_a_few_stops_at_a_time_at_the_end(monkeypatch):
    calls, reached = _scheduled(monkeypatch, list(range(100, 1001, 100)), 4)
    # 40 stops left: run 0 may take 20 (all its 10), then 30 → 15, 20 → 10 (whole runs);
    # 10 left → 5, then 5 → 3, 2 → 1, 1 → 1
    assert calls == [
        (0, 0, 1000), (1, 0, 1000), (2, 0, 1000),
        (3, 0, 500), (3, 500, 800), (3, 800, 900), (3, 900, 1000),
    ]  # fmt: skip
    assert reached == [1000] * 4


def test_a_full_edge_list_stops_the_queue_so_the_lists_grow_at_once(monkeypatch):
    calls, reached = _scheduled(monkeypatch, list(range(100, 1001, 100)), 4, short=(1, 250))
    # run 1 stops short at tick 250: no run is taken after it; the caller grows, calls again
    assert calls == [(0, 0, 1000), (1, 0, 250)]
    assert reached == [1000, 250, 0, 0]


def test_after_a_full_list_a_thread_goes_on_a_window_at_a_time_while_another_ends_its_take(
    monkeypatch,
):
    # Two threads, four runs of ten stops, run 0 first (the slowest last time): one thread takes
    # run 0 whole and is held in it; the other takes run 1, whose list fills at once. That one
    # must not wait idle for run 0's take: it runs the others a window at a time (the third
    # such call lets run 0 end), and both stop once no thread is in a run (run 1 stays short).
    import threading

    stops = list(range(100, 1001, 100))
    calls, singles, release = [], [], threading.Event()

    def kernel(stop, t_reached, run):
        b, t = int(run[0, 0]), int(t_reached[0])
        if b == 0:
            release.wait(timeout=5)
        end = 150 if b == 1 and t == 0 else stop
        calls.append((b, t, end))
        if b in (2, 3):
            singles.append((b, t, end))
            if len(singles) == 3:
                release.set()
        t_reached[0] = end

    monkeypatch.setattr(numba_engine, "run_ticks", kernel)
    monkeypatch.setattr(numba_engine, "_called", {kernel})
    t_reached = np.zeros(4, dtype=np.int64)
    seconds = np.array([4.0, 3.0, 2.0, 1.0])
    numba_engine._run_each(2, stops, (t_reached, np.arange(4)[:, None]), seconds)
    assert release.is_set(), calls  # the other runs went on while run 0 ran
    assert (0, 0, 1000) in calls and (1, 0, 150) in calls
    # a window at a time after the full list (how many before run 0's thread wakes: timing)
    assert all(end - t == 100 for _, t, end in singles), singles
    assert t_reached[0] == 1000 and t_reached[1] == 150
