"""The pool's lanes take the cores of the lanes that ended (``runs.pool``, ``runs.runner``)."""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path

import pytest
import torch

from himit_torch.runs.pool import run_pool
from himit_torch.runs.runner import join_lanes, share_cores, take_ended_lanes_cores

numba = pytest.importorskip("numba")
two_threads = pytest.mark.skipif(
    numba.config.NUMBA_NUM_THREADS < 2, reason="needs two Numba threads"
)


@pytest.fixture
def own_threads():
    before = numba.get_num_threads(), torch.get_num_threads()
    yield
    join_lanes(None, 1, 1)
    numba.set_num_threads(before[0])
    torch.set_num_threads(before[1])


@two_threads
def test_a_lane_takes_the_cores_of_the_lanes_that_ended(own_threads):
    working = multiprocessing.Value("i", 2)
    share_cores(1)
    join_lanes(working, 2, 1)
    take_ended_lanes_cores()
    assert numba.get_num_threads() == 1  # both lanes working: its share
    with working.get_lock():
        working.value = 1
    take_ended_lanes_cores()
    assert numba.get_num_threads() == 2 and torch.get_num_threads() == 1
    with working.get_lock():
        working.value = 0  # (the last lane itself ending) never fewer threads, nor more cores
    take_ended_lanes_cores()
    assert numba.get_num_threads() == 2


@two_threads
def test_outside_a_pool_the_threads_are_left_alone(own_threads):
    numba.set_num_threads(1)
    take_ended_lanes_cores()
    assert numba.get_num_threads() == 1


def _wait_for_cores(flag: str, seconds: float = 120.0) -> int:
    """A job that waits for two threads (taking ended lanes' cores as a batch does between
    windows); returns the threads it reached."""
    Path(flag).touch()
    deadline = time.monotonic() + seconds
    while numba.get_num_threads() < 2 and time.monotonic() < deadline:
        take_ended_lanes_cores()
        time.sleep(0.05)
    return numba.get_num_threads()


def _call(job, *args):
    return job(*args)


def _short(flag: str, seconds: float = 120.0) -> int:
    """A job that ends once the other lane's job has started (so that it is not taken here)."""
    deadline = time.monotonic() + seconds
    while not Path(flag).exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    return numba.get_num_threads()


@pytest.mark.slow
@two_threads
def test_the_pools_last_lane_runs_on_the_cores_of_the_lanes_that_ended(tmp_path, own_threads):
    """Two lanes on a machine seen as two cores: each job starts on one thread, and the job
    left running once the other lane has ended reaches two, in this process's lane and in the
    other process's."""
    if (multiprocessing.cpu_count() or 1) < 2:
        pytest.skip("needs two cores")
    for first, second, longer in ((_wait_for_cores, _short, "a"), (_short, _wait_for_cores, "b")):
        flag = str(tmp_path / f"started-{longer}")
        got: dict = {}
        # this process takes the first job; the other lane (a process of its own) the second
        run_pool(
            _call,
            [("first", (first, flag)), ("second", (second, flag))],
            2,
            got.__setitem__,
        )
        longest = "first" if longer == "a" else "second"
        assert got[longest] == 2, got
