"""Soak benchmark: a long run's memory and its final checkpoint (not a test).

Runs ``--total-steps`` primitive steps (summed over the batch) on experiment 1's world (80×80,
10×10 rooms, the learner's corner options, 20 mentor episodes per seed) with experiment 1's
agents and learner settings, saving a checkpoint generation (``himit_torch.runs.checkpoints``) every
``--checkpoint-every`` steps. At every checkpoint it records the process's current and peak
resident memory (``/proc/self/statm``, ``getrusage``), the model sizes (edges of the fullest run)
and the wall time. At the end it

* fits the growth of the current RSS per million steps over the second half of the run (where the
  models have saturated: no new edges are being added at a noticeable rate), and
* resumes a fresh learner from the checkpoint before the last one, runs it to the end and checks
  that its state equals the uninterrupted run's, tensor for tensor (``--no-resume-check`` skips
  this).

Usage (from the project root)::

    .venv/bin/python benchmarks/soak.py                        # 10 M steps, B = 20 (exp1's batch)
    .venv/bin/python benchmarks/soak.py --total-steps 1000000  # a short try
    .venv/bin/python benchmarks/soak.py --json soak.json       # also write the curve as JSON
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import tempfile
import time
from pathlib import Path

import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from himit_torch.learner.learner import Learner  # noqa: E402
from himit_torch.mentor.policy import mentor_policy, record_demonstrations  # noqa: E402
from himit_torch.options.builders import learner_options, mentor_options  # noqa: E402
from himit_torch.runs.checkpoints import BatchShape, CheckpointGenerations  # noqa: E402
from himit_torch.runs.config import EXPERIMENTS  # noqa: E402


def rss_mib() -> float:
    """Current resident set size of this process, MiB."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * resource.getpagesize() / 2**20


def peak_rss_mib() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # KiB on Linux


def build(seeds: int, engine: str):
    config = EXPERIMENTS["exp1"]
    world = config.world(config.sizes[0])
    options = learner_options(world, corners=config.corner_options)
    mentor = mentor_policy(
        world, mentor_options(world, corners=config.corner_options), config.mentor_preference
    )
    seed_list = list(range(seeds))
    agents = [a for a in config.agents for _ in seed_list]
    run_seeds = [s for _ in config.agents for s in seed_list]
    learner = Learner(world, options, agents, run_seeds, config=config.learner, engine=engine)
    for s in seed_list:
        demos = record_demonstrations(world, mentor, config.mentor_episodes, seed=s)
        learner.add_demonstrations(demos, runs=[b for b, rs in enumerate(run_seeds) if rs == s])
    return learner, BatchShape(agents, run_seeds, world.num_states)


def same_state(a, b, where: str = "state") -> list[str]:
    """Paths where two state dicts differ (empty: identical)."""
    if isinstance(a, torch.Tensor):
        # bit for bit, NaN equal to NaN (a window without an episode has a NaN mean length)
        same = (
            isinstance(b, torch.Tensor)
            and a.shape == b.shape
            and a.dtype == b.dtype
            and bool(
                ((a == b) | (a.isnan() & b.isnan()) if a.is_floating_point() else a == b).all()
            )
        )
        return [] if same else [where]
    if isinstance(a, dict):
        if not isinstance(b, dict) or set(a) != set(b):
            return [where]
        return [d for k in a for d in same_state(a[k], b[k], f"{where}.{k}")]
    if isinstance(a, (list, tuple)):
        if not isinstance(b, (list, tuple)) or len(a) != len(b):
            return [where]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in same_state(x, y, f"{where}[{i}]")]
    return [] if a == b or (a != a and b != b) else [where]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--total-steps",
        type=int,
        default=10_000_000,
        help="primitive steps summed over the batch (default 10 M)",
    )
    p.add_argument(
        "--checkpoint-every",
        type=int,
        default=500_000,
        help="steps (summed over the batch) between checkpoints (default 500 k)",
    )
    p.add_argument("--seeds", type=int, default=5, help="seeds per agent (exp1: 5 → B = 20)")
    p.add_argument("--engine", default="auto")
    p.add_argument("--dir", default=None, help="checkpoint folder (default: a temporary one)")
    p.add_argument("--json", default=None, help="write the memory curve here as JSON")
    p.add_argument("--no-resume-check", action="store_true")
    args = p.parse_args()

    t0 = time.perf_counter()
    learner, batch = build(args.seeds, args.engine)
    B = learner.batch
    window = learner.config.window
    ticks_per_ckpt = args.checkpoint_every // B
    ticks_per_ckpt -= ticks_per_ckpt % window  # the learner records metrics per window
    if ticks_per_ckpt < window:
        p.error(
            f"--checkpoint-every {args.checkpoint_every} is less than one window "
            f"({window} ticks × B = {B})"
        )
    total_ticks = args.total_steps // B // ticks_per_ckpt * ticks_per_ckpt
    setup_s = time.perf_counter() - t0
    print(
        f"B = {B} runs on {learner.num_states} states, {learner.num_options} options, engine "
        f"{learner.engine.name}; {total_ticks} ticks = {total_ticks * B:,} steps, a checkpoint "
        f"every {ticks_per_ckpt} ticks = {ticks_per_ckpt * B:,} steps; set-up {setup_s:.1f} s, "
        f"RSS {rss_mib():.0f} MiB",
        flush=True,
    )

    tmp = None
    if args.dir is None:
        tmp = tempfile.TemporaryDirectory(prefix="himit-soak-")
        folder = Path(tmp.name)
    else:
        folder = Path(args.dir)
    generations = CheckpointGenerations(folder / "soak.pt")
    generations.clear()
    layout = Learner.STATE_LAYOUT_VERSION
    curve = [
        {
            "steps": 0,
            "rss_mib": rss_mib(),
            "peak_rss_mib": peak_rss_mib(),
            "edges": 0,
            "mentor_edges": int(learner.mentor.num_edges.max()),
            "wall_s": 0.0,
        }
    ]
    print(
        f"{'steps':>12} {'RSS MiB':>8} {'peak MiB':>9} {'edges':>7} {'ckpt MiB':>9} {'wall s':>7}",
        flush=True,
    )
    start = time.perf_counter()
    while learner.views.t < total_ticks:
        learner.run(ticks_per_ckpt)
        generations.save(
            {"learner": learner.state_dict()},
            step=learner.views.t,
            batch=batch,
            state_layout_version=layout,
        )
        row = {
            "steps": learner.views.t * B,
            "rss_mib": rss_mib(),
            "peak_rss_mib": peak_rss_mib(),
            "edges": int(learner.model.num_edges.max()),
            "mentor_edges": int(learner.mentor.num_edges.max()),
            "checkpoint_mib": generations.newest.stat().st_size / 2**20,
            "wall_s": time.perf_counter() - start,
        }
        curve.append(row)
        print(
            f"{row['steps']:>12,} {row['rss_mib']:>8.0f} {row['peak_rss_mib']:>9.0f} "
            f"{row['edges']:>7} {row['checkpoint_mib']:>9.1f} {row['wall_s']:>7.1f}",
            flush=True,
        )

    half = [r for r in curve if r["steps"] >= curve[-1]["steps"] / 2]
    xs = torch.tensor([r["steps"] / 1e6 for r in half], dtype=torch.float64)
    ys = torch.tensor([r["rss_mib"] for r in half], dtype=torch.float64)
    slope = (
        float(((xs - xs.mean()) * (ys - ys.mean())).sum() / ((xs - xs.mean()) ** 2).sum())
        if len(half) > 1
        else float("nan")
    )
    edge_growth = (half[-1]["edges"] - half[0]["edges"]) / max(1e-9, float(xs[-1] - xs[0]))
    summary = {
        "batch": B,
        "total_steps": curve[-1]["steps"],
        "setup_s": setup_s,
        "run_s": curve[-1]["wall_s"],
        "rss_growth_mib_per_million_steps": slope,
        "edge_growth_per_million_steps": edge_growth,
        "final_peak_rss_mib": curve[-1]["peak_rss_mib"],
        "curve": curve,
    }
    print(
        f"second half: RSS grows {slope:+.2f} MiB per million steps (least squares over "
        f"{len(half)} checkpoints); the fullest run's model gains {edge_growth:.0f} edges per "
        "million steps",
        flush=True,
    )

    if not args.no_resume_check:
        # The previous generation is the checkpoint before the last: resume from it and run the
        # last interval again; the result must equal the uninterrupted run's final state.
        final = learner.state_dict()
        resumed_learner, _ = build(args.seeds, args.engine)
        found = generations.load(expect_batch=batch, expect_layout=layout)
        assert found is not None
        prev = found.checkpoint.path
        from himit_torch.runs.checkpoints import read_checkpoint

        ckpt = read_checkpoint(generations.previous, expect_batch=batch, expect_layout=layout)
        resumed_learner.load_state_dict(ckpt.payload["learner"])
        from_step = resumed_learner.views.t
        resumed_learner.run(total_ticks - from_step)
        differ = same_state(final, resumed_learner.state_dict())
        # and the newest checkpoint itself loads into a fresh learner and runs on
        newest = read_checkpoint(prev, expect_batch=batch, expect_layout=layout)
        fresh, _ = build(args.seeds, args.engine)
        fresh.load_state_dict(newest.payload["learner"])
        fresh.run(window)
        summary["resume"] = {
            "from_step": from_step * B,
            "to_step": total_ticks * B,
            "identical": not differ,
            "differences": differ[:10],
            "final_checkpoint_loads_and_runs": fresh.views.t == total_ticks + window,
        }
        print(
            f"resume: from the checkpoint at {from_step * B:,} steps to {total_ticks * B:,}: "
            f"{'identical to the uninterrupted run' if not differ else f'DIFFERS at {differ[:5]}'}"
            f"; the final checkpoint loads into a fresh learner and runs on: "
            f"{summary['resume']['final_checkpoint_loads_and_runs']}",
            flush=True,
        )
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=1))
    if tmp is not None:
        tmp.cleanup()
    return 0 if summary.get("resume", {}).get("identical", True) else 1


if __name__ == "__main__":
    sys.exit(main())
