"""The puzzle box: Whiten et al.'s (2006) "keyway-fruit" task as a tabular world.

Whiten, Flynn, Brown & Lee (2006, *Imitation of hierarchical action structure by young
children*, Developmental Science 9(6)) let three-year-olds open a box whose lid is held by four
skewers; each skewer comes out by the same sequence of four steps, and each step is itself a
sequence of movements. The paper this library follows motivates its model with that study
(Section I) and models it by a gridworld (Section III); :class:`PuzzleBox` is the box itself.

Design (and why)
    *Skewers and steps.* ``k`` skewers, each at a level ``p_i ∈ {0 … n}``: the number of its ``n``
    steps done (``n = 4`` in the study). Step ``j`` of a skewer needs step ``j − 1`` of the same
    skewer: it takes the skewer from level ``j − 1`` to ``j``. The box opens (the goal, +1) when
    every skewer is out (every ``p_i = n``).

    *The hand.* A step is three movements of one hand: **reach** skewer ``i`` (from the rest
    position, *home*), **grip** it (a *power* grip — the whole hand — or a *pinch* — thumb and
    finger), then make the step's **motion**. Once the motion is made the part comes free and the
    hand returns home with it. The low-level state is the hand's place and grasp: home, or at
    skewer ``i`` with the hand open, in a power grip or in a pinch (``1 + 3k`` hand states).
    Two grips matter because they give the learner and the mentor *different low-level
    sequences to the same subgoals* — the learner's skills use the power grip, the mentor's the
    pinch — the box's version of the paper's learner that walks straight to a doorway while its
    mentor walks along the walls. The states between subgoals differ; the subgoals (a skewer's
    new level with the hand home, or the hand open at a skewer) are shared.

    *Reversibility.* A motion made again undoes its step (a turned bolt turns back, a pulled
    skewer is pushed back in): motion ``j`` takes a gripped skewer from level ``j − 1`` to ``j``
    and from ``j`` back to ``j − 1``, and does nothing at other levels. So an explorer's level on
    each skewer is a random walk, and finding the all-out state by chance is hard — as finding the
    goal of the paper's gridworld is — instead of a certainty that needs only persistence.

    *Why the two organisations cost the same.* Every step starts and ends with the hand home, so
    a step costs the same whichever skewer it is done on and whatever was done before: the
    expected cost of raising a skewer from level ``j − 1`` to ``j`` (slips and their repairs
    included) depends on ``j`` alone, and each skewer's attempts form the same random sequence
    whatever the order of the skewers. Every policy that never wastes a movement is therefore
    optimal — the two hierarchical organisations of the study, **skewer by skewer** (all steps
    of skewer 1, then of skewer 2, …) and **step by step** (step 1 on every skewer, then step
    2, …), and every mix between them — with the same distribution of the time to open, so
    that what the mentor shows, not efficiency, decides which one a learner prefers. Exact
    planning confirms it (``tests/worlds/test_puzzle_box.py``, ``himit info --puzzle-box k``).
    (With a hand that stayed at the last skewer, skewer by skewer would save the moves between
    skewers and the two would not cost the same.)

Action space (``A = k + n + 3``), with what the hand can do in each posture (its
*affordances*, :attr:`PuzzleBox.affordances`; the primitive options are usable only there):

    ``reach i`` (``i = 1 … k``, at home) — the hand goes to skewer ``i``, open;
    ``withdraw`` (hand at a skewer) — back home, letting go;
    ``power grip``, ``pinch grip`` (hand open at a skewer) — grip it;
    ``motion j`` (``j = 1 … n``, hand gripping) — step ``j`` of the gripped skewer, done or
    undone as above; the hand returns home when the skewer's level changed, and stays gripping
    when the motion did nothing.
    An action outside its posture does nothing (a wasted movement).

Dynamics (slip, like the grid's)
    With probability ``slip`` an action fails: a motion becomes one of the ``n − 1`` other
    motions, uniformly (a bolt turned the wrong way: it may undo the previous step), and any other
    action fumbles — the hand stays as it was. The ``pinch grip`` and the motions made in a pinch
    fail with probability ``pinch_slip`` (default: ``slip``, the two grips equally good, so that
    neither the organisation nor the grip has an efficiency advantage). ``pinch_slip > slip``
    makes the mentor's way of doing a step (in a pinch) a little slower than the learner's own
    (in a power grip), as the paper's mentor's wall-following doorway options are a little slower
    than the learner's direct ones ("slips cost it slightly more"). Slips are local to the hand and the
    gripped skewer, so the dynamics of a box's first ``k'`` skewers do not depend on how many
    others it has: a ``k'``-skewer box embeds exactly in a larger one (what the state mappings
    of :mod:`himit_torch.mentor.puzzle_box` rely on). One uniform ``u`` decides: with failure
    probability ``q``, motion ``j`` slips to the ``m``-th other motion for ``m·q/(n−1) ≤ u <
    (m+1)·q/(n−1)``.

Rewards
    ``step_reward`` (−0.01) for entering any state but an open box, ``goal_reward`` (+1.0) for
    opening it; discount ``gamma`` (0.99), as in the paper's worlds.

States
    ``s = code(p) · H + h`` with ``code(p) = Σ_i p_i (n+1)^i`` and hand index ``h``: 0 = home,
    ``1 + 3i + g`` = at skewer ``i`` (0-based) with grasp ``g`` (0 open, 1 power, 2 pinch),
    ``H = 1 + 3k``; ``|S| = (n+1)^k (1 + 3k)``. Every state with all skewers out is terminal
    (only the one with the hand home can be entered). The episode starts with every skewer in and
    the hand home (state 0).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import torch

from himit_torch.validation import (
    COUNT_MAX,
    as_float,
    as_index_tensor,
    as_int,
    as_int_array,
    check_memory,
)
from himit_torch.worlds.table_world import TableWorld
from himit_torch.worlds.tabular import DynamicsTable

__all__ = [
    "GRASPS",
    "ORGANISATIONS",
    "PuzzleBox",
    "SKEWERS_MAX",
    "check_puzzle_box",
    "next_step",
    "organisation_of",
    "organisation_scores",
    "puzzle_box_size",
]

#: Grasps of a hand at a skewer: open (just reached), the learner's power grip, the mentor's pinch.
GRASPS = ("open", "power", "pinch")

#: The two hierarchical organisations of the study: ``"skewer"`` — skewer by skewer (all steps of
#: the first skewer not yet out, then the next); ``"step"`` — step by step across skewers (the
#: next step of the least advanced skewer, the first of ties).
ORGANISATIONS = ("skewer", "step")

#: Most skewers a :class:`PuzzleBox` may have: the largest ``k`` whose box with the fewest steps
#: (2) still has at most :data:`~himit_torch.validation.COUNT_MAX` states (``3^16 · 49``); the
#: number of states is also held to ``COUNT_MAX`` for any ``steps``, before anything is built.
SKEWERS_MAX = 16


def puzzle_box_size(skewers: int, steps: int = 4) -> int:
    """``|S| = (steps + 1)^skewers · (1 + 3·skewers)`` of a :class:`PuzzleBox`.

    Raises:
        ValueError: ``skewers`` not a whole number in ``1 …`` :data:`SKEWERS_MAX`, or ``steps``
            not one in ``2 … COUNT_MAX`` (the box's own bounds; a power of ``10**18`` skewers
            would never finish).
    """
    skewers = as_int("puzzle_box_size: skewers", skewers, 1, SKEWERS_MAX)
    steps = as_int("puzzle_box_size: steps", steps, 2, COUNT_MAX)
    return (steps + 1) ** skewers * (1 + 3 * skewers)


def check_puzzle_box(where: str, box: Any) -> PuzzleBox:
    """``box`` if it is a :class:`PuzzleBox`; else a ``TypeError`` naming ``where`` (the puzzle
    box's helpers are for the box alone: another world, ``None`` or a number is no box)."""
    if not isinstance(box, PuzzleBox):
        raise TypeError(f"{where} must be a PuzzleBox, got {type(box).__name__}")
    return box


def _advances(where: str, advances: Any) -> list[tuple[int, int]]:
    """``advances`` as ``(skewer, step)`` pairs of whole numbers (``1.5`` is no step)."""
    if isinstance(advances, (str, bytes, dict)) or not isinstance(advances, Iterable):
        raise ValueError(
            f"{where} must be a list of (skewer, step) pairs, got {type(advances).__name__}"
        )
    out = []
    for n, pair in enumerate(advances):
        if not isinstance(pair, (tuple, list)) or len(pair) != 2:
            raise ValueError(f"{where}[{n}]={pair!r} must be a (skewer, step) pair")
        out.append((as_int(f"{where}[{n}] skewer", pair[0]), as_int(f"{where}[{n}] step", pair[1])))
    return out


def next_step(progress: Sequence[int], organisation: str, steps: int = 4) -> tuple[int, int]:
    """``(skewer, step)`` an ``organisation`` (:data:`ORGANISATIONS`) does next at ``progress``
    (levels ``p_i``): skewer by skewer, the first skewer not out; step by step, the least advanced
    skewer (the first of ties). ``step`` is 1-based: the level the skewer reaches.

    Raises:
        ValueError: unknown organisation, ``steps`` not a whole number ≥ 2, ``progress`` not a
            non-empty list of whole-number levels in ``0 … steps`` (``1.5`` is no level), or
            every skewer already out.
    """
    if organisation not in ORGANISATIONS:
        raise ValueError(f"organisation={organisation!r}: use one of {ORGANISATIONS}")
    steps = as_int("next_step: steps", steps, 2, COUNT_MAX)
    levels = as_int_array("next_step: progress", progress, 0, steps).tolist()
    if not levels:
        raise ValueError("next_step: progress is empty; give one level per skewer")
    if all(p >= steps for p in levels):
        raise ValueError(f"progress {levels}: every skewer is out, there is no next step")
    if organisation == "skewer":
        skewer = next(i for i, p in enumerate(levels) if p < steps)
    else:
        skewer = min(range(len(levels)), key=lambda i: (levels[i], i))
    return skewer, levels[skewer] + 1


def organisation_of(advances: Sequence[tuple[int, int]], skewers: int, steps: int = 4) -> str:
    """Which organisation a sequence of completed steps follows.

    Args:
        advances: ``(skewer, step)`` pairs in the order they were done (``step`` 1-based, as
            :meth:`PuzzleBox.step_events` gives them).

    Returns:
        ``"skewer"`` (each skewer's steps are done together, one skewer after the other),
        ``"step"`` (every step ``j`` on every skewer before any step ``j + 1``), ``"mixed"`` (every
        step done once, in another order), or ``"incomplete"`` (not every step done exactly once:
        the box was not opened, or a step was undone and redone).
    """
    skewers = as_int("organisation_of: skewers", skewers, 1, SKEWERS_MAX)
    steps = as_int("organisation_of: steps", steps, 1, COUNT_MAX)
    done = _advances("organisation_of: advances", advances)
    if len(done) != skewers * steps or sorted(done) != [
        (i, j) for i in range(skewers) for j in range(1, steps + 1)
    ]:
        return "incomplete"
    blocks = [i for n, (i, _) in enumerate(done) if n == 0 or done[n - 1][0] != i]
    if len(blocks) == skewers:  # each skewer in one run of consecutive steps
        return "skewer"
    if all(a[1] <= b[1] for a, b in zip(done, done[1:])):
        return "step"
    return "mixed"


def organisation_scores(
    advances: Sequence[tuple[int, int]], skewers: int, steps: int = 4, focus: int | None = None
) -> dict[str, float]:
    """How close a complete sequence of steps comes to each organisation, in ``[0, 1]`` (1: that
    organisation exactly); ``nan`` for a sequence that is not every step done once.

    * ``"step"`` — of the pairs of steps on different skewers and at different levels, the
      share done in level order (a lower step first). Step by step: 1; skewer by skewer: 0.5.
    * ``"skewer"`` — how few times the hand changes skewer between consecutive steps:
      ``(k·n − 1 − changes) / (k·n − k)``. Skewer by skewer (``k − 1`` changes): 1; step by step
      (``k·n − 1``): 0.

    ``focus``: the same two scores for one skewer only (0-based) — the pairs that involve it, and
    the number of separate runs its steps are done in (``(n − runs) / (n − 1)``): how far that
    skewer (a new one, say) is fitted into each organisation.

    Raises:
        ValueError: ``skewers < 1`` or ``steps < 2`` (a box of one-step skewers has no
            organisation to score: every order is skewer by skewer, and ``"skewer"`` would divide
            by zero; :class:`PuzzleBox` itself needs ``steps ≥ 2``), or ``focus`` not one of the
            skewers ``0 … skewers − 1``.
    """
    skewers = as_int("organisation_scores: skewers", skewers, 1, SKEWERS_MAX)
    steps = as_int("organisation_scores: steps", steps, 2, COUNT_MAX)
    if focus is not None:
        focus = as_int("organisation_scores: focus", focus, 0, skewers - 1)
    done = _advances("organisation_scores: advances", advances)
    if len(done) != skewers * steps or sorted(done) != [
        (i, j) for i in range(skewers) for j in range(1, steps + 1)
    ]:
        return {"skewer": math.nan, "step": math.nan}
    right = total = 0
    for a in range(len(done)):
        for b in range(a + 1, len(done)):
            (i, j), (i2, j2) = done[a], done[b]
            if i == i2 or j == j2 or (focus is not None and focus not in (i, i2)):
                continue
            total += 1
            right += j < j2
    step = right / total if total else math.nan
    if focus is None:
        changes = sum(x[0] != y[0] for x, y in zip(done, done[1:]))
        skewer = (skewers * steps - 1 - changes) / (skewers * steps - skewers)
    else:
        mine = [i == focus for i, _ in done]
        runs = sum(m and (n == 0 or not mine[n - 1]) for n, m in enumerate(mine))
        skewer = (steps - runs) / (steps - 1)
    return {"skewer": skewer, "step": step}


class PuzzleBox(TableWorld):
    """Whiten et al.'s keyway-fruit box: ``skewers`` skewers of ``steps`` steps, a hand that
    reaches, grips and moves (see the module docstring for the design and why).

    Args:
        skewers: ``1 ≤ k ≤`` :data:`SKEWERS_MAX` (the study: 4, and 5 at its transfer test).
        steps: ``n ≥ 2`` steps per skewer (the study: 4); the box's ``(n+1)^k (1+3k)`` states
            at most :data:`~himit_torch.validation.COUNT_MAX`, and within the memory limit.
        slip: probability that an action fails, in ``[0, 1)`` (the paper's 0.1).
        pinch_slip: probability that the pinch grip fails, and that a motion made in a pinch
            slips, in ``[0, 1)``; default ``slip``.
        step_reward, goal_reward, gamma: as in :class:`~himit_torch.MultiRooms`.
    """

    #: Bytes a state costs while the world is built (tables of ``A·n`` slots): the size check.
    BYTES_PER_STATE = 1024

    def __init__(
        self,
        skewers: int = 4,
        steps: int = 4,
        slip: float = 0.1,
        pinch_slip: float | None = None,
        step_reward: float = -0.01,
        goal_reward: float = 1.0,
        gamma: float = 0.99,
    ):
        k = as_int("PuzzleBox skewers", skewers, minimum=1, maximum=SKEWERS_MAX)
        n = as_int("PuzzleBox steps", steps, minimum=2, maximum=COUNT_MAX)
        if puzzle_box_size(k, n) > COUNT_MAX:
            raise ValueError(
                f"PuzzleBox(skewers={k}, steps={n}) would have {puzzle_box_size(k, n):,} states, "
                f"more than COUNT_MAX = {COUNT_MAX:,} (the library's largest count); choose fewer "
                "skewers or steps"
            )
        slip = as_float("PuzzleBox slip", slip, 0.0, 1.0, high_open=True)
        if pinch_slip is None:
            pinch_slip = slip
        pinch_slip = as_float("PuzzleBox pinch_slip", pinch_slip, 0.0, 1.0, high_open=True)
        step_reward = as_float("PuzzleBox step_reward", step_reward)
        goal_reward = as_float("PuzzleBox goal_reward", goal_reward)
        gamma = as_float("PuzzleBox gamma", gamma, 0.0, 1.0, low_open=True)
        check_memory(
            f"PuzzleBox(skewers={k}, steps={n}) ({puzzle_box_size(k, n):,} states)",
            puzzle_box_size(k, n) * (k + n + 3) * 24 + puzzle_box_size(k, n) * self.BYTES_PER_STATE,
            "choose fewer skewers",
        )
        self.skewers, self.steps, self.slip = k, n, float(slip)
        self.pinch_slip = float(pinch_slip)
        self.step_reward, self.goal_reward = float(step_reward), float(goal_reward)
        self.hand_states = 1 + 3 * k
        self.num_actions = k + n + 3
        self._radix = (n + 1) ** np.arange(k)  # code(p) = Σ p_i (n+1)^i
        names = (
            [f"reach {i + 1}" for i in range(k)]
            + ["withdraw", "power grip", "pinch grip"]
            + [f"motion {j}" for j in range(1, n + 1)]
        )
        S = puzzle_box_size(k, n)
        succ, terminal = self._build_tables()
        state_reward = np.where(terminal, self.goal_reward, self.step_reward)
        # cdf: n − 1 slip slots of q/(n−1) each, then the intended action; q = pinch_slip for
        # the pinch grip and for motions made in a pinch, slip elsewhere
        hand = np.arange(S) % self.hand_states
        in_pinch = (hand > 0) & ((hand - 1) % 3 == 2)
        q = np.full((S, self.num_actions), self.slip)
        q[:, k + 2] = self.pinch_slip
        q[in_pinch, k + 3 :] = self.pinch_slip
        cdf = np.concatenate(
            [q[..., None] * (np.arange(1, n) / (n - 1)), np.ones((S, self.num_actions, 1))], axis=2
        )
        table = DynamicsTable(
            torch.from_numpy(succ),
            torch.from_numpy(cdf),
            torch.from_numpy(state_reward[succ]),
        )
        start = torch.zeros(S, dtype=torch.float64)
        start[0] = 1.0
        super().__init__(
            table,
            start,
            torch.from_numpy(terminal),
            gamma=gamma,
            action_names=names,
            name=f"PuzzleBox(skewers={k}, steps={n})",
        )

    # ----------------------------------------------------------------------------- layout
    @property
    def action_reach(self) -> int:
        """Index of ``reach 1`` (``reach i`` is ``action_reach + i - 1``)."""
        return 0

    @property
    def action_withdraw(self) -> int:
        return self.skewers

    @property
    def action_power(self) -> int:
        return self.skewers + 1

    @property
    def action_pinch(self) -> int:
        return self.skewers + 2

    def action_motion(self, step: int) -> int:
        """Index of ``motion step`` (``step`` 1-based)."""
        step = as_int("PuzzleBox.action_motion: step (a motion is for steps 1 … steps)", step,
                      1, self.steps)  # fmt: skip
        return self.skewers + 2 + step

    def encode(
        self, progress: Sequence[int], skewer: int | None = None, grasp: str = "open"
    ) -> int:
        """The state with skewer levels ``progress`` and the hand home (``skewer=None``) or at
        ``skewer`` (0-based) with ``grasp`` (:data:`GRASPS`)."""
        p = as_int_array("PuzzleBox.encode progress", progress).tolist()  # 1.7 is no level
        if len(p) != self.skewers or not all(0 <= x <= self.steps for x in p):
            raise ValueError(f"progress {p}: give {self.skewers} levels, each in 0 … {self.steps}")
        code = int(np.dot(p, self._radix))
        if skewer is None:
            return code * self.hand_states
        at = as_int("PuzzleBox.encode skewer", skewer)
        if not 0 <= at < self.skewers or grasp not in GRASPS:
            raise ValueError(
                f"hand at skewer {skewer} with {grasp!r}: skewers are 0 … {self.skewers - 1}, "
                f"grasps {GRASPS}"
            )
        return code * self.hand_states + 1 + 3 * at + GRASPS.index(grasp)

    def decode(self, state: int) -> tuple[tuple[int, ...], int | None, str | None]:
        """``(progress, skewer, grasp)`` of ``state``: the levels, and the hand's skewer (0-based)
        and grasp, or ``(None, None)`` when the hand is home."""
        s = as_int("PuzzleBox.decode: state", state, 0, self.num_states - 1)
        code, hand = divmod(s, self.hand_states)
        progress = tuple(int(code // r % (self.steps + 1)) for r in self._radix)
        if hand == 0:
            return progress, None, None
        skewer, grasp = divmod(hand - 1, 3)
        return progress, skewer, GRASPS[grasp]

    def progress(self, states: torch.Tensor) -> torch.Tensor:
        """``[..., k]`` int64 skewer levels of ``states [...]``."""
        code = self._states("PuzzleBox.progress: states", states) // self.hand_states
        radix = torch.from_numpy(self._radix).to(code.device)
        return code[..., None] // radix % (self.steps + 1)

    def hand(self, states: torch.Tensor) -> torch.Tensor:
        """``[...]`` int64 hand index of ``states``: 0 home, ``1 + 3i + g`` at skewer ``i``."""
        return self._states("PuzzleBox.hand: states", states) % self.hand_states

    def _states(self, where: str, states: Any, dim: int | None = None) -> torch.Tensor:
        """``states`` as an int64 tensor of states of this box (whole numbers in ``0 … S − 1``;
        ``9.5``, a bool or a state of a bigger box is refused, never cast)."""
        return as_index_tensor(where, states, 0, self.num_states - 1, dim)

    @property
    def home_mask(self) -> torch.Tensor:
        """``[S]`` bool: the hand is home."""
        return self.hand(torch.arange(self.num_states)) == 0

    def grasp_mask(self, grasp: str) -> torch.Tensor:
        """``[S]`` bool: the hand is at some skewer with ``grasp``."""
        h = self.hand(torch.arange(self.num_states))
        return (h > 0) & ((h - 1) % 3 == GRASPS.index(grasp))

    @property
    def affordances(self) -> torch.Tensor:
        """``[A, S]`` bool: where each action can do something — reaches at home, withdraw at a
        skewer, grips with the hand open, motions while gripping; never at terminal states. The
        primitive options (:func:`~himit_torch.primitive_options`) are usable exactly there."""
        S, k = self.num_states, self.skewers
        h = self.hand(torch.arange(S))
        grasp = torch.where(h > 0, (h - 1) % 3, torch.full_like(h, -1))
        live = ~self.terminal_mask
        out = torch.zeros(self.num_actions, S, dtype=torch.bool)
        out[:k] = (h == 0) & live
        out[k] = (h > 0) & live
        out[k + 1 : k + 3] = (grasp == 0) & live
        out[k + 3 :] = (grasp >= 1) & live
        return out

    # ----------------------------------------------------------------------------- dynamics
    def _build_tables(self) -> tuple[np.ndarray, np.ndarray]:
        """``successors [S, A, n]`` (slots 0 … n−2 the slips, slot n−1 the intended action) and
        the terminal states ``[S]``."""
        k, n, H = self.skewers, self.steps, self.hand_states
        S, A = puzzle_box_size(k, n), self.num_actions
        s = np.arange(S)
        code, hand = np.divmod(s, H)
        levels = code[:, None] // self._radix % (n + 1)  # [S, k]
        at = np.where(hand > 0, (hand - 1) // 3, -1)
        grasp = np.where(hand > 0, (hand - 1) % 3, -1)
        intended = np.repeat(s[:, None], A, axis=1)  # [S, A]: no effect unless changed below
        home = hand == 0
        for i in range(k):
            intended[home, i] = code[home] * H + 1 + 3 * i
        intended[hand > 0, k] = code[hand > 0] * H
        for g, a in ((1, k + 1), (2, k + 2)):
            intended[grasp == 0, a] = s[grasp == 0] + g
        gripping = grasp >= 1
        held = np.where(gripping, levels[np.arange(S), np.maximum(at, 0)], -1)
        bump = self._radix[np.maximum(at, 0)]
        for j in range(1, n + 1):
            do = gripping & (held == j - 1)
            undo = gripping & (held == j)
            intended[do, k + 2 + j] = (code[do] + bump[do]) * H
            intended[undo, k + 2 + j] = (code[undo] - bump[undo]) * H
        succ = np.repeat(s[:, None, None], n, axis=2).repeat(A, axis=1)  # slips: no effect
        succ[:, :, n - 1] = intended
        for j in range(1, n + 1):  # a motion slips to the other motions, in order
            others = [m for m in range(1, n + 1) if m != j]
            for slot, m in enumerate(others):
                succ[:, k + 2 + j, slot] = intended[:, k + 2 + m]
        terminal = (levels == n).all(1)
        return succ, terminal

    def step_events(self, states: Sequence[int] | torch.Tensor) -> list[tuple[int, int, int]]:
        """The steps done and undone along a sequence of states: ``(skewer, step, +1)`` where a
        skewer went from level ``step − 1`` to ``step``, ``(skewer, step, −1)`` where step ``step``
        was undone (skewer 0-based, step 1-based)."""
        p = self.progress(self._states("PuzzleBox.step_events: states", states, 1))
        diff = (p[1:] - p[:-1]).tolist()
        before = p[:-1].tolist()
        events = []
        for d, b in zip(diff, before):
            for i, change in enumerate(d):
                if change == 1:
                    events.append((i, b[i] + 1, 1))
                elif change == -1:
                    events.append((i, b[i], -1))
        return events

    def subgoals(self, states: Sequence[int] | torch.Tensor) -> list[tuple[int, int]]:
        """The ``(skewer, step)`` advances along ``states`` when no step was undone; a sequence
        with an undo yields its net advances in order (what :func:`organisation_of` reads)."""
        done: list[tuple[int, int]] = []
        states = self._states("PuzzleBox.subgoals: states", states, 1)
        for i, j, sign in self.step_events(states):
            if sign > 0:
                done.append((i, j))
            elif (i, j) in done:
                done.remove((i, j))
        return done

    def grasps_used(self, states: Sequence[int] | torch.Tensor) -> list[str]:
        """The grasp the hand held just before each step was done along ``states`` (``power`` —
        the learner's skills — or ``pinch`` — the mentor's), in order."""
        seq = self._states("PuzzleBox.grasps_used: states", states, 1).tolist()
        out = []
        for a, b in zip(seq, seq[1:]):
            events = self.step_events([a, b])
            if events and events[0][2] > 0:
                out.append(self.decode(a)[2] or "none")
        return out

    # ----------------------------------------------------------------------------- queries
    def describe(self) -> dict:
        """A JSON-able description that identifies the box (saved with demonstrations)."""
        return {
            "kind": "PuzzleBox",
            "skewers": self.skewers,
            "steps": self.steps,
            "slip": self.slip,
            "pinch_slip": self.pinch_slip,
            "step_reward": self.step_reward,
            "goal_reward": self.goal_reward,
            "gamma": self.gamma,
        }

    @classmethod
    def from_description(cls, desc: dict) -> PuzzleBox:
        """The box a :meth:`describe` dict names.

        Raises:
            TypeError: ``desc`` is not a dict.
            ValueError: a description of another kind of world, one that lacks a field (naming
                it), or a field the box refuses.
        """
        if not isinstance(desc, dict):
            raise TypeError(
                f"PuzzleBox.from_description: give a PuzzleBox.describe() dict, got "
                f"{type(desc).__name__}"
            )
        if desc.get("kind") != "PuzzleBox":
            raise ValueError(f"description is of a {desc.get('kind')!r} world, not PuzzleBox")
        fields = ("skewers", "steps", "slip", "pinch_slip", "step_reward", "goal_reward", "gamma")
        missing = [name for name in fields if name not in desc]
        if missing:
            raise ValueError(
                f"PuzzleBox description lacks {missing}; a PuzzleBox.describe() dict holds "
                f"{['kind', *fields]}"
            )
        return cls(
            skewers=desc["skewers"],
            steps=desc["steps"],
            slip=desc["slip"],
            pinch_slip=desc["pinch_slip"],
            step_reward=desc["step_reward"],
            goal_reward=desc["goal_reward"],
            gamma=desc["gamma"],
        )

    def render_ansi(self, state: int) -> str:
        """Text picture of a state: one row per skewer, its steps done (``#``) and to do
        (``.``), and where the hand is (``<- open`` / ``<- power`` / ``<- pinch``, or ``hand home``)."""
        progress, at, grasp = self.decode(state)
        rows = []
        for i, p in enumerate(progress):
            bar = "#" * p + "." * (self.steps - p)
            out = " out" if p == self.steps else ""
            hand = f"  <- hand, {grasp}" if at == i else ""
            rows.append(f"skewer {i + 1} [{bar}]{out}{hand}")
        if at is None:
            rows.append("hand home")
        return "\n".join(rows) + "\n"

    def __repr__(self) -> str:
        return (
            f"PuzzleBox(skewers={self.skewers}, steps={self.steps}, slip={self.slip}, "
            f"pinch_slip={self.pinch_slip}, "
            f"S={self.num_states}, A={self.num_actions})"
        )
