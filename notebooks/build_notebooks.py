"""Write ``quickstart.ipynb``, ``intrinsic_reward.ipynb``, ``your_own_world.ipynb``,
``option_discovery.ipynb``, ``puzzle_box.ipynb`` and ``minigrid.ipynb`` from the cells below, and (with
``--execute``) run them top to bottom in place so that they are committed with their outputs.

    .venv/bin/python notebooks/build_notebooks.py --execute     # about a minute on a laptop CPU

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
from matplotlib.lines import Line2D

import himit_torch as ht
from himit_torch.runs.experiment import PAPER
from himit_torch.viz.plotting import map_legend, plot_goal_curves, plot_state_map, plot_world

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 15_000))   # primitive steps per run
WINDOW = 1000 if STEPS >= 4000 else max(STEPS // 4, 1)        # goals are counted per window
torch.set_num_threads(1)            # tiny tensors: one thread is fastest
plt.rcParams["figure.dpi"] = 100"""),
    new_markdown_cell("""\
## The world and the learner's options

A 40×40 grid divided into a 10×10 grid of rooms of 4×4 cells (3×3 free cells and a wall row and
column each), joined by single-cell doorways. Actions slip 10 % of the time; −0.01 a step, +1
at the goal (bottom-right). The learner's options: 4 primitives and, in every room, one option
per doorway that heads *directly* to it. `ht.optimal_baseline` computes what the optimal policy
achieves from the start — our exact reference for the curves below."""),
    new_code_cell("""\
world = ht.MultiRooms(size=40, rooms=10)
options = ht.learner_options(world)
best = ht.optimal_baseline(world)     # exact: value iteration on the true model
print(world)
print(options.num_options, "options:", dict(Counter(options.kinds)))
print(f"optimal policy: {best.steps_to_goal:.1f} steps a trip, {best.goals_per(5000):.1f} goals per "
      f"5000 steps (the paper reports ≈ {PAPER['exp2']['optimal_goals_per_5000']}), "
      f"V*(start) = {best.value_start:.3f}")"""),
    new_markdown_cell("""\
## The mentor and its demonstrations

The mentor has its own options (doorway options that travel *along the walls*) and runs the
optimal policy for them. The learner gets only the mentor's states — no actions, no rewards."""),
    new_code_cell("""\
mentor = ht.mentor_policy(world, ht.mentor_options(world))
demos = ht.record_demonstrations(world, mentor, episodes=20, seed=0)
print(demos)
fig, ax = plt.subplots(figsize=(5, 5.4))
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
for agent, seed, first, goals in zip(agents, seeds, learner.views.first_goal_step.tolist(),
                                     learner.views.goals.tolist()):
    print(f"{agent:>9} seed {seed}: first goal at step {first:>6} (−1: never), {goals} goals")"""),
    new_code_cell("""\
curve = learner.metrics.curve().double()          # [windows, runs] goals per window
goals = {agent: curve[:, [b for b, a in enumerate(agents) if a == agent]].T.numpy()
         for agent in ("imitation", "options")}
fig, ax = plt.subplots(figsize=(9.5, 3.8), layout="constrained")
plot_goal_curves(ax, learner.metrics.steps, goals, window=WINDOW, seed_lines=True,
                 optimum=best.goals_per(WINDOW),
                 paper_optimum=PAPER["exp2"]["optimal_goals_per_5000"] * WINDOW / 5000)
ax.set_title(f"Goals per {WINDOW:,} steps on the 40×40 world: imitators vs options only "
             f"(thin lines: single seeds)", fontsize="medium")
plt.show()"""),
    new_markdown_cell("""\
## Why the options-only runs may reach no goal at all

Not a bug: before a run first reaches the goal, every value it knows is −1 — the initial value,
which is also the exact value of never reaching the goal (−0.01 a step forever:
−0.01 / (1 − 0.99) = −1), so nothing it experiences changes it. All its options tie, ties are
broken at random, and ε stays at 0.75 (it decays only after the first goal): the options-only
learner does a random walk. The cell below shows what that walk does in the stored run. It does
cover the grid — 98 to 100 of the 100 rooms — but it rarely stays in the goal's room, a corner
room with only 2 doorways whose doorway options lead straight back out: 0, 32 and 18 of the
15,000 steps there, against about 108 in the average room. And the goal is a single cell of that
room, entered only by a primitive step from next to it. Such a walk can take a long time:
experiment 2 ran the same three learners (options only, seeds 0–2) for 200,000 steps, and they
first reached the goal at step 97,145, at step 31,118, and never
(`experiments/results/exp2/results.md`). The imitators' mentor term gives the states along the
mentor's route values above −1 from the start, which leads them to the goal within a few
thousand steps."""),
    new_code_cell("""\
# Room of each state: (room id + 1) / rooms² in the features' "room" column, 0 off rooms.
room = (world.stimulus_features()[:, 0] * world.rooms ** 2).round().long()   # room id + 1, or 0
visits = learner.views.visit_counts().double()
goal_room = int(room[world.goal_state])
goal_row, goal_col = world.coords(world.goal_state)
for b, (agent, seed) in enumerate(zip(agents, seeds)):
    per_room = torch.zeros(world.rooms ** 2 + 1, dtype=torch.float64).index_add_(0, room, visits[b])[1:]
    seen = (visits[b] > 0).nonzero()[:, 0]
    closest = int(((goal_row - seen // world.size).abs() + (goal_col - seen % world.size).abs()).min())
    print(f"{agent:>9} seed {seed}: entered {int((per_room > 0).sum()):>3} of {world.rooms ** 2} rooms, "
          f"{int(per_room[goal_room - 1]):>5} steps in the goal's room (average room "
          f"{float(per_room.mean()):.0f}), came within {closest} cells of the goal, "
          f"ε now {float(learner.views.epsilon[b]):.2f}")"""),
    new_markdown_cell("""\
## What the imitator believes: its value map and greedy path

`learner.views.state_values()` is `[runs, S]`. Grey cells hold exactly V = −1: no route from them to
the goal is known yet (see above; most were never visited). The orange line is one episode that
follows run 0's greedy options from the start."""),
    new_code_cell("""\
values = learner.views.state_values()[0]
path = learner.views.greedy_trajectory(0, max_steps=2000, seed=0)
fig, ax = plt.subplots(figsize=(6.2, 5.6), layout="constrained")
plot_state_map(ax, world, values, label="V(s), the learner's value",
               no_data=torch.isclose(values, torch.tensor(-1.0, dtype=values.dtype)),
               title=f"V of run 0 ({agents[0]}, seed {seeds[0]}) after {learner.views.t:,} steps")
ax.plot(path % world.size, path // world.size, color="#e8590c", linewidth=1.2)
map_legend(ax, "V = −1: no route to the goal known yet",
           extra=[Line2D([], [], color="#e8590c", label="greedy episode")])
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
WHAT_WE_SEE = """\
## What we see, and why

*Written from the stored run: n = 5 seeds per variant × 100,000 steps. Numbers are quoted from
the cells above — "C1" … "C12" are the checks in the previous cell; ranges are over the five
seeds, CIs are 95 % intervals of the mean (paired by seed for differences). With another budget
the numbers above change and this text may not hold; the checks say which parts do.*

**The intrinsic reward with its defaults did better than the known reward.** Over 100,000 steps
the `intrinsic` runs reached the goal 958 times on average (949–977 per seed) against 892
(841–916) with the known reward: 66 more, paired CI +33 to +99, ahead in 5 of 5 seeds (C1).
Over the last 4 windows they reached 51.5 goals per 5000 steps (50.5–52.8) against 49.2
(47.8–50.5); the exact optimum is 54.7 (the paper reports ≈ 53.2). Their first goals came about
as early: medians 3536 and 3179, paired difference +581 steps, CI covering 0 (C12).

**Salience is not the reason; the level of `R_m` is.** The control `flat_0.02` — the same
learner and module with no step salience (`scale=0`: every mentor step costs 0.02, the end pays
0.5) — reached 960 goals (945–969), as many as `intrinsic`: paired difference −1, CI from −16
to +14, covering 0 (C2). The control `flat_0.01` — the real step cost, no salience, the same end —
reached 853 (819–884), not measurably different from the known reward (paired −39, CI −80 to +3,
just covering 0; behind in 4 of 5 seeds; C4) and 106 fewer than `flat_0.02` (CI +70 to +142,
above 0; `flat_0.02` ahead in 5 of 5 seeds; C3). So the smaller end reward alone changes nothing
measurable at n = 5 (if anything it costs a few goals); charging the mentor's steps *more* than
they really cost is what helps:

* The mentor term enters the max of eq. 2 and nothing ever corrects it. With the known reward
  it is **optimistic**: every known-reward run believes `V(start)` is −0.154 to −0.173, above the
  true optimum −0.192 (C5) — the mentor model lumps the mentor's different wall-following
  options into one next-state distribution per state, and the learner's own options cannot
  follow the mentor's moves exactly (`docs/reproduction-notes.md`, section 3). The inflated
  values keep pulling the learner back onto the mentor's route: at the end the mentor term still
  wins at 65–78 % of the mentor's states (mean 72 %; C7).
* Charging 0.01–0.02 per mentor step (never less than the real 0.01) and paying 0.5 at the end
  makes the mentor term **pessimistic**: `V(start)` −0.197 to −0.224 (`intrinsic`) and −0.204 to
  −0.213 (`flat_0.02`), all below −0.192 (C6). It still guides the learner to the goal early —
  any route that ends in the goal beats the −1 of the unknown — and then loses the max wherever
  the learner's own experience of the real +1 is better: it wins at only 43–73 % of the
  mentor's states (mean 54 %; C7), and the learner's own route takes over (in the visits maps
  above, the greedy episode of `intrinsic` leaves the mentor's diagonal; that of `known` follows it).

**The end event: no measurable effect on the first goal or on the final rate.** Without it
(`intrinsic_no_end`: no reward above −0.01 anywhere) the median first goal came at step 2961
against 3536, later in only 2 of 5 seeds; the paired difference (+293 steps, CI −3820 to +4406)
covers 0, and so does that of the final rate (51.5 per window, −0.1, CI −2.4 to +2.3; 958 goals;
C8). Even without any
positive reward the mentor term helps, because this learner knows which states are terminal
(value 0) and starts every other state at −1: a mentor route that ends in a terminal state is
already attractive. A learner that did not know where episodes end would depend on the end
event.

**Where intrinsic reward is worse: when it overestimates.**

* `intrinsic_free` makes salient steps free (`scale = step_cost = 0.01`). That is cycle-safe,
  but the room entries along each mentor episode (about one per doorway crossed, 18 on the
  shortest route) now cost 0 instead of 0.01: `V(start)` −0.040
  to −0.062, far above the true −0.192. The mentor term wins more (72–83 % of the mentor's
  states), and the learners reach fewer goals than with the known reward: 712 (640–819), paired
  −180, CI −310 to −49, behind in 5 of 5 seeds (C9); 44.0 per window at the end (38.0–49.2).
* `intrinsic_paying` lets salient steps pay +0.1. The learners farm it: `V(start)` 3.49–3.85
  (nothing real exceeds 1), 0 to 2 goals in 100,000 steps (C10); the greedy episode of seed 0
  spends 1928 of its 2000 steps on a doorway cell, (2, 4), and the cell next to it in the start
  room, (2, 3). Stepping through a doorway and back is worth about 0.1 / (1 − γ²) ≈ 5 to them;
  their own experience cannot correct it, because the mentor term is never checked against it.

**Without a mentor the runs split** (`none`, options only): one never found the goal and one only
at step 97,145; the other three needed 10–31k steps (C11). The mean of 32 goals per window at
the end describes none of them — the median (dashed in its panel) and the outcome count do. The
three that found it early end at 52.0–53.0 per window, above the known-reward imitators
(47.8–50.5) and level with the intrinsic ones (50.5–52.8): with no mentor term nothing pulls
them off their own best route (`docs/reproduction-notes.md`, section 3).

**In short:** in this world the intrinsic learner does as well as the known reward, and better,
*because* its reward is a cautious lower bound — the flat control without salience does the same
(C2). The salient events themselves (rooms, slips, lights) shift step costs by at most 0.01 and
are not what decides the result. Salience that makes the mentor's steps look better than they
are is harmful, and salience that pays is fatal. A fair test of salience as information —
worlds where the learner does not know the goal, or rewards that do not follow the mentor's
route — is left open."""


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

**Never above the real reward.** The mentor term is trusted without correction, so `R_m` must
not overestimate the learner's real reward (−0.01 a step, +1 at the goal). The module declares
`upper_bound = bound` (0.5 by default), which the learner checks against its best real reward.
The defaults go further: an ordinary mentor step costs `step_cost = 0.02`, a fully salient one
`step_cost − scale = 0.01` — never less than a real step — and the end pays 0.5 < 1. So
salience makes the mentor's salient steps *cheaper*, never rewarding, and no transition is
overestimated. This notebook also runs two modules that break this, to show what it costs, and
two controls without salience, to show what salience itself contributes.

Budget: `STEPS` per run and `SEEDS` seeds per variant (environment variables
`HIMIT_NOTEBOOK_STEPS`, `HIMIT_NOTEBOOK_SEEDS`). The outputs stored with the notebook come from
the defaults below: 5 seeds × 100,000 steps × 8 variants, under a minute on one CPU core."""),
    new_code_cell("""\
import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import torch
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from scipy import stats

import himit_torch as ht
from himit_torch.runs.experiment import PAPER
from himit_torch.viz.plotting import (CURVE_COLORS, map_legend, plot_first_goals, plot_goal_curves,
                                  plot_state_map)

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 100_000))  # primitive steps per run
SEEDS = int(os.environ.get("HIMIT_NOTEBOOK_SEEDS", 5))        # runs per variant
LOGDIR = Path(os.environ.get("HIMIT_NOTEBOOK_LOGDIR", "runs/intrinsic_reward"))
WINDOW = 5000 if STEPS >= 20_000 else max(STEPS // 4, 1)       # the paper's 5000-step windows
torch.set_num_threads(1)
plt.rcParams["figure.dpi"] = 100

world = ht.MultiRooms(size=40, rooms=10)                   # experiment 2's world
options = ht.learner_options(world)                        # primitives + direct doorway options
mentor = ht.mentor_policy(world, ht.mentor_options(world))
demos = {seed: ht.record_demonstrations(world, mentor, episodes=20, seed=seed)
         for seed in range(SEEDS)}                         # each seed watches its own episodes
best = ht.optimal_baseline(world)                          # exact, from the true model
OPTIMUM = best.goals_per(WINDOW)
PAPER_OPTIMUM = PAPER["exp2"]["optimal_goals_per_5000"] * WINDOW / 5000
print(world, "|", options.num_options, "options |", demos[0])
print(f"optimal policy (exact): {best.steps_to_goal:.1f} steps a trip = {OPTIMUM:.1f} goals per "
      f"{WINDOW} steps (the paper reports ≈ {PAPER_OPTIMUM:.1f}); V*(start) = {best.value_start:.3f}")"""),
    new_markdown_cell("""\
## The salience map, from the mentor's states alone

Per state, the salience of the mentor's arrivals there (all four events, weighted and clipped
to [0, 1], averaged over its arrivals). Grey: the mentor never arrived there, so there is no
salience to show — different from a cell it arrived at without any salient event (salience 0,
the dark end of the scale). The world's stimulus features are `[S, 4]`: room, doorway flag,
light, sound. Light and sound are off unless you set them. On the right, lamps light rows
16–23 (outlined; `world.set_stimulus("light", …)`) and only light changes count (`weights` of
room and novelty 0): the mentor's steps into and out of the lit band stand out."""),
    new_code_cell("""\
salience = ht.SalienceReward(world, demos[0])
print(salience)
print("features:", tuple(world.stimulus_features().shape), world.stimulus_feature_names)

lit = ht.MultiRooms(size=40, rooms=10)
lamp = torch.zeros(world.size, world.size)
lamp[16:24] = 1.0                                            # rows 16–23 are lit
lit.set_stimulus("light", lamp.flatten())
lit_salience = ht.SalienceReward(lit, demos[0], weights={"room": 0.0, "novelty": 0.0})

src, dst = demos[0].transitions()
arrived = torch.bincount(dst, minlength=world.num_states) > 0   # where the mentor ever arrived
maps = salience.event_maps()
panels = [(salience.salience_map(), "total salience"), (maps["room"], "room entered"),
          (maps["novelty"], "novelty (the mentor's slips)"),
          (lit_salience.salience_map(), "light changes only (rows 16–23 lit)")]
fig, axes = plt.subplots(1, 4, figsize=(15, 4.6), layout="constrained")
for ax, (field, title) in zip(axes, panels):
    image = plot_state_map(ax, world, field, label="", title=title, vmin=0, vmax=1,
                           no_data=~arrived, colorbar=False)
axes[3].add_patch(Rectangle((-0.5, 15.5), world.size, 8, fill=False, edgecolor="#e8590c",
                            linewidth=1.8, linestyle="--"))
fig.colorbar(image, ax=axes, shrink=0.8,
             label="mean salience of the mentor's arrivals (0–1)")
map_legend(fig, "the mentor never arrived here",
           extra=[Line2D([], [], color="#e8590c", linestyle="--", label="lit rows 16–23")])
fig.suptitle(f"Salience from the mentor's {demos[0].num_episodes} episodes of seed 0")
plt.show()

r = salience.transition_reward(src, dst)
paying = r > 0
into_goal = int(world.terminal_mask[dst[paying]].sum())
print(f"rewards of the mentor's steps: min {r.min():.4f}, max {r.max():.4f}; "
      f"steps paying > 0: {int(paying.sum())} of {len(r)}, {into_goal} of them into the goal; "
      f"cycle-safe: {salience.cycle_safe}; a step's reward lies in {salience.step_reward_range}")"""),
    new_markdown_cell("""\
## Known vs intrinsic vs no mentor reward, with controls, in one batch

Eight variants × `SEEDS` seeds, all in one `Learner` batch; each run has its own reward module
(`reward=[…]`, one per run). Seed `k` of every variant watches the same mentor episodes and
draws the same random numbers, so variants are compared seed by seed.

| variant | agent | `R_m` | a mentor step pays |
|---|---|---|---|
| `known` | imitation | the world's reward (the paper's experiments) | −0.01, +1 into the goal |
| `intrinsic` | imitation | `SalienceReward` with its defaults: never above the real reward | −0.02 … −0.01, +0.5 at the end |
| `flat_0.02` | imitation | control: `SalienceReward(scale=0)` — no salience, the same flat cost and end | −0.02, +0.5 at the end |
| `flat_0.01` | imitation | control: `scale=0, step_cost=0.01` — no salience, exactly the real step cost | −0.01, +0.5 at the end |
| `intrinsic_no_end` | imitation | the defaults without the end event (`weights={"end": 0}`) | −0.02 … −0.01 everywhere |
| `intrinsic_free` | imitation | salient steps free: `scale = step_cost = 0.01` (cycle-safe, optimistic) | −0.01 … 0, +0.5 |
| `intrinsic_paying` | imitation | salient steps pay: `scale=0.1, step_cost=0` (not cycle-safe) | 0 … +0.1, +0.5 |
| `none` | options | no mentor term (options only) | — |

Every run logs to TensorBoard as `himit run` does (`ht.TensorBoardLogger`): its own folder
`world40__<variant>__seed<k>`, scalars with descriptions, maps of seeds 0 and 1 four times
during training, and hyperparameters that group the seeds of a variant."""),
    new_code_cell("""\
VARIANTS = {   # name: (agent, reward module for one seed)
    "known": ("imitation", lambda seed: ht.KnownReward(world)),
    "intrinsic": ("imitation", lambda seed: ht.SalienceReward(world, demos[seed])),
    "flat_0.02": ("imitation", lambda seed: ht.SalienceReward(world, demos[seed], scale=0.0)),
    "flat_0.01": ("imitation",
                  lambda seed: ht.SalienceReward(world, demos[seed], scale=0.0, step_cost=0.01)),
    "intrinsic_no_end": ("imitation",
                         lambda seed: ht.SalienceReward(world, demos[seed], weights={"end": 0.0})),
    "intrinsic_free": ("imitation",
                       lambda seed: ht.SalienceReward(world, demos[seed], scale=0.01, step_cost=0.01)),
    "intrinsic_paying": ("imitation",
                         lambda seed: ht.SalienceReward(world, demos[seed], scale=0.1, step_cost=0.0)),
    "none": ("options", lambda seed: ht.KnownReward(world)),   # unused: no mentor term
}
COLORS = dict(zip(VARIANTS, CURVE_COLORS))
names, agents, seeds, modules = [], [], [], []
for name, (agent, make) in VARIANTS.items():
    for seed in range(SEEDS):
        names.append(name); agents.append(agent); seeds.append(seed); modules.append(make(seed))
runs_of = {name: [b for b, n in enumerate(names) if n == name] for name in VARIANTS}

learner = ht.Learner(world, options, agents, seeds, reward=modules,
                     config=ht.LearnerConfig(window=WINDOW))
for seed in range(SEEDS):
    learner.add_demonstrations(demos[seed], runs=[b for b, s in enumerate(seeds) if s == seed])


def settings(name, module):
    \"\"\"What tells a variant apart (TensorBoard hparams; never the seed).\"\"\"
    hp = {"variant": name, "agent": VARIANTS[name][0], "reward": type(module).__name__}
    if isinstance(module, ht.SalienceReward) and VARIANTS[name][0] == "imitation":
        hp.update(scale=module.scale, step_cost=module.step_cost, bound=module.bound,
                  end_weight=module.weights["end"])
    return hp


# This notebook owns LOGDIR/tb: each execution replaces its runs' folders (overwrite=True), so
# TensorBoard never shows two executions in one curve.
logger = ht.TensorBoardLogger(LOGDIR / "tb", [f"world40__{n}__seed{s}" for n, s in zip(names, seeds)],
                              world=world, options=options, true_value_start=best.value_start,
                              overwrite=True)
map_runs = [b for b, s in enumerate(seeds) if s < 2]
mentor_visits = {b: torch.bincount(dst_of, minlength=world.num_states)
                 for b in map_runs for dst_of in [demos[seeds[b]].transitions()[1]]}
map_every = max(STEPS // 4, 1)
while learner.views.t < STEPS:
    learner.run(min(WINDOW - learner.views.t % WINDOW, STEPS - learner.views.t))
    if learner.metrics.steps and learner.metrics.steps[-1] == learner.views.t:
        logger.window(learner, len(learner.metrics.steps) - 1)
    if learner.views.t % map_every == 0 or learner.views.t == STEPS:
        logger.maps(learner, map_runs, learner.views.t, mentor_visits)
final_curve = learner.metrics.curve()
logger.hparams([settings(n, m) for n, m in zip(names, modules)],
               [{"hparam/total_goals": float(learner.views.goals[b]),
                 "hparam/final_window_goals": float(final_curve[-1, b]) if len(final_curve) else 0.0,
                 "hparam/first_goal_step": float(learner.views.first_goal_step[b]) if learner.views.first_goal_step[b] >= 0
                 else float(learner.views.t + 1),
                 "hparam/value_start": float(learner.views.state_values()[b, world.start_state])}
                for b in range(learner.batch)], learner.views.t)
logger.close()
print(f"{learner.batch} runs × {learner.views.t} steps; TensorBoard logs in {LOGDIR / 'tb'}")"""),
    new_markdown_cell("""\
## Learning curves, one panel per variant

Each panel: the mean over seeds (thick), every seed (thin), the seeds' range (band), the median
(dashed) where the seeds split into different outcomes, our exact optimum (dotted) and the
paper's (dash-dotted). The title says how many runs reached the goal at all."""),
    new_code_cell("""\
curve = learner.metrics.curve().double()                  # [windows, runs]
steps = learner.metrics.steps
fig, axes = plt.subplots(2, 4, figsize=(16, 7), sharex=True, sharey=True, layout="constrained")
for ax, name in zip(axes.flat, VARIANTS):
    runs = runs_of[name]
    plot_goal_curves(ax, steps, {name: curve[:, runs].T.numpy()}, colors=COLORS, window=WINDOW,
                     optimum=OPTIMUM, paper_optimum=PAPER_OPTIMUM, seed_lines=True, legend=False)
    found = int((learner.views.first_goal_step[runs] >= 0).sum())
    ax.set_title(f"{name}: n={len(runs)}, {found}/{len(runs)} found the goal", fontsize="medium")
    ax.label_outer()
fig.legend(handles=[Line2D([], [], color="0.3", lw=2, label="mean over seeds"),
                    Line2D([], [], color="0.3", lw=0.6, label="one seed"),
                    Rectangle((0, 0), 1, 1, color="0.3", alpha=0.18, label="seeds' range"),
                    Line2D([], [], color="0.3", lw=1.5, ls="--", label="median (where seeds split)"),
                    Line2D([], [], color="0.2", ls=":", label=f"optimal policy, exact: {OPTIMUM:.1f}"),
                    Line2D([], [], color="0.55", ls="-.",
                           label=f"the paper's optimum: ≈ {PAPER_OPTIMUM:.1f}")],
           loc="lower center", ncol=6, bbox_to_anchor=(0.5, -0.06), frameon=False)
fig.suptitle(f"40×40 world, a 10×10 grid of rooms: goals per {WINDOW:,} steps by mentor reward")
plt.show()"""),
    new_markdown_cell("""\
## First goals

5000-step windows cannot show which variant finds the goal first: each run's first-goal step,
one dot per seed (log scale; "never" on the right), the median as a bar."""),
    new_code_cell("""\
firsts = {name: learner.views.first_goal_step[runs].tolist() for name, runs in runs_of.items()}
fig, ax = plt.subplots(figsize=(11, 4.6), layout="constrained")
plot_first_goals(ax, firsts, STEPS, colors=COLORS,
                 title=f"Step of each run's first goal (n={SEEDS} seeds per variant)")
plt.show()"""),
    new_markdown_cell("""\
## Every run, and each variant's spread

Per run: first goal (−1: never), total goals, mean goals per window over the last 4 windows,
`V(start)` (what the run believes the start is worth) and the share of the mentor's states
where the mentor term wins eq. 2's max. Then per variant: mean, range over seeds `[min, max]`
and a 95 % confidence interval of the mean (Student t, n − 1 degrees of freedom; with n = 5 it
is wide)."""),
    new_code_cell("""\
v_start = learner.views.state_values()[:, world.start_state]
wins = learner.views.mentor_win_share()
last = curve[-4:].mean(0) if len(curve) >= 4 else curve.mean(0)
first = learner.views.first_goal_step
print(f"{'variant':<18}{'seed':>5}{'first goal':>12}{'goals':>8}{'last 4 windows':>16}"
      f"{'V(start)':>10}{'mentor wins':>13}")
for b in range(learner.batch):
    print(f"{names[b]:<18}{seeds[b]:>5}{int(first[b]):>12}{int(learner.views.goals[b]):>8}"
          f"{float(last[b]):>16.1f}{float(v_start[b]):>10.3f}{float(wins[b]):>13.2f}")


def spread(values, digits=0):
    \"\"\"'mean [min, max] (95% CI lo–hi)' of one variant's seeds.\"\"\"
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return "—"
    text = f"{x.mean():.{digits}f} [{x.min():.{digits}f}, {x.max():.{digits}f}]"
    if x.size > 1:
        half = stats.t.ppf(0.975, x.size - 1) * x.std(ddof=1) / np.sqrt(x.size)
        text += f" (CI {x.mean() - half:.{digits}f}–{x.mean() + half:.{digits}f})"
    return text


print(f"\\nPer variant, n = {SEEDS} seeds: mean [min, max] (95 % CI of the mean); V*(start) = "
      f"{best.value_start:.3f}, optimum {OPTIMUM:.1f} goals per window\\n")
for name, runs in runs_of.items():
    found = first[runs] >= 0
    med = f"{np.median(first[runs][found].numpy()):.0f}" if bool(found.any()) else "—"
    print(f"{name:<18} found the goal in {int(found.sum())}/{len(runs)} runs; their first goal: "
          f"median {med}, mean {spread(first[runs][found].tolist())}\\n"
          f"{'':<18} total goals: mean {spread(learner.views.goals[runs].tolist())}\\n"
          f"{'':<18} last 4 windows: mean {spread(last[runs].tolist(), 1)}\\n"
          f"{'':<18} V(start): mean {spread(v_start[runs].tolist(), 3)}\\n"
          f"{'':<18} mentor wins: mean {spread(wins[runs].tolist(), 2)}")"""),
    new_markdown_cell("""\
## Paired differences between variants

Seed `k` of two variants shares its mentor episodes and random numbers, so differences are taken
seed by seed: the mean difference, its 95 % confidence interval (paired t) and in how many seeds
the first variant is ahead."""),
    new_code_cell("""\
def paired(a, b, values, higher_is_better=True):
    \"\"\"Seed-by-seed difference of `values` between variants a and b.\"\"\"
    x = np.asarray(values, dtype=float)
    d = x[runs_of[a]] - x[runs_of[b]]
    ok = np.isfinite(d)
    d = d[ok]
    ahead = int((d > 0).sum() if higher_is_better else (d < 0).sum())
    if d.size > 1:
        half = stats.t.ppf(0.975, d.size - 1) * d.std(ddof=1) / np.sqrt(d.size)
        ci = (d.mean() - half, d.mean() + half)
    else:
        ci = (float("nan"), float("nan"))
    return {"mean": d.mean() if d.size else float("nan"), "ci": ci, "ahead": ahead, "n": d.size}


def fmt(result, digits=0):
    lo, hi = result["ci"]
    return (f"{result['mean']:+.{digits}f} (CI {lo:+.{digits}f} to {hi:+.{digits}f}), "
            f"ahead in {result['ahead']}/{result['n']} seeds")


goals_total = learner.views.goals.double().numpy()
last_np, first_np = last.numpy(), first.double().numpy()
first_np[first_np < 0] = np.nan                              # never found: left out of the pair
PAIRS = [("intrinsic", "known"), ("intrinsic", "flat_0.02"), ("flat_0.02", "flat_0.01"),
         ("flat_0.01", "known"), ("intrinsic_no_end", "intrinsic"), ("intrinsic_free", "known"),
         ("none", "known")]
comparisons = {}
for a, b in PAIRS:
    comparisons[a, b] = {"goals": paired(a, b, goals_total), "last": paired(a, b, last_np),
                         "first": paired(a, b, first_np, higher_is_better=False)}
    c = comparisons[a, b]
    print(f"{a} − {b}:\\n  total goals    {fmt(c['goals'])}\\n  last 4 windows {fmt(c['last'], 1)}"
          f"\\n  first goal     {fmt(c['first'])} (earlier = ahead; seeds where both found it)")"""),
    new_markdown_cell("""\
## Where the learners go

Visits of seed 0 of four variants over the whole run, on one log scale (grey: never visited),
and in orange one episode that follows the run's greedy options from the start (at most 2000
steps). If salient steps pay, the learner's values rise far above anything real (compare
`V(start)` above with `V*(start)`): a doorway it can step through and back again is worth about
`r / (1 − γ²)` to it, while it pays the real step cost every time."""),
    new_code_cell("""\
shown = ("known", "intrinsic", "intrinsic_free", "intrinsic_paying")
visits = learner.views.visit_counts().double()
top = float(visits[[runs_of[n][0] for n in shown]].max())
fig, axes = plt.subplots(1, 4, figsize=(16, 4.8), layout="constrained")
greedy_facts = {}
for ax, name in zip(axes, shown):
    b = runs_of[name][0]
    image = plot_state_map(ax, world, visits[b], label="", log=True, vmin=1, vmax=max(top, 10),
                           no_data=visits[b] == 0, colorbar=False,
                           title=f"{name}, seed {seeds[b]}")
    path = learner.views.greedy_trajectory(b, max_steps=2000, seed=0)
    ax.plot(path % world.size, path // world.size, color="#e8590c", linewidth=1.2)
    counts = torch.bincount(path, minlength=world.num_states).topk(2)
    greedy_facts[name] = {"steps": len(path) - 1, "goal": bool(world.terminal_mask[path[-1]]),
                          "top2": [world.coords(s) for s in counts.indices.tolist()],
                          "top2_steps": int(counts.values.sum())}
    f = greedy_facts[name]
    print(f"{name:<18} greedy episode: {f['steps']:>4} steps, "
          f"{'reaches the goal' if f['goal'] else 'no goal'}, {len(torch.unique(path))} distinct "
          f"states; most visited {f['top2']} ({f['top2_steps']} of its steps)")
fig.colorbar(image, ax=axes, shrink=0.8, label=f"visits in {learner.views.t:,} steps (log scale)")
map_legend(fig, "never visited",
           extra=[Line2D([], [], color="#e8590c", label="greedy episode from the start")])
plt.show()"""),
    new_markdown_cell("""\
## The claims, checked

Each statement of the next section, computed from the runs above; `True` means the data support
it at this budget (with another budget, read the numbers, not the text)."""),
    new_code_cell("""\
def rng(name, values, digits=0):
    x = np.asarray(values, dtype=float)[runs_of[name]]
    x = x[np.isfinite(x)]
    return f"{x.min():.{digits}f}–{x.max():.{digits}f}" if x.size else "—"


def median_first(name):
    x = first_np[runs_of[name]]
    x = x[np.isfinite(x)]                                    # runs that found the goal
    return float(np.median(x)) if x.size else float("nan")


vs = v_start.numpy()
wins_np = wins.numpy()
c = comparisons
claims = {
    "C1 intrinsic reaches more goals than known (paired CI above 0)":
        (c["intrinsic", "known"]["goals"]["ci"][0] > 0, fmt(c["intrinsic", "known"]["goals"])),
    "C2 salience adds nothing measurable: intrinsic vs flat_0.02 total goals, CI covers 0":
        (c["intrinsic", "flat_0.02"]["goals"]["ci"][0] <= 0 <= c["intrinsic", "flat_0.02"]["goals"]["ci"][1],
         fmt(c["intrinsic", "flat_0.02"]["goals"])),
    "C3 a step cost above the real one helps: flat_0.02 ahead of flat_0.01 (paired CI above 0)":
        (c["flat_0.02", "flat_0.01"]["goals"]["ci"][0] > 0, fmt(c["flat_0.02", "flat_0.01"]["goals"])),
    "C4 the real step cost with a smaller end reward behaves like known: flat_0.01 − known CI covers 0":
        (c["flat_0.01", "known"]["goals"]["ci"][0] <= 0 <= c["flat_0.01", "known"]["goals"]["ci"][1],
         fmt(c["flat_0.01", "known"]["goals"])),
    "C5 known is optimistic: every known run's V(start) is above V*(start)":
        (bool((vs[runs_of["known"]] > best.value_start).all()),
         f"V(start) {rng('known', vs, 3)} vs V* {best.value_start:.3f}"),
    "C6 intrinsic and flat_0.02 are pessimistic: every run's V(start) below V*(start)":
        (bool((vs[runs_of["intrinsic"] + runs_of["flat_0.02"]] < best.value_start).all()),
         f"intrinsic {rng('intrinsic', vs, 3)}, flat_0.02 {rng('flat_0.02', vs, 3)}"),
    "C7 the mentor term wins less often with intrinsic than with known (mean share)":
        (wins_np[runs_of["intrinsic"]].mean() < wins_np[runs_of["known"]].mean(),
         f"intrinsic {rng('intrinsic', wins_np, 2)}, known {rng('known', wins_np, 2)}"),
    "C8 without the end event neither the first goal nor the final rate changes measurably (paired CIs cover 0)":
        (c["intrinsic_no_end", "intrinsic"]["first"]["ci"][0] <= 0 <= c["intrinsic_no_end", "intrinsic"]["first"]["ci"][1]
         and c["intrinsic_no_end", "intrinsic"]["last"]["ci"][0] <= 0 <= c["intrinsic_no_end", "intrinsic"]["last"]["ci"][1],
         f"first goal {fmt(c['intrinsic_no_end', 'intrinsic']['first'])}; medians "
         f"{median_first('intrinsic_no_end'):.0f} vs {median_first('intrinsic'):.0f}; last 4 windows "
         f"{fmt(c['intrinsic_no_end', 'intrinsic']['last'], 1)}"),
    "C9 free salient steps overestimate and cost goals: intrinsic_free below known (paired CI)":
        (c["intrinsic_free", "known"]["goals"]["ci"][1] < 0
         and bool((vs[runs_of["intrinsic_free"]] > best.value_start).all()),
         f"{fmt(c['intrinsic_free', 'known']['goals'])}; V(start) {rng('intrinsic_free', vs, 3)}"),
    "C10 paying salient steps are farmed: V(start) > 1 and at most 2 goals in every run":
        (bool((vs[runs_of["intrinsic_paying"]] > 1).all()
              and (goals_total[runs_of["intrinsic_paying"]] <= 2).all()),
         f"V(start) {rng('intrinsic_paying', vs, 2)}, goals {rng('intrinsic_paying', goals_total)}; "
         f"greedy episode of seed 0: {greedy_facts['intrinsic_paying']['top2_steps']} of "
         f"{greedy_facts['intrinsic_paying']['steps']} steps on {greedy_facts['intrinsic_paying']['top2']}"),
    "C11 without a mentor the runs split: some never find the goal or only after half the run":
        (bool((first_np[runs_of["none"]] != first_np[runs_of["none"]]).any()
              or (np.nan_to_num(first_np[runs_of["none"]], nan=STEPS) > STEPS / 2).any()),
         f"first goals {[int(f) for f in first[runs_of['none']]]}; last 4 windows "
         f"{[round(float(x), 1) for x in last[runs_of['none']]]}"),
    "C12 intrinsic finds the goal about as early as known: paired first-goal CI covers 0":
        (c["intrinsic", "known"]["first"]["ci"][0] <= 0 <= c["intrinsic", "known"]["first"]["ci"][1],
         f"{fmt(c['intrinsic', 'known']['first'])}; medians {median_first('intrinsic'):.0f} vs "
         f"{median_first('known'):.0f}"),
}
for text, (holds, evidence) in claims.items():
    print(f"{str(bool(holds)):>5}  {text}\\n       {evidence}")"""),
    new_markdown_cell(WHAT_WE_SEE),
    new_markdown_cell("""\
## The same runs in TensorBoard

Every run above has its own folder `world40__<variant>__seed<k>` under `LOGDIR/tb`, the layout
`himit run` uses: scalars with descriptions (`charts/goals_in_window` per window,
`charts/goals_total` cumulative, `charts/first_goal_step`, `model/value_start` beside
`model/value_start_true` = V*(start), `mentor/term_wins`, …), maps of seeds 0 and 1 four times
during training (`maps/values`, `maps/greedy_option`, `maps/visits`) and hyperparameters in
which the seeds of one variant form one group. Open them with

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
    print(f"{agent:>10}: goals per run {learner.views.goals[runs].tolist()}, first goal at step "
          f"{learner.views.first_goal_step[runs].tolist()}")
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
    goals = [int(taxi_learner.views.goals[b]) for b, a in enumerate(agents) if a == agent]
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

# ========================================================================= option discovery
OPTION_DISCOVERY = [
    new_markdown_cell("""\
# Options discovered from the mentor's states

The paper's learner is *given* its doorway options, built from the world's true layout. Here the
learner finds them itself:

1. **Subgoals from state-only demonstrations** (`ht.discover_subgoals`): in the mentor's state
   graph (visited states, an edge for each observed move) a subgoal is a state that lies on every
   episode, is a cut vertex (no demonstrated way around it) and is narrow (few demonstrated
   neighbours); narrowest first, each suppressing candidates within `separation` moves.
2. **Options to them from what the learner knows** (`ht.learned_subgoal_options`): its own
   counts of its primitive steps (`ht.one_step_counts`) give a one-step model; each option heads
   for its subgoal by the fewest expected steps *in that model*, usable where the model says the
   subgoal is near. Nothing of the true layout is read.

Budgets: `HIMIT_NOTEBOOK_STEPS` steps per run and `HIMIT_NOTEBOOK_SEEDS` seeds (the tests run
this notebook with tiny ones). The full comparison, 10 seeds on experiment 1's and 2's worlds,
is `himit run discovery` (results in `experiments/results/discovery/`)."""),
    new_code_cell("""\
import os

import matplotlib.pyplot as plt
import numpy as np
import torch

import himit_torch as ht
from himit_torch.viz.plotting import plot_goal_curves, plot_subgoals

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 40_000))   # primitive steps per run
SEEDS = int(os.environ.get("HIMIT_NOTEBOOK_SEEDS", 3))
WINDOW = 2000 if STEPS >= 8000 else max(STEPS // 4, 1)       # goals are counted per window
WARMUP = WINDOW * max(1, STEPS // WINDOW // 4)               # the primitives-only phase
torch.set_num_threads(1)
plt.rcParams["figure.dpi"] = 100

world = ht.MultiRooms(size=40, rooms=10)                     # experiment 2's world
mentor = ht.mentor_policy(world, ht.mentor_options(world))
demos = {s: ht.record_demonstrations(world, mentor, episodes=20, seed=s) for s in range(SEEDS)}
SEPARATION = world.size // world.rooms - 1                   # the room spacing − 1
print(f"{STEPS} steps per run, warm-up {WARMUP}, {SEEDS} seed(s), separation {SEPARATION}")"""),
    new_markdown_cell("""\
## Subgoals found vs the true doorways

Precision: the share of subgoals that are doorways. Recall: the share of the doorways the
mentor passed through that were found (no method can find a doorway it was never shown)."""),
    new_code_cell("""\
found = {}
for s in range(SEEDS):
    found[s] = ht.discover_subgoals(demos[s], separation=SEPARATION)
    pr = found[s].precision_recall(world.doorways)
    print(f"seed {s}: {pr['found']} subgoals, {pr['hits']} of them doorways; the mentor passed "
          f"{pr['true']} doorways → precision {pr['precision']:.2f}, recall {pr['recall']:.2f}")
fig, ax = plt.subplots(figsize=(6, 6.6))
plot_subgoals(world, found[0], demonstrations=demos[0], ax=ax,
              title="subgoals found in 20 mentor episodes (seed 0)")
plt.show()"""),
    new_markdown_cell("""\
## How many demonstrations does discovery need?"""),
    new_code_cell("""\
for n in (1, 2, 5, 10, 20):
    prs = [ht.discover_subgoals(ht.record_demonstrations(world, mentor, n, seed=s),
                                separation=SEPARATION).precision_recall(world.doorways)
           for s in range(SEEDS)]
    print(f"{n:>2} episodes: precision {np.mean([p['precision'] for p in prs]):.2f}, "
          f"recall {np.mean([p['recall'] for p in prs]):.2f}")"""),
    new_markdown_cell("""\
## Options built from the learner's own one-step model

Each seed runs `imitation_primitives` (primitives + the mentor term) for `WARMUP` steps; the
options are built from its counts. Shaded: how many options may start in a cell; arrows: each
option's action there, all from the learned model."""),
    new_code_cell("""\
config = ht.LearnerConfig(window=WINDOW, plan_every=4, sweep_rounds=1)
prims = ht.primitive_options(world)
seeds = list(range(SEEDS))

def with_demos(learner, run_seeds):
    for s in sorted(set(run_seeds)):
        learner.add_demonstrations(demos[s], runs=[b for b, x in enumerate(run_seeds) if x == s])
    return learner

phase1 = with_demos(ht.Learner(world, prims, ["imitation_primitives"] * SEEDS, seeds, config=config), seeds)
phase1.run(WARMUP)
usable = world.free_mask & ~world.terminal_mask
discovered = {s: ht.learned_subgoal_options(ht.one_step_counts(phase1, s), world.num_actions, found[s],
                                            terminal=world.terminal_mask, max_steps=2 * SEPARATION,
                                            usable=usable) for s in seeds}
for s in seeds:
    opts = discovered[s]
    print(f"seed {s}: {0 if opts is None else opts.num_options} options built after {WARMUP} steps"
          + ("" if opts is None else f", usable in {int(opts.initiation.any(0).sum())} states"))
if discovered[0] is not None:
    fig, ax = plt.subplots(figsize=(6, 6.6))
    plot_subgoals(world, found[0], options=discovered[0], ax=ax,
                  title=f"options built from the learner's model after {WARMUP} steps (seed 0)")
    plt.show()"""),
    new_markdown_cell("""\
## Learning curves

The discovered-options imitator continues from its warm-up phase with a new learner (its models
start empty; what the warm-up learned reaches it through its options). It is compared with the
hand-built doorway options and with primitives-only imitation over the same steps."""),
    new_code_cell("""\
phase1.run(STEPS - WARMUP)                       # the primitives-only imitators, to the end
early = phase1.metrics.goals_in_window[:WARMUP // WINDOW]
hand = with_demos(ht.Learner(world, ht.Options.concat(prims, ht.doorway_options(world)),
                             ["imitation"] * SEEDS, seeds, config=config), seeds)
hand.run(STEPS)
curves = {"imitation_primitives": torch.stack(phase1.metrics.goals_in_window, 1).numpy(),
          "doorway_imitation": torch.stack(hand.metrics.goals_in_window, 1).numpy()}
runs = []
for s in seeds:
    opts = prims if discovered[s] is None else ht.Options.concat(prims, discovered[s])
    learner = with_demos(ht.Learner(world, opts, ["imitation"], [s], config=config), [s])
    learner.run(STEPS - WARMUP)
    runs.append(torch.cat([torch.stack(early, 1)[s], torch.stack(learner.metrics.goals_in_window, 1)[0]]))
curves["discovered_imitation"] = torch.stack(runs).numpy()
for name, g in curves.items():
    print(f"{name:>22}: total goals per run {g.sum(1).astype(int).tolist()}")
steps = np.arange(1, STEPS // WINDOW + 1) * WINDOW
fig, ax = plt.subplots(figsize=(10, 4))
plot_goal_curves(ax, steps, curves, window=WINDOW)
ax.axvline(WARMUP, color="0.5", ls=":", lw=1)
plt.show()"""),
]


# ============================================================================== puzzle box
PUZZLE_BOX = [
    new_markdown_cell("""\
# The puzzle box: Whiten et al.'s children's test, run on the model

Whiten, Flynn, Brown & Lee (2006) gave three-year-olds the "keyway-fruit" box: four skewers
hold its lid, each comes out by the same four steps, and each step is itself a sequence of
movements. The steps can be done in two hierarchical orders — **skewer by skewer** or **step by
step** across the skewers. The children who watched a solution (1) did much better than those
who did not, (2) copied whichever organisation they saw but not the demonstrator's movements,
and (3) fitted a fifth skewer, never demonstrated, into the rule they had inferred.

`ht.PuzzleBox` is that box as a tabular world (`himit_torch/worlds/puzzle_box.py` argues its
design): a hand that reaches a skewer, grips it — a *power* grip (the learner's skills) or a
*pinch* (the mentor's) — and makes the step's motion; a motion made again undoes its step; 10 %
of movements slip. This notebook draws the box, shows a demonstration, learns from both
organisations, and maps a 4-skewer mentor onto a 5-skewer box. The 20-seed experiments are
`himit run puzzlebox` (results: `experiments/results/puzzlebox/results.md`).

Budgets: `HIMIT_NOTEBOOK_STEPS` steps per run, `HIMIT_NOTEBOOK_SEEDS` runs per condition (the
tests run this notebook with tiny ones)."""),
    new_code_cell("""\
import os
from pathlib import Path

import matplotlib.pyplot as plt
import torch

import himit_torch as ht
from himit_torch.options.puzzle_box import intended_rollout
from himit_torch.runs.puzzle_box import greedy_plan
from himit_torch.viz.puzzle_box import plot_box, plot_levels, plot_step_order

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 100_000))  # primitive steps per run
SEEDS = int(os.environ.get("HIMIT_NOTEBOOK_SEEDS", 2))        # runs per condition
WINDOW = 5000 if STEPS >= 20_000 else max(STEPS // 4, 1)
torch.set_num_threads(1)
plt.rcParams["figure.dpi"] = 100

box = ht.PuzzleBox(skewers=4)
print(box)
print("actions:", ", ".join(box.action_names))
middle = box.encode([4, 2, 1, 0], skewer=1, grasp="pinch")
fig, axes = plt.subplots(1, 2, figsize=(12, 3.2), layout="constrained")
plot_box(axes[0], box, box.start_state, "the start: every skewer in, the hand home")
plot_box(axes[1], box, middle, "skewer 1 out, skewer 2 half-way, the hand pinching it")
plt.show()"""),
    new_markdown_cell("""\
## Two organisations, one cost

Every step starts and ends with the hand home, so a step costs the same whichever skewer it is
done on: every order that wastes no movement is optimal. Exact planning on the true model, for
the learner's skills and the mentor's:"""),
    new_code_cell("""\
best = ht.optimal_baseline(box)
print(f"optimal policy: {best.steps_to_goal:.3f} movements to open the box, "
      f"V*(start) = {best.value_start:.6f}")
for style in ("learner", "mentor"):
    options = ht.puzzle_box_options(box, style)
    durations = ht.option_durations(box, options)
    for org in ht.ORGANISATIONS:
        policy = ht.organisation_mentor(box, org, options=options).option
        steps = ht.expected_steps(durations, policy, box.start_state, box.terminal_mask)
        value = ht.evaluate_option_choice(box, options, policy, 1).value_start.item()
        print(f"  {org:>6}-by-{org:<6} with the {style}'s skills: {steps:.3f} movements, "
              f"V(start) = {value:.6f}")"""),
    new_markdown_cell("""\
## A demonstration

A mentor that works step by step, with its own skills (pinch). The learner gets only its states.
Left: each skewer's level along one episode, and the moments the hand held a grip (slips show as
repeated attempts, and now and then a step undone). Right: the order of the steps it did."""),
    new_code_cell("""\
mentors = {org: ht.organisation_mentor(box, org) for org in ht.ORGANISATIONS}
demos = {(org, s): ht.record_demonstrations(box, mentors[org], episodes=20, seed=s)
         for org in ht.ORGANISATIONS for s in range(SEEDS)}
episode = demos["step", 0].episodes[0]
print(f"{len(episode) - 1} movements; the first states:")
for s in episode[:4].tolist():
    print(box.render_ansi(s))
fig, axes = plt.subplots(1, 2, figsize=(14, 3.6), layout="constrained", width_ratios=(1.6, 1))
plot_levels(axes[0], box, episode, "one demonstration (step by step), states only")
plot_step_order(axes[1], box.subgoals(episode), 4, grips=box.grasps_used(episode),
                title="the order of its steps (orange: done in a pinch)")
plt.show()"""),
    new_markdown_cell("""\
## Learning under either demonstration

Imitators (the learner's options + the mentor term of eq. 2) watch a skewer-by-skewer or a
step-by-step mentor; options-only learners watch nothing. After `STEPS` steps each run's greedy
policy is read from the start with every movement doing what it intends: the grids show the
order in which it does the 16 steps (blue numbers: done in a power grip, its own; orange: in
the mentor's pinch)."""),
    new_code_cell("""\
options = ht.puzzle_box_options(box, "learner")
conditions = [("imitation", "skewer"), ("imitation", "step"), ("options", None)]
agents = [a for a, _ in conditions for _ in range(SEEDS)]
seeds = [s for _ in conditions for s in range(SEEDS)]
watched = [w for _, w in conditions for _ in range(SEEDS)]
learner = ht.Learner(box, options, agents, seeds,
                     config=ht.LearnerConfig(plan_every=4, sweep_rounds=1, window=WINDOW))
for b, (agent, seed, org) in enumerate(zip(agents, seeds, watched)):
    if org is not None:
        learner.add_demonstrations(demos[org, seed], runs=[b])
learner.run(STEPS)
greedy = learner.views.greedy_options()
plans = [greedy_plan(box, options, greedy[b]) for b in range(learner.batch)]
fig, axes = plt.subplots(len(conditions), SEEDS, figsize=(4.2 * SEEDS, 3.1 * len(conditions)),
                         layout="constrained", squeeze=False)
for b, plan in enumerate(plans):
    ax = axes[b // SEEDS, b % SEEDS]
    grips = box.grasps_used(torch.tensor(plan["states"]))
    plot_step_order(ax, plan["subgoals"], 4, grips=grips,
                    title=f"{agents[b]}" + (f", watched {watched[b]}" if watched[b] else "")
                    + f", seed {seeds[b]}: {plan['organisation']}")
plt.show()
for b, plan in enumerate(plans):
    print(f"{agents[b]:>9} watched {str(watched[b]):>6} seed {seeds[b]}: first opening at step "
          f"{int(learner.views.first_goal_step[b]):>6} (−1: never), plan {plan['organisation']:>10}, "
          f"{plan['pinch_steps']} of {plan['pinch_steps'] + plan['power_steps']} steps in the "
          "mentor's pinch")"""),
    new_markdown_cell("""\
## A fifth skewer

The mentors demonstrate on the 4-skewer box; the learner faces 5 skewers. The paper assumes one
state space for both and allows "appropriate mappings" (its footnote 2). `ht.map_demonstrations`
makes two explicit: *plain* — mentor skewer i is learner skewer i, skewer 5 stays in; *any* —
the mentor's box seen in any 4 of the 5 skewers, the fifth at any level. Both keep eq. 2 sound
(the box's dynamics are local to the hand and the skewer it acts on, so every mapped move is one
the learner can make with the same probability). Below: one seed that watched step by step,
under each mapping, and a learner without demonstrations."""),
    new_code_cell("""\
five = ht.PuzzleBox(skewers=5)
four = box
five_options = ht.puzzle_box_options(five, "learner")
seed = 1 if SEEDS > 1 else 0
shown = demos["step", seed]
mapped = {m: ht.map_demonstrations(shown, four, five, m) for m in ("plain", "any")}
print({m: d.num_episodes for m, d in mapped.items()}, "mapped episodes")
transfer = ht.Learner(five, five_options, ["imitation", "imitation", "options"], [seed] * 3,
                      config=ht.LearnerConfig(plan_every=4, sweep_rounds=1, window=WINDOW))
transfer.add_demonstrations(mapped["plain"], runs=[0])
transfer.add_demonstrations(mapped["any"], runs=[1])
transfer.run(2 * STEPS)
greedy = transfer.views.greedy_options()
fig, axes = plt.subplots(1, 3, figsize=(14, 3.4), layout="constrained")
for b, label in enumerate(["plain mapping", "'any' mapping", "no demonstrations"]):
    plan = greedy_plan(five, five_options, greedy[b], focus=4)
    score = plan["focus_scores"]["step"] if plan["focus_scores"] else None
    plot_step_order(axes[b], plan["subgoals"], 5,
                    grips=five.grasps_used(torch.tensor(plan["states"])),
                    title=f"{label}: {plan['organisation']}\\nfirst opening at step "
                          f"{int(transfer.views.first_goal_step[b])}; skewer 5's step-by-step score "
                          + ("–" if score is None else f"{score:.2f}"))
plt.show()"""),
    new_markdown_cell("""\
## The 20-seed result

The committed run of `himit run puzzlebox` (if this checkout has it): assimilation of skewer 5
by mapping and organisation watched, and the three findings beside the study's."""),
    new_code_cell("""\
results = Path(ht.__file__).resolve().parents[1] / "experiments/results/puzzlebox/results.md"
if results.exists():
    text = results.read_text()
    start = text.index("Assimilation:")
    print(text[start:text.index("Greedy plans", start)])
    print(text[text.index("## Beside Whiten"):text.index("Verdicts are computed")])
else:
    print("no committed results here: run `himit run puzzlebox`")"""),
    new_markdown_cell("""\
## What the 20-seed run says

* **Copying the organisation** is the model's clearest match with the children: imitators'
  greedy plans follow the organisation they watched (13 of 20; 15 of 20 for a learner that
  cannot make the mentor's grip), non-imitators' never do (0 of 20).
* **But not the movements?** Only where the learner cannot copy them. When it can and they are
  as good as its own, the mentor term of eq. 2 draws it onto the mentor's own states: 57 % of
  its steps in the mentor's pinch against 23 % for non-imitators. When the mentor's grip is a
  little worse, imitators drop it (12 %) — and with it most of the organisation (4 of 20).
* **Speed**: on the 4-skewer box options alone open it as soon as imitators do; on the 5-skewer
  box only the *any* mapping opens it sooner (median first opening halved), and it ends with
  fewer openings (not significant after Holm); the *plain* mapping equals no demonstrations.
* **A new skewer**: no imitator's plan fits skewer 5 exactly into the organisation it watched.
  With the *plain* mapping the mentor model says nothing about skewer 5 — and, until the learner
  has opened the box once, nothing at all: the mapped episodes end short of the learner's goal,
  so their values rest on the learner's own. With the *any* mapping the step-by-step watchers'
  plans come close (score 0.97) but not all the way, and more of them get stuck.

Details, intervals and tests: `experiments/results/puzzlebox/results.md`; the design of the box
and the mappings: `docs/puzzle_box.md`."""),
]

# ============================================================================== MiniGrid
MINIGRID = [
    new_markdown_cell("""\
# MiniGrid: get the key, open the door, reach the goal

Farama's MiniGrid DoorKey-6x6 as a tabular world: `ht.from_minigrid` enumerates every full state
reachable from one reset seed (the agent's cell and direction, where the key is, the door's
state) through MiniGrid's own `step`. The learner's options walk to and face the key, the door
or the goal; between them it must use the primitives `pickup`, `toggle` and `forward` — the
kind of task where a flat learner rarely tries the one primitive that matters. The mentor
never turns left (three right turns instead) and has right-handed skills of its own: the
learner can copy where it goes, not how it moves.

The budget is `STEPS` primitive steps per run (`HIMIT_NOTEBOOK_STEPS` overrides it; the tests
run this notebook with a tiny one). Needs the `[minigrid]` extra."""),
    new_code_cell("""\
import os

import matplotlib.pyplot as plt
import torch

import himit_torch as ht
from himit_torch.viz.minigrid import plot_minigrid_paths

STEPS = int(os.environ.get("HIMIT_NOTEBOOK_STEPS", 30_000))   # primitive steps per run
SEEDS = int(os.environ.get("HIMIT_NOTEBOOK_SEEDS", 2))
WINDOW = 1000 if STEPS >= 4000 else max(STEPS // 4, 1)
torch.set_num_threads(1)
plt.rcParams["figure.dpi"] = 100

world = ht.from_minigrid("MiniGrid-DoorKey-6x6-v0")   # reset seed 0: one layout
print(world)
print("objects:", world.object_names)
print("start:", world.describe_state(world.start_state))"""),
    new_markdown_cell("""\
## Options, the mentor and its demonstrations

Exact planning on the table gives the optimum with primitives and with the learner's options;
the mentor is optimal for its own (no left turn), a little slower. Its path is drawn over the
grid as MiniGrid draws it."""),
    new_code_cell("""\
options = ht.minigrid_options(world)            # 6 primitives + "go to the key / door / goal"
mentor = ht.minigrid_mentor(world)              # no left turn, right-handed skills
print(options)
print(mentor.options)
for name, opts, policy in [
    ("primitives", ht.primitive_options(world), None),
    ("learner's options", options, None),
    ("mentor", mentor.options, mentor.option),
]:
    models = ht.option_models(world, opts)
    policy = ht.smdp_value_iteration(models).policy if policy is None else policy
    steps = ht.expected_steps(ht.option_durations(world, opts), policy, 0, world.terminal_mask)
    print(f"{name:>18}: {steps:.0f} steps start → goal")

demos = ht.record_demonstrations(world, mentor, episodes=10, seed=0)
fig, ax = plt.subplots(figsize=(4, 4.4))
plot_minigrid_paths(world, [("mentor", demos.episodes[0])], ax=ax, colors=["tab:orange"])
plt.show()"""),
    new_markdown_cell("""\
## Learning

Three agents, `SEEDS` runs each, in one batch: imitation (eq. 2, the mentor's states), options
only and primitives only."""),
    new_code_cell("""\
agents = ["imitation", "options", "primitives"]
learner = ht.Learner(
    world, options, agents * SEEDS, [s for s in range(SEEDS) for _ in agents],
    demonstrations=demos, reward=ht.KnownReward(world),
    config=ht.LearnerConfig(window=WINDOW),
)
learner.run(STEPS)
curve = learner.metrics.curve().double()        # goals per window, [windows, B]
fig, ax = plt.subplots(figsize=(6, 3))
for i, agent in enumerate(agents):
    ax.plot(curve[:, i::len(agents)].mean(1), label=agent)
ax.set_xlabel(f"window of {WINDOW} steps")
ax.set_ylabel("goals per window")
ax.legend()
plt.show()
print({a: float(curve[-1, i::len(agents)].mean()) for i, a in enumerate(agents)})"""),
    new_markdown_cell("""\
## The greedy policies, replayed in MiniGrid itself

Each imitation run's greedy option policy, stepped in a fresh MiniGrid environment
(`world.make_env`), each state read back with `world.state_of`, each frame from MiniGrid's own
`render()`. A greedy policy may still loop somewhere (two turns that undo each other, where its
values tie): the replay stops at a repeated (state, option) and says so. The first run that
reached the goal is drawn: its path beside the mentor's over MiniGrid's drawing of the grid,
then frames of its episode."""),
    new_code_cell("""\
def replay(run):
    \"\"\"The run's greedy policy stepped in MiniGrid: its states, frames and how it ended.\"\"\"
    greedy = learner.views.greedy_options([run])[0]
    env = world.make_env(render_mode="rgb_array")
    s, option, states, frames, seen = world.start_state, -1, [world.start_state], [env.render()], set()
    while True:
        if option < 0:
            option = int(greedy[s])
            if option < 0:
                return states, frames, "no option chosen yet"
        if (s, option) in seen:
            return states, frames, "a loop"
        seen.add((s, option))
        _, reward, terminated, _, _ = env.step(int(options.policy[option, s]))
        frames.append(env.render())
        s = world.state_of(env)
        states.append(s)
        if terminated:
            return states, frames, "reached the goal" if reward > 0 else "ended"
        if float(options.termination[option, s]) >= 1.0:
            option = -1

replays = {run: replay(run) for run in range(0, len(agents) * SEEDS, len(agents))}
for run, (states, frames, end) in replays.items():
    print(f"imitation run {run // len(agents)}: {len(frames) - 1} steps, {end}")
states, frames, _ = next((r for r in replays.values() if r[2] == "reached the goal"), replays[0])

fig, ax = plt.subplots(figsize=(4, 4.6))            # both paths over MiniGrid's drawing,
plot_minigrid_paths(                                # side by side where they share cells
    world, [("mentor", demos.episodes[0]), ("learner (greedy)", states)], ax=ax,
    colors=["tab:orange", "tab:blue"],
)
plt.show()

shown = frames[:: max(len(frames) // 6, 1)][:6]
fig, axes = plt.subplots(1, len(shown), figsize=(2 * len(shown), 2), squeeze=False)
for ax, frame in zip(axes[0], shown):
    ax.imshow(frame)
    ax.set_axis_off()
plt.show()"""),
]


NOTEBOOKS = (("quickstart", QUICKSTART), ("intrinsic_reward", INTRINSIC),
             ("your_own_world", YOUR_OWN_WORLD), ("option_discovery", OPTION_DISCOVERY),
             ("puzzle_box", PUZZLE_BOX), ("minigrid", MINIGRID))


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
