"""One imitator on the compiled engine against the bare compiled loop, in one process, alternating.

The bare loop is the "aos" kernel of ``../shared/anchors/numba_limit.py`` (a throw-away Numba
port of the same algorithm, no batching, no metrics, no checkpoints), imported from there by path,
never copied. The issue's reference command for it is

    python ../shared/anchors/numba_limit.py bench --N 40 --R 10 --agent imitation \\
        --steps 200000 --no-ref --kernels aos

This script runs, in one process, after warming both (compile or cache load, then one untimed
run of each): ``--reps`` times, alternating which goes first, one imitator for ``--steps`` steps
from scratch with

* **ours**: a fresh :class:`himit_torch.Learner` (B = 1, ``engine="numba"``, 40×40 world with 10
  rooms, doorway options, 20 mentor episodes recorded with seed 0, run seed 0), timed around
  ``learner.run(steps)`` only (building the learner is not timed: the anchor's set-up is not
  either). That call includes what the user gets per window of 5,000 steps: the metrics row,
  the mentor-win share (one ``mentor_wins`` kernel call), the edge-list growth, the heap rebuild
  and the argument tuples of each ``run_ticks`` call. The time inside ``run_ticks`` alone is
  reported too (``kernel``), by wrapping the engine's module-level ``run_ticks``.
* **limit**: the anchor's ``run_aos(W, steps, seed=0, **HP)`` (its ``alloc`` + ``kernel``),
  with the anchor's own hyper-parameters ``HP``.

and prints steps/s per repeat, the medians, and the median of the per-repeat ratios ours/limit.

Same work, and where it differs:

* Same world size (40×40, 10 rooms), steps (``--steps``, 200,000), slip, rewards, γ, options
  (primitives + doorway options), ε schedule (0.75, ×0.999 per decision after the first goal,
  floor 0.01), initial value −1, untried options left out of the max ("skip").
* Planning, by default (``--settings anchor``): classic one-at-a-time prioritized sweeping
  (``sweep_rounds = backups``, so ``round_size = 1``, ``plan_every = 1``), threshold 1e-5 (the
  anchor's ``theta``; the package's default is 1e-6). The anchor backs up the option's start
  state and then up to ``nb = 10`` popped states (11 backups per decision at most); our budget
  counts the start state (pushed first with infinite priority) inside ``backups``, so
  ``--backups 11`` (the default here) gives the same at-most-11 per decision. The script prints
  the backups per decision that each actually did (the anchor's from its counting variant,
  one untimed run) so the two budgets can be compared.
  ``--settings bench`` uses ``himit bench``'s planning instead (``plan_every = 4``,
  ``sweep_rounds = 1``, ``backups = 10``, default threshold): the issue's 675k–820k steps/s.
* Not the same: the learner's random numbers (ours: counter-based Philox-style uniforms per
  tick; the anchor: splitmix64), and the mentor demonstrations (ours from
  ``record_demonstrations``; the anchor's from the reference's code), so the two runs take
  different trajectories; their steps per decision and goals are printed beside the rates.
  ``--threshold`` overrides ours' priority threshold alone (to see which setting costs).
  The anchor keeps no metrics, no visit counts, no linked edge lists and no per-window calls.

    python benchmarks/bench_vs_limit.py [--reps 5] [--steps 200000] [--settings anchor|bench]
"""

import argparse
import dataclasses
import importlib.util
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--reps", type=int, default=5, help="timed runs of each (alternating)")
parser.add_argument("--steps", type=int, default=200_000)
parser.add_argument("--size", type=int, default=40)
parser.add_argument("--rooms", type=int, default=10)
parser.add_argument("--settings", choices=["anchor", "bench"], default="anchor",
                    help="planning settings of ours: the anchor's (default) or himit bench's")  # fmt: skip
parser.add_argument("--backups", type=int, default=11,
                    help="ours: backups per decision, the start state included (anchor: 1 + 10)")  # fmt: skip
parser.add_argument("--threshold", type=float, default=None,
                    help="override ours' priority threshold (to isolate one setting)")  # fmt: skip
parser.add_argument("--anchor", default=str(ROOT.parent / "shared" / "anchors" / "numba_limit.py"))
parser.add_argument("--no-work", action="store_true",
                    help="skip the anchor's counting run (backups per decision)")  # fmt: skip
args = parser.parse_args()

import torch  # noqa: E402

import himit_torch.learner.engines.numba_engine as numba_engine  # noqa: E402
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


def load_anchor(path: str):
    spec = importlib.util.spec_from_file_location("numba_limit", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # (defines its kernels; Numba compiles them at first call)
    return module


t0 = time.perf_counter()
NL = load_anchor(args.anchor)
t_anchor_import = time.perf_counter() - t0
HP = NL.HP
W, info = NL.build(args.size, args.rooms, "imitation", False, 0)

if args.settings == "anchor":
    config = LearnerConfig(
        backups=args.backups,
        sweep_rounds=args.backups,  # round_size 1: one state at a time
        plan_every=1,
        priority_threshold=HP["theta"],
        initial_value=HP["v_init"],
        eps_start=HP["eps0"],
        eps_decay=HP["eps_decay"],
        eps_min=HP["eps_min"],
        window=HP["window"],
    )
else:
    config = LearnerConfig(plan_every=4, sweep_rounds=1)  # as himit bench
if args.threshold is not None:
    config = dataclasses.replace(config, priority_threshold=args.threshold)

world = MultiRooms(size=args.size, rooms=args.rooms)
demos = record_demonstrations(world, mentor_policy(world, mentor_options(world, False)), 20, seed=0)
options = learner_options(world, corners=False)

kernel_seconds = [0.0]
run_ticks = numba_engine.run_ticks


def timed_run_ticks(*args):
    began = time.perf_counter()
    run_ticks(*args)
    kernel_seconds[0] += time.perf_counter() - began


numba_engine.run_ticks = timed_run_ticks


def ours(steps: int) -> dict:
    learner = Learner(world, options, ["imitation"], [0], demonstrations=demos, config=config,
                      engine="numba")  # fmt: skip
    kernel_seconds[0] = 0.0
    began = time.perf_counter()
    learner.run(steps)
    seconds = time.perf_counter() - began
    decisions = int(learner.views.decisions.sum())
    return dict(rate=steps / seconds, seconds=seconds, kernel=kernel_seconds[0],
                decisions=decisions, backups=int(learner.views.backups_done.sum()),
                goals=int(learner.run_state.goals.sum()))  # fmt: skip


def limit(steps: int) -> dict:
    seconds, curve, st, _ = NL.nb_run(W, steps, 0, NL.run_aos)
    return dict(rate=st[0] / seconds, seconds=seconds, decisions=int(st[1]), goals=int(st[2]))


# ---- warm both: first calls (compile or cache load), then one untimed full run each
began = time.perf_counter()
ours(1)
first_ours = time.perf_counter() - began
began = time.perf_counter()
limit(10)
first_limit = time.perf_counter() - began
print(f"# first call: ours {first_ours:.2f} s (Numba cache: {os.environ.get('NUMBA_CACHE_DIR') or 'beside the kernels'}), "
      f"limit {first_limit:.2f} s (compiled, no cache); anchor import {t_anchor_import:.2f} s", flush=True)  # fmt: skip
print(f"# anchor world: {info}", flush=True)
print(f"# ours: settings={args.settings} backups={config.backups} sweep_rounds={config.sweep_rounds} "
      f"plan_every={config.plan_every} threshold={config.priority_threshold}; "
      f"anchor HP={HP}", flush=True)  # fmt: skip
w_ours, w_limit = ours(args.steps), limit(args.steps)
if not args.no_work:
    _, _, st, _ = NL.nb_run(W, args.steps, 0, NL.run_aos_prof)
    anchor_bpd = st[4] / st[1]
    work = f"limit {args.steps / st[1]:.2f} steps/decision, {anchor_bpd:.2f} backups/decision"
else:
    work = f"limit {args.steps / w_limit['decisions']:.2f} steps/decision"
print(f"# work: ours {args.steps / w_ours['decisions']:.2f} steps/decision, "
      f"{w_ours['backups'] / w_ours['decisions']:.2f} backups/decision, {w_ours['goals']} goals; "
      f"{work}, {w_limit['goals']} goals", flush=True)  # fmt: skip

rates: dict[str, list[float]] = {"ours": [], "limit": []}
kernel_share = []
for rep in range(args.reps):
    order = ("ours", "limit") if rep % 2 == 0 else ("limit", "ours")
    line = f"rep {rep}:"
    for name in order:
        r = ours(args.steps) if name == "ours" else limit(args.steps)
        rates[name].append(r["rate"])
        line += f" {name} {r['rate']:,.0f} steps/s ({r['seconds'] * 1e3:.0f} ms"
        if name == "ours":
            kernel_share.append(r["kernel"] / r["seconds"])
            line += f", {r['kernel'] * 1e3:.0f} ms in run_ticks"
        line += ");"
    line += f" ratio {rates['ours'][-1] / rates['limit'][-1]:.3f}"
    print(line, flush=True)

ratios = [a / b for a, b in zip(rates["ours"], rates["limit"])]
print(
    f"MEDIAN of {args.reps} alternating repeats, {args.size}x{args.size}/{args.rooms}, one imitator, "
    f"{args.steps} steps, settings={args.settings}: ours {statistics.median(rates['ours']):,.0f} "
    f"steps/s, limit {statistics.median(rates['limit']):,.0f} steps/s, median ratio ours/limit "
    f"{statistics.median(ratios):.3f} (range {min(ratios):.3f}-{max(ratios):.3f}); "
    f"ours spends {statistics.median(kernel_share):.1%} of run() inside run_ticks"
)
