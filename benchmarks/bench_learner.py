"""Throughput of the batched learner against the straightforward single-run implementation.

For each world (40×40 and 80×80, 10×10 rooms) and batch size B ∈ {1, 15, 64, 256}, run our
learner for T steps from scratch (agents cycling imitation / options / primitives, one thread)
and, side by side in the same session, the reference NumPy implementation
(``../shared/anchors/reference_learner.py``, run as a program, neutral settings) for the same
world, steps and agents. Each measurement is repeated; medians are reported, and the ratio of our
aggregate steps/s to the reference's (its three agents' total steps over their total time).

    python benchmarks/bench_learner.py [--steps 5000] [--repeats 3] [--sizes 40 80]
        [--batches 1 15 64 256] [--plan-every 1] [--out benchmarks/results.md]
"""
import argparse
import re
import statistics
import subprocess
import sys
from pathlib import Path

import torch

from himit_torch.bench import benchmark

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT.parent / "shared" / "anchors" / "reference_learner.py"

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--steps", type=int, default=5000)
parser.add_argument("--repeats", type=int, default=3)
parser.add_argument("--sizes", type=int, nargs="+", default=[40, 80])
parser.add_argument("--batches", type=int, nargs="+", default=[1, 15, 64, 256])
parser.add_argument("--plan-every", type=int, default=1)
parser.add_argument("--out", default=None, help="also write the table to this markdown file")
args = parser.parse_args()
torch.set_num_threads(1)


def reference_steps_per_second(size: int, steps: int) -> float:
    """The reference's aggregate steps/s over the three agents (total steps / total time)."""
    if not REFERENCE.exists():
        raise SystemExit(f"reference implementation not found at {REFERENCE}")
    total_time = 0.0
    for agent in ("imitation", "options", "primitives"):
        out = subprocess.run([sys.executable, str(REFERENCE), "--N", str(size), "--R", "10",
                              "--agent", agent, "--steps", str(steps), "--seed", "0",
                              "--untried", "skip", "--v-init", "-1"],
                             capture_output=True, text=True, check=True).stdout
        total_time += steps / float(re.search(r"steps/s=(\d+)", out).group(1))
    return 3 * steps / total_time


rows = ["| world | B | ours steps/s (median) | decisions/s | peak MiB | reference steps/s (median) | ratio |",
        "|---|---|---|---|---|---|---|"]
for size in args.sizes:
    ref = statistics.median(reference_steps_per_second(size, args.steps) for _ in range(args.repeats))
    for batch in args.batches:
        runs = [benchmark(size=size, rooms=10, batch=batch, steps=args.steps, warmup=0,
                          plan_every=args.plan_every) for _ in range(args.repeats)]
        ours = statistics.median(r.steps_per_second for r in runs)
        dec = statistics.median(r.decisions_per_second for r in runs)
        row = (f"| {size}×{size} | {batch} | {ours:,.0f} | {dec:,.0f} | "
               f"{max(r.peak_memory_mib for r in runs):,.0f} | {ref:,.0f} | {ours / ref:.2f}× |")
        rows.append(row)
        print(row, flush=True)
table = "\n".join(rows)
print()
print(table)
if args.out:
    Path(args.out).write_text(f"Steps {args.steps} per run from scratch, {args.repeats} repeats, "
                              f"plan_every={args.plan_every}, one torch thread.\n\n{table}\n")
