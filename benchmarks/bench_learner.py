"""Throughput and memory of the learner's engines, against the straightforward single-run loop.

For each engine × world × batch size B, a fresh process builds a batch (agents cycling
imitation / options / primitives; B = 1 runs the imitator alone), runs its first tick untimed
(the compiled engine loads its kernels there; a cold compile is measured once per run of this
script with an empty Numba cache) and times ``--steps`` ticks from scratch. Reported: aggregate
steps/s and decisions/s, the process's peak RSS, and — when ``../shared/anchors/reference_learner.py``
is present — the ratio to that reference run side by side, in the same session, for the same
world, steps and agents (its three agents' total steps ÷ total time for a mixed batch; the
imitator alone for B = 1). Medians of ``--repeats`` repeats.

    python benchmarks/bench_learner.py [--steps 30000] [--repeats 3] [--out benchmarks/results-table.md]
        [--worlds 40 80c 120c] [--batches 1 16 64 256] [--engines numba torch] [--torch-steps 2000]

A world is ``N`` (N×N, 10×10 rooms) or ``Nc`` (with corner options, rooms of 8 cells as in
experiments 1 and 3: N/8 rooms per side).
"""

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT.parent / "shared" / "anchors" / "reference_learner.py"

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--steps", type=int, default=30_000, help="timed ticks (compiled engine)")
parser.add_argument("--torch-steps", type=int, default=2000, help="timed ticks (torch engine)")
parser.add_argument("--repeats", type=int, default=3)
parser.add_argument("--worlds", nargs="+", default=["40", "80c", "120c"])
parser.add_argument("--batches", type=int, nargs="+", default=[1, 16, 64, 256])
parser.add_argument("--engines", nargs="+", default=["numba", "torch"])
parser.add_argument("--torch-batches", type=int, nargs="+", default=[1, 16, 64, 256])
parser.add_argument("--torch-worlds", nargs="+", default=["40", "80c"])
parser.add_argument(
    "--reference-worlds",
    nargs="+",
    default=["40", "80c"],
    help="worlds on which the reference runs beside ours",
)
parser.add_argument("--out", default=None, help="also write the table to this markdown file")


def parse_world(spec: str) -> tuple[int, int, bool]:
    corners = spec.endswith("c")
    size = int(spec.rstrip("c"))
    return size, (size // 8 if corners else 10), corners


def measure(spec: str, batch: int, steps: int, engine: str, env=None) -> dict:
    """One benchmark in a fresh process (so that its peak RSS is its own)."""
    size, rooms, corners = parse_world(spec)
    agent = "imitation" if batch == 1 else "mix"
    code = (
        "import json, torch; from himit_torch.runs.bench import benchmark; "
        f"r = benchmark(size={size}, rooms={rooms}, corner_options={corners}, batch={batch}, "
        f"steps={steps}, agent={agent!r}, warmup=0, engine={engine!r}); "
        "print(json.dumps(dict(steps_per_second=r.steps_per_second, "
        "decisions_per_second=r.decisions_per_second, peak=r.peak_memory_mib, "
        "first=r.first_call_seconds, engine=r.engine)))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env
    ).stdout
    return json.loads(out.strip().splitlines()[-1])


_reference: dict = {}


def reference_steps_per_second(
    spec: str, steps: int, agents: tuple[str, ...], worlds: list[str]
) -> float | None:
    """The reference's steps/s for ``agents`` (total steps ÷ total learning time), one repeat."""
    if not REFERENCE.exists() or spec not in worlds:
        return None
    size, rooms, corners = parse_world(spec)
    total_time = 0.0
    for agent in agents:
        cmd = [
            sys.executable,
            str(REFERENCE),
            "--N",
            str(size),
            "--R",
            str(rooms),
            "--agent",
            agent,
            "--steps",
            str(steps),
            "--seed",
            "0",
            "--untried",
            "skip",
            "--v-init",
            "-1",
        ]
        if corners:
            cmd.append("--corner-options")
        out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
        total_time += steps / float(re.search(r"steps/s=(\d+)", out).group(1))
    return len(agents) * steps / total_time


def main() -> None:
    args = parser.parse_args()
    rows = [
        "| engine | world | B | steps/s | decisions/s | steps/s per run | peak RSS MiB | "
        "first call s | reference steps/s | ratio |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        cold = measure("40", 1, 100, "numba", env) if "numba" in args.engines else None
    if cold:
        print(f"cold compile (empty Numba cache), first call: {cold['first']:.1f} s", flush=True)
    for engine in args.engines:
        worlds = args.worlds if engine == "numba" else args.torch_worlds
        batches = args.batches if engine == "numba" else args.torch_batches
        steps = args.steps if engine == "numba" else args.torch_steps
        for spec in worlds:
            for batch in batches:
                agents = ("imitation",) if batch == 1 else ("imitation", "options", "primitives")
                ours = []
                for _ in range(args.repeats):  # interleaved, so load changes hit both alike
                    ours.append(measure(spec, batch, steps, engine))
                    key = (spec, steps, agents)
                    if key not in _reference or len(_reference[key]) < args.repeats:
                        ref = reference_steps_per_second(spec, steps, agents, args.reference_worlds)
                        if ref is not None:
                            _reference.setdefault(key, []).append(ref)
                sps = statistics.median(r["steps_per_second"] for r in ours)
                dps = statistics.median(r["decisions_per_second"] for r in ours)
                ref = (
                    statistics.median(_reference[(spec, steps, agents)])
                    if _reference.get((spec, steps, agents))
                    else None
                )
                row = (
                    f"| {ours[0]['engine']} | {spec} | {batch} | {sps:,.0f} | {dps:,.0f} | "
                    f"{sps / batch:,.0f} | {max(r['peak'] for r in ours):,.0f} | "
                    f"{statistics.median(r['first'] for r in ours):.2f} | "
                    + (f"{ref:,.0f} | {sps / ref:.1f}× |" if ref else "— | — |")
                )
                rows.append(row)
                print(row, flush=True)
    table = "\n".join(rows)
    print()
    print(table)
    if args.out:
        header = (
            f"`python benchmarks/bench_learner.py {' '.join(sys.argv[1:])}`: {args.steps:,} "
            f"ticks (torch engine {args.torch_steps:,}) from scratch per measurement, medians "
            f"of {args.repeats}."
        )
        if cold:
            header += f" Cold compile of the kernels (empty cache): {cold['first']:.1f} s."
        Path(args.out).write_text(f"{header}\n\n{table}\n")


if __name__ == "__main__":
    main()
