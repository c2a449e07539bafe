"""Options for MiniGrid worlds (:func:`~himit_torch.from_minigrid`): "go to and face X" for each
key, door, box and ball and for the goal, built with :func:`~himit_torch.subgoal_options`, in
the learner's style and the mentor's.

The subgoal of "go to the yellow key" is every state in which the agent faces the cell where
that key lies (a door: its cell, whatever its state; the goal: its square). Both styles reach
the same subgoals through different movements: the learner's skills turn left or right and go
forward, by a shortest way; the mentor's are right-handed — they turn only right (three right
turns where the learner turns left once) — so between subgoals the mentor passes through states
the learner's skills do not, and any copying of the mentor by the learner is copying of
subgoals, not of movements. The skills never pick up, drop or toggle: those stay primitive, so
no MiniGrid task is solved by the skills alone — after "go to the key" comes the primitive
``pickup``, after "go to the door" ``toggle``, after "go to the goal" ``forward`` (reaching the
goal square ends the episode, so facing it is the last subgoal a skill can reach).
"""

from __future__ import annotations

import torch

from himit_torch.options.builders import primitive_options, subgoal_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.minigrid import MINIGRID_ACTION_NAMES, MiniGridWorld

__all__ = ["MINIGRID_STYLES", "minigrid_subgoals", "minigrid_options"]

#: The movement actions each style's skills use: the learner's turn both ways, the mentor's only
#: right.
MINIGRID_STYLES = {"learner": ("left", "right", "forward"), "mentor": ("right", "forward")}


def minigrid_subgoals(world: MiniGridWorld) -> dict[str, torch.Tensor]:
    """``{"go to the <object>": [S] bool}``: the non-terminal states where the agent faces each
    object of the world (:attr:`~himit_torch.worlds.minigrid.MiniGridWorld.object_names`, then
    ``"go to the goal"``); objects never faced (a ball inside a box that stays shut) are left
    out."""
    if not isinstance(world, MiniGridWorld):
        raise TypeError(
            f"minigrid_subgoals needs a world made by from_minigrid, got {type(world).__name__}"
        )
    front = world.front_cell()
    live = ~world.terminal_mask
    targets = {}
    for name in world.object_names:
        targets[f"go to the {name}"] = (front == world.object_cell(name)) & live
    if world.goal_cells:
        goal = torch.zeros_like(live)
        for cell in world.goal_cells:
            goal |= front == cell
        targets["go to the goal"] = goal & live
    return {name: mask for name, mask in targets.items() if bool(mask.any())}


def minigrid_options(world: MiniGridWorld, style: str = "learner") -> Options:
    """The primitives and the style's "go to and face X" skills (module docstring).

    ``style="learner"``: all six primitives, and skills that turn both ways. ``"mentor"``: the
    primitives without ``left``, and right-handed skills: a mentor that never turns left, whose
    every move the learner can make.

    Raises:
        ValueError: an unknown style. TypeError: a world not made by ``from_minigrid``.
    """
    if style not in MINIGRID_STYLES:
        raise ValueError(f"style={style!r}: use one of {sorted(MINIGRID_STYLES)}")
    moves = [MINIGRID_ACTION_NAMES.index(a) for a in MINIGRID_STYLES[style]]
    primitives = primitive_options(world)
    if style == "mentor":
        primitives = primitives.select(
            [a for a in range(world.num_actions) if a != MINIGRID_ACTION_NAMES.index("left")]
        )
    skills = []
    for name, mask in minigrid_subgoals(world).items():
        try:
            skills.append(subgoal_options(world, {name: mask}, actions=moves))
        except ValueError:  # faced only right after a pickup, drop or toggle: no skill to it
            continue
    return Options.concat([primitives, *skills])
