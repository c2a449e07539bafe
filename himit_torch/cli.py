"""The ``himit`` command line.

Subcommands (``himit <command> --help`` for their options):

* ``info``  — a world's summary: its size, option counts, and the optimal expected steps from
  start to goal (and goals per 5000 steps) for primitives only, the learner's options and the
  mentor, beside the paper's numbers where the world is one of the paper's.
* ``demo``  — experiment 2's world (40×40, 10×10 rooms): compute the mentor, record its
  state-only demonstrations, save them and a picture like the paper's Fig. 2, then a short
  batched learning run with figures and TensorBoard logs.
* ``run``   — reproduce experiment 1, 2 or 3 into a run directory (resumable), or
  ``gymnasium``: imitation vs options vs primitives on Taxi, CliffWalking and FrozenLake 8×8, or
  ``discovery``: options discovered from the mentor's states vs hand-built doorway options, or
  ``puzzlebox``: Whiten et al.'s keyway-fruit box (``himit info --puzzle-box K`` for the box).
* ``sweep`` — a grid of settings × seeds × worlds from a spec file, each trial a resumable run, as
  Ray tasks when Ray is installed (``himit sweep --help`` documents the spec).
* ``plot``  — redraw a run directory's figures and ``results.md`` from its records (or a
  sweep's ``summary.csv`` and ``summary.md`` from its ``runs.csv`` and ``sweep.json``).
* ``bench`` — steps per second of the batched learner.

User mistakes (bad arguments, invalid worlds) end with one line ``himit: error: …`` on stderr
and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NoReturn

import torch

from himit_torch import __version__
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.engines import ENGINES
from himit_torch.runs.runner import freeze_at_exit
from himit_torch.runs.studies import STUDIES, info_topics, study_of_run_dir
from himit_torch.runs.study import RunFlags, StudyEntry, read_config_file
from himit_torch.validation import COUNT_MAX, as_device, settings_of

__all__ = ["main", "build_parser", "COMMANDS", "study_configs"]


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (``himit: error: …``), exit status 2."""

    def error(self, message: str):
        _fail(f"{self.prog.split(' ', 1)[1] + ': ' if ' ' in self.prog else ''}{message}")


#: A Sphinx role, ``:func:`target``` or ``:py:class:`text <target>```: group 1 its content.
_ROLE = re.compile(r":(?:[a-z]+:)?[a-z]+:`([^`]+)`")
_LITERAL = re.compile(r"``(.+?)``", re.DOTALL)


def _role_text(content: str) -> str:
    """What a role shows: ``text <target>`` → text, ``~a.b.c`` → c, ``!a.b`` or ``a.b`` → a.b."""
    if content.endswith(">") and " <" in content:
        return content[: content.rindex(" <")].strip()
    if content.startswith("~"):
        return content[1:].rsplit(".", 1)[-1]
    return content.lstrip("!")


def plain_text(text: str) -> str:
    """``text`` (a docstring or a setting's doc, written for Sphinx) as a terminal shows it: roles
    replaced by what they name (``:func:`~a.b.c``` → ``c``) and double-backquoted literals by
    their content. The docs keep rendering the original."""
    text = _ROLE.sub(lambda m: _role_text(m.group(1)), text)
    return _LITERAL.sub(lambda m: m.group(1), text)


def _plain_help(parser: argparse.ArgumentParser) -> None:
    """Every help text, description and epilog of ``parser`` and its subcommands in plain text
    (:func:`plain_text`): they come from docstrings and settings' docs, written for Sphinx."""
    parser.description = parser.description and plain_text(parser.description)
    parser.epilog = parser.epilog and plain_text(parser.epilog)
    for action in parser._actions:
        if isinstance(action.help, str):
            action.help = plain_text(action.help)
        if isinstance(action, argparse._SubParsersAction):
            for choice in action._choices_actions:
                choice.help = choice.help and plain_text(choice.help)
            for sub in dict.fromkeys(action.choices.values()):
                _plain_help(sub)


def _fail(message: str | Exception, status: int = 2) -> NoReturn:
    line = " ".join(str(message).split())  # one line, whatever the message held
    print(f"himit: error: {line}", file=sys.stderr)
    raise SystemExit(status)


def _int_in_range(minimum: int, maximum: int = COUNT_MAX) -> Callable[[str], int]:
    """An argparse type: a whole number from ``minimum`` to ``maximum``, and ≤ :data:`COUNT_MAX`
    (a count a tick can honour)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid whole number: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be ≥ {minimum}, got {value}")
        for bound in (COUNT_MAX, maximum):  # COUNT_MAX first: its message wins when both fail
            if value > bound:
                raise argparse.ArgumentTypeError(f"must be ≤ {bound}, got {value}")
        return value

    return parse


_positive_int = _int_in_range(1)
_nonnegative_int = _int_in_range(0)


# ------------------------------------------------------------------- flags from the settings
# A small generator rather than tyro or simple-parsing: both build a whole config from the
# library's defaults, so they cannot tell a given flag from an absent one — and the precedence
# (the experiment's defaults < --config < flags) needs exactly that — and both would replace
# argparse's one-line errors and the subcommands. Here each declared field becomes one argparse
# flag whose value is only read from text; the config's own validation then judges it.
def _setting_text(kind: Any, optional: bool) -> Callable[[str], Any]:
    """An argparse type: the text of a flag as the number or string the config checks."""

    def parse(text: str) -> Any:
        if optional and text.lower() == "none":
            return None
        if kind is str:
            return text
        try:
            return int(text) if kind is int and text.lstrip("+-").isdigit() else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"invalid {'whole ' if kind is int else ''}number: {text!r}"
                + (" (or none)" if optional else "")
            ) from None

    return parse


def _add_setting_flags(
    group: argparse._ArgumentGroup,
    config_class: type,
    prefix: str,
    skip: Sequence[str] = (),
    defaults: Any = None,
) -> None:
    """One flag per declared field of ``config_class`` (``--mentor-fade`` for ``mentor_fade``),
    its help the field's doc and its default (``defaults``'s value, e.g. a study's own
    configuration; else the declared default). A flag not given leaves no attribute
    (``argparse.SUPPRESS``), so :func:`_given_settings` tells given flags from absent ones."""
    for s in settings_of(config_class):
        if s.name in skip or dataclasses.is_dataclass(s.kind):
            continue
        doc = " ".join(s.info.doc.split()).replace("%", "%%")
        value = s.default if defaults is None else getattr(defaults, s.name)
        default = "none" if value is None else value
        if isinstance(default, tuple):
            default = " ".join(map(str, default))
        options: dict[str, Any] = dict(
            dest=f"{prefix}.{s.name}",
            default=argparse.SUPPRESS,
            help=f"{doc} (default: {default})",
        )
        if s.kind is bool:
            options["action"] = argparse.BooleanOptionalAction
        else:
            options["type"] = _setting_text(s.item if s.kind is tuple else s.kind, s.optional)
            options["metavar"] = s.name.upper()
            if s.kind is tuple:
                options["nargs"] = "+"
                options["metavar"] = s.name.upper().removesuffix("S")
            if s.info.choices:
                options["choices"] = s.info.choices
                if s.kind is not tuple:
                    del options["metavar"]  # argparse shows {a,b,…}
                else:
                    options["help"] = (
                        f"{doc} From: {', '.join(s.info.choices)} (default: {default})"
                    )
        group.add_argument(f"--{s.name.replace('_', '-')}", **options)


def _given_settings(args: argparse.Namespace, prefix: str) -> dict[str, Any]:
    """The fields given as flags by :func:`_add_setting_flags` under ``prefix``."""
    return {
        dest.split(".", 1)[1]: tuple(value) if isinstance(value, list) else value
        for dest, value in vars(args).items()
        if dest.startswith(prefix + ".")
    }


def _flag(field: str) -> str:
    return "--" + field.replace("_", "-")


# ------------------------------------------------------------------------------------- info
def cmd_info(args: argparse.Namespace) -> int:
    """``himit info``: what the study that owns the chosen world says of it (the paper's
    MultiRooms world unless a study's flag, e.g. ``--env`` or ``--puzzle-box``, chooses
    another)."""
    t0 = time.perf_counter()
    topics = info_topics()
    chosen = [t for t in topics if t.flag is not None and getattr(args, t.flag) is not None]
    if len(chosen) > 1:
        raise ValueError(f"give {' or '.join(_flag(t.flag) for t in chosen if t.flag)}, not both")
    topic = chosen[0] if chosen else next(t for t in topics if t.flag is None)
    for other in topics:
        for dest in other.requires if other is not topic else ():
            if getattr(args, dest) is not None:
                raise ValueError(
                    f"{_flag(dest)} is for {_flag(other.flag or '')}: give "
                    f"{_flag(other.flag or '')} too, or leave it out"
                )
    for line in topic.show(args):
        print(line)
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


def _add_info(sub: argparse.ArgumentParser) -> None:
    sub.add_argument(
        "--slip", type=float, default=0.1, help="probability that an action fails (default 0.1)"
    )
    for topic in info_topics():
        topic.add_flags(sub)


# ------------------------------------------------------------------------------------- demo
def cmd_demo(args: argparse.Namespace) -> int:
    """The README's main job (:mod:`himit_torch.runs.demo`)."""
    from himit_torch.runs.demo import demo

    lines = demo(Path(args.out), args.episodes, args.seed, args.seeds, args.steps, not args.quiet)
    for line in lines:
        print(line)
    return 0


def _add_demo(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("--out", default="runs/demo", help="output folder (default runs/demo)")
    sub.add_argument(
        "--episodes", type=_positive_int, default=20, help="mentor episodes to record (default 20)"
    )
    sub.add_argument("--seed", type=_nonnegative_int, default=0, help="random seed (default 0)")
    sub.add_argument(
        "--seeds",
        type=_positive_int,
        default=2,
        help="runs per agent in the learning run (default 2)",
    )
    sub.add_argument(
        "--steps",
        type=_nonnegative_int,
        default=20_000,
        help="steps per run (default 20000; 0 = demonstrations only)",
    )
    sub.add_argument("--quiet", action="store_true", help="no progress bar")


# -------------------------------------------------------------------------------------- run
def cmd_run(args: argparse.Namespace) -> int:
    """``himit run STUDY``: the study's configurations with the flags given, run into
    ``<logdir>/<name>`` by its registry entry."""
    study = STUDIES[args.experiment]
    plans = []
    for config in study_configs(args):
        run_dir = Path(args.logdir) / config.name
        print(study.describe(config, run_dir))
        plans.append((config, run_dir))
    t0 = time.perf_counter()
    flags = RunFlags(args.resume, args.force, not args.quiet, args.workers)
    study.run(plans, flags)
    written = ", ".join(str(run_dir / "results.md") for _, run_dir in plans)
    print(f"done in {time.perf_counter() - t0:.0f} s: {written}")
    return 0


def study_configs(args: argparse.Namespace) -> list[Any]:
    """The configurations ``himit run STUDY`` runs (``args``: its parsed command line). Precedence, lowest first: the
    study's own (:attr:`~himit_torch.runs.study.StudyEntry.configs`), a ``--config`` file (a
    whole configuration, in their place), ``--quick``, the preset, the flags given (the
    learner's into its ``learner``), then the study's own adjustment.

    A resumed run must be given the configuration it started with (the same flags, or
    ``--config`` of its saved ``config.json``): the study refuses any other."""
    study = STUDIES[args.experiment]
    starts = study.configs()
    if getattr(args, "config", None):
        config: Any = read_config_file(study.config_class, args.config)
        if config.name != starts[0].name:
            raise ValueError(
                f"--config {args.config} is for {config.name!r}, not {starts[0].name!r}"
            )
        starts = (config,)
    given = _given_settings(args, "study")
    learner_changes = _given_settings(args, "learner")
    configs = []
    for config in starts:
        if args.quick:
            config = config.quick()
        config = config.with_settings(given, learner_changes)
        if study.adjust is not None:
            config = study.adjust(config, frozenset(given))
        if hasattr(config, "device"):
            as_device("--device", config.device)  # here, before any run starts
        configs.append(config)
    return configs


class _StudyParser(_Parser):
    """One ``himit run STUDY``'s parser: a flag it does not take (another study's setting, or
    a run flag it has no use for) is refused in one line, naming the flag."""

    def parse_known_args(self, args=None, namespace=None):
        parsed, extras = super().parse_known_args(args, namespace)
        flags = [a.split("=", 1)[0] for a in extras if a.startswith("-")]
        if flags:
            _fail(
                f"{self.prog} takes no {', '.join(flags)} (not a flag of this study; its flags: "
                f"{self.prog} --help)"
            )
        return parsed, extras


def _add_study(sub: argparse.ArgumentParser, study: StudyEntry) -> None:
    """The flags of ``himit run name``: the run's own, then one per setting of its
    configuration class and, where it has a learner, of the learner's."""
    sub.set_defaults(config=None, resume=False, workers=None)
    sub.add_argument("--quick", action="store_true", help="tiny budget (smoke test)")
    sub.add_argument(
        "--logdir", default="runs", help="parent folder of the run directory (default: runs)"
    )
    if "config" in study.run_flags:
        sub.add_argument(
            "--config",
            help="a config.json (as saved in a run directory) to run instead of the "
            "experiment's defaults; flags given beside it change it",
        )
    if "resume" in study.run_flags:
        sub.add_argument(
            "--resume",
            action="store_true",
            help="continue an interrupted run from its newest good checkpoint (give the flags "
            "it started with"
            + (", or --config of its config.json)" if "config" in study.run_flags else ")"),
        )
    sub.add_argument("--force", action="store_true", help="overwrite a finished run")
    sub.add_argument("--quiet", action="store_true", help="no progress bars")
    if "workers" in study.run_flags:
        sub.add_argument(
            "--workers",
            type=_positive_int,
            help="worlds run in parallel, one per process: this one and WORKERS-1 it "
            "starts (default: one per core, "
            "at most one per world — with paper, the worlds of all three experiments; "
            "the results do not depend on it)",
        )
    config_class = study.config_class
    defaults = study.defaults()
    _add_setting_flags(
        sub.add_argument_group(
            "settings",
            f"Fields of {config_class.__name__}; the defaults shown are this study's"
            + (" (--config: a file's)." if "config" in study.run_flags else "."),
        ),
        config_class,
        "study",
        skip=study.skip,
        defaults=defaults,
    )
    if any(f.name == "learner" for f in dataclasses.fields(config_class)):
        derived = getattr(config_class, "derived_learner", ())
        _add_setting_flags(
            sub.add_argument_group(
                "learner settings",
                "Fields of LearnerConfig, this study's defaults shown. Those it derives from "
                f"its own settings ({', '.join(derived)}) are not flags.",
            ),
            LearnerConfig,
            "learner",
            skip=derived,
            defaults=defaults.learner,
        )


def _add_run(sub: argparse.ArgumentParser) -> None:
    studies = sub.add_subparsers(
        dest="experiment",
        metavar="study",
        required=True,
        parser_class=_StudyParser,
        help="which study (himit run STUDY --help: its flags)",
    )
    for name, study in STUDIES.items():
        _add_study(studies.add_parser(name, help=study.help, description=study.help), study)


# ------------------------------------------------------------------------------------- plot
def cmd_plot(args: argparse.Namespace) -> int:
    """``himit plot``: a sweep's tables, or a run directory's page redrawn by the study its
    ``config.json`` names (:func:`~himit_torch.runs.studies.study_of_run_dir`)."""
    run_dir = Path(args.run_dir)
    if (run_dir / "sweep.json").exists() and (run_dir / "runs.csv").exists():
        from himit_torch.runs.sweep import rewrite_summary

        rewrite_summary(run_dir)  # a himit sweep folder: its tables from runs.csv
        print(f"wrote {run_dir / 'summary.csv'} and {run_dir / 'summary.md'}")
        return 0
    study = study_of_run_dir(run_dir)
    if study.redraw is None:
        raise ValueError(f"{run_dir} is a himit run {study.name} directory: {study.no_redraw}")
    study.redraw(run_dir)
    print(f"wrote {run_dir / 'figures'} and {run_dir / 'results.md'}")
    return 0


def _add_plot(sub: argparse.ArgumentParser) -> None:
    sub.add_argument(
        "run_dir", help="a run directory written by himit run, or a sweep's folder (himit sweep)"
    )


# ------------------------------------------------------------------------------------ sweep
def cmd_sweep(args: argparse.Namespace) -> int:
    from himit_torch.runs.sweep import load_spec, run_sweep

    spec = load_spec(args.spec)
    out = Path(args.out) if args.out else Path("runs") / "sweeps" / spec.name
    if args.dry_run:
        for trial in spec.trials(out):
            print(trial.run_dir)
        print(f"{len(spec.cells)} cells, {len(spec.trials(out))} trials")
        return 0
    t0 = time.perf_counter()
    try:
        record = run_sweep(
            spec,
            out,
            address=args.address,
            use_ray=not args.no_ray,
            workers=args.workers,
            worker_niceness=args.worker_niceness,
        )
    except KeyboardInterrupt:
        _fail(
            f"interrupted: the finished trials are kept in {out}; the same command resumes "
            "the others from their checkpoints",
            status=130,
        )
    print(
        f"done in {time.perf_counter() - t0:.0f} s (commit {', '.join(record['commit'])}, engine "
        f"{', '.join(record['engine'])}): {out / 'summary.md'}, {out / 'results.csv'}"
    )
    return 0


def _add_sweep(sub: argparse.ArgumentParser) -> None:
    from himit_torch.runs import sweep

    sub.formatter_class = argparse.RawDescriptionHelpFormatter
    doc = sweep.__doc__
    sub.epilog = doc[
        doc.index("A sweep is described") : doc.index("**Where the trials run")
    ].rstrip()
    sub.add_argument("spec", help="the sweep spec, a .toml or .json file (see below)")
    sub.add_argument(
        "--out",
        help="the sweep's folder (default runs/sweeps/<name>); rerunning "
        "into it skips finished trials and resumes interrupted ones",
    )
    sub.add_argument(
        "--address",
        help="join this Ray cluster (host:port, or auto) instead of starting a local Ray; a "
        "cluster's token is read as Ray reads it (RAY_AUTH_TOKEN, RAY_AUTH_TOKEN_PATH, "
        "~/.ray/auth_token): docs/cluster.md",
    )
    sub.add_argument(
        "--no-ray",
        action="store_true",
        help="run the trials in this process, one at a time, even if Ray is installed",
    )
    sub.add_argument(
        "--workers",
        type=_positive_int,
        help="trials at a time on a local Ray (default: one per core)",
    )
    sub.add_argument(
        "--worker-niceness",
        type=_int_in_range(0, 19),
        metavar="N",
        help="niceness of Ray's workers, 0-19 (default: the spec's worker_niceness, else 0; "
        "Ray's own is 15, which lets every other process on a shared machine go first)",
    )
    sub.add_argument(
        "--dry-run",
        action="store_true",
        help="check the spec and list the trials' run directories; run nothing",
    )


# ------------------------------------------------------------------------------------ bench
def cmd_bench(args: argparse.Namespace) -> int:
    from himit_torch.runs.bench import benchmark

    settings = {name: value for name, value in vars(args).items() if name != "command"}
    print(benchmark(**settings).line())
    return 0


def _add_bench(sub: argparse.ArgumentParser) -> None:
    sub.add_argument("--size", type=_positive_int, default=40)
    sub.add_argument("--rooms", type=_positive_int, default=10)
    sub.add_argument("--corner-options", action="store_true")
    sub.add_argument("--batch", type=_positive_int, default=15, help="runs advancing together")
    sub.add_argument("--steps", type=_positive_int, default=5000, help="timed steps per run")
    sub.add_argument("--warmup", type=_nonnegative_int, default=1000, help="untimed steps first")
    sub.add_argument(
        "--agent",
        default="mix",
        help="agent variant for every run, or 'mix' (imitation/options/primitives)",
    )
    sub.add_argument(
        "--plan-every",
        type=_positive_int,
        default=4,
        help="sweep every this many ticks (the experiments' 4; 1 = every decision)",
    )
    sub.add_argument("--device", default="cpu")
    sub.add_argument(
        "--engine",
        default="auto",
        choices=ENGINES,
        help="auto: the compiled loop on a CPU, torch on a GPU",
    )


# ------------------------------------------------------------------------------------- main
#: Subcommand → (function, argument adder, one-line help).
COMMANDS: dict[
    str, tuple[Callable[[argparse.Namespace], int], Callable[[argparse.ArgumentParser], None], str]
] = {
    "info": (cmd_info, _add_info, "summarize a world: sizes, options, optimal steps and goals"),
    "demo": (
        cmd_demo,
        _add_demo,
        "experiment 2's world: mentor demonstrations, a short batched "
        "learning run, figures and TensorBoard logs",
    ),
    "run": (
        cmd_run,
        _add_run,
        "run a study into a run directory: the paper's experiments, or another "
        "(himit run --help lists them)",
    ),
    "sweep": (
        cmd_sweep,
        _add_sweep,
        "run a sweep spec: settings × seeds × worlds as resumable "
        "trials (on Ray when installed), with tables and 95 %% CIs",
    ),
    "plot": (
        cmd_plot,
        _add_plot,
        "redraw the figures and results.md of a run directory (a sweep's summary.md) from its "
        "records",
    ),
    "bench": (cmd_bench, _add_bench, "steps per second of the batched learner"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="himit",
        description="Hierarchical goal-based imitation from state-only demonstrations.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subs = parser.add_subparsers(dest="command", metavar="command", required=True)
    for name, (_, add_arguments, help_text) in COMMANDS.items():
        add_arguments(subs.add_parser(name, help=help_text, description=help_text))
    _plain_help(parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``himit``; returns 0 on success, raises ``SystemExit(2)`` on a user mistake.

    Torch runs on one thread (``HIMIT_THREADS`` to change): the learner's tensors are small, and
    on a CPU two processes use two cores far better than two threads in one."""
    args = build_parser().parse_args(argv)
    freeze_at_exit()  # (≈ 1 s less at every command's exit)
    threads = os.environ.get("HIMIT_THREADS", "1")
    if not threads.strip().isdigit() or int(threads) < 1:
        _fail(f"HIMIT_THREADS={threads!r} must be a whole number ≥ 1")
    torch.set_num_threads(int(threads))
    try:
        return COMMANDS[args.command][0](args)
    except (ValueError, FileNotFoundError, IsADirectoryError, NotADirectoryError) as err:
        # a user mistake, or a path the user gave names nothing usable (e.g. --logdir under a
        # file): exit 2
        _fail(err)
    except OSError as err:
        # the machine failing on the right path (permissions, a full disk): exit 1, so that
        # scripts can tell a retry-worthy fault from a command to fix
        _fail(err, status=1)
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's status for SIGINT
        _fail("interrupted", status=130)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
