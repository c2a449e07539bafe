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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import torch

from himit_torch import __version__
from himit_torch.exact.greedy_evaluation import (
    OptionPolicy,
    PolicyEvaluator,
    evaluate_option_choice,
)
from himit_torch.exact.option_models import (
    option_durations,
    option_models,
    option_models_and_durations,
)
from himit_torch.exact.planning import expected_steps, smdp_value_iteration
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.engines import ENGINES
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import mentor_policy, run_mentor
from himit_torch.options.builders import learner_options, mentor_options, primitive_options
from himit_torch.options.bundle import Options
from himit_torch.runs.config import ExperimentConfig
from himit_torch.runs.runner import freeze_at_exit
from himit_torch.validation import COUNT_MAX, as_device, settings_of
from himit_torch.viz.tensorboard import tensorboard_command
from himit_torch.worlds.multirooms import MultiRooms

__all__ = ["main", "build_parser", "COMMANDS"]

#: Window over which the paper counts goals (its Figs. 3 and 4).
GOALS_WINDOW = 5000

#: The paper's optimal-policy numbers, by (size, rooms, slip): (experiment, steps, goals / 5000).
PAPER_OPTIMUM = {
    (80, 10, 0.1): ("experiment 1", 190.0, 26.3),
    (40, 10, 0.1): ("experiment 2", 5000 / 53.2, 53.2),
}


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


def _int_at_least(minimum: int) -> Callable[[str], int]:
    """An argparse type: a whole number ≥ ``minimum`` and ≤ :data:`COUNT_MAX` (a count a tick
    can honour)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid whole number: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be ≥ {minimum}, got {value}")
        if value > COUNT_MAX:
            raise argparse.ArgumentTypeError(f"must be ≤ {COUNT_MAX}, got {value}")
        return value

    return parse


def _int_in_range(minimum: int, maximum: int) -> Callable[[str], int]:
    """An argparse type: a whole number from ``minimum`` to ``maximum``."""
    at_least = _int_at_least(minimum)

    def parse(text: str) -> int:
        value = at_least(text)
        if value > maximum:
            raise argparse.ArgumentTypeError(f"must be ≤ {maximum}, got {value}")
        return value

    return parse


_positive_int = _int_at_least(1)
_nonnegative_int = _int_at_least(0)


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
@dataclass(frozen=True)
class OptimalTrip:
    """Expected primitive steps from start to goal of a policy, and its goals per window (the
    long-run rate of episode after episode: :mod:`himit_torch.exact.greedy_evaluation`)."""

    steps: float
    goals_per_window: float


def optimal_trip(
    world: MultiRooms, options: Options, policy: torch.Tensor | None = None
) -> OptimalTrip:
    """Steps start → goal of the optimal policy for ``options`` (or of the given ``policy [S]``,
    e.g. the mentor's), evaluated exactly like every greedy policy of a run
    (:class:`~himit_torch.exact.greedy_evaluation.PolicyEvaluator`): exact option models →
    SMDP value iteration → the policy's expected steps and goal rate."""
    if policy is None:
        models = option_models_and_durations(world, options)
        policy = smdp_value_iteration(models[0]).policy
        evaluation = PolicyEvaluator(world, options, GOALS_WINDOW, models=models).evaluate(
            OptionPolicy.deterministic(policy), values=False
        )
    else:
        evaluation = evaluate_option_choice(world, options, policy, GOALS_WINDOW)
    return OptimalTrip(
        float(evaluation.steps_per_episode[0]), float(evaluation.goals_per_window[0])
    )


def _kind_counts(options: Options) -> str:
    counts: dict[str, int] = {}
    for k in options.kinds:
        counts[k] = counts.get(k, 0) + 1
    return ", ".join(f"{n} {k}" for k, n in counts.items())


def cmd_info(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    if args.env is not None and args.puzzle_box is not None:
        raise ValueError("give --env or --puzzle-box, not both")
    if args.puzzle_box is not None and args.env_kwargs is not None:
        raise ValueError(
            "--env-kwargs is for a Gymnasium environment (--env), not --puzzle-box: leave it out"
        )
    if args.puzzle_box is None and args.pinch_slip is not None:
        raise ValueError(
            "--pinch-slip is the puzzle box's: give --puzzle-box K too (e.g. --puzzle-box 4 "
            "--pinch-slip 0.2), or leave it out"
        )
    if args.minigrid is not None:
        return _info_minigrid(args, t0)
    if args.env is not None:
        return _info_gymnasium(args, t0)
    if args.puzzle_box is not None:
        return _info_puzzle_box(args, t0)
    if args.env_kwargs is not None:
        raise ValueError(
            "--env-kwargs is for a Gymnasium environment: give --env too (e.g. --env "
            'FrozenLake-v1 --env-kwargs \'{"map_name": "8x8"}\'), or leave it out'
        )
    world = MultiRooms(size=args.size, rooms=args.rooms, slip=args.slip)
    learner = learner_options(
        world, doorways=not args.no_doorway_options, corners=args.corner_options
    )
    mentor_opts = mentor_options(world, corners=args.corner_options)
    free = int(world.free_mask.sum())
    print(
        f"world      {world.size}×{world.size} cells, {world.rooms}×{world.rooms} rooms "
        f"{world.room_size} cells apart (one-cell walls between), slip {world.slip}, gamma "
        f"{world.gamma}, reward {world.step_reward} a step and {world.goal_reward} at the goal"
    )
    print(
        f"states     {world.num_states} (free cells {free}, doorways {len(world.doorway_rooms)}, "
        f"rooms {world.num_rooms})"
    )
    print(f"start/goal {world.coords(world.start_state)} → {world.coords(world.goal_state)}")
    print(
        f"learner    {learner.num_options} options ({_kind_counts(learner)}; doorway/corner "
        "options head directly to their target)"
    )
    print(
        f"mentor     {mentor_opts.num_options} options ({_kind_counts(mentor_opts)}; doorway/corner "
        "options travel along the room's walls)"
    )
    rows = [
        ("primitives only", optimal_trip(world, primitive_options(world))),
        ("learner's options", optimal_trip(world, learner)),
    ]
    mentor = mentor_policy(world, mentor_opts)
    rows.append(
        (
            f"mentor (prefers its options within {mentor.tolerance:g})",
            optimal_trip(world, mentor_opts, mentor.option),
        )
    )
    width = max(len(name) for name, _ in rows) + 2
    print(
        f"\n{'optimal policy':<{width}}{'steps start→goal':>18}{f'goals / {GOALS_WINDOW} steps':>22}"
    )
    for name, trip in rows:
        print(f"{name:<{width}}{trip.steps:>18.1f}{trip.goals_per_window:>22.1f}")
    paper = PAPER_OPTIMUM.get((world.size, world.rooms, world.slip))
    if paper is not None:
        experiment, steps, goals = paper
        print(f"{'paper, ' + experiment:<{width}}{'≈' + format(steps, '.0f'):>18}{goals:>22.1f}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


def _info_gymnasium(args: argparse.Namespace, t0: float) -> int:
    """``himit info --env``: a Gymnasium world through the adapter, exactly solved."""
    import json

    from himit_torch.exact.planning import value_iteration
    from himit_torch.mentor.reward import KnownReward
    from himit_torch.runs.gymnasium import TASKS, episode_statistics
    from himit_torch.worlds.gymnasium import from_gymnasium
    from himit_torch.worlds.table_world import world_model

    try:
        kwargs = json.loads(args.env_kwargs) if args.env_kwargs else {}
    except json.JSONDecodeError as err:
        raise ValueError(f"--env-kwargs is not valid JSON: {err}") from None
    if not isinstance(kwargs, dict):
        raise ValueError('--env-kwargs must be a JSON object, e.g. \'{"map_name": "8x8"}\'')
    task = TASKS.get(args.env)
    if task is not None:
        if kwargs:
            raise ValueError(
                f"--env {args.env} is a task with its own kwargs ({task.kwargs}); give "
                f"--env {task.env_id} to choose them"
            )
        world = task.world(args.gamma)
        options = task.options(world)
    else:
        world = from_gymnasium(args.env, gamma=args.gamma, **kwargs)
        options = primitive_options(world)
    P, R = world_model(world)
    plan = value_iteration(P, R, world.gamma)
    mu = world.start_distribution
    rewards = world.dynamics_table().rewards
    known = KnownReward(world)
    print(
        f"world      {world.name} {world.describe().get('kwargs', {})} through from_gymnasium, "
        f"gamma {world.gamma}"
    )
    print(
        f"states     {world.num_states} (start states {int((mu > 0).sum())}, terminal "
        f"{int(world.terminal_mask.sum())}, goal {int(world.goal_mask.sum())})"
    )
    print(f"actions    {world.num_actions}: {', '.join(world.action_names)}")
    print(
        f"rewards    {float(rewards.min()):g} … {float(rewards.max()):g} per transition; "
        f"mentor reward: {known.note}"
    )
    extended = [n for n, k in zip(options.names, options.kinds) if k != "primitive"]
    print(
        f"learner    {options.num_options} options ({_kind_counts(options)}"
        + (f": {', '.join(extended)})" if extended else ")")
    )
    p_goal, length = episode_statistics(world, plan.policy)
    models = smdp_value_iteration(option_models(world, options))
    print("\noptimal (value iteration on the true model, primitives)")
    print(f"  V*(start distribution)      {float(plan.values @ mu):.3f}")
    print(f"  with the learner's options  {float(models.values @ mu):.3f}")
    print(f"  P(goal) per episode         {p_goal:.3f}")
    print(f"  steps per episode           {length:.1f}")
    print(f"  {f'goals per {GOALS_WINDOW} steps':<28}{GOALS_WINDOW * p_goal / length:.1f}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


def _info_minigrid(args: argparse.Namespace, t0: float) -> int:
    """``himit info --minigrid ID``: a MiniGrid task (seed 0, MiniGrid's determinism) as a world,
    its options and mentor, solved exactly."""
    from himit_torch.mentor.minigrid import minigrid_mentor
    from himit_torch.options.minigrid import minigrid_options
    from himit_torch.worlds.minigrid import from_minigrid

    if args.env is not None or args.puzzle_box is not None or args.env_kwargs is not None:
        raise ValueError("give --minigrid alone, without --env, --env-kwargs or --puzzle-box")
    # (Any: optimal_trip is annotated for MultiRooms but evaluates any world with a model)
    world: Any = from_minigrid(args.minigrid, gamma=args.gamma)
    terminal = int(world.terminal_mask.sum())
    print(
        f"world      {world.name}, reset seed {world.seed}, {world.width}×{world.height} cells, "
        f"no slip (MiniGrid's own step), gamma {world.gamma}, reward −0.01 a step and +1 at "
        "success"
    )
    print(
        f"states     {world.num_states:,} reachable ({terminal} entered at success); objects: "
        f"{', '.join(world.object_names) or 'none'}"
    )
    print(f"actions    {world.num_actions}: {', '.join(world.action_names)}")
    learner, mentor_opts = minigrid_options(world), minigrid_options(world, "mentor")
    skills = [n for n, k in zip(learner.names, learner.kinds) if k != "primitive"]
    print(
        f"learner    {learner.num_options} options ({_kind_counts(learner)}: {', '.join(skills)})"
    )
    print(
        f"mentor     {mentor_opts.num_options} options ({_kind_counts(mentor_opts)}; no left turn, "
        "right-handed skills)"
    )
    mentor = minigrid_mentor(world, mentor_opts)
    rows = [
        ("primitives only", optimal_trip(world, primitive_options(world))),
        ("learner's options", optimal_trip(world, learner)),
        (
            f"mentor (prefers its options within {mentor.tolerance:g})",
            optimal_trip(world, mentor_opts, mentor.option),
        ),
    ]
    width = max(len(name) for name, _ in rows) + 2
    print(
        f"\n{'optimal policy':<{width}}{'steps start→goal':>18}{f'goals / {GOALS_WINDOW} steps':>22}"
    )
    for name, trip in rows:
        print(f"{name:<{width}}{trip.steps:>18.1f}{trip.goals_per_window:>22.1f}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


def _info_puzzle_box(args: argparse.Namespace, t0: float) -> int:
    """``himit info --puzzle-box K``: the box's size, and the optimal cost of each hierarchical
    organisation by exact planning."""
    from himit_torch.exact.planning import optimal_baseline
    from himit_torch.mentor.puzzle_box import organisation_mentor
    from himit_torch.options.puzzle_box import puzzle_box_options
    from himit_torch.worlds.puzzle_box import ORGANISATIONS, PuzzleBox, puzzle_box_size

    k = args.puzzle_box
    if k < 1 or k > 5:
        raise ValueError(f"--puzzle-box {k}: give 1 … 5 skewers (6: 357,000 states)")
    box = PuzzleBox(k, slip=args.slip, pinch_slip=args.pinch_slip)
    sizes = ", ".join(f"k={j}: {puzzle_box_size(j):,}" for j in range(2, 6))
    print(
        f"world      {box.name}, slip {box.slip} (pinch {box.pinch_slip}), gamma {box.gamma}, "
        f"reward {box.step_reward} a movement and {box.goal_reward} when the box opens"
    )
    print(f"states     {box.num_states:,} ((n+1)^k · (1+3k); {sizes})")
    print(f"actions    {box.num_actions}: {', '.join(box.action_names)}")
    from himit_torch.exact.greedy_evaluation import evaluate_option_choice

    best = optimal_baseline(box)
    rows = [("optimal policy (value iteration)", best.steps_to_goal, best.value_start)]
    for style in ("learner", "mentor"):
        options = puzzle_box_options(box, style)
        if style == "learner":
            print(f"learner    {options.num_options} options ({_kind_counts(options)})")
        durations = option_durations(box, options)
        for org in ORGANISATIONS:
            policy = organisation_mentor(box, org, options=options).option
            steps = expected_steps(durations, policy, box.start_state, box.terminal_mask)
            value = float(evaluate_option_choice(box, options, policy, 1).value_start[0])
            grip = "power" if style == "learner" else "pinch"
            rows.append((f"{org:>6} by {org}, {style}'s skills ({grip})", steps, value))
    print("\nexact planning; organisations: skewer by skewer / step by step across skewers")
    width = max(len(name) for name, _, _ in rows) + 2
    print(f"{'':<{width}}{'steps to open':>15}{'V(start)':>12}")
    for name, steps, value in rows:
        print(f"{name:<{width}}{steps:>15.3f}{value:>12.6f}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


def _add_info(sub: argparse.ArgumentParser) -> None:
    sub.add_argument(
        "--env",
        help="a Gymnasium tabular environment instead of MultiRooms: an id "
        "(e.g. Taxi-v4, FrozenLake-v1) or a task of himit run gymnasium "
        "(taxi, cliffwalking, frozenlake8x8)",
    )
    sub.add_argument(
        "--env-kwargs",
        help='JSON keyword arguments of gymnasium.make, e.g. \'{"map_name": "8x8"}\'',
    )
    sub.add_argument(
        "--minigrid",
        metavar="ID",
        help="a MiniGrid task, e.g. MiniGrid-DoorKey-8x8-v0 (reset seed 0): its states, the "
        "learner's and the mentor's options, the optimum's steps and the mentor's goal rate",
    )
    sub.add_argument(
        "--puzzle-box",
        type=int,
        metavar="K",
        help="the puzzle box with K skewers of 4 steps (Whiten et al.'s keyway-fruit box): its "
        "size and the optimal cost of each hierarchical organisation",
    )
    sub.add_argument(
        "--pinch-slip",
        type=float,
        help="--puzzle-box: failure probability of the mentor's pinch grip (default: --slip)",
    )
    sub.add_argument("--gamma", type=float, default=0.99, help="discount of a --env world (0.99)")
    sub.add_argument("--size", type=int, default=40, help="cells per side, N (default 40)")
    sub.add_argument("--rooms", type=int, default=10, help="rooms per side, R (default 10)")
    sub.add_argument(
        "--slip", type=float, default=0.1, help="probability that an action fails (default 0.1)"
    )
    sub.add_argument(
        "--corner-options",
        action="store_true",
        help="give the learner (and the mentor) 8 corner options per room (experiment 1)",
    )
    sub.add_argument(
        "--no-doorway-options",
        action="store_true",
        help="the learner gets primitives only (plus corners if asked)",
    )


# ------------------------------------------------------------------------------------- demo
def cmd_demo(args: argparse.Namespace) -> int:
    """The README's main job: experiment 2's world, the mentor's demonstrations and a short
    batched learning run with TensorBoard logs and figures (about a minute on a laptop CPU)."""
    from dataclasses import replace

    from himit_torch.runs.config import EXPERIMENTS
    from himit_torch.runs.experiment import run_experiment
    from himit_torch.viz.plotting import (
        save_world_figure,  # matplotlib only when a picture is wanted
    )

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    world = MultiRooms(size=40, rooms=10)
    options = mentor_options(world)
    print(f"world     {world!r} (experiment 2)")
    mentor = mentor_policy(world, options)
    rollout = run_mentor(world, mentor, args.episodes, seed=args.seed)
    demos = Demonstrations(list(rollout.states), world.describe())
    lengths = demos.episode_lengths.double()
    counts = rollout.decision_counts()
    print(
        f"mentor    {options.num_options} options; {args.episodes} episodes, "
        f"{lengths.mean():.1f} steps on average (min {int(lengths.min())}, max "
        f"{int(lengths.max())}); decisions: "
        + ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
    )
    npz = demos.save(out / "demonstrations.npz")
    png = save_world_figure(
        out / "world_mentor.png",
        world,
        demos,
        title=f"Mentor demonstrations ({args.episodes} episodes), 40×40, 10×10 rooms",
    )
    print(
        f"saved     {npz}  (states only: {demos.num_transitions} transitions, "
        f"{len(demos.visited_states())} distinct states)"
    )
    print(f"saved     {png}")
    if args.steps == 0:
        return 0
    config = replace(
        EXPERIMENTS["exp2"],
        name="demo",
        agents=("imitation", "options", "primitives"),
        seeds=args.seeds,
        first_seed=args.seed,
        steps=args.steps,
        mentor_episodes=args.episodes,
        window=min(5000, args.steps),
        checkpoint_every=min(5000, args.steps),
    )
    print(
        f"learning  {len(config.agents)} agents × {config.seeds} seeds = "
        f"{len(config.agents) * config.seeds} runs in one batch, {config.steps:,} steps each"
    )
    t0 = time.perf_counter()
    results = run_experiment(config, out / "learning", force=True, progress=not args.quiet)
    r = results[0]
    for agent in config.agents:
        idx = [b for b, a in enumerate(r.agents) if a == agent]
        print(
            f"  {agent:<12} goals in the last {config.window} steps: "
            + ", ".join(str(r.final_window_goals[b]) for b in idx)
            + f"   (optimal ≈ {r.optimal_goals_per_window:.1f})"
        )
    print(
        f"saved     {out / 'learning'}/results.md, figures/, curves.csv  "
        f"({time.perf_counter() - t0:.0f} s)"
    )
    print(f"watch     {tensorboard_command(out / 'learning' / 'tb')}")
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
@dataclass(frozen=True)
class StudyCommand:
    """One ``himit run STUDY``: its configuration class, its help, which of the run's own
    flags it takes (``config``: a saved ``config.json`` in place of its defaults; ``resume``;
    ``workers``: worlds in parallel) and its runner (``cmd_run`` dispatches by name). Its
    setting flags are built from the configuration class: every declared field (the learner's
    too, where it has one, but its ``window``, which is the study's ``--window``), so a new
    setting is a flag of every study that has it, and a flag of another study's is refused in
    one line."""

    config_class: Callable[[], type]
    help: str
    run_flags: tuple[str, ...] = ()
    skip: tuple[str, ...] = ()


def _experiment_class() -> type:
    return ExperimentConfig


def _gym_class() -> type:
    from himit_torch.runs.gymnasium import GymExperimentConfig

    return GymExperimentConfig


def _discovery_class() -> type:
    from himit_torch.runs.discovery import DiscoveryConfig

    return DiscoveryConfig


def _puzzle_box_class() -> type:
    from himit_torch.runs.puzzle_box import PuzzleBoxConfig

    return PuzzleBoxConfig


#: ``himit run paper``: the paper's three experiments, their worlds in one pool.
PAPER_EXPERIMENTS = ("exp1", "exp2", "exp3")

#: The studies of ``himit run``, by name.
STUDIES: dict[str, StudyCommand] = {
    **{
        name: StudyCommand(
            _experiment_class,
            f"the paper's experiment {name[-1]} (himit_torch.runs.experiment)",
            ("config", "resume", "workers"),
        )
        for name in PAPER_EXPERIMENTS
    },
    "paper": StudyCommand(
        _experiment_class,
        "the paper's experiments 1, 2 and 3, their worlds shared out over the cores together "
        "(each keeps its own name and configuration)",
        ("resume", "workers"),
        skip=("name",),
    ),
    "gymnasium": StudyCommand(
        _gym_class,
        "imitation against options and primitives on Gymnasium's Taxi, CliffWalking and "
        "FrozenLake 8×8 (himit_torch.runs.gymnasium; each task is one batch, rerun with --force)",
    ),
    "discovery": StudyCommand(
        _discovery_class,
        "options discovered from the mentor's states against hand-built doorway options "
        "(himit_torch.runs.discovery; one process on the CPU, rerun with --force)",
    ),
    "puzzlebox": StudyCommand(
        _puzzle_box_class,
        "Whiten et al.'s keyway-fruit box: speed, copying the organisation, a new skewer "
        "(himit_torch.runs.puzzle_box; its batches run one after the other)",
        ("resume",),
    ),
}


def _study_defaults(name: str) -> Any:
    """The configuration ``himit run name`` starts from (its flags' defaults)."""
    if name in PAPER_EXPERIMENTS or name == "paper":
        from himit_torch.runs.config import EXPERIMENTS

        return EXPERIMENTS.get(name, ExperimentConfig())
    return STUDIES[name].config_class()()


def cmd_run(args: argparse.Namespace) -> int:
    from himit_torch.runs.experiment import run_experiments

    if args.experiment == "gymnasium":
        return _run_gymnasium(args)
    if args.experiment == "discovery":
        return _run_discovery(args)
    if args.experiment == "puzzlebox":
        return _run_puzzle_box(args)
    names = PAPER_EXPERIMENTS if args.experiment == "paper" else (args.experiment,)
    plans = []
    for name in names:
        config = _experiment_config(name, args)
        run_dir = Path(args.logdir) / config.name
        print(
            f"{config.name}: worlds {list(config.sizes)}, agents {list(config.agents)}, "
            f"{config.seeds} seeds, {config.steps:,} steps → {run_dir}"
        )
        plans.append((config, run_dir))
    t0 = time.perf_counter()
    run_experiments(
        plans,
        resume=args.resume,
        force=args.force,
        progress=not args.quiet,
        workers=args.workers,
    )
    written = ", ".join(str(run_dir / "results.md") for _, run_dir in plans)
    print(f"done in {time.perf_counter() - t0:.0f} s: {written}")
    return 0


def _study_config(config: Any, args: argparse.Namespace) -> Any:
    """``config`` with the command line's changes: ``--quick``, then the preset, then the
    settings given (the learner's into its ``learner``)."""
    if args.quick:
        config = config.quick()
    changes = _given_settings(args, "study")
    if "preset" in changes:
        config = _with_preset(config, changes.pop("preset"))
    learner_changes = _given_settings(args, "learner")
    if learner_changes:
        changes["learner"] = dataclasses.replace(config.learner, **learner_changes)
    return dataclasses.replace(config, **changes)


def _experiment_config(name: str, args: argparse.Namespace) -> ExperimentConfig:
    """The configuration of experiment ``name`` with the command line's changes. Precedence,
    lowest first: the library's defaults, the experiment's own (:data:`EXPERIMENTS`), a
    ``--config`` file (a whole configuration, in their place), ``--quick``, the flags given.

    A resumed run must be given the configuration it started with (the same flags, or
    ``--config`` of its saved ``config.json``): :func:`~himit_torch.runs.experiment.run_experiments`
    refuses any other."""
    from himit_torch.runs.config import EXPERIMENTS, load_config

    if getattr(args, "config", None):
        config = load_config(args.config)
        if name != config.name:
            raise ValueError(f"--config {args.config} is for {config.name!r}, not {name!r}")
    else:
        config = EXPERIMENTS[name]
    changes = _given_settings(args, "study")
    config = _study_config(config, args)
    if "steps" in changes and "checkpoint_every" not in changes:
        # A shorter run still saves at least once before its end (at a window boundary).
        window = config.window
        checkpoint_every = max(
            window, min(config.checkpoint_every, config.steps // window * window)
        )
        config = dataclasses.replace(config, checkpoint_every=checkpoint_every)
    as_device("--device", config.device)  # here, before any run starts
    return config


def _with_preset(config: Any, name: str | None) -> Any:
    """``config`` with preset ``name`` applied (``--preset none``: the recorded preset dropped,
    the settings kept)."""
    return dataclasses.replace(config, preset=None) if name is None else config.with_preset(name)


def _run_gymnasium(args: argparse.Namespace) -> int:
    """``himit run gymnasium``: Taxi, CliffWalking, FrozenLake 8×8 (:mod:`himit_torch.runs.gymnasium`)."""
    from himit_torch.runs.gymnasium import run_gym_experiment

    config = _gym_config(args)
    run_dir = Path(args.logdir) / config.name
    print(
        f"{config.name}: tasks {list(config.tasks)}, agents {list(config.agents)}, "
        f"{config.seeds} seeds → {run_dir}"
    )
    t0 = time.perf_counter()
    run_gym_experiment(config, run_dir, force=args.force, progress=not args.quiet)
    print(f"done in {time.perf_counter() - t0:.0f} s: {run_dir / 'results.md'}")
    return 0


def _gym_config(args: argparse.Namespace) -> Any:
    """The Gymnasium comparison's configuration with ``himit run gymnasium``'s flags."""
    from himit_torch.runs.gymnasium import GymExperimentConfig

    config = _study_config(GymExperimentConfig(), args)
    as_device("--device", config.device)
    return config


def _discovery_config(args: argparse.Namespace) -> Any:
    """The discovery experiment's configuration with ``himit run discovery``'s flags."""
    from himit_torch.runs.discovery import DiscoveryConfig

    return _study_config(DiscoveryConfig(), args)


def _run_discovery(args: argparse.Namespace) -> int:
    """``himit run discovery``: options discovered from the mentor's states
    (:mod:`himit_torch.runs.discovery`) on experiment 1's and 2's worlds."""
    from himit_torch.runs.discovery import run_discovery

    config = _discovery_config(args)
    run_dir = Path(args.logdir) / config.name
    print(f"{config.name}: worlds {list(config.worlds)}, {config.seeds} seeds → {run_dir}")
    t0 = time.perf_counter()
    run_discovery(config, run_dir, force=args.force, progress=not args.quiet)
    print(f"done in {time.perf_counter() - t0:.0f} s: {run_dir / 'results.md'}")
    return 0


def _run_puzzle_box(args: argparse.Namespace) -> int:
    """``himit run puzzlebox``: Whiten et al.'s three findings on the puzzle box
    (:mod:`himit_torch.runs.puzzle_box`)."""
    from himit_torch.runs.puzzle_box import run_puzzle_box

    config = _puzzle_box_config(args)
    run_dir = Path(args.logdir) / config.name
    print(
        f"{config.name}: {config.skewers}- and {config.transfer_skewers}-skewer boxes, "
        f"{config.seeds} seeds per condition → {run_dir}"
    )
    t0 = time.perf_counter()
    run_puzzle_box(config, run_dir, resume=args.resume, force=args.force, progress=not args.quiet)
    print(f"done in {time.perf_counter() - t0:.0f} s: {run_dir / 'results.md'}")
    return 0


def _puzzle_box_config(args: argparse.Namespace) -> Any:
    """The puzzle box's configuration with ``himit run puzzlebox``'s flags."""
    from himit_torch.runs.puzzle_box import PuzzleBoxConfig

    return _study_config(PuzzleBoxConfig(), args)


class _StudyParser(_Parser):
    """One ``himit run STUDY``'s parser: a flag it does not take (another study's setting, or
    a run flag it has no use for) is refused in one line, naming the flag."""

    def parse_known_args(self, args=None, namespace=None):
        parsed, extras = super().parse_known_args(args, namespace)
        flags = [a.split("=", 1)[0] for a in extras if a.startswith("-")]
        if flags:
            self.error(
                f"takes no {', '.join(flags)} (not a flag of this study; its flags: "
                f"{self.prog} --help)"
            )
        return parsed, extras

    def error(self, message: str):
        if message.startswith("takes no"):
            _fail(f"{self.prog} {message}")
        super().error(message)


def _add_study(sub: argparse.ArgumentParser, name: str, study: StudyCommand) -> None:
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
    config_class = study.config_class()
    defaults = _study_defaults(name)
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
        _add_setting_flags(
            sub.add_argument_group(
                "learner settings",
                "Fields of LearnerConfig, this study's defaults shown. Its window is the "
                "study's --window.",
            ),
            LearnerConfig,
            "learner",
            skip=("window",),
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
        _add_study(studies.add_parser(name, help=study.help, description=study.help), name, study)


# ------------------------------------------------------------------------------------- plot
def _saved_fields(run_dir: Path) -> set[str] | None:
    """The field names of ``run_dir/config.json`` (``None``: no such file, or not a dict)."""
    from himit_torch.validation import parse_document, read_text

    path = run_dir / "config.json"
    if not path.is_file():
        return None
    where = f"himit plot: {path}"
    data = parse_document(where, read_text(where, path), "json")
    return set(data) if isinstance(data, dict) else None


def cmd_plot(args: argparse.Namespace) -> int:
    run_dir = Path(args.run_dir)
    if (run_dir / "summary.json").exists():
        if not (run_dir / "batches").is_dir():
            raise ValueError(
                f"{run_dir} is a puzzle-box run directory without its batches/ records: its page "
                "is redrawn from them (summary.json holds only the aggregates); put the batches/ "
                "folder back, or run it again with himit run puzzlebox"
            )
        from himit_torch.runs.puzzle_box import recorded_run_command
        from himit_torch.runs.puzzle_box_report import rewrite_puzzle_box_report

        # a himit run puzzlebox directory
        rewrite_puzzle_box_report(run_dir, recorded_run_command(run_dir))
        print(f"wrote {run_dir / 'figures'} and {run_dir / 'results.md'}")
        return 0
    if (run_dir / "tasks").is_dir() and not (run_dir / "worlds").is_dir():
        from himit_torch.runs.gymnasium import rewrite_gym_report

        rewrite_gym_report(run_dir)  # a himit run gymnasium directory
        print(f"wrote {run_dir / 'figures'} and {run_dir / 'results.md'}")
        return 0
    if (run_dir / "sweep.json").exists() and (run_dir / "runs.csv").exists():
        from himit_torch.runs.sweep import rewrite_summary

        rewrite_summary(run_dir)  # a himit sweep folder: its tables from runs.csv
        print(f"wrote {run_dir / 'summary.csv'} and {run_dir / 'summary.md'}")
        return 0
    from himit_torch.runs.discovery import DiscoveryConfig
    from himit_torch.runs.experiment import rewrite_report
    from himit_torch.validation import settings_of

    saved = _saved_fields(run_dir)
    discovery = {s.name for s in settings_of(DiscoveryConfig)}
    experiment = {s.name for s in settings_of(ExperimentConfig)}
    if saved is not None and saved <= discovery and not saved <= experiment:
        raise ValueError(
            f"{run_dir} is a himit run discovery directory: its results.md and figures are "
            "written at the end of the run, and himit plot does not redraw them"
        )
    rewrite_report(run_dir)
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

    result = benchmark(
        size=args.size,
        rooms=args.rooms,
        corner_options=args.corner_options,
        batch=args.batch,
        steps=args.steps,
        agent=args.agent,
        device=args.device,
        plan_every=args.plan_every,
        warmup=args.warmup,
        engine=args.engine,
    )
    print(result.line())
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
        "reproduce one of the paper's experiments (exp1, exp2, exp3), or "
        "the Gymnasium comparison (gymnasium), or the puzzle box (puzzlebox)",
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
    except ValueError as err:
        _fail(err)
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError) as err:
        # A path the user gave names nothing usable (missing, a directory for a file, a file
        # where a folder belongs): their mistake, exit 2 as for any bad argument. The loaders
        # say so themselves (validation.read_text); this catches the paths that are only opened
        # or created (--logdir under a file, a run directory removed mid-way).
        _fail(err)
    except OSError as err:
        # Everything else — permissions, a full disk, a failing device, a lost network mount —
        # is the machine failing on the right path: exit 1, one line, so scripts can tell a
        # retry-worthy fault from a command to fix.
        _fail(err, status=1)
    except KeyboardInterrupt:  # Ctrl-C: one line, the shell's status for SIGINT
        _fail("interrupted", status=130)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
