"""Enumerating a MiniGrid task's reachable states (``from_minigrid``): the state read and set
directly, against a breadth-first search that deep-copies the environment at every state (the
obvious way), side by side in one process.

Prints, per repeat, the seconds of ``from_minigrid`` on DoorKey-5x5 and of the deep-copy search
on the same task (both step MiniGrid's own ``step``; the deep-copy search keeps MiniGrid's
observations, as a plain use of the env would), their ratio, and ``from_minigrid`` on
DoorKey-8x8 (the bound: ≤ 5 s on 2 cores); then the medians. It also checks the states found:
the same number both ways on DoorKey-5x5, and on each task the count of non-terminal states
against the breadth-first counts known beforehand (260 and 9,152 with seed 0).

    python benchmarks/bench_minigrid_enumeration.py [--repeats 3]
"""

import argparse
import copy
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--repeats", type=int, default=3)
args = parser.parse_args()

import gymnasium  # noqa: E402

from himit_torch import from_minigrid  # noqa: E402

KNOWN = {"MiniGrid-DoorKey-5x5-v0": 260, "MiniGrid-DoorKey-8x8-v0": 9152}


def state_of(env) -> tuple:
    """The full state of a MiniGrid env, by value (for the deep-copy search's set of seen)."""
    cells = tuple(
        None
        if c is None
        else (c.type, c.color, getattr(c, "is_open", None), c.__dict__.get("is_locked"))
        for c in env.grid.grid
    )
    carried = None if env.carrying is None else (env.carrying.type, env.carrying.color)
    return (tuple(env.agent_pos), env.agent_dir, carried, cells)


def deep_copy_search(env_id: str) -> int:
    """Breadth first over MiniGrid's step, each successor from a deep copy of the env."""
    env = gymnasium.make(env_id).unwrapped
    env.reset(seed=0)
    seen = {state_of(env)}
    frontier, live = [env], 0
    while frontier:
        nxt = []
        for e in frontier:
            live += 1
            for a in range(6):
                twin = copy.deepcopy(e)
                _, _, terminated, _, _ = twin.step(a)
                key = state_of(twin)
                if key not in seen:
                    seen.add(key)
                    if not terminated:
                        nxt.append(twin)
        frontier = nxt
    return live


def timed(f, *a, **k):
    t0 = time.perf_counter()
    out = f(*a, **k)
    return time.perf_counter() - t0, out


from_minigrid("MiniGrid-DoorKey-5x5-v0")  # import MiniGrid and pygame once, outside the timing
rows = []
for r in range(args.repeats):
    fast, small = timed(from_minigrid, "MiniGrid-DoorKey-5x5-v0")
    slow, live = timed(deep_copy_search, "MiniGrid-DoorKey-5x5-v0")
    big_s, big = timed(from_minigrid, "MiniGrid-DoorKey-8x8-v0")
    small_live = small.num_states - int(small.terminal_mask.sum())
    big_live = big.num_states - int(big.terminal_mask.sum())
    assert small_live == live == KNOWN["MiniGrid-DoorKey-5x5-v0"], (small_live, live)
    assert big_live == KNOWN["MiniGrid-DoorKey-8x8-v0"], big_live
    rows.append((fast, slow, big_s))
    print(
        f"repeat {r}: DoorKey-5x5 from_minigrid {fast:.3f} s, deep copies {slow:.3f} s "
        f"(×{slow / fast:.1f}); DoorKey-8x8 from_minigrid {big_s:.2f} s ({big.num_states:,} "
        f"states, {big_live:,} non-terminal)"
    )
fast, slow, big_s = (statistics.median(c) for c in zip(*rows))
print(
    f"median of {args.repeats}: DoorKey-5x5 {fast:.3f} s vs deep copies {slow:.3f} s "
    f"(×{slow / fast:.1f}); DoorKey-8x8 {big_s:.2f} s (bound 5 s)"
)
