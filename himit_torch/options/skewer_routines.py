"""Skewer routines: options discovered from a mentor's puzzle-box states, expressed relative to
the skewer they act on, and carried to every skewer of a learner's box — the fifth included,
which the mentor never touched.

The paper's second proposal for future work is state abstraction with the action hierarchy:
options learned from watching, described relative to the object they act on, so that they
apply to objects the mentor never showed. On the puzzle box (:class:`~himit_torch.PuzzleBox`)
the object is a skewer, and what the mentor shows are routines such as "take the skewer at
hand out" (a skewer-by-skewer mentor) or "do the next step on the skewer at hand" (a
step-by-step mentor).

Discovery (:func:`discover_skewer_routines`)
    The learner perceives the box as skewers with levels and a hand that is home or at one of
    them (the state abstraction; :meth:`PuzzleBox.decode <himit_torch.PuzzleBox.decode>`). It
    segments each mentor episode where the mentor's *attention moves*: a segment is a maximal
    stretch in which the hand is only ever at one skewer ``X`` (home states in between do not
    break it); a new segment starts with the last home state before the hand is at another
    skewer. The subgoals are the segments' ends, found from the demonstrations: where the mentor
    leaves a skewer, not where the box's designer put a step. Each segment is described
    relative to its skewer by the net change it made there, "the skewer at hand from level
    ``a`` to level ``b``" (the other skewers are unchanged: the box's dynamics are local); the
    distinct descriptions with ``a < b`` are the routines. A skewer-by-skewer mentor yields "0 →
    ``n``" (the whole skewer), a step-by-step one "0 → 1", "1 → 2", … (one step each); slips
    that undo a step inside a segment leave its net change as it is. A segment with no net
    advance (the hand went to a skewer and came back) is no routine, so a mentor whose episodes
    never change a skewer yields none.

Options (:func:`skewer_routine_options`)
    For each routine and each skewer ``Y`` of the learner's box, one option "skewer ``Y``: ``a``
    → ``b``", built with the learner's own movements (its grip, the power grip; never the
    mentor's pinch). Its policy is planned once per routine in the *one-skewer view* — a
    one-skewer box with the same steps and slips, the policy of fewest expected steps to the
    view's target, level ``b`` with the hand home (:func:`~himit_torch.subgoal_options` on that
    box) — and lifted to skewer ``Y``: a state of the learner's box is seen through its level of
    ``Y`` and where the hand is relative to ``Y``. Because a movement changes only the hand and
    the skewer it acts on, and its slips too (:class:`~himit_torch.PuzzleBox`), the lifted option
    makes in the learner's box exactly the transitions its view makes, whatever the other
    skewers hold (tested against the exact option models).

    Usable where the routine starts in the mentor's segments: the hand home and ``Y`` at level
    ``a``. It runs while ``Y`` is below ``b`` and the hand is home or at ``Y`` open or in the
    power grip (an undone step is redone), and terminates at ``Y`` on level ``b`` with the hand
    home (or on leaving that set, or when the box opens).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import torch

from himit_torch.options.builders import subgoal_options
from himit_torch.options.bundle import Options
from himit_torch.worlds.puzzle_box import PuzzleBox, check_puzzle_box

__all__ = ["SkewerRoutine", "skewer_segments", "discover_skewer_routines", "skewer_routine_options"]


@dataclass(frozen=True, order=True)
class SkewerRoutine:
    """One routine seen in a mentor's episodes: the skewer at hand from level ``start`` to level
    ``end`` (``start < end``), with the hand home before and after.

    Attributes:
        start, end: the levels (0 … the box's steps).
        segments: how many of the mentor's segments made this net change (what was seen).
    """

    start: int
    end: int
    segments: int = 0

    def __post_init__(self):
        for name in ("start", "end", "segments"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"SkewerRoutine.{name}={value!r} must be a whole number ≥ 0")
        if not self.start < self.end:
            raise ValueError(
                f"SkewerRoutine from level {self.start} to {self.end}: a routine advances its "
                "skewer (start < end)"
            )

    def name(self, skewer: int) -> str:
        """The option's name for ``skewer`` (0-based): ``"skewer 5: 0 → 4"``."""
        return f"skewer {skewer + 1}: {self.start} → {self.end}"


def _episodes(box: PuzzleBox, demonstrations) -> list[list[int]]:
    """Each episode as a list of states of ``box`` (a state outside it is refused)."""
    episodes = getattr(demonstrations, "episodes", demonstrations)
    if isinstance(episodes, (str, bytes, dict)) or not isinstance(episodes, Iterable):
        raise ValueError(
            "discover_skewer_routines: demonstrations must be Demonstrations of the mentor's box "
            f"or a list of episodes (1-D sequences of its states), got "
            f"{type(demonstrations).__name__}"
        )
    out = [
        box._states(f"discover_skewer_routines: episode {i}", e, 1).tolist()
        for i, e in enumerate(episodes)
    ]
    if not out or any(not e for e in out):
        raise ValueError(
            "discover_skewer_routines: demonstrations must hold at least one episode, each a "
            "non-empty sequence of states"
        )
    return out


def skewer_segments(box: PuzzleBox, episode: Sequence[int]) -> list[tuple[int, int, int]]:
    """An episode's segments (module docstring): ``(skewer, level at its start, level at its
    end)`` in order, skewer 0-based; a segment starts at the episode's first state or at the
    last home state before the hand is at another skewer, and ends where the next one starts
    (the last one at the episode's end)."""
    decoded = [box.decode(s) for s in episode]
    segments = []
    current, start, last_home = None, 0, 0
    for t, (_, at, _) in enumerate(decoded):
        if at is None:
            last_home = t
            continue
        if current is None:
            current = at
        elif at != current:
            segments.append((current, start, last_home))
            current, start = at, last_home
    if current is not None:
        segments.append((current, start, len(decoded) - 1))
    return [(x, decoded[a][0][x], decoded[b][0][x]) for x, a, b in segments]


def discover_skewer_routines(box: PuzzleBox, demonstrations) -> tuple[SkewerRoutine, ...]:
    """The routines of a mentor's puzzle-box episodes (the module docstring's method).

    Args:
        box: the box the mentor demonstrated on (its states decode the episodes).
        demonstrations: :class:`~himit_torch.Demonstrations` on ``box``, or a list of episodes
            (1-D sequences of its states).

    Returns:
        The distinct routines ``start → end`` (``start < end``), ordered by their levels, each
        with the number of segments that made it; empty when no segment advanced a skewer.

    Raises:
        TypeError: ``box`` is not a :class:`~himit_torch.PuzzleBox`.
        ValueError: no episode, an empty one, or a state that is not one of ``box``'s.
    """
    check_puzzle_box("discover_skewer_routines: box", box)
    seen: dict[tuple[int, int], int] = {}
    for episode in _episodes(box, demonstrations):
        for _, start, end in skewer_segments(box, episode):
            if start < end:
                seen[(start, end)] = seen.get((start, end), 0) + 1
    return tuple(SkewerRoutine(a, b, n) for (a, b), n in sorted(seen.items()))


def _view_policy(box: PuzzleBox, routine: SkewerRoutine) -> torch.Tensor:
    """The routine's policy in the one-skewer view: ``[(n + 1) · 4]`` actions of a one-skewer box
    with ``box``'s steps and slips, fewest expected steps to level ``end`` with the hand home,
    with the learner's movements (reach, withdraw, power grip, the motions)."""
    view = PuzzleBox(1, box.steps, slip=box.slip, pinch_slip=box.pinch_slip, gamma=box.gamma)
    target = view.home_mask & (view.progress(torch.arange(view.num_states))[:, 0] == routine.end)
    actions = [a for a in range(view.num_actions) if a != view.action_pinch]
    return subgoal_options(view, {"view": target}, actions=actions).policy[0].long()


def skewer_routine_options(box: PuzzleBox, routines: Sequence[SkewerRoutine]) -> Options:
    """Options for every routine on every skewer of ``box`` (the module docstring): option
    ``r · k + Y`` is routine ``r`` on skewer ``Y`` (``k`` the box's skewers), kind
    ``"subgoal"``, named by :meth:`SkewerRoutine.name`.

    Raises:
        TypeError: ``box`` is not a :class:`~himit_torch.PuzzleBox`, or a routine is not a
            :class:`SkewerRoutine`.
        ValueError: no routines (a mentor that advanced no skewer gives none: use the
            primitives alone), or a routine's end beyond the box's steps.
    """
    check_puzzle_box("skewer_routine_options: box", box)
    if isinstance(routines, SkewerRoutine) or not isinstance(routines, Sequence):
        raise TypeError(
            "skewer_routine_options: routines must be a sequence of SkewerRoutine "
            f"(discover_skewer_routines' result), got {type(routines).__name__}"
        )
    wrong = [type(r).__name__ for r in routines if not isinstance(r, SkewerRoutine)]
    if wrong:
        raise TypeError(f"skewer_routine_options: routines must be SkewerRoutine, got {wrong}")
    if not routines:
        raise ValueError(
            "skewer_routine_options: no routines (the mentor advanced no skewer); there is "
            "nothing to build, use the primitives alone"
        )
    for r in routines:
        if r.end > box.steps:
            raise ValueError(
                f"skewer_routine_options: routine {r.start} → {r.end} goes beyond the box's "
                f"{box.steps} steps; discover routines on a box with as many steps"
            )
    states = torch.arange(box.num_states)
    levels = box.progress(states)  # [S, k]
    hand = box.hand(states)
    live = ~box.terminal_mask
    k, view_hand = box.skewers, 4  # the view's hand: home, or at its skewer open/power/pinch
    parts = []
    for routine in routines:
        view_policy = _view_policy(box, routine)
        for y in range(k):
            at_y = (hand >= 1 + 3 * y) & (hand <= 3 + 3 * y)
            relative = torch.where(at_y, hand - 3 * y, torch.zeros_like(hand))
            grasp = hand - 1 - 3 * y  # 0 open, 1 power, 2 pinch where the hand is at y
            level = levels[:, y]
            in_view = (hand == 0) | at_y
            view_state = level * view_hand + torch.where(in_view, relative, 0)
            action = view_policy[view_state]
            # the view's actions, lifted: reach 1 → reach y; the others keep their place after
            # the reaches (withdraw, the grips, the motions)
            policy = torch.where(action == 0, y, action + k - 1)
            runs = live & (level < routine.end) & ((hand == 0) | (at_y & (grasp <= 1)))
            initiation = live & (hand == 0) & (level == routine.start)
            parts.append(
                Options.from_policy(
                    initiation,
                    torch.where(runs, policy, torch.zeros_like(policy)),
                    termination=(~runs).float(),
                    name=routine.name(y),
                    kind="subgoal",
                )
            )
    return Options.concat(parts)
