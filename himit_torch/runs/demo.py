"""``himit demo``, the README's main job: experiment 2's world, the mentor's state-only
demonstrations (saved, with a picture like the paper's Fig. 2), then a short batched learning
run with figures and TensorBoard logs (about a minute on a laptop CPU)."""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import mentor_policy, run_mentor
from himit_torch.options.builders import mentor_options
from himit_torch.runs.config import EXPERIMENTS
from himit_torch.runs.experiment import run_experiment
from himit_torch.validation import check_folder_path
from himit_torch.viz.tensorboard import tensorboard_command
from himit_torch.worlds.multirooms import MultiRooms

__all__ = ["demo"]


def demo(
    out: Path, episodes: int, seed: int, seeds: int, steps: int, progress: bool = True
) -> Iterator[str]:
    """Record ``episodes`` of the mentor's demonstrations on experiment 2's world into ``out``
    (``demonstrations.npz``, ``world_mentor.png``), then (``steps`` > 0) a batch of
    imitation, options and primitives, ``seeds`` runs each, into ``out/learning``; yields the
    lines ``himit demo`` prints. A file where ``out`` belongs is a ``ValueError``."""
    check_folder_path("himit demo: --out", out)
    out.mkdir(parents=True, exist_ok=True)
    yield from _demonstrations(out, episodes, seed)
    if steps > 0:
        yield from _learning(out, episodes, seed, seeds, steps, progress)


def _demonstrations(out: Path, episodes: int, seed: int) -> Iterator[str]:
    from himit_torch.viz.plotting import save_world_figure  # matplotlib only when drawing

    world = MultiRooms(size=40, rooms=10)
    options = mentor_options(world)
    yield f"world     {world!r} (experiment 2)"
    mentor = mentor_policy(world, options)
    rollout = run_mentor(world, mentor, episodes, seed=seed)
    demos = Demonstrations(list(rollout.states), world.describe())
    lengths = demos.episode_lengths.double()
    yield (
        f"mentor    {options.num_options} options; {episodes} episodes, "
        f"{lengths.mean():.1f} steps on average (min {int(lengths.min())}, max "
        f"{int(lengths.max())}); decisions: "
        + ", ".join(f"{n} {k}" for k, n in sorted(rollout.decision_counts().items()))
    )
    npz = demos.save(out / "demonstrations.npz")
    png = save_world_figure(
        out / "world_mentor.png",
        world,
        demos,
        title=f"Mentor demonstrations ({episodes} episodes), 40×40, 10×10 rooms",
    )
    yield (
        f"saved     {npz}  (states only: {demos.num_transitions} transitions, "
        f"{len(demos.visited_states())} distinct states)"
    )
    yield f"saved     {png}"


def _learning(
    out: Path, episodes: int, seed: int, seeds: int, steps: int, progress: bool
) -> Iterator[str]:
    config = replace(
        EXPERIMENTS["exp2"],
        name="demo",
        agents=("imitation", "options", "primitives"),
        seeds=seeds,
        first_seed=seed,
        steps=steps,
        mentor_episodes=episodes,
        window=min(5000, steps),
        checkpoint_every=min(5000, steps),
    )
    yield (
        f"learning  {len(config.agents)} agents × {config.seeds} seeds = "
        f"{len(config.agents) * config.seeds} runs in one batch, {config.steps:,} steps each"
    )
    t0 = time.perf_counter()
    results = run_experiment(config, out / "learning", force=True, progress=progress)
    r = results[0]
    for agent in config.agents:
        yield (
            f"  {agent:<12} goals in the last {config.window} steps: "
            + ", ".join(str(g) for a, g in zip(r.agents, r.final_window_goals) if a == agent)
            + f"   (optimal ≈ {r.optimal_goals_per_window:.1f})"
        )
    yield (
        f"saved     {out / 'learning'}/results.md, figures/, curves.csv  "
        f"({time.perf_counter() - t0:.0f} s)"
    )
    yield f"watch     {tensorboard_command(out / 'learning' / 'tb')}"
