"""Figures and ``results.md`` of ``himit run puzzlebox`` (:mod:`himit_torch.runs.puzzle_box`),
beside Whiten et al.'s (2006) three findings.

Statistics (every interval says what it is):

* means over runs: mean ± half-width of the 95 % Student-t confidence interval (n runs);
* shares: k/n with the 95 % Clopper–Pearson (exact) interval;
* first openings: runs that never opened the box count as opening one step after the end, so
  the median and the paired tests use every run (ranks only); means are given over the runs
  that opened it;
* paired comparisons (runs of one seed share their random streams, so conditions are paired by
  seed): the mean of the per-seed differences with its 95 % t interval, and the two-sided
  Wilcoxon signed-rank p, Holm-corrected within each experiment's declared comparisons;
* organisation shares, imitators against non-imitators: Fisher's exact test, two-sided.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from himit_torch.runs.runner import source_commit
from himit_torch.runs.study import Field, read_record, read_table, series_of
from himit_torch.statistics import holm, paired_comparison, share_interval, t_interval
from himit_torch.viz.results_page import plot_command, provenance_line, write_results_page

__all__ = [
    "read_summary",
    "rewrite_puzzle_box_report",
    "write_puzzle_box_figures",
    "write_puzzle_box_results",
]

_ORDER = ("skewer", "step", "mixed", "incomplete")
#: The header of the speed tables of (a) and (c).
_SPEED_HEADER = (
    "| condition | n | opened the box [95 % Clopper–Pearson] | first opening, median | first opening, "
    "mean ± 95 % t (runs that opened) | openings, last window | greedy V^π(start) |",
    "|---|---|---|---|---|---|---|",
)
#: Lines of the organisation-over-learning panel: batch, label, colour, style.
_TIME_LINES = (
    ("speed_imitation", "imitation", "#d62728", "-"),
    ("speed_options", "options (no mentor)", "#1f77b4", "-"),
    ("harder_pinch_imitation", "imitation, harder pinch", "#d62728", "--"),
    ("harder_pinch_options", "options, harder pinch", "#1f77b4", "--"),
    ("no_pinch_imitation", "imitation, no pinch", "#d62728", ":"),
    ("no_pinch_options", "options, no pinch", "#1f77b4", ":"),
)


# ================================================================================ statistics
def _firsts(runs: list[dict], steps: int) -> np.ndarray:
    """First openings, a run that never opened counted at ``steps + 1``."""
    return np.array([r["first_opening"] if r["first_opening"] >= 0 else steps + 1 for r in runs])


def _cell(values, digits: int = 1) -> str:
    """Mean ± 95 % t over the finite ``values`` (the mean alone for one, "–" for none)."""
    measured = [x for x in values if x is not None and math.isfinite(x)]
    return t_interval(measured).plus_minus(digits) if measured else "–"


def _share(k: int, n: int) -> str:
    if n == 0:
        return "–"
    ci = share_interval(k, n)
    return f"{k}/{n} = {ci.estimate:.0%} [{ci.low:.0%}, {ci.high:.0%}]"


def _paired(a, b) -> tuple[float, float, float] | None:
    """``(mean of a − b, its 95 % t half-width, Wilcoxon p)`` over the pairs where both are
    finite (:func:`~himit_torch.statistics.paired_comparison`); None for fewer than 2 pairs."""
    pairs = [(x, y) for x, y in zip(a, b) if math.isfinite(x) and math.isfinite(y)]
    if len(pairs) < 2:
        return None
    c = paired_comparison([x for x, _ in pairs], [y for _, y in pairs], interval="t")
    return c.difference.estimate, c.difference.half_width, c.wilcoxon_p


def _diff_text(diff, pairs: str = "") -> str:
    """A :func:`_paired` result as ``mean ± half-width<pairs>, p = …`` ("–" for None)."""
    return "–" if diff is None else f"{diff[0]:+.2f} ± {diff[1]:.2f}{pairs}, p = {diff[2]:.2g}"


def _batch(summary: dict, tag: str) -> dict:
    return next(b for b in summary["batches"] if b["batch"] == tag)


#: What its ``config`` must hold for the page.
_SUMMARY_CONFIG_KEYS = (
    "skewers", "transfer_skewers", "seeds", "steps", "transfer_steps", "mentor_episodes", "slip",
    "window", "learner", "box_steps",
)  # fmt: skip
#: What each run of a batch holds for the page.
_SUMMARY_RUN_KEYS = (
    "seed", "watched", "paired_organisation", "first_opening", "openings",
    "final_window_openings", "greedy_value", "organisation", "opens", "pinch_steps",
    "power_steps", "same_low_level_as_mentor", "stuck_at",
)  # fmt: skip
#: What ``summary.json`` must hold for the page: its configuration's settings, and each batch's
#: name, steps and states ≥ 1, an optimum > 0 (what its rates divide by), numbers where the
#: page prints them, and at least one run, each an object with every key the page reads.
_SUMMARY = {
    "config": Field("object", items=dict.fromkeys(_SUMMARY_CONFIG_KEYS, Field())),
    "commit": Field("text"),
    "mentor_plans": Field("object"),
    "batches": Field(
        "list",
        items={
            "batch": Field("text"),
            "steps": Field("whole", above=0),
            "runs": Field("list", items=dict.fromkeys(_SUMMARY_RUN_KEYS, Field())),
            "engine": Field("text"),
            "wall_seconds": Field("number", above=-1e-9),
            "num_states": Field("whole", above=0),
            "optimal_steps": Field("number", above=0),
            "value_star": Field("finite"),
        },
    ),
}
#: The batches every page draws: (a)'s and (c)'s conditions.
_NEEDED_BATCHES = {
    "speed": ("imitation", "options", "primitives"),
    "transfer": ("any", "plain", "options"),
}


def read_summary(run_dir: str | Path) -> dict:
    """A finished ``himit run puzzlebox`` directory's ``summary.json``, checked for what its
    page reads (:func:`~himit_torch.runs.study.read_record`): a damaged file (not JSON, or a
    field missing or of another type) is a ``ValueError`` naming the file and the field."""
    path = Path(run_dir) / "summary.json"
    where = f"summary {path}"
    fix = "; the record is damaged (run the study again, or restore the file)"
    data = read_record(path, where, _SUMMARY, fix)
    tags = {batch["batch"] for batch in data["batches"]}
    needed = [f"{e}_{c}" for e, cs in _NEEDED_BATCHES.items() for c in cs]
    if not set(needed) <= tags:
        raise ValueError(
            f"{where}: field 'batches' lacks {sorted(set(needed) - tags)} (the page's "
            f"experiments (a) and (c)){fix}"
        )
    return data


def rewrite_puzzle_box_report(run_dir: str | Path, run_command: str | None = None) -> None:
    """Redraw the figures and ``results.md`` of a finished ``himit run puzzlebox`` directory
    from its ``summary.json`` and ``batches/`` (``himit plot``); ``run_command`` as
    :func:`write_puzzle_box_results`."""
    run_dir = Path(run_dir)
    summary = read_summary(run_dir)
    write_puzzle_box_figures(run_dir, summary)
    write_puzzle_box_results(run_dir, summary, run_command)


# ================================================================================ figures
def _curves(run_dir: Path, tag: str) -> tuple[np.ndarray, np.ndarray]:
    """``(steps [W], openings [n, W])`` of batch ``tag`` from ``batches/<tag>.csv``."""
    path = run_dir / "batches" / f"{tag}.csv"
    where = f"curves file {path}"
    steps, series = series_of(
        read_table(path, where, ("seed", "step"), ("openings",)), "openings", where
    )
    return np.array(steps), np.array(series)


def _thousands_label(x, _pos=None) -> str:
    return f"{x / 1000:g}k" if x else "0"


def _evals(run_dir: Path, tag: str, key: str = "value") -> tuple[np.ndarray, np.ndarray]:
    """``(steps [E], values [n, E])`` of the greedy policies' evaluations of batch ``tag``
    (``key``: ``value``, ``organisation`` or ``pinch_steps``)."""
    path = run_dir / "batches" / f"{tag}.evals.json"
    evals = {int(k): v for k, v in json.loads(path.read_text()).items()}
    steps = np.array(sorted(evals))
    return steps, np.array([evals[s][key] for s in steps]).T


def write_puzzle_box_figures(run_dir: Path, summary: dict) -> None:
    """``figures/speed.png``, ``figures/organisation.png``, ``figures/transfer.png``."""
    from himit_torch.viz.report import AGENT_COLORS

    colors = {
        **AGENT_COLORS,
        "plain": AGENT_COLORS["imitation_confident"],
        "any": AGENT_COLORS["imitation"],
    }
    for experiment, conditions in _NEEDED_BATCHES.items():
        _experiment_figure(run_dir, summary, experiment, conditions, colors)
    _organisation_figure(run_dir, summary)


def _experiment_figure(
    run_dir: Path, summary: dict, experiment: str, conditions: tuple[str, ...], colors: dict
) -> None:
    """``figures/<experiment>.png``: the conditions' openings per window, first openings and
    greedy values."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    from himit_torch.viz.plotting import (
        plot_first_goals,
        plot_goal_curves,
        plot_mean_band,
        save_figure,
    )

    cfg = summary["config"]
    window = cfg["window"]
    tags = {c: f"{experiment}_{c}" for c in conditions}
    first = _batch(summary, tags[conditions[0]])
    fig = Figure(figsize=(15, 4.2), layout="constrained")
    ax_curves, ax_first, ax_value = fig.subplots(1, 3, width_ratios=(1.3, 1, 1))
    goals, firsts = {}, {}
    steps = None
    for c, tag in tags.items():
        steps, goals[c] = _curves(run_dir, tag)
        firsts[c] = [r["first_opening"] for r in _batch(summary, tag)["runs"]]
    optimum = window / first["optimal_steps"]
    plot_goal_curves(ax_curves, steps, goals, colors=colors, optimum=optimum, window=window,
                     legend=False)  # fmt: skip
    ax_curves.legend(fontsize="x-small", loc="lower right", title="band: seeds' range",
                     title_fontsize="x-small")  # fmt: skip
    ax_curves.set_ylabel(f"openings per {window:,} steps")
    plot_first_goals(ax_first, firsts, int(first["steps"]), colors=colors)
    ax_first.set_xlabel("step of the first opening (log; dots: seeds)")
    for c, tag in tags.items():
        at, values = _evals(run_dir, tag, "value")
        plot_mean_band(ax_value, at, values, color=colors[c], label=f"{c} (n={len(values)})")
    ax_value.axhline(first["value_star"], color="0.3", ls=":", label="V*(start), exact")
    ax_value.set_xlabel("primitive steps")
    ax_value.xaxis.set_major_formatter(FuncFormatter(_thousands_label))
    ax_value.set_ylabel("V^π(start) of the greedy policy, exact")
    ax_value.grid(alpha=0.3)
    ax_value.legend(fontsize="small", title="mean, 95 % t CI", title_fontsize="small")
    what = (
        f"(a) speed, {cfg['skewers']}-skewer box"
        if experiment == "speed"
        else f"(c) a new element: {cfg['skewers']}-skewer demonstrations, "
        f"{cfg['transfer_skewers']}-skewer box"
    )
    fig.suptitle(f"{what} — {len(first['runs'])} seeds per condition")
    save_figure(fig, run_dir / "figures" / f"{experiment}.png", dpi=100, fit=True)


def _organisation_figure(run_dir: Path, summary: dict) -> None:
    from matplotlib.figure import Figure
    from matplotlib.ticker import FuncFormatter

    from himit_torch.viz.plotting import save_figure

    groups = _organisation_groups(summary, ("speed", "harder_pinch", "no_pinch", "transfer"))
    fig = Figure(figsize=(16, 6.4), layout="constrained")
    ax, ax_time = fig.subplots(1, 2, width_ratios=(1.2, 1))
    for tag, label, color, ls in _TIME_LINES:
        if not any(b["batch"] == tag for b in summary["batches"]):
            continue
        # whether each run's plan followed the organisation its seed watched (or would have)
        steps, orgs = _evals(run_dir, tag, "organisation")
        paired = [r["paired_organisation"] for r in _batch(summary, tag)["runs"]]
        follows = orgs == np.array(paired)[:, None]
        n = follows.shape[0]
        cis = [share_interval(int(f.sum()), n) for f in follows.T]
        share = np.array([(ci.estimate, ci.low, ci.high) for ci in cis])
        ax_time.plot(steps, share[:, 0], color=color, ls=ls, lw=2, label=f"{label} (n={n})")
        ax_time.fill_between(steps, share[:, 1], share[:, 2], color=color, alpha=0.12, lw=0)
    ax_time.set_ylim(0, 1)
    ax_time.set_xlabel("primitive steps")
    ax_time.xaxis.set_major_formatter(FuncFormatter(_thousands_label))
    ax_time.set_ylabel("share following the organisation watched")
    ax_time.grid(alpha=0.3)
    ax_time.legend(fontsize="small", title="band: 95 % Clopper–Pearson", title_fontsize="small")
    ax_time.set_title("over learning (non-imitators: their seed's imitator's)", fontsize="medium")
    colors = {"skewer": "#1f77b4", "step": "#ff7f0e", "mixed": "#7f7f7f", "incomplete": "#d9d9d9"}
    names = list(groups)
    left = np.zeros(len(names))
    for org in _ORDER:
        share = np.array(
            [
                sum(r["organisation"] == org for r in runs) / max(len(runs), 1)
                for runs in groups.values()
            ]
        )
        ax.barh(names, share, left=left, color=colors[org], label=org)
        left += share
    ax.invert_yaxis()
    ax.set_xlabel("share of runs whose final greedy policy (read without slips) follows …")
    ax.set_xlim(0, 1)
    ax.legend(ncol=4, loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize="small")
    ax.grid(axis="x", alpha=0.3)
    save_figure(fig, run_dir / "figures" / "organisation.png", dpi=100)


def _organisation_groups(summary: dict, experiments=("speed", "transfer")) -> dict[str, list[dict]]:
    """Runs by group (condition, and organisation watched for imitators) for the tables and the
    organisation figure."""
    cfg = summary["config"]
    k, K = cfg["skewers"], cfg["transfer_skewers"]
    out: dict[str, list[dict]] = {}
    for tag, label in (
        ("speed_imitation", f"imitation, {k} skewers"),
        ("speed_options", f"options (no mentor), {k} skewers"),
        ("speed_primitives", f"primitives, {k} skewers"),
        ("harder_pinch_imitation", f"imitation, harder pinch, {k} skewers"),
        ("harder_pinch_options", f"options, harder pinch, {k} skewers"),
        ("no_pinch_imitation", f"imitation, no pinch, {k} skewers"),
        ("no_pinch_options", f"options, no pinch, {k} skewers"),
        ("transfer_plain", f"imitation, plain mapping, {K} skewers"),
        ("transfer_any", f"imitation, 'any' mapping, {K} skewers"),
        ("transfer_options", f"options (no mentor), {K} skewers"),
    ):
        if not tag.startswith(tuple(experiments)) or not any(
            b["batch"] == tag for b in summary["batches"]
        ):
            continue
        runs = _batch(summary, tag)["runs"]
        if tag.endswith(("options", "primitives")):
            out[label] = runs
            continue
        for org in ("skewer", "step"):
            out[f"{label}, watched {org}"] = [r for r in runs if r["watched"] == org]
    return out


# ================================================================================ results.md
def write_puzzle_box_results(run_dir: Path, summary: dict, run_command: str | None = None) -> None:
    """``results.md``: the three experiments' tables and the findings set beside the study's
    (:func:`~himit_torch.viz.results_page.write_results_page`: the provenance, then this study's
    sections). ``run_command``: the ``himit run puzzlebox`` command of the runs
    (:func:`himit_torch.runs.puzzle_box.puzzle_box_run_command`; None: the settings the
    summary records)."""
    cfg = summary["config"]
    speed = {c: _batch(summary, f"speed_{c}") for c in ("imitation", "options", "primitives")}
    transfer = {c: _batch(summary, f"transfer_{c}") for c in ("options", "plain", "any")}
    org_lines, org_facts = _organisation_section(summary, speed)
    transfer_lines, transfer_facts = _transfer_section(cfg, transfer)
    write_results_page(
        run_dir,
        "The puzzle box: Whiten et al.'s (2006) three findings, run on the model",
        _provenance(run_dir, summary, run_command),
        [
            _settings_section(cfg, speed, transfer),
            _speed_section(cfg, speed),
            org_lines,
            transfer_lines,
            _findings_table(cfg, speed, org_facts, transfer_facts),
            _closing_section(summary),
        ],
    )


def _provenance(run_dir: Path, summary: dict, run_command: str | None) -> list[str]:
    """Which commit and engines ran the batches, how the page is redrawn and the runs rerun."""
    engines = sorted({b["engine"] for b in summary["batches"]})
    now = source_commit()
    written = "" if now == summary["commit"] else f" (this report written at commit `{now}`)"
    return [
        provenance_line(
            [summary["commit"]],
            " (from `summary.json`)",
            plot_command(run_dir),
            f"`{run_command}`."
            if run_command
            else "the settings in `summary.json`'s `config` (not all of them flags of "
            "`himit run puzzlebox`).",
        ),
        "Produced by `himit run puzzlebox` (the same as `python experiments/puzzle_box.py`); "
        f"settings: `himit_torch/runs/puzzle_box.py`. Code at commit `{summary['commit']}`, "
        f"engine {', '.join(f'`{e}`' for e in engines)}{written}. The world: "
        "`himit_torch/worlds/puzzle_box.py` (`himit info --puzzle-box K`).",
    ]


def _settings_section(cfg: dict, speed: dict[str, dict], transfer: dict[str, dict]) -> list[str]:
    """What runs (seeds, steps, mentors, learner settings), the intervals, and the two boxes."""
    k, K = cfg["skewers"], cfg["transfer_skewers"]
    return [
        f"{cfg['seeds']} seeds per condition; {cfg['steps']:,} steps per run on the {k}-skewer "
        f"box, {cfg['transfer_steps']:,} on the {K}-skewer box; {cfg['mentor_episodes']} mentor "
        f"episodes (states only) per seed, the seed's mentor showing skewer by skewer (even seeds) "
        f"or step by step (odd); slip {cfg['slip']}; openings counted per {cfg['window']:,} "
        "steps. Learner settings: "
        + ", ".join(f"`{key}={v}`" for key, v in cfg["learner"].items() if key != "window")
        + ".",
        "",
        "Intervals: means ± half-width of the 95 % Student-t interval over runs; shares k/n with "
        "the 95 % Clopper–Pearson interval; paired differences (conditions share seeds, hence "
        "random streams) as mean ± 95 % t half-width with the two-sided Wilcoxon signed-rank p, "
        "Holm-corrected within each experiment. A run that never opened the box counts as "
        "opening one step after its end in medians and paired tests.",
        "",
        f"Boxes: {k} skewers — {speed['imitation']['num_states']:,} states, optimal "
        f"{speed['imitation']['optimal_steps']:.1f} steps to open, V*(start) = "
        f"{speed['imitation']['value_star']:.4f}; {K} skewers — "
        f"{transfer['options']['num_states']:,} states, {transfer['options']['optimal_steps']:.1f}"
        f" steps, V*(start) = {transfer['options']['value_star']:.4f}. Both organisations are "
        "optimal with equal cost (exact planning: `himit info --puzzle-box K`).",
        "",
    ]


def _closing_section(summary: dict) -> list[str]:
    """The learning wall time of every batch, and where the curves and logs are."""
    wall = sum(b["wall_seconds"] for b in summary["batches"])
    each = ", ".join(f"{b['batch']} {b['wall_seconds']:.0f} s" for b in summary["batches"])
    return [
        "",
        f"Learning wall time, all batches: {wall:.0f} s ({each}).",
        "",
        "Curves: `curves.csv`; per run: `batches/*.json`; TensorBoard logs: the run directory's "
        "`tb/` (`tensorboard --logdir <run dir>/tb`).",
        "",
    ]


def _speed_rows(batches: dict[str, dict], reference: str) -> tuple[list[str], dict]:
    """Rows of a speed table (first opening, last window, greedy value) and the paired tests of
    ``reference`` against the other conditions (Holm over all of them)."""
    rows, tests = [], []
    ref = batches[reference]
    for c, b in batches.items():
        runs, steps = b["runs"], b["steps"]
        firsts = _firsts(runs, steps)
        opened = [r["first_opening"] for r in runs if r["first_opening"] >= 0]
        values = [r["greedy_value"] for r in runs if r["greedy_value"] is not None]
        rows.append(
            f"| {c} | {len(runs)} | {_share(len(opened), len(runs))} | {np.median(firsts):,.0f} | "
            f"{_cell(opened, 0)} | {_cell([r['final_window_openings'] for r in runs])} | "
            f"{_cell(values, 4)} |"
        )
        if c == reference:
            continue
        for what, get in (
            ("first opening", _firsts),
            ("openings, last window", lambda rs, st: [r["final_window_openings"] for r in rs]),
            ("greedy value", lambda rs, st: [r["greedy_value"] or math.nan for r in rs]),
        ):
            diff = _paired(get(ref["runs"], ref["steps"]), get(runs, steps))
            tests.append((f"{reference} − {c}: {what}", *(diff or (math.nan,) * 3)))
    adjusted = holm([t[3] for t in tests])
    return rows, {name: (mean, half, p, q) for (name, mean, half, p), q in zip(tests, adjusted)}


def _test_lines(tests: dict) -> list[str]:
    lines = ["| paired comparison (per seed) | mean difference ± 95 % t | Wilcoxon p | Holm p |"]
    lines.append("|---|---|---|---|")
    for name, (mean, half, p, q) in tests.items():
        digits = 4 if "value" in name else 1
        lines.append(f"| {name} | {mean:+,.{digits}f} ± {half:,.{digits}f} | {p:.2g} | {q:.2g} |")
    return lines


def _speed_section(cfg: dict, speed: dict[str, dict]) -> list[str]:
    rows, tests = _speed_rows(speed, "imitation")
    return [
        f"## (a) Speed: imitation against options only and primitives only ({cfg['skewers']} "
        "skewers)",
        "",
        "Endpoints (declared before the runs): the first opening; openings in the last window; "
        "the exact value V^π(start) of the final greedy option policy, frozen as everywhere "
        "else (ties as configured; states where the run tried nothing: uniformly any of its "
        "options there). Figure: `figures/speed.png`.",
        "",
        *_SPEED_HEADER,
        *rows,
        "",
        *_test_lines(tests),
        "",
    ]


#: (b)'s designs: batch prefix, description.
_DESIGNS = (
    ("speed", "both grips, equally good (the main design)"),
    ("harder_pinch", "both grips, the mentor's pinch fails more often"),
    ("no_pinch", "the learner has no pinch (only subgoals can be copied)"),
)


def _score(run: dict, organisation: str, key: str = "scores") -> float:
    value = (run.get(key) or {}).get(organisation)
    return math.nan if value is None else float(value)


def _organisation_section(summary: dict, speed: dict[str, dict]) -> tuple[list[str], dict]:
    """(b): the organisation each design's runs follow, their low-level movements, their first
    openings, and the mentors' own plans; with the facts the findings table reads, per design
    (``follows``, ``others``, ``fisher``, ``holm``, ``pinch``, ``same``, ``n``, ``first``)."""
    cfg = summary["config"]
    rows, facts = _organisation_rows(summary)
    lines = [
        "## (b) Copying the organisation",
        "",
        "Each run's final greedy option policy is read from the start with every movement doing "
        f"what it intends (no slips): the order in which it does the {cfg['skewers'] * cfg['box_steps']} "
        "steps, classified as skewer by skewer, step by step, another order (mixed) or not "
        "opening the box (incomplete), and scored for how close it comes to the organisation "
        "watched (`organisation_scores`: 1 = exactly that organisation; for reference, a "
        "skewer-by-skewer plan scores 0.5 as step by step, a step-by-step plan 0 as skewer by "
        "skewer). Non-imitators watched nothing; each is "
        "compared with the organisation its seed's imitator watched. Three designs: the main "
        "one, where the learner can make the mentor's pinch and both grips are equally good, and "
        "two controls — the mentor's pinch a little worse than the learner's own grip, and a "
        "learner without the pinch. Figure: `figures/organisation.png` (final plans, and the "
        "share following over learning).",
        "",
        "| design | imitators following the watched organisation [95 % Clopper–Pearson] | non-imitators "
        "(paired) | Fisher p | watched-organisation score: imitators | non-imitators | paired "
        "difference, Wilcoxon p | Holm p |",
        "|---|---|---|---|---|---|---|---|",
        *rows,
        *_organisation_counts(summary),
        *_low_level_table(summary, facts),
        *_design_firsts_table(summary, facts),
        *_stuck_plans_note(summary),
    ]
    return lines, facts


def _organisation_rows(summary: dict) -> tuple[list[str], dict[str, Any]]:
    """Rows of (b)'s first table, per design: imitators and non-imitators following the watched
    organisation (Fisher's exact test) and their scores for it (paired, Holm over the designs);
    with each design's ``follows``, ``others``, ``fisher`` and ``holm``."""
    from scipy import stats

    facts: dict[str, Any] = {}
    rows, tests = [], []
    for prefix, about in _DESIGNS:
        if not any(b["batch"] == f"{prefix}_imitation" for b in summary["batches"]):
            continue
        imit = _batch(summary, f"{prefix}_imitation")["runs"]
        others = _batch(summary, f"{prefix}_options")["runs"]
        a = sum(r["organisation"] == r["paired_organisation"] for r in imit)
        b = sum(r["organisation"] == r["paired_organisation"] for r in others)
        fisher = float(stats.fisher_exact([[a, len(imit) - a], [b, len(others) - b]]).pvalue)
        mine = [_score(r, r["paired_organisation"]) for r in imit]
        theirs = [_score(r, r["paired_organisation"]) for r in others]
        both = sum(math.isfinite(x) and math.isfinite(y) for x, y in zip(mine, theirs))
        diff = _paired(mine, theirs)
        tests.append(diff[2] if diff else 1.0)
        rows.append(  # its last cell, the Holm-adjusted p, is added once every design is in
            f"| {about} | {_share(a, len(imit))} | {_share(b, len(others))} | {fisher:.2g} | "
            f"{_cell(mine, 2)} | {_cell(theirs, 2)} | {_diff_text(diff, f' (n={both})')} |"
        )
        facts[prefix] = {"follows": (a, len(imit)), "others": (b, len(others)), "fisher": fisher}
    adjusted = holm(tests) if tests else []
    for prefix, q in zip(facts, adjusted):
        facts[prefix]["holm"] = q
    return [f"{row} {q:.2g} |" for row, q in zip(rows, adjusted)], facts


def _organisation_counts(summary: dict) -> list[str]:
    """What the scores are over, then how many runs of each group follow each organisation."""
    lines = [
        "",
        "Scores are over the runs whose plan opens the box (mean ± 95 % t); the paired "
        "difference is over seeds where both plans open it.",
        "",
        "| runs | n | skewer by skewer | step by step | mixed | incomplete |",
        "|---|---|---|---|---|---|",
    ]
    for label, runs in _organisation_groups(summary, ("speed", "harder_pinch", "no_pinch")).items():
        counts = [sum(r["organisation"] == o for r in runs) for o in _ORDER]
        lines.append(f"| {label} | {len(runs)} | " + " | ".join(map(str, counts)) + " |")
    return lines


def _low_level_table(summary: dict, facts: dict[str, Any]) -> list[str]:
    """Per design: the share of the plans' steps done in the mentor's pinch, the plans that are
    the mentor's own, and the imitators' stuck plans; adds ``pinch``, ``same`` and ``n`` to each
    design's ``facts``."""
    lines = [
        "",
        "Low-level movements. The mentor does every step in a pinch grip, the learner's own "
        "skills in a power grip; in the first two designs the learner can also make the pinch "
        "with its primitives. Per design: the share of the greedy plan's steps done in the "
        "mentor's pinch (runs whose plan opens the box; mean ± 95 % t), runs whose whole plan "
        "(every state) is the mentor's own plan, and imitators whose plan gets stuck (and where).",
        "",
        "| design | pinch share: imitators | non-imitators | whole plan the mentor's: imitators "
        "| non-imitators | imitators stuck |",
        "|---|---|---|---|---|---|",
    ]
    for prefix, about in _DESIGNS:
        if prefix not in facts:
            continue
        groups = {c: _batch(summary, f"{prefix}_{c}")["runs"] for c in ("imitation", "options")}
        pinch = {
            c: [r["pinch_steps"] / max(r["pinch_steps"] + r["power_steps"], 1) for r in runs if r["opens"]]
            for c, runs in groups.items()
        }  # fmt: skip
        same = {c: sum(r["same_low_level_as_mentor"] for r in runs) for c, runs in groups.items()}
        stuck = [r["stuck_at"] for r in groups["imitation"] if r["stuck_at"]]
        facts[prefix].update(pinch=pinch, same=same, n=len(groups["imitation"]))
        where = "; ".join(f"`{s}`" for s in stuck[:3]) + (" …" if len(stuck) > 3 else "")
        lines.append(
            f"| {about} | {_cell(pinch['imitation'], 2)} | {_cell(pinch['options'], 2)} | "
            f"{same['imitation']}/{len(groups['imitation'])} | {same['options']}/"
            f"{len(groups['options'])} | {len(stuck)}{': ' + where if stuck else ''} |"
        )
    return lines


def _design_firsts_table(summary: dict, facts: dict[str, Any]) -> list[str]:
    """Per design: the median first openings of imitators and options runs and their paired
    difference; adds ``first`` (the two medians and the Wilcoxon p) to each design's ``facts``."""
    lines = [
        "",
        "First openings in each design (the main design's are (a)'s; the controls' were not "
        "among (a)'s declared comparisons): median step, and the paired difference imitation − "
        "options.",
        "",
        "| design | imitation, median | options, median | paired difference ± 95 % t | "
        "Wilcoxon p |",
        "|---|---|---|---|---|",
    ]
    for prefix, about in _DESIGNS:
        if prefix not in facts:
            continue
        imit = _batch(summary, f"{prefix}_imitation")
        opts = _batch(summary, f"{prefix}_options")
        a_first = _firsts(imit["runs"], imit["steps"])
        o_first = _firsts(opts["runs"], opts["steps"])
        mean, half, p = _paired(a_first, o_first) or (math.nan,) * 3
        facts[prefix]["first"] = (float(np.median(a_first)), float(np.median(o_first)), p)
        lines.append(
            f"| {about} | {np.median(a_first):,.0f} | {np.median(o_first):,.0f} | "
            f"{mean:+,.0f} ± {half:,.0f} | {p:.2g} |"
        )
    return lines


def _stuck_plans_note(summary: dict) -> list[str]:
    """What a stuck plan is, and the mentors' own plans."""
    plans = summary["mentor_plans"]
    return [
        "",
        "A stuck plan comes back to a state it has left with the same option (a loop) or stops "
        "where the run has tried nothing; the table names the state and the greedy option "
        "there. A loop in the mentor's pinch is the mentor term at work: eq. 2 makes the state "
        "valuable (the mentor went on from it), but the only own option the run has tried there "
        "is a motion that does nothing, and the greedy choice is among tried options.",
        "",
        f"The mentors' own plans: skewer by skewer `{' '.join(plans['skewer'])}`; step by step "
        f"`{' '.join(plans['step'])}` (`i.j` = skewer i, step j).",
        "",
    ]


def _transfer_section(cfg: dict, transfer: dict[str, dict]) -> tuple[list[str], dict]:
    rows, _ = _speed_rows({c: transfer[c] for c in ("plain", "any", "options")}, "plain")
    tests = {}
    for mapping in ("plain", "any"):
        _, mine = _speed_rows({c: transfer[c] for c in (mapping, "options")}, mapping)
        tests.update({n: v[:3] for n, v in mine.items()})
    adjusted = holm([v[2] for v in tests.values()])
    tests = {n: (*v, q) for (n, v), q in zip(tests.items(), adjusted)}
    K, k, n = cfg["transfer_skewers"], cfg["skewers"], cfg["box_steps"]
    lines = [
        f"## (c) A new element: {k}-skewer demonstrations, a {K}-skewer box",
        "",
        f"The mentors demonstrate on the {k}-skewer box (the episodes of (a)); the learner "
        f"works on a {K}-skewer box. The mapping (the paper's footnote 2; "
        "`himit_torch/mentor/puzzle_box.py`): *plain* — mentor skewer i is learner skewer i, the "
        f"learner's skewer {K} stays in; *any* — the mentor's box seen in any {k} of the "
        f"learner's {K} skewers, in order, the other held at any level (C({K},{k}) · {n + 1} "
        "mapped episodes per episode: a state abstraction, each skewer seen relative to the "
        "others, written as the concrete transitions it implies). Both keep eq. 2 sound: the "
        "box's dynamics are local to the hand and the skewer it acts on, so every mapped step "
        "is one the learner's relabelled movement makes with the same probability "
        "(`tests/worlds/test_puzzle_box.py::test_the_mapping_keeps_every_transition_law`). "
        "Against options without demonstrations. Figure: `figures/transfer.png`.",
        "",
        *_SPEED_HEADER,
        *rows,
        "",
        *_test_lines(tests),
        "",
        f"Assimilation: how the final greedy plan fits skewer {K}, the one no demonstration "
        f"showed, into the organisation watched. *Strict*: the plan follows the watched "
        f"organisation over all {K} skewers. *Score*: `organisation_scores` of the watched "
        f"organisation over all skewers, and for skewer {K} alone (step by step: the share of "
        f"its pairs with other skewers' steps done in level order; skewer by skewer: whether its "
        f"steps are done in one run) — mean ± 95 % t over plans that open the box; options "
        "runs: the same scores for the organisation their seed's imitators watched.",
        "",
        "| mapping | watched | n | plans: skewer / step / mixed / incomplete | strict [95 % "
        f"Clopper–Pearson] | score, all skewers | score, skewer {K} | options' score, skewer "
        f"{K} (paired) | paired difference, Wilcoxon p |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    rows, facts = _assimilation_rows(transfer)
    lines += [*rows, "", "Greedy plans of the first seeds (`i.j` = skewer i, step j):", ""]
    for m in ("plain", "any"):
        for org in ("skewer", "step"):
            shown = [r for r in transfer[m]["runs"] if r["watched"] == org and r["opens"]][:2]
            for r in shown:
                lines.append(f"* {m}, watched {org}, seed {r['seed']}: `{' '.join(r['subgoals'])}`")
    lines.append("")
    facts["tests"] = tests
    return lines, facts


def _assimilation_rows(transfer: dict[str, dict]) -> tuple[list[str], dict[Any, Any]]:
    """(c)'s assimilation table, a row per mapping and organisation watched, and its facts."""
    lines, facts = [], {}
    others = transfer["options"]["runs"]
    for mapping in ("plain", "any"):
        runs = transfer[mapping]["runs"]
        for org in ("skewer", "step"):
            idx = [i for i, r in enumerate(runs) if r["watched"] == org]
            follows = sum(runs[i]["organisation"] == org for i in idx)
            overall = [_score(runs[i], org) for i in idx]
            new = [_score(runs[i], org, "focus_scores") for i in idx]
            base = [_score(others[i], org, "focus_scores") for i in idx]
            pairs = sum(math.isfinite(x) and math.isfinite(y) for x, y in zip(new, base))
            diff = _paired(new, base)
            facts[(mapping, org)] = {"strict": (follows, len(idx)), "new": new, "diff": diff}
            counts = " / ".join(str(sum(runs[i]["organisation"] == o for i in idx)) for o in _ORDER)
            lines.append(
                f"| {mapping} | {org} | {len(idx)} | {counts} | {_share(follows, len(idx))} | "
                f"{_cell(overall, 2)} | {_cell(new, 2)} | {_cell(base, 2)} | "
                f"{_diff_text(diff, f' (n={pairs})')} |"
            )
    return lines, facts


def _verdict(ok: bool, partly: bool = False) -> str:
    return "reproduced" if ok else ("partly" if partly else "not reproduced")


def _findings_table(cfg: dict, speed: dict, org: dict, transfer: dict) -> list[str]:
    """The study's findings beside ours, each verdict computed from the numbers above (one row
    per finding: :func:`_speed_finding`, :func:`_organisation_findings`,
    :func:`_assimilation_finding`), then the rules of the verdicts."""
    K = cfg["transfer_skewers"]
    return [
        "## Beside Whiten et al. (2006)",
        "",
        "| finding of the study (3-year-olds, keyway-fruit box) | here | verdict | evidence |",
        "|---|---|---|---|",
        _speed_finding(cfg, speed, org, transfer),
        *_organisation_findings(org),
        _assimilation_finding(cfg, transfer),
        "",
        "Verdicts are computed from the numbers (`himit_torch/runs/puzzle_box_report.py`, "
        "`_findings_table`): 1 reproduced when imitators open the box significantly sooner than "
        "options-only learners in (a) (Holm p < 0.05), partly when they are significantly better "
        "on another of (a)'s endpoints (openings in the last window, greedy value) — the rule "
        "declared with the code of the first run (commit 5f23ff7); exploratory, by a rule added "
        "after that run (commit 652878d): partly also when they open the "
        f"{K}-skewer box of (c) significantly sooner with the *any* mapping; 2a when imitators "
        "follow the watched organisation significantly more often than non-imitators (Fisher "
        "p < 0.05) in the main design; 2b when no imitator's plan is the mentor's movement for "
        "movement and imitators do at most 10 points more of their steps in the mentor's grip "
        "than non-imitators (partly: only the first); 3 when at least half of the *any*-mapped "
        "imitators follow the watched organisation over every skewer, partly when some do or "
        "when the new skewer's step-by-step score beats the options runs' (Wilcoxon p < 0.05). "
        "Skewer by skewer is the weak test of assimilation (a learner that leaves the new "
        "skewer to the end is still skewer by skewer); step by step is the strict one.",
    ]


def _speed_finding(cfg: dict, speed: dict, org: dict, transfer: dict) -> str:
    """Finding 1 (watching a solution helps): (a)'s endpoints, (b)'s controls' first openings and
    (c)'s first opening with the *any* mapping, and its verdict."""
    imit, opts = speed["imitation"]["runs"], speed["options"]["runs"]
    steps = speed["imitation"]["steps"]
    first_i, first_o = np.median(_firsts(imit, steps)), np.median(_firsts(opts, steps))
    _, tests = _speed_rows(speed, "imitation")
    faster = tests["imitation − options: first opening"]
    better = tests["imitation − options: greedy value"]
    later = tests["imitation − options: openings, last window"]
    ok1 = faster[0] < 0 and faster[3] < 0.05
    sooner5 = transfer["tests"]["any − options: first opening"]
    # The rule declared with the code of the first run (5f23ff7): (a)'s endpoints only.
    partly1 = any(
        t[3] < 0.05 and t[0] * sign > 0 for t, sign in ((faster, -1), (better, 1), (later, 1))
    )
    # Exploratory: a rule added after that run (652878d) also counts (c)'s first opening.
    partly1_later = partly1 or (sooner5[3] < 0.05 and sooner5[0] < 0)
    verdict1 = _verdict(ok1, partly1)
    if _verdict(ok1, partly1_later) != verdict1:
        verdict1 += f" (exploratory, by a rule added after the run: {_verdict(ok1, partly1_later)})"
    first_controls = "; ".join(
        f"{p.replace('_', ' ')}: {org[p]['first'][0]:,.0f} vs {org[p]['first'][1]:,.0f} "
        f"(Wilcoxon p = {org[p]['first'][2]:.2g})"
        for p in ("harder_pinch", "no_pinch")
        if p in org and "first" in org[p]
    )
    return (
        "| 1. Children who watched a solution did much better than those who did not | "
        f"{cfg['skewers']} skewers: first opening, median: imitation {first_i:,.0f} vs options "
        f"{first_o:,.0f} steps; paired difference {faster[0]:+,.0f} ± {faster[1]:,.0f} (Holm p = "
        f"{faster[3]:.2g}); openings in the last window {later[0]:+.1f} ± {later[1]:.1f} (Holm "
        f"p = {later[3]:.2g}); final greedy value {better[0]:+.4f} ± {better[1]:.4f} (Holm p = "
        f"{better[3]:.2g}). First openings in (b)'s controls, imitation vs options: "
        f"{first_controls}. {cfg['transfer_skewers']} skewers, *any* mapping: first opening "
        f"{sooner5[0]:+,.0f} ± {sooner5[1]:,.0f} steps against options (Holm p = "
        f"{sooner5[3]:.2g}) | {verdict1} | (a), (b), (c) |"
    )


def _organisation_findings(org: dict) -> list[str]:
    """Findings 2a (the organisation watched is copied) and 2b (the mentor's low-level movements
    are not), from (b)'s facts, and their verdicts."""
    main = org["speed"]
    a, n = main["follows"]
    b, m = main["others"]
    ok2a = main["fisher"] < 0.05 and a / max(n, 1) > b / max(m, 1)
    pinch = {c: (np.mean(v) if v else math.nan) for c, v in main["pinch"].items()}
    ok2b = main["same"]["imitation"] == 0 and bool(pinch["imitation"] <= pinch["options"] + 0.1)
    controls = "; ".join(
        f"{p.replace('_', ' ')}: {_share(*org[p]['follows'])} vs {_share(*org[p]['others'])}"
        for p in ("harder_pinch", "no_pinch")
        if p in org
    )
    pinch_controls = "; ".join(
        f"{p.replace('_', ' ')}: imitators {np.mean(org[p]['pinch']['imitation']):.0%}, "
        f"non-imitators {np.mean(org[p]['pinch']['options']):.0%}"
        for p in ("harder_pinch",)
        if p in org and org[p]["pinch"]["imitation"] and org[p]["pinch"]["options"]
    )
    return [
        "| 2a. They copied whichever hierarchical organisation they saw | "
        f"main design: imitators following the watched organisation {_share(a, n)} vs "
        f"non-imitators {_share(b, m)} (Fisher p = {main['fisher']:.2g}); controls — "
        f"{controls} | {_verdict(ok2a, a > b)} | (b) |",
        "| 2b. … but not the demonstrator's low-level movements | main design: steps done in the "
        f"mentor's pinch: imitators {pinch['imitation']:.0%}, non-imitators "
        f"{pinch['options']:.0%}; whole plan the mentor's: {main['same']['imitation']}/"
        f"{main['n']} imitators; {pinch_controls} | "
        f"{_verdict(ok2b, main['same']['imitation'] == 0)} | (b) |",
    ]


def _assimilation_finding(cfg: dict, transfer: dict) -> str:
    """Finding 3 (a new skewer is assimilated into the organisation watched), from (c)'s facts,
    and its verdict."""
    K = cfg["transfer_skewers"]
    step_any, step_plain = transfer[("any", "step")], transfer[("plain", "step")]
    strict_any = sum(transfer[("any", o)]["strict"][0] for o in ("skewer", "step"))
    n_any = sum(transfer[("any", o)]["strict"][1] for o in ("skewer", "step"))
    d_any, d_plain = step_any["diff"], step_plain["diff"]
    ok3 = n_any > 0 and strict_any / n_any >= 0.5
    partly3 = strict_any > 0 or (d_any is not None and d_any[0] > 0 and d_any[2] < 0.05)

    def mean_new(facts):
        v = [x for x in facts["new"] if math.isfinite(x)]
        return f"{np.mean(v):.2f}" if v else "–"

    return (
        f"| 3. At test they assimilated a new (fifth) skewer into the rule they had inferred | "
        f"strict, *any* mapping: {_share(strict_any, n_any)}; skewer {K}'s step-by-step score "
        f"after watching step by step: *plain* {mean_new(step_plain)} (paired difference to "
        f"the options runs {_diff_text(d_plain)}), *any* {mean_new(step_any)} (paired "
        f"difference {_diff_text(d_any)}) | "
        f"{_verdict(ok3, partly3)} | (c) |"
    )
