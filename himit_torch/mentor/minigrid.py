"""The MiniGrid mentor: optimal for its own right-handed skills
(:func:`~himit_torch.minigrid_options` with ``style="mentor"``), recording state-only
demonstrations like every mentor of the library; and its demonstrations carried to another
task of the same layout (:func:`demonstrations_in`: transfer)."""

from __future__ import annotations

import torch

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.observation import CoarseDemonstrations
from himit_torch.mentor.policy import MentorPolicy, mentor_policy
from himit_torch.options.bundle import Options
from himit_torch.options.minigrid import minigrid_options
from himit_torch.worlds.minigrid import STEP_REWARD, MiniGridWorld

__all__ = ["minigrid_mentor", "demonstrations_in"]


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


def demonstrations_in(
    world: MiniGridWorld,
    demonstrations: Demonstrations | CoarseDemonstrations,
    source: MiniGridWorld,
) -> Demonstrations | CoarseDemonstrations:
    """Demonstrations recorded in ``source`` as states of ``world``, a world of the same layout
    (e.g. the same task with its goal moved, :func:`~himit_torch.from_minigrid`'s ``goal``):
    each state matched by its full state (agent, objects, doors;
    :meth:`~himit_torch.MiniGridWorld.states_from`). The mentor demonstrates ``source``'s task;
    a learner in ``world`` watches the same states, rewarded on its own task (transfer).
    Coarse demonstrations keep their observed positions and durations. (The puzzle box's
    sibling, between boxes of different sizes, is :func:`~himit_torch.map_demonstrations`.)

    >>> import himit_torch as ht
    >>> task = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0")
    >>> shown = ht.from_minigrid("MiniGrid-DoorKey-5x5-v0", goal=(3, 2))
    >>> demos = ht.record_demonstrations(shown, ht.minigrid_mentor(shown), 1, seed=0)
    >>> seen = demonstrations_in(task, demos, shown)
    >>> [task.describe_state(int(e[-1])) for e in seen.episodes]
    ['agent (3, 2) facing south, carrying yellow key, yellow door open']

    Raises:
        TypeError: ``world`` or ``source`` not made by ``from_minigrid``, or ``demonstrations``
            neither :class:`~himit_torch.Demonstrations` nor coarse ones.
        ValueError: the demonstrations are not ``source``'s, the worlds' layouts differ, or a
            demonstrated state is not one of ``world``'s, or ends its episodes early (one of
            ``world``'s goals lies on the mentor's way: its episodes would not be moves of
            ``world``'s).
    """
    if not isinstance(world, MiniGridWorld) or not isinstance(source, MiniGridWorld):
        raise TypeError("demonstrations_in needs two worlds made by from_minigrid")
    if not isinstance(demonstrations, (Demonstrations, CoarseDemonstrations)):
        raise TypeError(
            "demonstrations_in carries Demonstrations or CoarseDemonstrations, got "
            f"{type(demonstrations).__name__}"
        )
    full = demonstrations if isinstance(demonstrations, Demonstrations) else demonstrations.full
    full.check_world(source)
    moved = Demonstrations([world.states_from(source, e) for e in full.episodes], world)
    if isinstance(demonstrations, Demonstrations):
        return moved
    # the observed positions: each episode's first, then its observed moves' durations summed
    lengths = [len(e) - 1 for e in demonstrations.episodes]
    durations = torch.split(demonstrations.durations(), lengths)
    positions = [torch.cat([torch.zeros(1, dtype=torch.int64), d.cumsum(0)]) for d in durations]
    return CoarseDemonstrations(moved, positions=positions)
