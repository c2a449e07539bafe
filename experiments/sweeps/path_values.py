"""The bias account, tested along the mentor's path: per state, what the learner believes (V̂)
against what its own greedy policy is really worth (V^π, exact) and the optimum (V*).

    python experiments/sweeps/path_values.py runs/sweeps/exp1_factors/trials/baseline [--out …csv]

For every finished trial folder under the given folder (``world<N>_seeds<a>-<b>``), the learner is
rebuilt from its config and restored from its last checkpoint; for each run, π(s) is its greedy
own option (:meth:`learner.views.greedy_options`; a state where it tried nothing: the uniform mix of its
usable options), V^π is solved exactly with the learner options' exact models ((I − P_π) V = r_π,
sparse), and on the states its seed's mentor visited (``record_demonstrations`` with the seed, as
in the run) it reports the means of V̂ − V^π (over-estimation of its own policy), V* − V^π (what
the policy loses), and V̂ − V* (the bias results.md measured at the start only). Also V^π(start)
against V*(start), and where the greedy option chain from the start first leaves the mentor's
states (the most likely successor of each greedy option, followed while it stays on them).
"""

import argparse
import csv
import json
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from himit_torch.exact.option_models import option_models
from himit_torch.exact.planning import smdp_value_iteration
from himit_torch.learner.learner import Learner
from himit_torch.mentor.policy import mentor_policy, record_demonstrations
from himit_torch.options.builders import learner_options, mentor_options
from himit_torch.runs.checkpoints import BatchShape
from himit_torch.runs.config import load_config
from himit_torch.runs.runner import Checkpoints

parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
parser.add_argument("cell_dir", help="a sweep cell's folder (…/trials/<cell>)")
parser.add_argument("--out", help="CSV, one row per run (default: print only)")
args = parser.parse_args()

rows = []
for trial in sorted(Path(args.cell_dir).glob("world*_seeds*")):
    if not (trial / "results.md").exists():
        continue
    config = load_config(trial / "config.json")
    [size] = config.sizes
    world = config.world(size)
    options = learner_options(world, corners=config.corner_options)
    mentor = mentor_policy(
        world, mentor_options(world, corners=config.corner_options), config.mentor_preference
    )
    seeds = list(range(config.first_seed, config.first_seed + config.seeds))
    agents = [a for a in config.agents for _ in seeds]
    run_seeds = [s for _ in config.agents for s in seeds]
    learner = Learner(world, options, agents, run_seeds, config=config.learner, engine="torch")
    demos = {}
    for s in seeds:
        demos[s] = record_demonstrations(world, mentor, config.mentor_episodes, seed=s)
        learner.add_demonstrations(demos[s], runs=[b for b, rs in enumerate(run_seeds) if rs == s])
    Checkpoints(
        trial / "checkpoints" / f"world{size}.pt",
        BatchShape(agents, run_seeds, world.num_states),
        config.checkpoint_every,
        config.device,
    ).resume(learner)
    assert learner.views.t == config.steps, f"{trial}: checkpoint at {learner.views.t}, not the end"
    models = option_models(world, options)
    S = world.num_states
    T = models.transition.to_sparse_coo().coalesce()
    idx = T.indices().numpy()
    Tm = sp.csr_matrix((T.values().numpy(), (idx[0], idx[1])), shape=tuple(T.shape))
    r = models.reward.numpy()
    row_state, row_option = models.row_state.numpy(), models.row_option.numpy()
    v_star = smdp_value_iteration(models).values.numpy()
    greedy = learner.views.greedy_options().cpu().numpy()
    v_hat = learner.views.state_values().double().cpu().numpy()
    enabled = learner.rows.row_enabled.cpu().numpy()
    learner_row_option = learner.rows.row_option.cpu().numpy()
    for b in range(learner.batch):
        ok_opts = np.unique(learner_row_option[:-1][enabled[b, :-1]])
        ok = np.isin(row_option, ok_opts)
        chosen = ok & (row_option == greedy[b, row_state])
        has_choice = np.bincount(row_state, weights=chosen, minlength=S) > 0
        sel = (chosen | (ok & ~has_choice[row_state])).astype(float)
        weight = sel / np.maximum(np.bincount(row_state, weights=sel, minlength=S)[row_state], 1)
        W = sp.csr_matrix(
            (weight, (row_state, np.arange(len(row_state)))), shape=(S, len(row_state))
        )
        P_pi, r_pi = W @ Tm, W @ r
        v_pi = spla.spsolve((sp.identity(S, format="csr") - P_pi).tocsc(), r_pi)
        seen = np.unique(np.concatenate([np.asarray(e) for e in demos[run_seeds[b]].episodes]))
        seen = seen[~world.terminal_mask.numpy()[seen]]
        # the greedy chain from the start: the most likely successor of each greedy option
        s, steps_on, on = world.start_state, 0, set(seen.tolist())
        visited = set()
        while s in on and s not in visited and not world.terminal_mask[s]:
            visited.add(s)
            steps_on += 1
            m = np.flatnonzero((row_state == s) & (weight > 0))
            if len(m) != 1:
                break
            s = int(Tm[m[0]].indices[np.argmax(Tm[m[0]].data)])
        rows.append(
            {
                "trial": trial.name,
                "agent": agents[b],
                "seed": run_seeds[b],
                "mentor_states": len(seen),
                "vhat_minus_vpi": float(np.mean(v_hat[b, seen] - v_pi[seen])),
                "vstar_minus_vpi": float(np.mean(v_star[seen] - v_pi[seen])),
                "vhat_minus_vstar": float(np.mean(v_hat[b, seen] - v_star[seen])),
                "vpi_start": float(v_pi[world.start_state]),
                "vstar_start": float(v_star[world.start_state]),
                "vhat_start": float(v_hat[b, world.start_state]),
                "greedy_chain_on_mentor_states": steps_on,
                "chain_reached_goal": bool(world.terminal_mask[s]),
            }
        )
        print(json.dumps(rows[-1]), flush=True)
if args.out:
    with open(args.out, "w", newline="") as f:
        out = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        out.writeheader()
        out.writerows(rows)
