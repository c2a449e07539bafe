"""Issue 9 part 2: first goal, end performance and reliability of the psrl agents against their
mean-model twins, from a sweep's runs.csv (one row per run).

Usage: python experiments/results/psrl/analyze.py runs/sweeps/psrl_exp2/runs.csv [...]
Prints a markdown table per sweep: means with 95 % t intervals; `no late goal`: runs with no goal
in the last 50k steps (Clopper–Pearson 95 %); `Δ late (paired)`: psrl − mean-model twin, same
seed and cell, with its 95 % t interval. Below each table, per psrl agent and cell, the paired psrl − twin
differences of total goals and of the first goal's step (a run that never found the goal counts
as the sweep's steps + 1, from the `sweep.json` beside `runs.csv`) and the mean V(start)."""

import csv
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from himit_torch.statistics import share_interval, t_interval


def t_ci(x):
    """The mean and its 95 % t-interval (``himit_torch.statistics.t_interval``)."""
    ci = t_interval(np.asarray(x, dtype=float))
    return ci.estimate, ci.low, ci.high


def cp(k, n):
    ci = share_interval(k, n)
    return ci.low, ci.high


def main(paths):
    for path in paths:
        rows = list(csv.DictReader(open(path)))
        groups = defaultdict(dict)
        for r in rows:
            groups[(r["cell"], r["agent"])][int(r["seed"])] = r
        print(f"\n### {rows[0]['sweep']} ({path})\n")
        print(
            "| cell | agent | n | first goal | late goals (last 50k) | no late goal | "
            "Δ late vs mean twin (paired) |"
        )
        print("|---|---|---|---|---|---|---|")
        steps = {
            c["cell"]: int(c["config"]["steps"])
            for c in json.loads((Path(path).parent / "sweep.json").read_text())["cells"]
        }
        totals = []
        for (cell, agent), runs in groups.items():
            seeds = sorted(runs)
            first = [int(runs[s]["first_goal_step"]) for s in seeds]
            never = sum(f < 0 for f in first)
            late = [int(runs[s]["late_goals"]) for s in seeds]
            fail = sum(v == 0 for v in late)
            fm = [f for f in first if f >= 0]
            f_m, f_lo, f_hi = t_ci(fm) if fm else (float("nan"),) * 3
            l_m, l_lo, l_hi = t_ci(late)
            lo, hi = cp(fail, len(seeds))
            diff = ""
            if agent.endswith("_psrl"):
                twin = groups.get((cell, agent[: -len("_psrl")]))
                if twin:
                    d = [
                        int(runs[s]["late_goals"]) - int(twin[s]["late_goals"])
                        for s in seeds
                        if s in twin
                    ]
                    diff = paired(d)
                    totals.append((cell, agent, runs, twin))
            print(
                f"| {cell} | {agent} | {len(seeds)} | {f_m:,.0f}"
                # one run that found the goal: its step, no interval (one value has none)
                f"{f' [{f_lo:,.0f}, {f_hi:,.0f}]' if len(fm) > 1 else ''}"
                f"{f' ({never} never)' if never else ''} | {l_m:.0f} [{l_lo:.0f}, {l_hi:.0f}] | "
                f"{fail}/{len(seeds)} [{lo:.2f}, {hi:.2f}] | {diff} |"
            )
        print()
        for cell, agent, runs, twin in totals:
            seeds = [s for s in sorted(runs) if s in twin]

            def first(r, never=steps[cell] + 1):
                f = int(r["first_goal_step"])
                return f if f >= 0 else never

            d_total = [int(runs[s]["total_goals"]) - int(twin[s]["total_goals"]) for s in seeds]
            d_first = [first(runs[s]) - first(twin[s]) for s in seeds]
            v = np.mean([float(runs[s]["value_start"]) for s in seeds])
            v_twin = np.mean([float(twin[s]["value_start"]) for s in seeds])
            print(
                f"- {cell}, {agent} − twin: total goals {paired(d_total)}, first goal "
                f"{paired(d_first)} steps; V(start) {v:.3f} vs {v_twin:.3f} "
                f"(truth {float(runs[seeds[0]]['true_value_start']):.3f})"
            )


def paired(d):
    m, lo, hi = t_ci(d)
    return f"{m:+,.0f} [{lo:+,.0f}, {hi:+,.0f}]"


if __name__ == "__main__":
    main(sys.argv[1:])
