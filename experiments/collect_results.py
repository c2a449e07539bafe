"""Copy the figures, results tables and configs of finished run directories into
experiments/results/ (small PNGs and markdown only; curves.csv is kept too, it is small, and
so are each world's record ``worlds/world<N>.json`` — first goals, greedy values — and a
Gymnasium run's ``tasks/*.json``, which experiments/claims.py reads).

    python experiments/collect_results.py runs/exp1 runs/exp2 runs/exp3 [--out experiments/results]
"""

import argparse
import shutil
from pathlib import Path

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("run_dirs", nargs="+")
parser.add_argument("--out", default=str(Path(__file__).parent / "results"))
args = parser.parse_args()

out = Path(args.out)
for run_dir in map(Path, args.run_dirs):
    if not (run_dir / "results.md").exists():
        raise SystemExit(f"{run_dir} has no results.md: it has not finished")
    target = out / run_dir.name
    target.mkdir(parents=True, exist_ok=True)
    for name in ("results.md", "config.json", "curves.csv"):
        shutil.copy(run_dir / name, target / name)
    for png in (run_dir / "figures").glob("*.png"):
        shutil.copy(png, target / png.name)
    for folder in ("worlds", "tasks"):
        for record in (run_dir / folder).glob("*.json"):
            (target / folder).mkdir(exist_ok=True)
            shutil.copy(record, target / folder / record.name)
    print(f"{run_dir} → {target}")
