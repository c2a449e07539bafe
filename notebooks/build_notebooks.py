"""Write ``quickstart.ipynb``, ``intrinsic_reward.ipynb`` and ``your_own_world.ipynb`` from the
cells below, and (with ``--execute``) run them top to bottom in place so that they are committed
with their outputs.

    .venv/bin/python notebooks/build_notebooks.py --execute     # a few minutes on a laptop CPU

Edit the notebooks here, not in Jupyter, so that text and code stay reviewable in one place.
The budgets come from environment variables (``HIMIT_NOTEBOOK_STEPS``, ``HIMIT_NOTEBOOK_SEEDS``);
the tests run every notebook with tiny ones (``tests/test_notebooks.py``).
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

# ========================================================================= your own world
YOUR_OWN_WORLD = [
    new_markdown_cell("""\
# Your own world: a hand-written four-rooms world, then Gymnasium's Taxi

The learner does not need `MultiRooms`. Any tabular world works that has

* `num_states`, `num_actions`, `start_state`, `gamma`, `terminal_mask [S]` (entering one of
  these states ends the episode), and
* a batched `step(positions [B], actions [B], uniforms [B]) → (next [B], reward [B])`;

and, optionally, the wider protocol:

* `start_distribution [S]` — episodes start at a draw from it (from each run's own random
  stream, so runs stay reproducible);
* `dynamics_table()` — a `ht.DynamicsTable` (successors, cdf and rewards per slot `[S, A, K]`)
  that `step` uses: rewards per transition `(s, a, s')`, and from it the true model, so exact
  value iteration, exact option models, an optimal mentor and checked demonstrations come for
  free.

Part 1 writes Sutton, Precup & Singh's four-rooms world by hand; part 2 takes Gymnasium's Taxi
through `ht.from_gymnasium`. Budget: `STEPS` primitive steps per run and `SEEDS` seeds per agent
(`HIMIT_NOTEBOOK_STEPS`, `HIMIT_NOTEBOOK_SEEDS`; the tests run this notebook with tiny ones)."""),
    new_code_cell("""\
import os

import matplotlib.pyplot as plt
import torch

import himit_torch as ht

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 40_000))   # primitive steps per run
SEEDS = int(os.environ.get("HIMIT_NOTEBOOK_SEEDS", 3))        # runs per agent
WINDOW = 2000 if STEPS >= 8000 else max(STEPS // 4, 1)        # goals are counted per window
AGENTS = ["imitation", "options", "primitives"]
torch.set_num_threads(1)
plt.rcParams["figure.dpi"] = 72


def plot_goals(learner, title):
    \"\"\"Goals per window, mean over each agent's seeds (thin lines: single seeds).\"\"\"
    curve = learner.metrics.curve().double()
    fig, ax = plt.subplots(figsize=(6, 3.2))
    for agent, color in zip(AGENTS, ("C3", "C0", "C2")):
        runs = [b for b, a in enumerate(learner.agents) if a == agent]
        ax.plot(learner.metrics.steps, curve[:, runs], color=color, alpha=0.3, lw=0.8)
        ax.plot(learner.metrics.steps, curve[:, runs].mean(1), color=color, lw=2,
                label=f"{agent} (mean of {len(runs)})")
    ax.set_xlabel("steps")
    ax.set_ylabel(f"goals per {WINDOW} steps")
    ax.set_title(title)
    ax.legend(fontsize="small")
    plt.show()"""),
    new_markdown_cell("""\
## Part 1 — four rooms, written by hand

104 free cells in four rooms joined by four hallways. A state is the index of a *free* cell
(no wall states at all). Actions N, S, W, E go the intended way with probability 2/3 and each
other way with 1/9; a move into a wall stays put. Rewards are per transition: −0.01 a step,
−0.05 more for bumping into a wall, +1 for entering the goal in the bottom-right corner.
Episodes start anywhere in the top-left room (a start distribution)."""),
    new_code_cell("""\
FOUR_ROOMS = [
    "#############",
    "#     #     #",
    "#     #     #",
    "#           #",
    "#     #     #",
    "#     #     #",
    "## ####     #",
    "#     ### ###",
    "#     #     #",
    "#     #     #",
    "#           #",
    "#     #     #",
    "#############",
]
MOVES = ((-1, 0), (1, 0), (0, -1), (0, 1))           # N, S, W, E


class FourRooms:
    \"\"\"Sutton, Precup & Singh's four rooms, to the world protocol: states are free cells.\"\"\"

    num_actions = 4
    action_names = ("N", "S", "W", "E")

    def __init__(self, gamma=0.99, goal=(11, 11)):
        self.cells = [(r, c) for r, row in enumerate(FOUR_ROOMS) for c, ch in enumerate(row) if ch == " "]
        index = {cell: i for i, cell in enumerate(self.cells)}
        self.num_states, self.gamma, self.goal = len(self.cells), gamma, index[goal]
        S = self.num_states
        succ = torch.zeros(S, 4, 4, dtype=torch.int64)
        reward = torch.zeros(S, 4, 4, dtype=torch.float64)
        for s, (r, c) in enumerate(self.cells):
            for a in range(4):
                # slots 0-2: the three other directions (1/9 each), slot 3: the intended one
                for k, d in enumerate([(a + 1 + j) % 4 for j in range(3)] + [a]):
                    t = index.get((r + MOVES[d][0], c + MOVES[d][1]), s)
                    succ[s, a, k] = t
                    reward[s, a, k] = 1.0 if t == self.goal else -0.01 - 0.05 * (t == s)
        cdf = torch.tensor([1 / 9, 2 / 9, 3 / 9, 1.0], dtype=torch.float64).expand(S, 4, 4)
        self.table = ht.DynamicsTable(succ, cdf.contiguous(), reward)
        room = torch.tensor([r < 6 and c < 6 for r, c in self.cells])
        self.start_distribution = room.double() / room.sum()
        self.start_state = int(self.start_distribution.argmax())

    @property
    def terminal_mask(self):
        mask = torch.zeros(self.num_states, dtype=torch.bool)
        mask[self.goal] = True
        return mask

    def dynamics_table(self):
        return self.table

    def step(self, positions, actions, uniforms):
        return self.table.step(positions, actions, uniforms)


world = FourRooms()
print(world.num_states, "states;", isinstance(world, ht.TabularWorld), "for the TabularWorld protocol")"""),
    new_markdown_cell("""\
### Options: hallway options with `from_policy`

In each room, one option per hallway of that room: it heads for the hallway by the policy of
fewest expected steps on the true model (`ht.subgoal_options` solves that), usable only inside
the room — `Options.from_policy(initiation, policy, kind="subgoal")` restricts it. The learner's
set is the primitives plus these eight options (`Options.concat` takes a list)."""),
    new_code_cell("""\
rows, cols = torch.tensor(world.cells).T
rooms = {"NW": (rows < 6) & (cols < 6), "NE": (rows < 7) & (cols > 6),
         "SW": (rows > 6) & (cols < 6), "SE": (rows > 7) & (cols > 6)}
hallways = {"W": (6, 2), "N": (3, 6), "E": (7, 9), "S": (10, 6)}
room_hallways = {"NW": "NW", "NE": "NE", "SW": "WS", "SE": "ES"}
hallway_mask = {h: torch.tensor([cell == rc for cell in world.cells]) for h, rc in hallways.items()}
to_hallway = ht.subgoal_options(world, hallway_mask)       # one option per hallway, from anywhere

parts = [ht.primitive_options(world)]
for room, doors in room_hallways.items():
    for h in doors:
        o = list(hallway_mask).index(h)
        parts.append(ht.Options.from_policy(rooms[room] & to_hallway.initiation[o],
                                            to_hallway.policy[o], name=f"{room} → hallway {h}",
                                            kind="subgoal"))
options = ht.Options.concat(parts)
print(options, options.names[4:])"""),
    new_markdown_cell("""\
### An optimal mentor, watched through its states only

The mentor is optimal for primitive actions: value iteration on the true model, which
`ht.world_model` derives from the dynamics table. `Demonstrations(episodes, world)` checks
every step against the world's transition support — an impossible step is refused, naming
the episode and the index — and stores a description of the world (here: its class and a
fingerprint of its dynamics), so the file is refused in another world.

`KnownReward` gives the mentor term the reward of each observed move `(s, s')`, which the
learner never sees paid. Where that reward depends on the unseen action it takes the least of
the actions that can make the move, so the mentor term never overestimates what the learner
gets, and it says so when built. In four rooms no reward depends on the action (a move that
stays put is always a bump); in Taxi, below, 416 pairs do."""),
    new_code_cell("""\
P, R = ht.world_model(world)
plan = ht.value_iteration(P, R, world.gamma)
print(f"V* from the start distribution: {float(plan.values @ world.start_distribution):.3f}")
mentor = ht.mentor_policy(world, ht.primitive_options(world))
demos = {seed: ht.record_demonstrations(world, mentor, episodes=20, seed=seed) for seed in range(SEEDS)}
print(demos[0], "| steps per episode:", demos[0].episode_lengths.tolist()[:8], "…")
try:
    ht.Demonstrations([[0, 1, 50]], world)
except ValueError as err:
    print("refused:", err)
known = ht.KnownReward(world)
print(known)"""),
    new_code_cell("""\
agents = [a for a in AGENTS for _ in range(SEEDS)]
seeds = [s for _ in AGENTS for s in range(SEEDS)]
learner = ht.Learner(world, options, agents, seeds, config=ht.LearnerConfig(window=WINDOW),
                     reward=[known if a == "imitation" else None for a in agents])
for s in range(SEEDS):          # each seed watches its own mentor episodes
    learner.add_demonstrations(demos[s], runs=[b for b, x in enumerate(seeds) if x == s])
learner.run(STEPS)
for agent in AGENTS:
    runs = [b for b, a in enumerate(agents) if a == agent]
    print(f"{agent:>10}: goals per run {learner.goals[runs].tolist()}, first goal at step "
          f"{learner.first_goal_step[runs].tolist()}")
plot_goals(learner, "four rooms (104 states)")"""),
    new_markdown_cell("""\
In this small, slippery world every agent finds the goal within a few thousand steps, and
primitives alone are enough. The mentor term need not help here, and it can leave the imitator
below the others late in learning: it is never corrected by the learner's own experience, and
its estimate is biased upwards, the same limitation the README describes for the paper's large
worlds (the `imitation_confident` agent and `LearnerConfig.mentor_override_after` are the
settings to try). Taxi, next, is where watching a mentor matters."""),
    new_markdown_cell("""\
## Part 2 — Taxi through the Gymnasium adapter

`ht.from_gymnasium(id or env, **kwargs)` reads the tabular model `P[s][a] = [(p, s', r,
terminated)]` of Gymnasium's toy-text environments and returns a batched world with its true
model: Taxi's 500 states, its 300 start states, its rewards per transition (−1 a step, −10 for
an illegal pick-up or drop-off, +20 for a delivery), and the delivery states as terminal states.
The same uniforms give exactly Gymnasium's transitions (tested).

Dietterich's navigation subtasks become four options, "drive to R / G / Y / B"
(`ht.taxi_navigation_options`); pick-up and drop-off stay primitive. The mentor is optimal."""),
    new_code_cell("""\
taxi = ht.from_gymnasium("Taxi-v4")
print(taxi, taxi.describe())
taxi_options = ht.Options.concat([ht.primitive_options(taxi), ht.taxi_navigation_options(taxi)])
print(taxi_options.names)
P, R = ht.world_model(taxi)
plan = ht.value_iteration(P, R, taxi.gamma)
print(f"V* from the start distribution: {float(plan.values @ taxi.start_distribution):.3f}")
taxi_mentor = ht.mentor_policy(taxi, ht.primitive_options(taxi))
taxi_demos = {s: ht.record_demonstrations(taxi, taxi_mentor, episodes=20, seed=s) for s in range(SEEDS)}
taxi_known = ht.KnownReward(taxi)
print(taxi_known)"""),
    new_markdown_cell("""\
The learner's initial value is set to the value of never delivering, −1 / (1 − γ) = −100 (the
neutral start that −1 is in the paper's worlds)."""),
    new_code_cell("""\
config = ht.LearnerConfig(window=WINDOW, initial_value=-1 / (1 - taxi.gamma), plan_every=4, sweep_rounds=1)
taxi_learner = ht.Learner(taxi, taxi_options, agents, seeds, config=config,
                          reward=[taxi_known if a == "imitation" else None for a in agents])
for s in range(SEEDS):
    taxi_learner.add_demonstrations(taxi_demos[s], runs=[b for b, x in enumerate(seeds) if x == s])
taxi_learner.run(STEPS)
for agent in AGENTS:
    goals = [int(taxi_learner.goals[b]) for b, a in enumerate(agents) if a == agent]
    print(f"{agent:>10}: deliveries per run {goals}")
plot_goals(taxi_learner, "Taxi-v4 through ht.from_gymnasium")"""),
    new_markdown_cell("""\
## Next

* `himit info --env taxi` (or any toy-text id: `--env FrozenLake-v1 --env-kwargs
  '{"map_name": "8x8"}'`) solves a Gymnasium world exactly.
* `himit run gymnasium` compares imitation, options only and primitives only on Taxi,
  CliffWalking and FrozenLake 8×8 over 10 seeds, with confidence intervals, figures and
  TensorBoard logs; the committed results are in `experiments/results/gymnasium/`."""),
]


NOTEBOOKS = (("quickstart", QUICKSTART), ("intrinsic_reward", INTRINSIC),
             ("your_own_world", YOUR_OWN_WORLD))


def build() -> dict[str, nbformat.NotebookNode]:
    """The notebooks, unexecuted."""
    out = {}
    for name, cells in NOTEBOOKS:
        nb = new_notebook(cells=cells)
        nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3",
                                     "language": "python"}
        nb.metadata["language_info"] = {"name": "python"}
        out[name] = nb
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--execute", action="store_true", help="run them and store the outputs")
    parser.add_argument("--only", choices=[name for name, _ in NOTEBOOKS], default=None)
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
