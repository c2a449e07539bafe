"""The CUDA path: the torch engine on a GPU against the compiled engine on the CPU, and big batches.

1. Parity: the same batch (every agent variant, 12×12 world, 5000 ticks) on ``device="cuda"``
   (torch engine) and on the CPU (compiled engine): decisions, goals and values compared. On a GPU
   ``index_add_`` adds repeated indices in no fixed order, so values may differ in the last bits;
   this reports how far they drift and whether any decision differs.
2. Throughput of the torch engine on the GPU for large batches (experiment 2's 40×40 world).

    python benchmarks/gpu_check.py [--batches 256 1024 4096] [--steps 2000]
"""

import argparse
import time

import torch

from himit_torch import (
    Learner,
    LearnerConfig,
    MultiRooms,
    learner_options,
    mentor_options,
    mentor_policy,
    record_demonstrations,
)

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("--batches", type=int, nargs="+", default=[256, 1024, 4096])
parser.add_argument("--steps", type=int, default=2000)
args = parser.parse_args()
if not torch.cuda.is_available():
    raise SystemExit("no CUDA device")
print(torch.cuda.get_device_name(), torch.__version__)

world = MultiRooms(12, 2)
demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 5, seed=0)
agents = ["imitation", "options", "primitives", "imitation_confident", "imitation_primitives"]
config = LearnerConfig(plan_every=4, sweep_rounds=1, window=1000)
runs = {}
for device, engine in (("cpu", "numba"), ("cuda", "torch")):
    learner = Learner(
        world,
        learner_options(world),
        agents,
        range(5),
        config=config,
        demonstrations=demos,
        device=device,
        engine=engine,
    )
    learner.run(5000)
    runs[device] = learner
cpu, gpu = runs["cpu"], runs["cuda"]
same_rows = torch.equal(cpu.run_state.row, gpu.run_state.row.cpu())
same_goals = torch.equal(cpu.views.goals, gpu.views.goals.cpu())
same_curves = torch.equal(cpu.metrics.curve(), gpu.metrics.curve())
drift = (cpu.views.state_values() - gpu.views.state_values().cpu()).abs().max().item()
print(
    f"parity 12x12, 5 agents, 5000 ticks: same decisions {same_rows}, same goals {same_goals}, "
    f"same curves {same_curves}, max |V_cpu - V_cuda| = {drift:.3g}"
)
print("goals cpu", cpu.views.goals.tolist(), "cuda", gpu.views.goals.cpu().tolist())

world = MultiRooms(40, 10)
demos = record_demonstrations(world, mentor_policy(world, mentor_options(world)), 20, seed=0)
for batch in args.batches:
    mix = ["imitation", "options", "primitives"]
    learner = Learner(
        world,
        learner_options(world),
        [mix[b % 3] for b in range(batch)],
        range(batch),
        config=config,
        demonstrations=demos,
        device="cuda",
        engine="torch",
    )
    learner.run(100)
    torch.cuda.synchronize()
    start = time.perf_counter()
    learner.run(args.steps)
    torch.cuda.synchronize()
    seconds = time.perf_counter() - start
    print(
        f"cuda torch engine 40x40 B={batch}: {batch * args.steps / seconds:,.0f} steps/s "
        f"({seconds:.1f} s for {args.steps} ticks), peak {torch.cuda.max_memory_allocated() / 2**20:,.0f} MiB",
        flush=True,
    )
