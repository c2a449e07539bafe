"""The TensorBoard maps drawn as arrays against a figure redrawn per map: the milliseconds a
map takes on the paper's 80 × 80 world, this tree against another commit's (by default
``4f484d6``, the last whose ``MapRenderer`` redrew a matplotlib figure per map).

Each tree draws, in its own process, the values, visits (with the mentor's states) and
greedy-option maps of the same data on exp1's 80 × 80 world with corner options, each map with
a new title (a step count, as a run's maps have), ``--maps`` times after one untimed first
draw (which draws the frame, or builds the figure); the trees alternate ``--repeats`` times.
Prints each repeat's milliseconds a map per kind, then the medians and the ratio. With
``--png DIR``, each tree's three maps are written there as PNGs, to compare by eye.

    python benchmarks/bench_maps.py [--against 4f484d6] [--repeats 3] [--maps 20] [--png DIR]
"""

import argparse
import json
import statistics
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

DRAW = r"""
import json, sys, time
import numpy as np, torch
from himit_torch.options.builders import learner_options
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.viz.plotting import MapRenderer

maps, png = int(sys.argv[1]), sys.argv[2]
world = EXPERIMENTS["exp1"].world(80)
options = learner_options(world, corners=True)
S = world.num_states
gen = torch.Generator().manual_seed(0)
row, col = torch.arange(S) // 80, torch.arange(S) % 80
values = -(row + col).double() / 160.0
values[(row < 30) & (col > 40)] = -1.0
visits = (torch.rand(S, generator=gen) ** 6 * 5000).long()
visits[row > 60] = 0
mentor = ((row == 5) | (col == 70)).long()
greedy = torch.randint(-1, len(options.names), (S,), generator=gen)
renderer = MapRenderer(world, options)
draw = {
    "values": lambda t: renderer.values(values, f"values V(s) after {t:,} steps\nworld80__a__seed0"),
    "visits": lambda t: renderer.visits(visits, mentor, f"visits up to {t:,} steps\nworld80__a__seed0"),
    "policy": lambda t: renderer.policy(greedy, f"greedy option after {t:,} steps\nworld80__a__seed0"),
}
ms = {}
for kind, f in draw.items():
    first = f(0)
    if png:
        from matplotlib.image import imsave
        imsave(f"{png}_{kind}.png", first)
    start = time.perf_counter()
    for t in range(1, maps + 1):
        f(5000 * t)
    ms[kind] = 1000 * (time.perf_counter() - start) / maps
print(json.dumps(ms))
"""


def draw(tree: Path, maps: int, png: str) -> dict[str, float]:
    out = subprocess.run(
        [sys.executable, "-c", DRAW, str(maps), png],
        cwd=tree,
        env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"},
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--against", default="4f484d6", help="the other tree's commit")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--maps", type=int, default=20, help="timed maps per kind and repeat")
    parser.add_argument("--png", help="write each tree's maps as PNGs into this folder")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="himit-maps-") as tmp:
        other = Path(tmp)
        archive = subprocess.run(
            ["git", "archive", args.against, "himit_torch"],
            cwd=ROOT,
            check=True,
            capture_output=True,
        ).stdout
        with tarfile.open(fileobj=__import__("io").BytesIO(archive)) as tar:
            tar.extractall(other, filter="data")
        trees = {"arrays (this tree)": ROOT, f"figure ({args.against})": other}
        results: dict[str, list[dict[str, float]]] = {name: [] for name in trees}
        for r in range(args.repeats):
            for name, tree in trees.items():
                png = "" if not args.png else str(Path(args.png).resolve() / name.split()[0])
                results[name].append(draw(tree, args.maps, png if r == 0 else ""))
                ms = results[name][-1]
                print(
                    f"repeat {r + 1}, {name}: "
                    + ", ".join(f"{k} {v:.1f}" for k, v in ms.items())
                    + " ms a map",
                    flush=True,
                )
    medians = {
        name: {k: statistics.median(m[k] for m in runs) for k in runs[0]}
        for name, runs in results.items()
    }
    (arrays, figure) = medians.values()
    for name, ms in medians.items():
        print(f"median, {name}: " + ", ".join(f"{k} {v:.1f}" for k, v in ms.items()) + " ms a map")
    print("figure ÷ arrays: " + ", ".join(f"{k} {figure[k] / arrays[k]:.1f}×" for k in arrays))


if __name__ == "__main__":
    main()
