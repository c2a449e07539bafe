"""The MiniGrid mentor: optimal for its own right-handed skills
(:func:`~himit_torch.minigrid_options` with ``style="mentor"``), recording state-only
demonstrations like every mentor of the library."""

from __future__ import annotations

from himit_torch.mentor.policy import MentorPolicy, mentor_policy
from himit_torch.options.bundle import Options
from himit_torch.options.minigrid import minigrid_options
from himit_torch.worlds.minigrid import STEP_REWARD, MiniGridWorld

__all__ = ["minigrid_mentor"]


def minigrid_mentor(world: MiniGridWorld, options: Options | None = None) -> MentorPolicy:
    """The mentor of a MiniGrid world: the optimal policy for its own options (by default
    :func:`~himit_torch.minigrid_options` ``(world, "mentor")``: no ``left`` turn, right-handed
    "go to and face X" skills), by exact SMDP value iteration
    (:func:`~himit_torch.mentor_policy`), taking a skill wherever one is within one step's cost
    (0.01) of the optimum — so it goes from subgoal to subgoal by its skills and uses the
    primitives ``pickup``, ``toggle`` and ``forward`` in between.

    Raises:
        TypeError: a world not made by :func:`~himit_torch.from_minigrid`.
    """
    if not isinstance(world, MiniGridWorld):
        raise TypeError(
            f"minigrid_mentor needs a world made by from_minigrid, got {type(world).__name__}"
        )
    options = minigrid_options(world, "mentor") if options is None else options
    return mentor_policy(world, options, prefer_extended_within=abs(STEP_REWARD))
