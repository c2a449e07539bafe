"""The mixed batch of the scaling benchmarks (``bench_scaling.py``, ``bench_batch_schedule.py``):
imitation / options / primitives in turn, one seed per run, on the 40×40 world with 10 rooms,
watching one mentor's 20 episodes, with the experiments' planning (``plan_every = 4``,
``sweep_rounds = 1``), on the compiled engine. Imported by those scripts (their folder is on
``sys.path`` when run as ``python benchmarks/…``), not a script itself."""

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import torch  # noqa: E402

from himit_torch import (  # noqa: E402
    Learner,
    LearnerConfig,
    MultiRooms,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)

torch.set_num_threads(1)
world = MultiRooms(40, 10)
demos = record_demonstrations(world, mentor_policy(world, mentor_options(world, False)), 20, seed=0)
options = learner_options(world)
config = LearnerConfig(plan_every=4, sweep_rounds=1)
MIX = ["imitation", "options", "primitives"]


def timed(runs: list[int], steps: int) -> float:
    """Seconds of ``steps`` timed steps (``learner.run(steps)``, one call) of a fresh learner of
    the mix's ``runs`` (run ``b``: agent ``MIX[b % 3]``, seed ``b``), after 20,000 untimed
    steps (past the first goals)."""
    learner = Learner(world, options, [MIX[b % 3] for b in runs], runs,
                      demonstrations=demos, config=config, engine="numba")  # fmt: skip
    learner.run(20_000)
    began = time.perf_counter()
    learner.run(steps)
    return time.perf_counter() - began
