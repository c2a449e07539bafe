"""``himit info --minigrid ID``: a MiniGrid task's states, both option sets, the optimum's steps
and the mentor's goal rate. ``himit run minigrid`` (the Gymnasium comparison on MiniGrid's
tasks, :data:`himit_torch.runs.gymnasium.MINIGRID_TASKS`) carries this topic."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from himit_torch.runs.study import InfoTopic, optimum_lines, option_kinds_text

__all__ = ["INFO"]


def _info_flags(parser) -> None:
    parser.add_argument(
        "--minigrid",
        metavar="ID",
        help="a MiniGrid task, e.g. MiniGrid-DoorKey-8x8-v0 (reset seed 0): its states, the "
        "learner's and the mentor's options, the optimum's steps and the mentor's goal rate",
    )


def _info(args: Any) -> Iterator[str]:
    """``himit info --minigrid ID`` (reset seed 0, MiniGrid's determinism), solved exactly."""
    from himit_torch.mentor.minigrid import minigrid_mentor
    from himit_torch.options.minigrid import minigrid_options
    from himit_torch.worlds.minigrid import from_minigrid

    world = from_minigrid(args.minigrid, gamma=args.gamma)
    yield (
        f"world      {world.name}, reset seed {world.seed}, {world.width}×{world.height} cells, "
        f"no slip (MiniGrid's own step), gamma {world.gamma}, reward −0.01 a step and +1 at "
        "success"
    )
    yield (
        f"states     {world.num_states:,} reachable ({int(world.terminal_mask.sum())} entered at "
        f"success); objects: {', '.join(world.object_names) or 'none'}"
    )
    yield f"actions    {world.num_actions}: {', '.join(world.action_names)}"
    learner, mentor_opts = minigrid_options(world), minigrid_options(world, "mentor")
    skills = [n for n, k in zip(learner.names, learner.kinds) if k != "primitive"]
    yield (
        f"learner    {learner.num_options} options ({option_kinds_text(learner)}: "
        f"{', '.join(skills)})"
    )
    yield (
        f"mentor     {mentor_opts.num_options} options ({option_kinds_text(mentor_opts)}; no "
        "left turn, right-handed skills)"
    )
    yield from optimum_lines(world, learner, minigrid_mentor(world, mentor_opts))[0]


#: ``himit info --minigrid ID`` (``--gamma`` is the Gymnasium topic's flag, shared).
INFO = InfoTopic("minigrid", _info_flags, _info)
