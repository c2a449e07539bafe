"""The benchmark's runs (PROTOCOL.md): the agents the claims' runs do not hold, on every world,
seeds 0–19, the paper preset with random ties — then the stress sweep, and the tables.

    python experiments/benchmark/run_benchmark.py [--agents …] [--logdir runs/benchmark] [--skip-runs]

The claims' runs (``experiments/results/paper-random/``, ``recommended-random/``) supply
``imitation``, ``options`` and ``primitives``; this adds the baselines beside ``options`` again
(whose curves must equal the committed ones). ≈ 10 min for the worlds, ≈ 10 min for the
stresses and ≈ 5 min for the puzzle box (``puzzle_box_benchmark.py``) on a 2-core CPU. Copies the records into ``experiments/results/benchmark/`` and runs
``analyse.py``.
"""

import argparse
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results" / "benchmark"
#: The agents beside the claims' runs, and options-only again as the batch-independence check.
AGENTS = ("imitation_primitives", "pbrs", "pbrs_primitives", "bco", "options")

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--agents", nargs="+", default=list(AGENTS))
parser.add_argument("--seeds", type=int, default=20)
parser.add_argument("--logdir", default="runs/benchmark")
parser.add_argument("--skip-runs", action="store_true", help="copy and analyse finished runs")
args = parser.parse_args()
logdir = Path(args.logdir)


def run(*argv: str) -> None:
    print("$", " ".join(argv), flush=True)
    subprocess.run([sys.executable, *argv], check=True)


if not args.skip_runs:
    common = ["--seeds", str(args.seeds), "--preset", "paper", "--tie-break", "random"]
    run(
        "-m",
        "himit_torch.cli",
        "run",
        "paper",
        *common,
        "--agents",
        *args.agents,
        "--logdir",
        str(logdir / "worlds"),
        "--quiet",
        "--force",
    )
    run(
        str(HERE.parent / "gymnasium_worlds.py"),
        "--seeds",
        str(args.seeds),
        "--preset",
        "paper",
        "--agents",
        *args.agents,
        "--logdir",
        str(logdir / "worlds"),
        "--force",
    )
    run(
        "-m",
        "himit_torch.cli",
        "sweep",
        str(HERE / "stress_exp2.toml"),
        "--out",
        str(logdir / "stress_exp2"),
    )

run(
    str(HERE.parent / "collect_results.py"),
    *(str(logdir / "worlds" / n) for n in ("exp1", "exp2", "exp3", "gymnasium")),
    "--out",
    str(RESULTS / "worlds"),
)
stress = RESULTS / "stress_exp2"
stress.mkdir(parents=True, exist_ok=True)
for name in ("runs.csv", "summary.md", "sweep.json"):
    shutil.copy(logdir / "stress_exp2" / name, stress / name)
run(str(HERE / "analyse.py"))
