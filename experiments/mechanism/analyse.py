"""Tables for experiments/results/mechanism/results.md from the raw JSONs of run_mechanism.py.

Per experiment and world size: for each agent/variant, total goals (mean ± half-width of the
95 % Student-t interval of the mean), as % of the best non-imitator's mean (95 % percentile
bootstrap CI of the ratio of means, **paired**: the same seeds resampled for both, as the runs
share their seeds' mentor episodes and random numbers; 10 000 resamples, seed 0), the paired
difference in total goals against the best non-imitator (mean, 95 % BCa interval, paired t-test
and sign test p, raw — `himit_torch.statistics.paired_comparison`), median first
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

from himit_torch.statistics import paired_comparison, t_interval


def _ci_mean(x):
    """The mean and the half-width of its 95 % Student-t interval."""
    ci = t_interval(np.asarray(x, float))
    return ci.estimate, ci.half_width


def _ratio_ci(a, b, rng, n=10_000):
    """100 · mean(a) / mean(b) and its paired percentile bootstrap 95 % CI (a[i], b[i]: seed i)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    if len(a) != len(b):
        raise ValueError("paired ratio: a and b must hold the same seeds")
    i = rng.integers(0, len(a), (n, len(a)))
    r = a[i].mean(1) / b[i].mean(1)
    return 100 * a.mean() / b.mean(), 100 * np.percentile(r, 2.5), 100 * np.percentile(r, 97.5)


def main(raw: str) -> None:
    groups = defaultdict(dict)  # (exp, size) -> name -> per-run arrays
    for path in sorted(Path(raw).glob("*.json")):
        rec = json.loads(path.read_text())
        half = 0.5 * rec["window"] / rec["optimal_steps"]
        for agent in sorted(set(rec["agents"])):
            idx = sorted(
                (b for b, a in enumerate(rec["agents"]) if a == agent),
                key=lambda b: rec["seeds"][b],  # seed order: every comparison is paired by seed
            )
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
                "seed_list": [rec["seeds"][b] for b in idx],
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
            "| agent | seeds | total goals (mean ± 95 % t half-width) | % of best (paired 95 % "
            "CI) | last 50k % of best (paired 95 % CI) | total − best, paired (95 % BCa; p t / "
            "sign) | median first goal | median steps to ½ optimal rate (never) | mentor wins at "
            "end | median margin |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for name, r in sorted(agents.items(), key=lambda kv: -kv[1]["goals"].mean()):
            if r["seed_list"] != agents[best]["seed_list"]:
                raise ValueError(f"{exp} {size}: {name} and {best} ran different seeds")
            m, h = _ci_mean(r["goals"])
            pct, lo, hi = _ratio_ci(r["goals"], agents[best]["goals"], rng)
            late, llo, lhi = _ratio_ci(r["last50k"], agents[best]["last50k"], rng)
            if name == best:
                paired = "–"
            else:
                c = paired_comparison(r["goals"], agents[best]["goals"])
                paired = f"{c.difference.format(0)}; {c.t_p:.3f} / {c.sign_p:.3f}"
            never = int(np.isinf(r["half"]).sum())
            win = np.nanmean(r["win"]) if not np.isnan(r["win"]).all() else float("nan")
            marg = np.nanmedian(r["margin"]) if not np.isnan(r["margin"]).all() else float("nan")
            print(
                f"| {name} | {r['seeds']} | {m:.0f} ± {h:.0f} | {pct:.1f} ({lo:.1f}–{hi:.1f}) | "
                f"{late:.1f} ({llo:.1f}–{lhi:.1f}) | {paired} | {np.median(r['first']):.0f} | {np.median(r['half']):.0f} ({never}) | "
                f"{win:.3f} | {marg:.4f} |"
            )


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "experiments/results/mechanism/raw")
