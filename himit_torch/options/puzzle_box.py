"""Skills for the puzzle box (:class:`~himit_torch.PuzzleBox`): "go to skewer i" and "do step j
on the skewer at hand", in the learner's style (power grip) and the mentor's (pinch).

Both styles reach the same subgoals — the hand open at a skewer, a skewer one level further with
the hand home — through different low-level states: between the two the learner's hand is in a
power grip, the mentor's in a pinch. Any copying of the mentor's organisation by the learner is
therefore copying of subgoals, not of movements.
"""

from __future__ import annotations

import torch

from himit_torch.options.builders import primitive_options, subgoal_options
from himit_torch.options.bundle import Options
from himit_torch.validation import COUNT_MAX, as_index_tensor, as_int
from himit_torch.worlds.puzzle_box import PuzzleBox, check_puzzle_box

__all__ = [
    "STYLES",
    "go_to_skewer_options",
    "step_options",
    "puzzle_box_options",
    "intended_rollout",
    "check_box_options",
]

#: The grip each style's step skills use: the learner's ``"power"``, the mentor's ``"pinch"``.
STYLES = {"learner": "power", "mentor": "pinch"}


def go_to_skewer_options(box: PuzzleBox) -> Options:
    """``k`` options "go to skewer i": from the rest position (hand home), reach skewer ``i``
    (again after a fumble) and stop with the hand open there. Built with
    :func:`~himit_torch.subgoal_options` (target: the hand open at skewer ``i``; action: ``reach
    i``), so usable exactly where that reaches it: every state with the hand home."""
    check_puzzle_box("go_to_skewer_options: box", box)
    targets = {}
    for i in range(box.skewers):
        hand_at = box.hand(torch.arange(box.num_states)) == 1 + 3 * i
        targets[f"go to skewer {i + 1}"] = hand_at & box.grasp_mask("open")
    parts = [
        subgoal_options(box, {name: mask}, actions=[box.action_reach + i])
        for i, (name, mask) in enumerate(targets.items())
    ]
    return Options.concat(parts)


def step_options(box: PuzzleBox, style: str = "learner") -> Options:
    """``n`` options "do step j on the skewer at hand" (one per step, whichever skewer the hand
    is at): the skill of motion ``j``, usable where it moves the skewer — the hand open at a
    skewer whose level is ``j − 1`` (the step is done) or ``j`` (it is undone: the skill knows
    *how* to move the part, not whether it should), or already gripping it with the style's
    grip. It grips (``power`` for the learner, ``pinch`` for the mentor, :data:`STYLES`) and makes
    motion ``j``, again after a fumble or a slip that did nothing, and stops when the skewer's
    level changed (the hand is home).

    Raises:
        ValueError: ``style`` is not one of :data:`STYLES`.
    """
    check_puzzle_box("step_options: box", box)
    if not isinstance(style, str) or style not in STYLES:
        raise ValueError(f"style={style!r}: use one of {sorted(STYLES)}")
    grip = STYLES[style]
    states = torch.arange(box.num_states)
    hand = box.hand(states)
    at = torch.where(hand > 0, (hand - 1) // 3, torch.zeros_like(hand))
    level = box.progress(states).gather(1, at[:, None])[:, 0]
    is_open, gripping = box.grasp_mask("open"), box.grasp_mask(grip)
    grip_action = box.action_power if grip == "power" else box.action_pinch
    live = ~box.terminal_mask
    parts = []
    for j in range(1, box.steps + 1):
        ready = ((level == j - 1) | (level == j)) & live
        initiation = ready & (is_open | gripping)
        policy = torch.zeros(box.num_states, dtype=torch.int64)
        policy[ready & is_open] = grip_action
        policy[ready & gripping] = box.action_motion(j)
        parts.append(
            Options.from_policy(
                initiation,
                policy,
                name=f"step {j} on the skewer at hand ({grip})",
                kind="subgoal",
            )
        )
    return Options.concat(parts)


def puzzle_box_options(box: PuzzleBox, style: str = "learner", pinch: bool = True) -> Options:
    """Primitives (usable where they afford something), "go to skewer i" and the style's "do
    step j on the skewer at hand": the learner's options (``style="learner"``) or the mentor's
    (``"mentor"``). Both bundles have the same layout: option ``o`` is the same kind of skill in
    both, only the grip of the step skills differs.

    ``pinch=False`` leaves the ``pinch grip`` primitive out (a learner that cannot make the
    mentor's grip, so cannot pass through the mentor's states between subgoals: its imitation
    can only be of subgoals); the layout is then the mentor's minus that one option."""
    check_puzzle_box("puzzle_box_options: box", box)
    if not isinstance(pinch, bool):
        raise ValueError(f"puzzle_box_options: pinch={pinch!r} must be True or False")
    if not isinstance(style, str) or style not in STYLES:
        raise ValueError(f"puzzle_box_options: style={style!r}: use one of {sorted(STYLES)}")
    primitives = primitive_options(box)
    if not pinch:
        if style == "mentor":
            raise ValueError("puzzle_box_options: the mentor's skills need the pinch grip")
        keep = [a for a in range(box.num_actions) if a != box.action_pinch]
        primitives = primitives.select(keep)
    return Options.concat([primitives, go_to_skewer_options(box), step_options(box, style)])


def check_box_options(where: str, box: PuzzleBox, options: Options) -> Options:
    """``options`` if they are an :class:`~himit_torch.Options` bundle over ``box``'s states
    (another world's options, ``None`` or a list are refused: ``TypeError`` for no bundle,
    ``ValueError`` for a bundle of another world)."""
    if not isinstance(options, Options):
        raise TypeError(
            f"{where}: options must be an Options bundle of the box (e.g. "
            f"puzzle_box_options(box)), got {type(options).__name__}"
        )
    if options.num_states != box.num_states:
        raise ValueError(
            f"{where}: options are over {options.num_states} states but the box has "
            f"{box.num_states}: they are another world's; give puzzle_box_options(box)"
        )
    return options


def intended_rollout(
    box: PuzzleBox, options: Options, policy: torch.Tensor, max_steps: int | None = None
) -> tuple[torch.Tensor, bool]:
    """The states of one episode from the start following the option policy ``policy [S]`` (an
    option per state, −1 where none) with every action doing what was intended (no slip): the
    plan a policy stands for, read without the world's noise.

    Returns:
        ``(states, complete)``: the states visited (start included), and whether the box was
        opened. It stops early, incomplete, at a state whose policy is −1 or whose option is not
        usable there, at a repeated (state, option) pair (a loop) or after ``max_steps`` (default
        ``4·|S|``).
    """
    check_puzzle_box("intended_rollout: box", box)
    check_box_options("intended_rollout", box, options)
    policy = as_index_tensor("intended_rollout: policy", policy, -1, options.num_options - 1, 1)
    if policy.shape != (box.num_states,):
        raise ValueError(f"policy must be [S] = [{box.num_states}], got {tuple(policy.shape)}")
    intended = box.dynamics_table().successors[:, :, -1]
    terminal = box.terminal_mask
    limit = (
        4 * box.num_states
        if max_steps is None
        else as_int("intended_rollout: max_steps", max_steps, 0, COUNT_MAX)
    )
    s, option = int(box.start_state), -1
    states, seen = [s], set()
    for _ in range(limit):
        if bool(terminal[s]):
            return torch.tensor(states), True
        if option < 0:
            option = int(policy[s])
            if option < 0 or not bool(options.initiation[option, s]):
                break
        if (s, option) in seen:
            break
        seen.add((s, option))
        s = int(intended[s, int(options.policy[option, s])])
        states.append(s)
        if bool(terminal[s]) or float(options.termination[option, s]) >= 1.0:
            option = -1
    return torch.tensor(states), bool(terminal[s])
