"""Where one world of a study spends its time: ``run_world`` of one experiment's world in this
process (committed settings, warm kernels), its wall time split into exclusive parts.

Every part is timed exclusively (a part called inside another is taken out of the outer one),
so the parts add up to ``run_world``'s wall time; what no part claims is ``other``. The parts,
grouped as the study's costs:

- **learning**: the kernel's seconds per agent kind (each run of a batch is its own kernel
  call, ``numba_engine._run_all``'s per-run seconds, summed by agent), and the engine's Python
  around it (``learning, engine``: the batch's run less everything timed inside it);
- **exact**: the mentor's exact policy, its exact evaluation and transitions, the optimum, the
  greedy tracker's option models (``PolicyEvaluator``) and its greedy evaluations;
- **set-up**: the option sets, the mentor's recorded episodes, the learner;
- **maps** (TensorBoard's, ``TensorBoardLogger.maps``), **figures** (the world and curve
  figures);
- **logging**: the TensorBoard logger (its imports included: the first world of a process pays
  them), its scalars, texts and hparams;
- **checkpoints**: the saves and the start; **I/O**: the curves and the record.

    python benchmarks/bench_world_phases.py exp3 120 [--preset paper] [--agents A ...]
        [--seeds 5] [--tie-break random] [--logdir DIR] [--threads 1] [--bco-refit torch]

The process is set up as each world process of ``himit run paper`` is (``share_cores``): torch
on one thread, the compiled engine on ``--threads`` (default 1: two world processes on two
cores). (Before it was, torch ran on every core: small torch ops then wait on a busy machine —
BCO's refit in torch ran ≈ 25× slower under a load of 8, which the split of 2026-11-28 took
for the study's cost.) ``--bco-refit torch``: BCO's refit by the torch functions, as before it
was compiled (the same actions), for a side-by-side run.

Run it once per world, each in a fresh process, for the whole reproduction's share of each
part. The benchmark's factorial (``experiments/benchmark/run_benchmark.py``) runs ``himit run
paper --preset P --agents … --tie-break random --seeds 20``: ``--preset``, ``--agents``,
``--seeds`` and ``--tie-break`` give a slice of it.
"""

import argparse
import dataclasses
import functools
import shutil
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

began = time.perf_counter()
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("experiment", choices=["exp1", "exp2", "exp3"])
parser.add_argument("size", type=int, help="the world's side (one of the experiment's sizes)")
parser.add_argument("--preset", help="a learner preset (as `himit run --preset`)")
parser.add_argument("--agents", nargs="+", help="the agents (default: the experiment's)")
parser.add_argument("--seeds", type=int, help="seeds per agent (default: the experiment's)")
parser.add_argument("--tie-break", help="the learner's tie_break (the factorial's: random)")
parser.add_argument("--logdir", help="the run directory (default: a temporary one, removed)")
parser.add_argument("--threads", type=int, default=1, help="the compiled engine's threads")
parser.add_argument("--bco-refit", choices=["compiled", "torch"], default="compiled")
args = parser.parse_args()

import torch  # noqa: E402

import himit_torch  # noqa: E402, F401
import himit_torch.learner.engines.numba_engine as numba_engine  # noqa: E402
import himit_torch.runs.runner as runner  # noqa: E402
import himit_torch.viz.tensorboard as tensorboard  # noqa: E402
from himit_torch.exact.greedy_evaluation import PolicyEvaluator  # noqa: E402
from himit_torch.learner.learner import Learner  # noqa: E402
from himit_torch.runs import experiment, greedy  # noqa: E402
from himit_torch.runs.config import EXPERIMENTS  # noqa: E402
from himit_torch.runs.kernels import prepare_kernels  # noqa: E402
from himit_torch.runs.runner import share_cores  # noqa: E402

imports = time.perf_counter() - began
share_cores(args.threads)
kernels = prepare_kernels()
seconds: dict[str, float] = defaultdict(float)
#: the timed calls under way: [label, start, seconds of the timed calls inside it]
stack: list[list] = []


def timed(owner, name: str, label: str) -> None:
    """Replace ``owner.name`` by a wrapper adding its exclusive seconds to ``seconds[label]``."""
    function = getattr(owner, name)

    @functools.wraps(function)
    def wrapper(*a, **k):
        frame = [label, time.perf_counter(), 0.0]
        stack.append(frame)
        try:
            return function(*a, **k)
        finally:
            stack.pop()
            spent = time.perf_counter() - frame[1]
            seconds[label] += spent - frame[2]
            if stack:
                stack[-1][2] += spent

    setattr(owner, name, wrapper)


#: (owner, function, part, group): the group is the row of the split table.
STEPS = [
    (experiment, "mentor_options", "mentor's options", "set-up"),
    (experiment, "learner_options", "learner's options", "set-up"),
    (experiment, "mentor_policy", "mentor's exact policy", "exact"),
    (experiment, "recorded_mentor_episodes", "mentor's episodes", "set-up"),
    (experiment, "_second_mentor", "mentor's episodes", "set-up"),
    (experiment, "evaluate_option_choice", "mentor's exact evaluation", "exact"),
    (experiment, "exact_mentor_transitions", "mentor's exact transitions", "exact"),
    (Learner, "__init__", "learner", "set-up"),
    (experiment, "watch_demonstrations", "learner", "set-up"),
    (experiment, "optimal_reference", "optimum", "exact"),
    (PolicyEvaluator, "__init__", "option models (PolicyEvaluator)", "exact"),
    (runner.Checkpoints, "start", "checkpoint start", "checkpoints"),
    (runner.Checkpoints, "save", "checkpoint saves", "checkpoints"),
    (tensorboard.TensorBoardLogger, "__init__", "logger (imports, folders)", "logging"),
    (tensorboard.TensorBoardLogger, "window", "logger: windows", "logging"),
    (tensorboard.TensorBoardLogger, "scalars", "logger: scalars", "logging"),
    (tensorboard.TensorBoardLogger, "text", "logger: texts", "logging"),
    (tensorboard.TensorBoardLogger, "hparams", "logger: hparams", "logging"),
    (tensorboard.TensorBoardLogger, "close", "logger: close", "logging"),
    (tensorboard.TensorBoardLogger, "maps", "TensorBoard maps", "maps"),
    (experiment, "_run_batch", "learning, engine", "learning"),
    (greedy.GreedyTracker, "evaluate", "greedy evaluations", "exact"),
    (greedy.GreedyTracker, "finish", "stuck evaluation", "exact"),
    (experiment, "_write_curves", "curves", "I/O"),
    (experiment, "write_atomically", "record", "I/O"),
    (experiment, "_world_figure", "world figure", "figures"),
    (experiment, "_world_curve_figures", "curve figures", "figures"),
]
for owner, name, label, _ in STEPS:
    timed(owner, name, label)

config = EXPERIMENTS[args.experiment]
if args.size not in config.sizes:
    parser.error(f"{args.experiment}'s worlds are {list(config.sizes)}, not {args.size}")
if args.preset:
    config = config.with_preset(args.preset)
if args.agents:
    config = dataclasses.replace(config, agents=tuple(args.agents))
if args.seeds:
    config = dataclasses.replace(config, seeds=args.seeds)
if args.tie_break:
    config = dataclasses.replace(
        config, learner=dataclasses.replace(config.learner, tie_break=args.tie_break)
    )
_, run_agents, _ = runner.batch_runs(config.agents, config.first_seed, config.seeds)

# The kernel's seconds per run (numba_engine._run_all fills them in per call), by agent kind.
kernel: dict[str, float] = defaultdict(float)
kernel_wall = 0.0
run_all = numba_engine._run_all


def _run_all_timed(stops, call_args, per_run):
    global kernel_wall
    start = time.perf_counter()
    run_all(stops, call_args, per_run)
    spent = time.perf_counter() - start
    kernel_wall += spent
    if len(run_agents) == 1:  # (one run: one call, no per-run seconds)
        per_run = [spent]
    for agent, s in zip(run_agents, per_run):
        kernel[agent] += float(s)
    if stack:  # the kernel's wall time is the learning's, not the engine's
        stack[-1][2] += spent


numba_engine._run_all = _run_all_timed

if args.bco_refit == "torch":
    from himit_torch.learner.cloned_policy import ClonedPolicy

    def _refit_in_torch(self, runs, model, mentor):
        runs = torch.as_tensor(runs, dtype=torch.int64).reshape(-1)
        runs = runs[self.rows.use_cloning.index_select(0, runs)]
        if runs.numel():
            S = self.rows.num_states
            self.action[runs, :S] = self.actions_in_torch(runs, model, mentor)

    ClonedPolicy.refit = _refit_in_torch  # type: ignore[method-assign]

run_dir = Path(args.logdir or tempfile.mkdtemp(prefix="himit-phases-")) / args.experiment
try:
    experiment.ExperimentStudy().prepare(config, run_dir, resume=False, force=True)
    start = time.perf_counter()
    experiment.run_world(config, args.size, run_dir, False, progress=False)
    total = time.perf_counter() - start
finally:
    if not args.logdir:
        shutil.rmtree(run_dir.parent, ignore_errors=True)

# The kernel's calls may overlap on two threads: its per-agent seconds (thread time) are shown
# as shares of its wall time.
kernel_threads = sum(kernel.values())
agents = ", ".join(config.agents)
print(
    f"{args.experiment} {args.size}×{args.size}, preset {config.preset or 'none'}, "
    f"{config.seeds} seeds of {agents}: imports {imports:.2f} s, kernels {kernels:.2f} s, "
    f"BCO's refit {args.bco_refit}, torch threads {torch.get_num_threads()}"
)
print(f"run_world {total:.2f} s")
groups: dict[str, float] = defaultdict(float)
labels_of: dict[str, list[str]] = defaultdict(list)
for _, _, label, group in STEPS:
    if label not in labels_of[group]:
        labels_of[group].append(label)
for group, labels in labels_of.items():
    groups[group] = sum(seconds[label] for label in labels)
groups["learning"] += kernel_wall
groups["other"] = total - sum(groups.values())
order = ("learning", "exact", "set-up", "maps", "figures", "logging", "checkpoints", "I/O", "other")
for group in order:
    print(f"  {group:34s} {groups[group]:7.2f}  ({100 * groups[group] / total:4.1f} %)")
    if group == "learning":
        for agent in config.agents:
            share = kernel[agent] / kernel_threads * kernel_wall if kernel_threads else 0.0
            print(f"    kernel, {agent:25s} {share:7.2f}")
    for label in labels_of.get(group, []):
        print(f"    {label:32s} {seconds[label]:7.2f}")
