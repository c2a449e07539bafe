"""The whole benchmark in one command (PROTOCOL.md, the fair factorial of 2026-11-26): every
method under every exploration schedule, every method with a mentor term with and without
fading, on the nine worlds and the puzzle box (seeds 0–19, random ties); the recommended
imitator's pick on fresh held-out seeds; the stresses; MiniGrid's tasks (amendment of
2026-11-29, ``minigrid_benchmark.py``); then the tables.

    python experiments/benchmark/run_benchmark.py [--parts worlds puzzlebox pick stress minigrid]
        [--logdir runs/benchmark] [--seeds 20] [--skip-runs | --timing-only]

Each part's wall time is written to ``experiments/results/benchmark/timing.json`` (and so onto
the benchmark's page). The records every table is made from are copied into
``experiments/results/benchmark/`` (``<preset>/`` per cell group, ``puzzlebox/``,
``stress_exp2/``, ``minigrid/``) and ``experiments/results/presets/records/`` (the pick's
sweeps), then
``analyse.py`` and ``../presets/analyse_search.py`` run on them.

``--timing-only`` times the parts and leaves the repository alone: the runs go to
``--logdir`` as always, each part's wall time to ``<logdir>/timing.json``, and nothing is
copied into ``experiments/results/`` nor analysed (for measuring the benchmark's time, or a
slice of it with ``--seeds``, without overwriting the committed records).
"""

import argparse
import json
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXPERIMENTS = HERE.parent
RESULTS = EXPERIMENTS / "results" / "benchmark"
PRESET_RECORDS = EXPERIMENTS / "results" / "presets" / "records"

#: Every method's agent, and those with a mentor term (the only ones fading changes).
ALL_AGENTS = (
    "imitation",
    "imitation_primitives",
    "pbrs",
    "pbrs_primitives",
    "bco",
    "options",
    "primitives",
)
MENTOR_AGENTS = ("imitation", "imitation_primitives")
#: The factorial's cells: preset → the agents that run under it (PROTOCOL.md's table).
CELLS = {
    "paper": ALL_AGENTS,
    "mentor-fade": MENTOR_AGENTS,
    "explore-goals": ALL_AGENTS,
    "recommended": MENTOR_AGENTS,
}
#: The held-out pick's sweeps (../presets/fair_*.toml).
PICK_SWEEPS = ("fair_plain_exp1", "fair_fade_exp1", "fair_plain_exp2", "fair_fade_exp2")
PARTS = ("worlds", "puzzlebox", "pick", "stress", "minigrid")


def run(*argv: str) -> None:
    print("$", " ".join(argv), flush=True)
    subprocess.run([sys.executable, *argv], check=True)


def himit(*argv: str) -> None:
    run("-m", "himit_torch.cli", *argv)


def worlds(logdir: Path, seeds: int) -> None:
    """Every preset's nine worlds: ``himit run paper`` (its six worlds over the cores) and the
    Gymnasium study, into ``<logdir>/<preset>/``. The Gymnasium studies run one after another
    *beside* the ``himit run paper`` runs, not after each: a study keeps one core busy (its
    batches are small and its exact evaluations between windows run on one thread: 1.13 cores
    asked for, ``benchmarks/bench_core_use.py``), so the other was idle for ≈ 190 s of the
    benchmark's worlds part. Each run's records are its own either way (seeded, no shared
    state)."""
    runs = []
    for preset, agents in CELLS.items():
        common = ["--seeds", str(seeds), "--preset", preset, "--agents", *agents]
        out = str(logdir / preset)
        runs.append((common, out))

    def gymnasium_studies() -> None:
        for common, out in runs:
            run(str(EXPERIMENTS / "gymnasium_worlds.py"), *common, "--logdir", out, "--force")

    with ThreadPoolExecutor(1) as beside:
        studies = beside.submit(gymnasium_studies)
        try:
            for common, out in runs:
                himit("run", "paper", *common, "--tie-break", "random", "--logdir", out,
                      "--quiet", "--force")  # fmt: skip
        finally:
            studies.result()  # (a failed study raises here, once the worlds have ended)


def collect_worlds(logdir: Path) -> None:
    for preset in CELLS:
        run(
            str(EXPERIMENTS / "collect_results.py"),
            *(str(logdir / preset / n) for n in ("exp1", "exp2", "exp3", "gymnasium")),
            "--out",
            str(RESULTS / preset),
        )


def pick(logdir: Path) -> None:
    for name in PICK_SWEEPS:
        spec = EXPERIMENTS / "presets" / f"{name}.toml"
        himit("sweep", str(spec), "--out", str(logdir / "presets" / name))


def collect_sweep(
    source: Path, target: Path, names=("runs.csv", "results.csv", "sweep.json")
) -> None:
    """Copy a sweep's records (per-run summaries, per-window goals, its spec) into the
    repository."""
    target.mkdir(parents=True, exist_ok=True)
    for name in names:
        shutil.copy(source / name, target / name)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", nargs="+", choices=PARTS, default=list(PARTS))
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--logdir", default="runs/benchmark")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--skip-runs", action="store_true", help="copy and analyse finished runs")
    mode.add_argument(
        "--timing-only",
        action="store_true",
        help="run and time the parts into --logdir (timing in <logdir>/timing.json); copy "
        "nothing into experiments/results/ and analyse nothing",
    )
    args = parser.parse_args(argv)
    logdir = Path(args.logdir)
    collect = not args.timing_only
    timing_path = logdir / "timing.json" if args.timing_only else RESULTS / "timing.json"
    timing = json.loads(timing_path.read_text()) if timing_path.exists() else {}

    for part in args.parts:
        started = time.perf_counter()
        if part == "worlds":
            if not args.skip_runs:
                worlds(logdir, args.seeds)
            if collect:
                collect_worlds(logdir)
        elif part == "puzzlebox":
            run(
                str(HERE / "puzzle_box_benchmark.py"),
                "--seeds",
                str(args.seeds),
                "--logdir",
                str(logdir / "puzzlebox"),
                *(["--skip-runs"] if args.skip_runs else []),
                *([] if collect else ["--print-only"]),
            )
        elif part == "pick":
            if not args.skip_runs:
                pick(logdir)
            if collect:
                for name in PICK_SWEEPS:
                    collect_sweep(logdir / "presets" / name, PRESET_RECORDS / name)
        elif part == "stress":
            if not args.skip_runs:
                himit(
                    "sweep",
                    str(HERE / "stress_exp2.toml"),
                    "--out",
                    str(logdir / "stress_exp2"),
                )
            if collect:
                collect_sweep(
                    logdir / "stress_exp2",
                    RESULTS / "stress_exp2",
                    ("runs.csv", "summary.md", "sweep.json"),
                )
        elif part == "minigrid":  # (resumes: a finished cell is kept)
            run(
                str(HERE / "minigrid_benchmark.py"),
                "--seeds",
                str(args.seeds),
                "--logdir",
                str(logdir / "minigrid"),
                *(["--skip-runs"] if args.skip_runs else []),
                *([] if collect else ["--no-collect"]),
            )
        if not args.skip_runs:
            timing[part] = round(time.perf_counter() - started, 1)
            timing_path.parent.mkdir(parents=True, exist_ok=True)
            timing_path.write_text(json.dumps(timing, indent=1, sort_keys=True) + "\n")

    if collect:
        run(str(HERE / "analyse.py"))
        run(str(EXPERIMENTS / "presets" / "analyse_search.py"))


if __name__ == "__main__":
    main()
