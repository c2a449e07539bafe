"""Wall time of the paper's full reproduction (exp1 + exp2 + exp3, 5 seeds, committed budgets).

Runs ``himit run paper`` (the three experiments' six worlds in one pool over the cores) — or,
with ``--sequential``, ``himit run exp1``, ``exp2``, ``exp3`` one after the other — in fresh
processes: first with an empty Numba cache (``cold``: the kernels are compiled, counted in the
time), then with that cache filled (``warm``), ``--repeats`` times each, alternating. Everything
a user waits for is inside the time: imports, worlds, the mentor's exact planning and
demonstrations, options, learning, TensorBoard logs and maps, checkpoints, figures and
``results.md``. Prints each time, the medians, and how long each world took.

    python benchmarks/bench_reproduction.py [--repeats 3] [--sequential] [--keep DIR]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HIMIT = [sys.executable, "-m", "himit_torch.cli"]

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--repeats", type=int, default=3, help="cold and warm runs each (default 3)")
parser.add_argument(
    "--sequential",
    action="store_true",
    help="himit run exp1, exp2, exp3 one after the other instead of himit run paper",
)
parser.add_argument("--keep", help="keep the run directories under this folder")


def reproduce(logdir: Path, cache: Path, sequential: bool) -> float:
    """Seconds of one full reproduction into ``logdir`` with Numba cache ``cache``."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "PYTHONPATH": str(ROOT)}
    commands = (
        [
            [*HIMIT, "run", name, "--logdir", str(logdir), "--quiet"]
            for name in ("exp1", "exp2", "exp3")
        ]
        if sequential
        else [[*HIMIT, "run", "paper", "--logdir", str(logdir), "--quiet"]]
    )
    start = time.perf_counter()
    for command in commands:
        subprocess.run(command, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def world_seconds(logdir: Path) -> str:
    parts = []
    for path in sorted(logdir.glob("exp*/worlds/world*.json")):
        seconds = json.loads(path.read_text())["wall_seconds"]
        parts.append(f"{path.parts[-3]}/{path.stem} {seconds:.1f}")
    return ", ".join(parts)


def main() -> None:
    args = parser.parse_args()
    what = "exp1, exp2, exp3 one after the other" if args.sequential else "himit run paper"
    print(f"full reproduction ({what}), {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}")
    times: dict[str, list[float]] = {"cold": [], "warm": []}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep) if args.keep else Path(tmp)
        for r in range(args.repeats):
            cache = Path(tmp) / f"numba-cache-{r}"
            for kind in ("cold", "warm"):  # the warm run uses the cache the cold one filled
                logdir = out / f"{kind}{r}"
                seconds = reproduce(logdir, cache, args.sequential)
                times[kind].append(seconds)
                load = os.getloadavg()[0]
                print(f"{kind} {r}: {seconds:.1f} s (load {load:.1f}); {world_seconds(logdir)}")
    for kind, values in times.items():
        print(
            f"{kind}: median {statistics.median(values):.1f} s of {[round(v, 1) for v in values]}"
        )


if __name__ == "__main__":
    main()
