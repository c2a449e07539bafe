"""Write ``quickstart.ipynb`` and ``intrinsic_reward.ipynb`` from the cells below, and (with
``--execute``) run them top to bottom in place so that they are committed with their outputs.

    .venv/bin/python notebooks/build_notebooks.py --execute     # a few minutes on a laptop CPU

Edit the notebooks here, not in Jupyter, so that text and code stay reviewable in one place.
The budgets come from environment variables (``HIMIT_NOTEBOOK_STEPS``, ``HIMIT_NOTEBOOK_SEEDS``);
the tests run both notebooks with tiny ones (``tests/test_notebooks.py``).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent

# ============================================================================== quickstart
QUICKSTART = [
    new_markdown_cell("""\
# Quickstart: a learner that watches a mentor's states

The shortest path through `himit_torch`: build experiment 2's world and the learner's options,
record a mentor's state-only demonstrations, learn with a small batch of agents, and look at the
learning curve and the value map.

The budget is `STEPS` primitive steps per run (the environment variable `HIMIT_NOTEBOOK_STEPS`
overrides it; the tests run this notebook with a tiny one)."""),
    new_code_cell("""\
import os
from collections import Counter

import matplotlib.pyplot as plt
import torch

import himit_torch as ht
from himit_torch.plotting import plot_world

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 15_000))   # primitive steps per run
WINDOW = 1000 if STEPS >= 4000 else max(STEPS // 4, 1)        # goals are counted per window
torch.set_num_threads(1)            # tiny tensors: one thread is fastest
plt.rcParams["figure.dpi"] = 72"""),
    new_markdown_cell("""\
## The world and the learner's options

A 40×40 grid split into 10×10 rooms joined by single-cell doorways. Actions slip 10 % of the
time; −0.01 a step, +1 at the goal (bottom-right). The learner's options: 4 primitives and, in
every room, one option per doorway that heads *directly* to it."""),
    new_code_cell("""\
world = ht.MultiRooms(size=40, rooms=10)
options = ht.learner_options(world)
print(world)
print(options.num_options, "options:", dict(Counter(options.kinds)))"""),
    new_markdown_cell("""\
## The mentor and its demonstrations

The mentor has its own options (doorway options that travel *along the walls*) and runs the
optimal policy for them. The learner gets only the mentor's states — no actions, no rewards."""),
    new_code_cell("""\
mentor = ht.mentor_policy(world, ht.mentor_options(world))
demos = ht.record_demonstrations(world, mentor, episodes=20, seed=0)
print(demos)
fig, ax = plt.subplots(figsize=(4.5, 4.8))
plot_world(world, demonstrations=demos, ax=ax)
plt.show()"""),
    new_markdown_cell("""\
## Learning: a batch of runs in one tensor program

Each entry of `agents` is one run with its own seed: three imitators (options + the mentor term
of eq. 2) and three that use their options without a mentor."""),
    new_code_cell("""\
agents = ["imitation"] * 3 + ["options"] * 3
seeds = [0, 1, 2] * 2
learner = ht.Learner(world, options, agents, seeds, demonstrations=demos,
                     config=ht.LearnerConfig(window=WINDOW))
learner.run(STEPS)
for agent, seed, first, goals in zip(agents, seeds, learner.first_goal_step.tolist(),
                                     learner.goals.tolist()):
    print(f"{agent:>9} seed {seed}: first goal at step {first:>6} (−1: never), {goals} goals")"""),
    new_code_cell("""\
curve = learner.metrics.curve().double()          # [windows, runs] goals per window
steps = learner.metrics.steps
fig, ax = plt.subplots(figsize=(6, 3.2))
for agent, color in (("imitation", "C0"), ("options", "C1")):
    runs = [b for b, a in enumerate(agents) if a == agent]
    ax.plot(steps, curve[:, runs], color=color, alpha=0.3, linewidth=0.8)
    ax.plot(steps, curve[:, runs].mean(1), color=color, linewidth=2,
            label=f"{agent} (mean of {len(runs)})")
ax.set_xlabel("steps")
ax.set_ylabel(f"goals per {WINDOW} steps")
ax.legend()
plt.show()"""),
    new_markdown_cell("""\
## What the imitator believes: its value map and greedy path

`learner.state_values()` is `[runs, S]`. The orange line is one episode that follows run 0's
greedy options from the start."""),
    new_code_cell("""\
values = learner.state_values()[0].clone()
values[world.wall_mask] = float("nan")
path = learner.greedy_trajectory(0, max_steps=2000, seed=0)
rows, cols = path // world.size, path % world.size
fig, ax = plt.subplots(figsize=(5, 4.2))
image = ax.imshow(values.view(world.size, world.size), cmap="viridis")
ax.plot(cols, rows, color="#e8590c", linewidth=1.2)
ax.set_title(f"V of run 0 ({agents[0]}) after {learner.t} steps")
ax.set_xticks([]); ax.set_yticks([])
fig.colorbar(image, ax=ax, shrink=0.8)
plt.show()"""),
    new_markdown_cell("""\
## Next

* `notebooks/intrinsic_reward.ipynb`: the mentor term with an *intrinsic* reward computed from
  salient events in the mentor's states, against the known reward and no mentor.
* `himit run exp2` reproduces the paper's experiment 2 (5 seeds, 200k steps) with TensorBoard
  logs: `tensorboard --logdir runs/exp2/tb`.
* Your own world, options or demonstrations: see "Using the library" in `README.md`."""),
]

# ========================================================================= intrinsic reward
INTRINSIC = [
    new_markdown_cell("""\
# Intrinsic reward from the mentor's salient events

The paper (Section II) suggests that the reward an observer assigns to a mentor's moves, `R_m`
in the mentor term of eq. 2, need not be the known task reward: *as the mentor moves it
triggers salient stimuli — changes of light or sound — which generate reward for the observer.*
`ht.SalienceReward` is such a reward. It reads only the mentor's states and the world's
stimulus features, never the world's reward:

* **room** — the mentor enters a room from outside it (through a doorway);
* **end** — the place where the mentor's episodes stop (learned: `ε(s')` = share of its
  arrivals at `s'` that ended an episode — the goal, without being told);
* **novelty** — states the mentor was rarely in (`decay ** (sightings − 1)`);
* **stimulus** — a change of the `light` / `sound` channels between consecutive states.

Its reward for a mentor step `s → s'` interpolates between a terminal reward and a step reward,
`r = e·bound + (1 − e)·(scale·σ − step_cost)`, with `σ` the weighted step salience and `e` the
weighted end event, both clipped to [0, 1].

**Soundness.** The mentor term is trusted without correction, so `R_m` must not overestimate
the learner's real reward (−0.01 a step, +1 at the goal). The module declares
`upper_bound = bound` (0.5 by default), which the learner checks against its best real reward.
The defaults go further: an ordinary mentor step costs `step_cost = 0.02`, a fully salient one
`step_cost − scale = 0.01` — never less than a real step — and the end pays 0.5 < 1. So
salience makes the mentor's salient steps *cheaper*, never rewarding, and no transition is
overestimated. This notebook also runs two modules that break this, to show what it costs.

Budget: `STEPS` per run and `SEEDS` seeds per variant (environment variables
`HIMIT_NOTEBOOK_STEPS`, `HIMIT_NOTEBOOK_SEEDS`). The outputs stored with the notebook come from
the defaults below: 5 seeds × 100,000 steps × 6 variants, about 4 minutes on one CPU core."""),
    new_code_cell("""\
import os
from pathlib import Path

import matplotlib.pyplot as plt
import torch
from torch.utils.tensorboard import SummaryWriter

import himit_torch as ht
from himit_torch.experiment import PAPER

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 100_000))  # primitive steps per run
SEEDS = int(os.environ.get("HIMIT_NOTEBOOK_SEEDS", 5))        # runs per variant
LOGDIR = Path(os.environ.get("HIMIT_NOTEBOOK_LOGDIR", "runs/intrinsic_reward"))
WINDOW = 5000 if STEPS >= 20_000 else max(STEPS // 4, 1)       # the paper's 5000-step windows
torch.set_num_threads(1)
plt.rcParams["figure.dpi"] = 72

world = ht.MultiRooms(size=40, rooms=10)                   # experiment 2's world
options = ht.learner_options(world)                        # primitives + direct doorway options
mentor = ht.mentor_policy(world, ht.mentor_options(world))
demos = {seed: ht.record_demonstrations(world, mentor, episodes=20, seed=seed)
         for seed in range(SEEDS)}                         # each seed watches its own episodes
print(world, "|", options.num_options, "options |", demos[0])"""),
    new_markdown_cell("""\
## The salience map, from the mentor's states alone

Per state, the total salience of the mentor's arrivals there (all four events, weighted and
clipped to [0, 1]). The world's stimulus features are `[S, 4]`: room, doorway flag, light,
sound. Light and sound are off unless you set them. On the right, lamps light rows 16–23
(`world.set_stimulus("light", …)`) and only light changes count (`weights` of room and
novelty 0): the mentor's steps into and out of the lit band stand out."""),
    new_code_cell("""\
salience = ht.SalienceReward(world, demos[0])
print(salience)
print("features:", tuple(world.stimulus_features().shape), world.stimulus_feature_names)

lit = ht.MultiRooms(size=40, rooms=10)
lamp = torch.zeros(world.size, world.size)
lamp[16:24] = 1.0                                            # rows 16–23 are lit
lit.set_stimulus("light", lamp.flatten())
lit_salience = ht.SalienceReward(lit, demos[0], weights={"room": 0.0, "novelty": 0.0})

CMAP = plt.get_cmap("magma").copy()
CMAP.set_bad("0.8")                                          # walls grey

def show(ax, field, title):
    field = field.clone().double()
    field[world.wall_mask] = float("nan")
    image = ax.imshow(field.view(world.size, world.size), cmap=CMAP, vmin=0, vmax=1)
    ax.set_title(title, fontsize=10)
    ax.set_xticks([]); ax.set_yticks([])
    return image

maps = salience.event_maps()
fig, axes = plt.subplots(1, 4, figsize=(13, 3.6), layout="constrained")
show(axes[0], salience.salience_map(), "total salience")
show(axes[1], maps["room"], "room entered")
show(axes[2], maps["novelty"], "novelty (the mentor's slips)")
image = show(axes[3], lit_salience.salience_map(), "light changes only (rows 16–23 lit)")
fig.colorbar(image, ax=axes, shrink=0.8)
plt.show()

src, dst = demos[0].transitions()
r = salience.transition_reward(src, dst)
print(f"rewards of the mentor's steps: min {r.min():.4f}, max {r.max():.4f}; "
      f"steps paying > 0: {int((r > 0).sum())} of {len(r)} (all into the goal); "
      f"cycle-safe: {salience.cycle_safe}; a step's reward lies in {salience.step_reward_range}")"""),
    new_markdown_cell("""\
## Known vs intrinsic vs no mentor reward, in one batch

Six variants × `SEEDS` seeds, all in one `Learner` batch; each run has its own reward module
(`reward=[…]`, one per run):

| variant | agent | `R_m` | a mentor step pays |
|---|---|---|---|
| `known` | imitation | the world's reward (the paper's experiments) | −0.01, +1 into the goal |
| `intrinsic` | imitation | `SalienceReward` with its defaults (sound) | −0.02 … −0.01, +0.5 at the end |
| `intrinsic_no_end` | imitation | the same without the end event (`weights={"end": 0}`) | −0.02 … −0.01 everywhere |
| `intrinsic_free` | imitation | salient steps free: `scale = step_cost = 0.01` (cycle-safe, optimistic) | −0.01 … 0, +0.5 |
| `intrinsic_paying` | imitation | salient steps pay: `scale=0.1, step_cost=0` (not cycle-safe) | 0 … +0.1, +0.5 |
| `none` | options | no mentor term (options only) | — |

Every window's goals are also logged to TensorBoard, one run per folder, as `himit run` does."""),
    new_code_cell("""\
VARIANTS = {   # name: (agent, reward module for one seed)
    "known": ("imitation", lambda seed: ht.KnownReward(world)),
    "intrinsic": ("imitation", lambda seed: ht.SalienceReward(world, demos[seed])),
    "intrinsic_no_end": ("imitation",
                         lambda seed: ht.SalienceReward(world, demos[seed], weights={"end": 0.0})),
    "intrinsic_free": ("imitation",
                       lambda seed: ht.SalienceReward(world, demos[seed], scale=0.01, step_cost=0.01)),
    "intrinsic_paying": ("imitation",
                         lambda seed: ht.SalienceReward(world, demos[seed], scale=0.1, step_cost=0.0)),
    "none": ("options", lambda seed: ht.KnownReward(world)),   # unused: no mentor term
}
names, agents, seeds, modules = [], [], [], []
for name, (agent, make) in VARIANTS.items():
    for seed in range(SEEDS):
        names.append(name); agents.append(agent); seeds.append(seed); modules.append(make(seed))

learner = ht.Learner(world, options, agents, seeds, reward=modules,
                     config=ht.LearnerConfig(window=WINDOW))
for seed in range(SEEDS):
    learner.add_demonstrations(demos[seed], runs=[b for b, s in enumerate(seeds) if s == seed])

writers = [SummaryWriter(str(LOGDIR / "tb" / f"world40__{n}__seed{s}")) for n, s in zip(names, seeds)]
for writer, name, seed, module in zip(writers, names, seeds, modules):
    writer.add_text("run", f"variant {name}, agent {VARIANTS[name][0]}, seed {seed}, reward {module!r}")
while learner.t < STEPS:
    learner.run(min(WINDOW, STEPS - learner.t))
    m = learner.metrics
    if m.steps and m.steps[-1] == learner.t:
        values_start = learner.state_values()[:, world.start_state]
        for b, writer in enumerate(writers):
            writer.add_scalar("charts/goals_in_window", float(m.goals_in_window[-1][b]), learner.t)
            writer.add_scalar("charts/epsilon", float(m.epsilon[-1][b]), learner.t)
            writer.add_scalar("model/value_start", float(values_start[b]), learner.t)
            wins = float(m.mentor_term_wins[-1][b])
            if wins == wins:                               # NaN for runs without a mentor
                writer.add_scalar("mentor/term_wins", wins, learner.t)
for writer in writers:
    writer.close()
print(f"{learner.batch} runs × {learner.t} steps; TensorBoard logs in {LOGDIR / 'tb'}")"""),
    new_code_cell("""\
curve = learner.metrics.curve().double()                  # [windows, runs]
steps = learner.metrics.steps
optimal = PAPER["exp2"]["optimal_goals_per_5000"] * WINDOW / 5000
fig, ax = plt.subplots(figsize=(9.5, 4), layout="constrained")
for i, name in enumerate(VARIANTS):
    runs = [b for b, n in enumerate(names) if n == name]
    ax.plot(steps, curve[:, runs], color=f"C{i}", alpha=0.25, linewidth=0.8)
    ax.plot(steps, curve[:, runs].mean(1), color=f"C{i}", linewidth=2,
            label=f"{name} (mean of {len(runs)})")
ax.axhline(optimal, color="0.5", linestyle=":", label="optimal (the paper)")
ax.set_xlabel("steps")
ax.set_ylabel(f"goals per {WINDOW} steps")
ax.set_title("40×40, 10×10 rooms: mentor term with known, intrinsic or no reward")
ax.legend(fontsize="small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
plt.show()"""),
    new_code_cell("""\
true_v = ht.value_iteration(world.transition_model(), world.reward_model(), world.gamma).values
v_star = float(true_v[world.start_state])
v_start = learner.state_values()[:, world.start_state]
wins = learner.mentor_win_share()
last = curve[-4:].mean(0) if len(curve) >= 4 else curve.mean(0)
print(f"V*(start) = {v_star:.3f} (true optimum, primitive actions)\\n")
print(f"{'variant':<19}{'seed':>5}{'first goal':>12}{'goals':>8}{'last 4 windows':>16}"
      f"{'V(start)':>10}{'mentor wins':>13}")
for b in range(learner.batch):
    print(f"{names[b]:<19}{seeds[b]:>5}{int(learner.first_goal_step[b]):>12}{int(learner.goals[b]):>8}"
          f"{float(last[b]):>16.1f}{float(v_start[b]):>10.3f}{float(wins[b]):>13.2f}")
print()
for name in VARIANTS:
    runs = [b for b, n in enumerate(names) if n == name]
    firsts = learner.first_goal_step[runs]
    found = firsts >= 0
    mean_first = f"{firsts[found].double().mean():.0f}" if bool(found.any()) else "—"
    print(f"{name:<19} found the goal in {int(found.sum())}/{len(runs)} runs, mean first goal "
          f"{mean_first}, total goals {learner.goals[runs].double().mean():.0f}, "
          f"last 4 windows {last[runs].mean():.1f}, V(start) {v_start[runs].mean():.3f}")"""),
    new_markdown_cell("""\
## Where the learners go

Visits of one run of three intrinsic variants (log scale) and, in orange, one episode that
follows its greedy options from the start (at most 2000 steps). If salient steps pay, the
learner's values rise far above anything real (compare `V(start)` above with `V*(start)`): a
doorway it can step through and back again is worth about `r / (1 − γ²)` to it, while it pays
the real step cost every time."""),
    new_code_cell("""\
fig, axes = plt.subplots(1, 3, figsize=(12, 4), layout="constrained")
VISITS_CMAP = plt.get_cmap("viridis").copy()
VISITS_CMAP.set_bad("0.8")
for ax, name in zip(axes, ("intrinsic", "intrinsic_free", "intrinsic_paying")):
    b = names.index(name)
    visits = learner.visit_counts()[b].double().log1p()
    visits[world.wall_mask] = float("nan")
    ax.imshow(visits.view(world.size, world.size), cmap=VISITS_CMAP)
    path = learner.greedy_trajectory(b, max_steps=2000, seed=0)
    ax.plot(path % world.size, path // world.size, color="#e8590c", linewidth=1.2)
    reached = bool(world.terminal_mask[path[-1]])
    ax.set_title(f"{name}, seed {seeds[b]}", fontsize=10)
    ax.set_xticks([]); ax.set_yticks([])
    top = torch.bincount(path, minlength=world.num_states).topk(2)
    print(f"{name:<19} greedy episode: {len(path) - 1:>4} steps, "
          f"{'reaches the goal' if reached else 'no goal'}, {len(torch.unique(path))} distinct "
          f"states; most visited {[world.coords(s) for s in top.indices.tolist()]} "
          f"({int(top.values.sum())} of its steps)")
plt.show()"""),
    new_markdown_cell("""\
## What we see, and why

*(Written from the stored run: 5 seeds × 100,000 steps. With other budgets the numbers above
differ.)*

**The sound intrinsic reward did better than the known reward.** Over 100,000 steps the
`intrinsic` runs reached the goal 965 times on average (959–968 per seed) against 891 (814–936)
with the known reward, and ended at 51.8 goals per 5000 steps against 48.5 (the exact optimum is
54.7; the paper says ≈ 53.2). Their first goals came as early (mean step 3524 vs 3336; seed 0 found it at the same
step, 876). Salience is not the reason: what differs is the *level* of `R_m` against the real
reward.

* The mentor term enters the max of eq. 2 and nothing ever corrects it. With the known reward
  it is already **optimistic**: the known learners believe `V(start)` ≈ −0.162 while the true
  optimum is −0.192 (the mentor model lumps the mentor's wall-following moves into one step
  model per state; `shared/docs/REPRODUCTION-NOTES.md`, point 3). The inflated values keep
  pulling the learner back onto the mentor's route — the mentor term still wins at 61–78 % of
  the mentor's states at the end.
* The default `SalienceReward` charges 0.01–0.02 per mentor step (never less than the real
  0.01) and pays 0.5 at the end (less than the real 1.0): a **pessimistic** mentor term
  (`V(start)` ≈ −0.211). It guides the learner to the goal early — any route that ends in the
  goal beats the −1 of the unknown — and then loses the max wherever the learner's own
  experience of the real +1 is better: the mentor term wins at only 52–76 % of the mentor's
  states, and the learner settles on its own direct doorway options.
* A separate run (not in this notebook, same seeds) with `scale=0, step_cost=0.01` — exactly
  the real step cost, 0.5 at the end — behaved like the known reward (880 goals, 48.6 per
  window at the end, `V(start)` ≈ −0.165): the smaller end reward alone does not explain the
  gain; charging more than the real step cost does.

**The end event speeds up the first goal, not the final rate.** Without it
(`intrinsic_no_end`: no reward above −0.01 anywhere) the learners end as well (52.3 per window,
960 goals) but find the goal later (mean step 5336 vs 3524). Even without any positive reward the
mentor term helps, because this learner knows which states are terminal (value 0) and starts
every other state at −1: a mentor route that ends in a terminal state is already attractive. A
learner that did not know where episodes end would depend on the end event.

**Where intrinsic reward is worse: when it overestimates.**

* `intrinsic_free` makes salient steps free (`scale = step_cost = 0.01`). That is cycle-safe,
  but the ~20 room entries of each mentor episode now cost 0 instead of 0.01: `V(start)` ≈
  −0.049, far above the true −0.192. The mentor term wins more (73–81 %), and the learners do
  worse than with the known reward: 771 goals, 44.0 per window at the end (36.2–50.8 per seed),
  first goal at step 4120 on average.
* `intrinsic_paying` lets salient steps pay +0.1. The learners farm it: their values reach
  `V(start)` ≈ 3.7–4.1 (nothing real exceeds 1), their greedy policy steps back and forth between
  the first doorways — 1814 of 2000 steps of one greedy episode on two doorway cells, (2, 4)
  and (4, 6) — and they reach the goal 0 or 1 times in 100,000 steps. Stepping through a doorway
  and back is worth about 0.1 / (1 − γ²) ≈ 5 to them; their own experience cannot correct it,
  because the mentor term is never checked against it.

**Without a mentor** (`none`, options only) one run never found the goal and one found it only
at step 97,145; the other three needed 10–31k steps (504 goals on average). The three that found
it early end at 51.8–53.0 per window, above the known-reward imitators (48.5) and level with the
sound intrinsic ones: with no mentor term nothing pulls them off their own best route (the notes
report imitation 1–4 goals below the non-imitators in experiment 2, as here).

**In short:** in this world the intrinsic learner works as well as the known reward, and better,
*because* its reward is a cautious lower bound; the salient events themselves (rooms, slips,
lights) only shift step costs by at most 0.01 and are not what decides the result. Salience
that makes the mentor's steps look better than they are is harmful, and salience that pays is
fatal. A fair test of salience as information — worlds where the learner does not know the
goal, or rewards that do not follow the mentor's route — is left open."""),
    new_markdown_cell("""\
## The same runs in TensorBoard

Every run above wrote its scalars (`charts/goals_in_window`, `charts/epsilon`,
`model/value_start`, `mentor/term_wins`) to its own folder `world40__<variant>__seed<k>` under
`LOGDIR/tb`, the layout `himit run` uses. Open them with

```bash
.venv/bin/tensorboard --logdir runs/intrinsic_reward/tb
```

(run from the folder this notebook ran in; the next cell prints the exact path), then filter runs
with a regex such as `intrinsic_paying|known`. In a notebook, `%load_ext tensorboard` and
`%tensorboard --logdir runs/intrinsic_reward/tb` embed it."""),
    new_code_cell("""\
print(f"tensorboard --logdir {LOGDIR / 'tb'}")
print(len(list((LOGDIR / "tb").glob("world40__*"))), "run folders")"""),
]


def build() -> dict[str, nbformat.NotebookNode]:
    """The two notebooks, unexecuted."""
    out = {}
    for name, cells in (("quickstart", QUICKSTART), ("intrinsic_reward", INTRINSIC)):
        nb = new_notebook(cells=cells)
        nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                     "language": "python"}
        nb.metadata["language_info"] = {"name": "python"}
        out[name] = nb
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--execute", action="store_true", help="run them and store the outputs")
    parser.add_argument("--only", choices=["quickstart", "intrinsic_reward"], default=None)
    parser.add_argument("--update-text", action="store_true",
                        help="replace only the markdown cells of the stored notebooks, keeping "
                             "their outputs (the code cells must be unchanged)")
    args = parser.parse_args()
    from nbclient import NotebookClient
    for name, nb in build().items():
        if args.only and name != args.only:
            continue
        path = HERE / f"{name}.ipynb"
        if args.update_text:
            stored = nbformat.read(path, as_version=4)
            if [c.source for c in stored.cells if c.cell_type == "code"] != \
                    [c.source for c in nb.cells if c.cell_type == "code"]:
                raise SystemExit(f"{path}: code cells changed; run with --execute instead")
            for old, new in zip(stored.cells, nb.cells):
                if old.cell_type == "markdown":
                    old.source = new.source
            nb = stored
        elif args.execute:
            NotebookClient(nb, timeout=1800, kernel_name="python3",
                           resources={"metadata": {"path": str(HERE.parent)}}).execute()
        for cell in nb.cells:                 # reproducible files: no volatile metadata
            cell.metadata.pop("execution", None)
        nbformat.write(nb, path)
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
