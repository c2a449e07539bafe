"""What two threads can get from this machine's two cores: the ceiling of ``bench_scaling.py``.

``bench_scaling.py`` asks 16 runs on two cores for ≥ 1.8× one run's rate. On a virtual machine
the two cores may not give twice one core's work, whatever the program: the hypervisor may put
them on one physical core's two hardware threads, slow the clock when both are busy, or take
time from one (steal). This script measures that ceiling with work that shares nothing: a
compiled loop (Numba, ``nogil``) called from Python threads, as the compiled engine calls its
kernel (``himit_torch.learner.engines.numba_engine``), in two kinds:

- ``compute``: integer arithmetic in registers, no memory traffic;
- ``memory``: dependent random reads over a private 64 MiB table per thread (past each core's
  L2, through the shared L3 and memory), the learner's kind of access at its worst.

Each repeat times one call alone on one thread, then two calls on two threads at once
(alternating which goes first), and reports ``2 × alone / together``: 2.0 is a perfect second
core. The ceiling is the median of the repeats' ratios. Run it beside ``bench_scaling.py`` in the
same session: the machine's load moves both.

    python benchmarks/bench_host_scaling.py [--reps 9] [--seconds 0.5]
"""

import argparse
import statistics
import threading
import time

import numba
import numpy as np

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--reps", type=int, default=9)
parser.add_argument("--seconds", type=float, default=0.5, help="one call's length, roughly")
args = parser.parse_args()


@numba.njit(nogil=True, cache=False)
def compute(n: int) -> int:
    """``n`` rounds of a 64-bit linear congruential generator (registers only)."""
    x = np.uint64(12345)
    a, c = np.uint64(6364136223846793005), np.uint64(1442695040888963407)
    for _ in range(n):
        x = a * x + c
    return int(x >> np.uint64(33))


@numba.njit(nogil=True, cache=False)
def memory(table: np.ndarray, n: int) -> int:
    """``n`` dependent reads of ``table`` (each index the last read's value: no prefetching)."""
    i = 0
    for _ in range(n):
        i = table[i]
    return i


def permutation_cycle(size: int, seed: int) -> np.ndarray:
    """A table whose reads ``i → table[i]`` walk one cycle through all ``size`` entries."""
    order = np.random.default_rng(seed).permutation(size)
    table = np.empty(size, dtype=np.int64)
    table[order[:-1]] = order[1:]
    table[order[-1]] = order[0]
    return table


def together(calls) -> float:
    """Seconds for ``calls`` (zero-argument callables) run on threads of their own at once."""
    threads = [threading.Thread(target=c) for c in calls]
    began = time.perf_counter()
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return time.perf_counter() - began


def calibrate(call, seconds: float) -> int:
    """The ``n`` for which ``call(n)`` takes about ``seconds``."""
    n = 1_000_000
    while True:
        began = time.perf_counter()
        call(n)
        took = time.perf_counter() - began
        if took > 0.05:
            return max(1, int(n * seconds / took))
        n *= 4


def ceiling(kind: str, first, second) -> None:
    """Print each repeat's ``2 × alone / together`` for ``first`` and ``second`` (callables of
    ``n``), and their median."""
    first(1000), second(1000)  # compile
    n = calibrate(first, args.seconds)
    pair = [lambda: first(n), lambda: second(n)]
    ratios = []
    for rep in range(args.reps):
        if rep % 2:  # (alternating which goes first)
            t2, t1 = together(pair), together(pair[:1])
        else:
            t1, t2 = together(pair[:1]), together(pair)
        ratios.append(2 * t1 / t2)
        print(f"{kind} rep {rep}: alone {t1:.3f} s, two at once {t2:.3f} s, ratio {ratios[-1]:.3f}")
    print(
        f"MEDIAN of {args.reps}: {kind}, two threads give {statistics.median(ratios):.2f}× one "
        f"(range {min(ratios):.2f}-{max(ratios):.2f})"
    )


tables = [permutation_cycle(8 << 20, seed) for seed in (0, 1)]  # 8 Mi int64 = 64 MiB each
ceiling("compute", compute, compute)
ceiling("memory", lambda n: memory(tables[0], n), lambda n: memory(tables[1], n))
