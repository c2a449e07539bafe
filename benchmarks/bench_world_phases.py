"""Where one world of ``himit run paper`` spends its time: ``run_world`` of one experiment's world
in this process (committed settings, 5 seeds, warm kernels), each of its steps timed.

Prints the seconds of the imports and the kernels' load, of ``run_world`` as a whole, and of
its steps: the mentor's part (options, exact policy, demonstrations, its exact evaluation), the
learner, the optimum's evaluation, the greedy tracker's exact option models, the TensorBoard
logger (its imports included, the first world of a process pays them), the batch's run
(``_run_batch``: the learning with, inside it, the checkpoint saves, the greedy evaluations and
the maps, also shown apart), the final "stuck" evaluation and the figures. ``learning`` is the
batch's run less the saves, evaluations and maps in it (the kernel, per-window logging and the
engine's Python).

    python benchmarks/bench_world_phases.py exp3 120 [--logdir DIR]

Run it once per world, each in a fresh process, for the whole reproduction's share of each part.
"""

import argparse
import functools
import shutil
import sys
import tempfile
import time
from pathlib import Path

began = time.perf_counter()
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("experiment", choices=["exp1", "exp2", "exp3"])
parser.add_argument("size", type=int, help="the world's side (one of the experiment's sizes)")
parser.add_argument("--logdir", help="the run directory (default: a temporary one, removed)")
args = parser.parse_args()

import himit_torch  # noqa: E402, F401
import himit_torch.runs.runner as runner  # noqa: E402
import himit_torch.viz.tensorboard as tensorboard  # noqa: E402
from himit_torch.runs import experiment, greedy  # noqa: E402
from himit_torch.runs.config import EXPERIMENTS  # noqa: E402
from himit_torch.runs.kernels import prepare_kernels  # noqa: E402

imports = time.perf_counter() - began
kernels = prepare_kernels()
seconds: dict[str, float] = {}


def timed(owner, name: str, label: str) -> None:
    """Replace ``owner.name`` by a wrapper adding its seconds to ``seconds[label]``."""
    function = getattr(owner, name)

    @functools.wraps(function)
    def wrapper(*a, **k):
        start = time.perf_counter()
        try:
            return function(*a, **k)
        finally:
            seconds[label] = seconds.get(label, 0.0) + time.perf_counter() - start

    setattr(owner, name, wrapper)


STEPS = [
    (experiment, "_mentoring", "mentor"),
    (experiment, "_learner", "learner"),
    (experiment, "optimal_reference", "optimum"),
    (experiment, "_greedy_tracker", "greedy tracker"),
    (experiment, "_logger", "logger"),
    (experiment, "_run_batch", "batch run"),
    (runner.Checkpoints, "save", "  saves"),
    (greedy.GreedyTracker, "evaluate", "  greedy evaluations"),
    (tensorboard.TensorBoardLogger, "maps", "  maps"),
    (greedy.GreedyTracker, "finish", "stuck evaluation"),
    (experiment, "_world_figure", "world figure"),
    (experiment, "_world_curve_figures", "curve figures"),
]
for owner, name, label in STEPS:
    timed(owner, name, label)

config = EXPERIMENTS[args.experiment]
if args.size not in config.sizes:
    parser.error(f"{args.experiment}'s worlds are {list(config.sizes)}, not {args.size}")
run_dir = Path(args.logdir or tempfile.mkdtemp(prefix="himit-phases-")) / args.experiment
try:
    experiment.ExperimentStudy().prepare(config, run_dir, resume=False, force=True)
    start = time.perf_counter()
    experiment.run_world(config, args.size, run_dir, False, progress=False)
    total = time.perf_counter() - start
finally:
    if not args.logdir:
        shutil.rmtree(run_dir.parent, ignore_errors=True)

inside = sum(seconds.get(k, 0.0) for k in ("  saves", "  greedy evaluations", "  maps"))
print(
    f"{args.experiment} {args.size}×{args.size}: imports {imports:.2f} s, kernels {kernels:.2f} s"
)
print(f"run_world {total:.2f} s")
for _, _, label in STEPS:
    print(f"  {label:22s} {seconds.get(label, 0.0):6.2f}")
    if label == "  maps":
        print(f"  {'  learning':22s} {seconds.get('batch run', 0.0) - inside:6.2f}")
