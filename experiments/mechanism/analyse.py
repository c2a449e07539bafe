"""Tables for experiments/results/mechanism/results.md from the raw JSONs of run_mechanism.py.

Per experiment and world size: for each agent/variant, total goals (mean, 95 % CI), as % of the
best non-imitator's mean (95 % bootstrap CI over seeds, 10 000 resamples, seed 0), median first
goal step, median steps to half the optimal rate (first window with ≥ ½ · window/optimal_steps
goals; runs that never get there count as never), and for imitators the mentor-term
diagnostics at the end (share of mentor states where it still wins eq. 2, median margin over
the best own option tried).

    PYTHONPATH=$PWD python experiments/mechanism/analyse.py experiments/results/mechanism/raw
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np


def _ci_mean(x):
    x = np.asarray(x, float)
    h = 1.96 * x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else float("nan")
    return x.mean(), h


def _ratio_ci(a, b, rng, n=10_000):
    a, b = np.asarray(a, float), np.asarray(b, float)
    ia = rng.integers(0, len(a), (n, len(a)))
    ib = rng.integers(0, len(b), (n, len(b)))
    r = a[ia].mean(1) / b[ib].mean(1)
    return 100 * a.mean() / b.mean(), 100 * np.percentile(r, 2.5), 100 * np.percentile(r, 97.5)


def main(raw: str) -> None:
    groups = defaultdict(dict)  # (exp, size) -> name -> per-run arrays
    for path in sorted(Path(raw).glob("*.json")):
        rec = json.loads(path.read_text())
        half = 0.5 * rec["window"] / rec["optimal_steps"]
        for agent in sorted(set(rec["agents"])):
            idx = [b for b, a in enumerate(rec["agents"]) if a == agent]
            name = (
                agent
                if rec["variant"] in ("baselines", "imitation", "confident")
                else f"{agent}+{rec['variant']}"
            )
            curve = np.asarray(rec["curve"])[idx]
            reach = [
                (int(np.argmax(c >= half)) + 1) * rec["window"] if (c >= half).any() else np.inf
                for c in curve
            ]
            first = [f if f >= 0 else np.inf for f in np.asarray(rec["first_goal_step"])[idx]]
            d = rec["diagnostics"]
            groups[(rec["experiment"], rec["size"])][name] = {
                "goals": np.asarray(rec["goals"])[idx],
                "first": np.asarray(first, float),
                "half": np.asarray(reach, float),
                "seeds": len(idx),
                "steps": rec["steps"],
                "win": np.asarray(d["win_share"])[idx],
                "margin": np.asarray(d["median_margin"])[idx],
                "engine": rec["engine"],
                "commit": rec["commit"][:7],
                "last50k": curve[:, -(50_000 // rec["window"]) :].sum(1),
            }
    rng = np.random.default_rng(0)
    for (exp, size), agents in sorted(groups.items()):
        base = [a for a in ("options", "primitives") if a in agents]
        if not base:
            continue
        best = max(base, key=lambda a: agents[a]["goals"].mean())
        any_rec = next(iter(agents.values()))
        print(f"\n### {exp}, {size}×{size}, {any_rec['steps']} steps, best non-imitator: {best}\n")
        print(
            "| agent | seeds | total goals (95 % CI) | % of best (95 % CI) | last 50k % of best "
            "(95 % CI) | median first goal | median steps to ½ optimal rate (never) | mentor wins at end "
            "| median margin |"
        )
        print("|---|---|---|---|---|---|---|---|---|")
        for name, r in sorted(agents.items(), key=lambda kv: -kv[1]["goals"].mean()):
            m, h = _ci_mean(r["goals"])
            pct, lo, hi = _ratio_ci(r["goals"], agents[best]["goals"], rng)
            late, llo, lhi = _ratio_ci(r["last50k"], agents[best]["last50k"], rng)
            never = int(np.isinf(r["half"]).sum())
            win = np.nanmean(r["win"]) if not np.isnan(r["win"]).all() else float("nan")
            marg = np.nanmedian(r["margin"]) if not np.isnan(r["margin"]).all() else float("nan")
            print(
                f"| {name} | {r['seeds']} | {m:.0f} ± {h:.0f} | {pct:.1f} ({lo:.1f}–{hi:.1f}) | "
                f"{late:.1f} ({llo:.1f}–{lhi:.1f}) | {np.median(r['first']):.0f} | {np.median(r['half']):.0f} ({never}) | "
                f"{win:.3f} | {marg:.4f} |"
            )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "experiments/results/mechanism/raw")
