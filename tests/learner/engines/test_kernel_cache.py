"""The compiled engine's kernels are compiled once per cache: a process that needs them while
another compiles waits and loads them, and the warm-up compiles what real learners call."""

import subprocess
import sys
import time

import pytest

from himit_torch.learner.engines import numba_available

pytestmark = pytest.mark.skipif(not numba_available(), reason="numba is not installed")

WAITER = """
import sys, time
from himit_torch.runs.kernels import prepare_kernels
print("waiting", flush=True)
prepare_kernels()
print(time.time(), flush=True)
"""


# (two fresh interpreters that load the kernels, ≈ 8 s: CI's)
@pytest.mark.slow
def test_a_process_waits_for_the_one_preparing_the_kernels():
    from himit_torch.runs.kernels import kernels_prepared_here, prepare_kernels

    prepare_kernels()  # the cache is warm: the other process only has to load
    with kernels_prepared_here():
        waiter = subprocess.Popen([sys.executable, "-c", WAITER], stdout=subprocess.PIPE, text=True)
        assert waiter.stdout is not None
        assert waiter.stdout.readline().strip() == "waiting"
        time.sleep(1.5)  # it is now at the lock (or about to be)
        released = time.time()
    out, _ = waiter.communicate(timeout=120)
    assert waiter.returncode == 0
    assert float(out.strip()) >= released


def test_the_warm_up_compiles_the_signatures_real_learners_use(world12):
    """After :func:`prepare_kernels`, an experiment-like batch (corner options, every agent kind,
    demonstrations) calls no kernel with new argument types, so it compiles nothing."""
    from himit_torch.learner import cloned_refit
    from himit_torch.learner.config import LearnerConfig
    from himit_torch.learner.engines.numba_engine import KERNELS
    from himit_torch.learner.learner import Learner
    from himit_torch.mentor.policy import mentor_policy, record_demonstrations
    from himit_torch.options.builders import learner_options, mentor_options
    from himit_torch.runs.kernels import prepare_kernels

    prepare_kernels()
    # (the loop's callees, e.g. ``resample``, are compiled into it: not called from Python)
    kernels = [*KERNELS, cloned_refit._refit]
    before = [list(k.signatures) for k in kernels]
    assert all(len(s) >= 1 for s in before)
    demos = record_demonstrations(
        world12, mentor_policy(world12, mentor_options(world12)), 2, seed=1
    )
    agents = ["imitation", "imitation_confident", "options", "primitives", "options_psrl", "bco"]
    learner = Learner(
        world12,
        learner_options(world12, corners=True),
        agents,
        list(range(len(agents))),
        LearnerConfig(window=500, plan_every=4, sweep_rounds=1),
        demonstrations=demos,
        engine="numba",
    )
    learner.run(1000)
    assert [list(k.signatures) for k in kernels] == before
