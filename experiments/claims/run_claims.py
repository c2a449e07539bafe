"""Every run the claims rest on, then the tables: the paper's three experiments and the
Gymnasium comparison at 20 seeds, under both presets and both tie rules (PROTOCOL.md), copied
into ``experiments/results/<preset>-<ties>/`` and analysed into ``experiments/results/claims/``.

    python experiments/claims/run_claims.py [--seeds 20] [--logdir runs/claims] [--skip-runs]

≈ 14 minutes on a 2-core CPU (each preset and tie rule: ≈ 2–3.5 min for `himit run paper`,
≈ 30 s for the Gymnasium tasks). Finished runs are kept: rerun with ``--skip-runs`` to redo only
the copying and the tables, or delete a run directory to redo it.
"""

import argparse
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parent / "results"

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--seeds", type=int, default=20)
parser.add_argument("--logdir", default="runs/claims")
parser.add_argument("--skip-runs", action="store_true", help="copy and analyse finished runs")
args = parser.parse_args()


def himit(*argv: str) -> None:
    command = [sys.executable, "-m", "himit_torch.cli", *argv]
    print("$", " ".join(command[2:]), flush=True)
    subprocess.run(command, check=True)


for preset in ("paper", "recommended"):
    for ties in ("random", "first"):
        logdir = Path(args.logdir) / f"{preset}-{ties}"
        flags = ["--seeds", str(args.seeds), "--preset", preset, "--tie-break", ties]
        if not args.skip_runs:
            for experiment in ("paper", "gymnasium"):
                himit("run", experiment, *flags, "--logdir", str(logdir), "--quiet", "--force")
        subprocess.run(
            [
                sys.executable,
                str(HERE.parent / "collect_results.py"),
                *(str(logdir / name) for name in ("exp1", "exp2", "exp3", "gymnasium")),
                "--out",
                str(RESULTS / f"{preset}-{ties}"),
            ],
            check=True,
        )
subprocess.run([sys.executable, str(HERE / "analyse.py"), "--results", str(RESULTS)], check=True)
