"""The puzzle box's mentors, and the mapping of a smaller box's demonstrations into a larger one.

Mentors
    :func:`organisation_mentor` — a mentor with its own skills (the pinch-grip style of
    :func:`~himit_torch.options.puzzle_box.puzzle_box_options`) that follows one hierarchical
    organisation (:data:`~himit_torch.worlds.puzzle_box.ORGANISATIONS`): skewer by skewer, or step
    by step. Both are optimal (every policy that wastes no movement is, see
    :class:`~himit_torch.PuzzleBox`), so :func:`~himit_torch.mentor_policy`'s optimal policy would
    pick an organisation by its tie-breaking; here the organisation is chosen.

State mappings (the paper's footnote 2)
    The paper assumes that mentor and observer share one state space, and notes (footnote 2) that
    "these assumptions can be relaxed using appropriate mappings between the observer's
    states/actions and the mentor's". Whiten et al.'s test box had a fifth skewer that no
    demonstration showed; here the mentor demonstrates on a ``k_m``-skewer box and the learner
    works on a ``k_l``-skewer box (``k_l ≥ k_m``). :func:`map_demonstrations` makes the mapping
    explicit, in two forms:

    ``"plain"`` — the embedding ``ι``: mentor skewer ``c`` is learner skewer ``c``, and the
        learner's other skewers stay in (level 0). A mentor state maps to one learner state; the
        learner's mentor model covers only states whose extra skewers were never touched, so it
        says nothing about what to do with them (expected: no assimilation).

    ``"any"`` — the mentor's box seen in *any* ``k_m`` of the learner's skewers, in their order,
        the others held at any level: for every order-preserving injection ``ι`` of the mentor's
        skewers into the learner's and every level ``v`` of the skewers left out, the mentor's
        episode is mapped by ``ι`` with the others at ``v``. This is a state abstraction on which
        the mentor model is learned — a learner state is seen through each of its ``k_m``-skewer
        views, "each skewer relative to the others" — written as the concrete transitions it
        implies, so the learner's own mentor model (eq. 2's ``p_m``) holds it unchanged.

    Why eq. 2 stays sound under both. The box's dynamics are local: a movement changes only the
    hand and the skewer it acts on, and its slips are local too (a motion becomes another motion
    on the same skewer, any other movement fumbles). So a mentor step ``x → x'`` made with some
    movement on mentor skewer ``c`` maps under ``ι`` to a learner step ``ι(x) → ι(x')`` that the
    same movement on learner skewer ``ι(c)`` makes *with exactly the same probability*, whatever
    the skewers left out hold. The mapped mentor model at a learner state is therefore a mixture
    of the transition laws of the learner's own primitive actions there (one per view that the
    mentor's demonstrations cover), and eq. 2's mentor term — an average of those actions' values
    — never exceeds the value of the best of them: the observer can duplicate every mapped move
    (the paper's condition for eq. 2, Section II), the outer max is redundant at ``V*`` and
    ``V*`` stays the fixed point. Rewards are the learner's own (``KnownReward`` of the learner's
    box): a mapped episode that ends with the learner's box still closed pays the step reward,
    not the goal's.
"""

from __future__ import annotations

from itertools import combinations

import torch

from himit_torch.exact.option_models import option_models
from himit_torch.exact.planning import smdp_value_iteration
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import MentorPolicy
from himit_torch.options.bundle import Options
from himit_torch.options.puzzle_box import check_box_options, puzzle_box_options
from himit_torch.validation import as_index_tensor, as_int, as_int_array
from himit_torch.worlds.puzzle_box import ORGANISATIONS, PuzzleBox, check_puzzle_box, next_step

__all__ = ["MAPPINGS", "organisation_mentor", "map_states", "map_demonstrations"]

#: State mappings of :func:`map_demonstrations`.
MAPPINGS = ("plain", "any")


def organisation_mentor(
    box: PuzzleBox, organisation: str, options: Options | None = None
) -> MentorPolicy:
    """A mentor that opens ``box`` in one hierarchical ``organisation`` with its own skills.

    In each state it works on :func:`~himit_torch.worlds.puzzle_box.next_step` of the
    organisation: hand home — "go to" that skewer; hand open at it or in the skills' grip — "do
    step ``j`` on the skewer at hand"; hand in the other grip on it — the motion (primitive); hand
    at another skewer (never, in its own episodes) — withdraw (primitive). With the learner's
    options (``puzzle_box_options(box, "learner")``) it is the same organisation done the
    learner's way.

    Args:
        box: the puzzle box.
        organisation: ``"skewer"`` or ``"step"``.
        options: the mentor's options; default ``puzzle_box_options(box, "mentor")`` (its layout
            is assumed: the ``A`` primitives, ``k`` go-to options, ``n`` step options).

    Returns:
        A :class:`~himit_torch.MentorPolicy` whose ``values`` are the optimal values of the
        mentor's option SMDP (the organisation's policy attains them: see the tests).
    """
    check_puzzle_box("organisation_mentor: box", box)
    if not isinstance(organisation, str) or organisation not in ORGANISATIONS:
        raise ValueError(f"organisation={organisation!r}: use one of {ORGANISATIONS}")
    if options is None:
        options = puzzle_box_options(box, "mentor")
    else:
        check_box_options("organisation_mentor", box, options)
        layout = box.num_actions + box.skewers + box.steps
        if options.num_options != layout:
            raise ValueError(
                f"organisation_mentor: options hold {options.num_options} options; the box's "
                f"skills hold {layout} (its {box.num_actions} primitives, {box.skewers} go-to "
                f"and {box.steps} step options: puzzle_box_options(box, ...))"
            )
    A, k = box.num_actions, box.skewers
    go_to = A  # option index of "go to skewer 1"
    step = A + k  # option index of "do step 1 on the skewer at hand"
    policy = torch.full((box.num_states,), -1, dtype=torch.int64)
    terminal = box.terminal_mask
    for s in range(box.num_states):
        if bool(terminal[s]):
            continue
        progress, at, grasp = box.decode(s)
        skewer, j = next_step(progress, organisation, box.steps)
        if at is None:
            policy[s] = go_to + skewer
        elif at != skewer:
            policy[s] = box.action_withdraw
        elif bool(options.initiation[step + j - 1, s]):  # open, or in the skills' own grip
            policy[s] = step + j - 1
        else:  # in the other grip
            policy[s] = box.action_motion(j)
    values = smdp_value_iteration(option_models(box, options)).values
    return MentorPolicy(options=options, option=policy, values=values, tolerance=0.0)


def map_states(
    source: PuzzleBox, target: PuzzleBox, states: torch.Tensor, skewers: tuple[int, ...], level: int
) -> torch.Tensor:
    """Map ``source``-box states into ``target``: source skewer ``c`` becomes target skewer
    ``skewers[c]``, every other target skewer is held at ``level``; the hand keeps its grasp and
    goes to the mapped skewer (0-based skewer indices throughout).

    Raises:
        ValueError: boxes of different steps, slip or rewards; ``skewers`` not ``k_source``
            distinct target skewers; ``level`` outside ``0 … n``.
    """
    _check_pair(source, target)
    skewers = tuple(as_int_array("map_states: skewers", skewers).tolist())
    if len(skewers) != source.skewers or len(set(skewers)) != len(skewers):
        raise ValueError(
            f"skewers={skewers}: give {source.skewers} distinct target skewers, one per "
            "source skewer"
        )
    if not all(0 <= c < target.skewers for c in skewers):
        raise ValueError(f"skewers={skewers}: target skewers are 0 … {target.skewers - 1}")
    level = as_int(f"map_states: level (a skewer's level is 0 … {target.steps})", level, 0,
                   target.steps)  # fmt: skip
    states = as_index_tensor("map_states: states", states, 0, source.num_states - 1, 1)
    src_levels = source.progress(states)  # [T, k_s]
    levels = torch.full((states.numel(), target.skewers), int(level), dtype=torch.int64)
    index = torch.tensor(skewers, dtype=torch.int64)
    levels[:, index] = src_levels
    radix = torch.from_numpy(target._radix)
    code = (levels * radix).sum(1)
    hand = source.hand(states)
    at = (hand - 1).div(3, rounding_mode="floor").clamp(min=0)
    grasp = (hand - 1) % 3
    mapped_hand = torch.where(hand > 0, 1 + 3 * index[at] + grasp, torch.zeros_like(hand))
    return code * target.hand_states + mapped_hand


def map_demonstrations(
    demonstrations: Demonstrations, source: PuzzleBox, target: PuzzleBox, mapping: str = "plain"
) -> Demonstrations:
    """The ``source`` box's demonstrations as demonstrations in ``target`` (module docstring).

    ``"plain"``: one mapped episode per episode (skewers in place, the others in). ``"any"``:
    per episode, one for every order-preserving choice of ``k_source`` target skewers and every
    level of the others — ``C(k_t, k_s) · (n + 1)`` episodes per episode when ``k_t > k_s`` (one
    when the boxes are equal).

    Every mapped episode is a valid episode of ``target`` (checked by
    :class:`~himit_torch.Demonstrations`). Raises ``ValueError`` for an unknown mapping or boxes
    that differ in anything but their number of skewers (``k_target ≥ k_source``).
    """
    if not isinstance(mapping, str) or mapping not in MAPPINGS:
        raise ValueError(f"mapping={mapping!r}: use one of {MAPPINGS}")
    if not isinstance(demonstrations, Demonstrations):
        raise TypeError(
            "map_demonstrations: demonstrations must be Demonstrations of the source box, got "
            f"{type(demonstrations).__name__}"
        )
    _check_pair(source, target)
    demonstrations.check_world(source)
    if mapping == "plain":
        views = [(tuple(range(source.skewers)), 0)]
    else:
        extra = target.skewers - source.skewers
        levels = range(target.steps + 1) if extra else range(1)
        views = [
            (chosen, v)
            for chosen in combinations(range(target.skewers), source.skewers)
            for v in levels
        ]
    episodes = [
        map_states(source, target, ep, chosen, v)
        for chosen, v in views
        for ep in demonstrations.episodes
    ]
    return Demonstrations(episodes, target, source=f"mapped ({mapping}) demonstrations")


def _check_pair(source: PuzzleBox, target: PuzzleBox) -> None:
    for b, what in ((source, "source"), (target, "target")):
        if not isinstance(b, PuzzleBox):
            raise ValueError(f"the {what} must be a PuzzleBox, got {type(b).__name__}")
    same = ("steps", "slip", "pinch_slip", "step_reward", "goal_reward", "gamma")
    differ = [f for f in same if getattr(source, f) != getattr(target, f)]
    if differ or target.skewers < source.skewers:
        raise ValueError(
            f"cannot map {source!r} into {target!r}: the boxes must differ only in their "
            f"skewers, the target having at least as many"
            + (f" (they differ in {differ})" if differ else "")
        )
