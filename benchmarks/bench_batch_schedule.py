"""16 mixed runs on both cores, taken a window at a time against the guided takes, alternating
in one process: what the compiled engine's schedule (``numba_engine._stops_per_take``) is worth.

The batch of ``bench_scaling.py`` (imitation / options / primitives in turn, seeds 0…15, the
40×40 world with 10 rooms, the experiments' planning; 20,000 untimed steps, then
``learner.run(--steps)`` timed, in one call). Each repeat times a fresh learner with the
engine's schedule as it is (a run taken goes a ``2 × threads``-th of the stops the queued runs
have left: whole runs first, a window at a time at the end) and one whose every take is one
window, as before (the private function replaced for that learner's run). Both give the same
numbers to the bit (``tests/learner/engines/test_threads.py``); only the time differs. Prints
each repeat's seconds and the speed-up, and their median.

    python benchmarks/bench_batch_schedule.py [--reps 9] [--steps 100000] [--batch 16]
"""

import argparse
import statistics

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--reps", type=int, default=9)
parser.add_argument("--steps", type=int, default=100_000, help="timed steps per run")
parser.add_argument("--batch", type=int, default=16)
args = parser.parse_args()

import numba  # noqa: E402
from mixed_batch import timed  # noqa: E402

from himit_torch.learner.engines import numba_engine  # noqa: E402

GUIDED = numba_engine._stops_per_take


def window_at_a_time(stops_left: int, threads: int) -> int:
    return 1


def timed_with(take, steps: int) -> float:
    """Seconds of ``steps`` timed steps of a fresh batch whose runs go ``take`` stops a take."""
    numba_engine._stops_per_take = take
    try:
        return timed(list(range(args.batch)), steps)
    finally:
        numba_engine._stops_per_take = GUIDED


print(f"{args.batch} runs on {numba.get_num_threads()} threads, {args.steps:,} timed steps each")
timed_with(GUIDED, 1000)  # (kernels loaded, pool started)
speedups = []
for rep in range(args.reps):
    if rep % 2 == 0:  # (alternating which goes first)
        old, new = timed_with(window_at_a_time, args.steps), timed_with(GUIDED, args.steps)
    else:
        new, old = timed_with(GUIDED, args.steps), timed_with(window_at_a_time, args.steps)
    speedups.append(old / new)
    print(f"rep {rep}: a window at a time {old:.3f} s, guided {new:.3f} s, "
          f"speed-up {speedups[-1]:.3f}", flush=True)  # fmt: skip
print(f"MEDIAN of {args.reps}: guided takes {statistics.median(speedups):.3f}× the rate of a "
      f"window at a time (range {min(speedups):.3f}-{max(speedups):.3f})")  # fmt: skip
