"""Coarse observation of the mentor: the learner sees only some states of its episodes.

:func:`observe_every` keeps states ``0, k, 2k, …`` of each episode and always its last state;
:func:`observe_at_option_ends` keeps the states where the mentor's options ended (its subgoals:
a doorway, a key picked up), with the first and the last. Both return
:class:`CoarseDemonstrations`: what the learner is given instead of the full
:class:`~himit_torch.Demonstrations`.

What eq. 2 then needs
    The learner's mentor model ``p_m(s'|s)`` is estimated from consecutive *observed* states, so
    its transitions connect states up to ``k`` primitive steps apart (exactly ``k`` except an
    episode's last pair, which may be shorter): it describes the mentor's ``k``-step moves.
    Eq. 2's mentor term ``R_m(s) + γ Σ_{s'} p_m(s'|s) V(s')`` compares such a move with the
    learner's own options as if it took one step. Read correctly it is an option of the
    mentor's: the term it needs is the SMDP one the learner's own options get,
    ``E[Σ_{i<τ} γ^i r_i + γ^τ V(s')]`` with ``τ`` the move's duration (``k``), which would need
    the reward of the unseen steps and a discount ``γ^k``. By default (the paper's eq. 2) the
    coarse transitions enter the mentor term as they are: it discounts a ``k``-step move once
    and gives it one step's reward (with ``KnownReward``, that of entering ``s'``). It is then
    optimistic for ``k > 1`` (by ``(γ − γ^k) V(s')`` and the missing steps' costs where values
    are positive), and no longer the sound lower bound of the paper's argument: which is what
    the ``observation_stride`` stress measures. With ``LearnerConfig.mentor_segments`` the
    learner scores each observed move as the segment it is
    (:func:`~himit_torch.learner.backups.segment_mentor_backup`): :meth:`CoarseDemonstrations.durations`
    gives each move's duration (the learner knows when it saw each state).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.mentor.policy import MentorRollout
from himit_torch.validation import COUNT_MAX, as_float, as_int, as_int_array

__all__ = [
    "CoarseDemonstrations",
    "first_part",
    "observe_at_option_ends",
    "observe_every",
    "observed_indices",
]


def observed_indices(length: int, stride: int) -> torch.Tensor:
    """``[n]`` int64 positions kept of an episode of ``length`` states (``length ≥ 1``):
    ``0, stride, 2·stride, …`` and always ``length − 1``, sorted, each once."""
    length = as_int("observed_indices length", length, 1, COUNT_MAX)
    stride = as_int("observed_indices stride", stride, 1, COUNT_MAX)
    kept = torch.arange(0, length, stride, dtype=torch.int64)
    if int(kept[-1]) != length - 1:
        kept = torch.cat([kept, torch.tensor([length - 1])])
    return kept


class CoarseDemonstrations:
    """What a learner observing every ``stride``-th mentor state, or the states at the given
    ``positions`` of each episode, sees of ``demonstrations``.

    It offers what :meth:`Learner.add_demonstrations <himit_torch.Learner.add_demonstrations>`,
    the reward modules and the figures read of :class:`~himit_torch.Demonstrations` —
    ``episodes``, ``transitions()``, ``check_world()`` and the counts — over the kept states.
    Its states are checked as the full episodes they come from were (``check_world`` checks
    those); consecutive kept states are up to ``stride`` primitive steps apart, so it is not a
    :class:`~himit_torch.Demonstrations` and is not saved (save the full ones).

    Args:
        demonstrations: the full demonstrations.
        stride: keep states ``0, k, 2k, …`` and the last of each episode; or
        positions: per episode the positions to keep (whole numbers in ``0 … T_e``, any order,
            repeats allowed); the first and the last state are always kept. Give one of the two.

    Attributes:
        full: the demonstrations observed.
        stride: ``k``, or ``None`` where the positions were given.
    """

    def __init__(
        self,
        demonstrations: Demonstrations,
        stride: int | None = None,
        *,
        positions: Sequence[Sequence[int] | torch.Tensor] | None = None,
    ):
        if not isinstance(demonstrations, Demonstrations):
            raise TypeError(
                f"CoarseDemonstrations observes Demonstrations, got {type(demonstrations).__name__}"
            )
        if (stride is None) == (positions is None):
            raise ValueError("CoarseDemonstrations: give either stride or positions, not both")
        self.full = demonstrations
        if positions is None:
            self.stride: int | None = as_int("observation stride", stride, 1, COUNT_MAX)
            kept = [observed_indices(len(e), self.stride) for e in demonstrations.episodes]
        else:
            self.stride = None
            kept = _kept_positions(positions, demonstrations.episodes)
        self._episodes = tuple(e[k].clone() for e, k in zip(demonstrations.episodes, kept))
        # The primitive steps between consecutive kept states: the learner knows when it saw
        # each state (the mentor's time index), so each observed move's duration is known.
        self._durations = tuple(k.diff() for k in kept)

    @property
    def episodes(self) -> tuple[torch.Tensor, ...]:
        """Per episode an int64 tensor of the observed states."""
        return self._episodes

    @property
    def num_episodes(self) -> int:
        return len(self._episodes)

    @property
    def num_transitions(self) -> int:
        """Number of consecutive observed pairs over all episodes."""
        return sum(len(e) - 1 for e in self._episodes)

    def transitions(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``(from [T], to [T])`` int64: consecutive observed pairs, all episodes, in order
        (each up to ``stride`` primitive steps; never across episodes)."""
        return (
            torch.cat([e[:-1] for e in self._episodes]),
            torch.cat([e[1:] for e in self._episodes]),
        )

    def durations(self) -> torch.Tensor:
        """``[T]`` int64: the primitive steps each pair of :meth:`transitions` spans, in the same
        order: ``stride``, except an episode's last pair, which may be shorter. The learner's
        segment term (``LearnerConfig.mentor_segments``) discounts each move by them."""
        return torch.cat(self._durations)

    def visited_states(self) -> torch.Tensor:
        """Sorted unique int64 observed states."""
        return torch.unique(torch.cat(self._episodes))

    def check_world(self, world) -> None:
        """As :meth:`Demonstrations.check_world <himit_torch.Demonstrations.check_world>` of the
        full demonstrations (the kept states are theirs)."""
        self.full.check_world(world)

    @property
    def world_description(self) -> dict:
        return self.full.world_description

    def __len__(self) -> int:
        return self.num_episodes

    def __iter__(self):
        return iter(self._episodes)

    def __getitem__(self, index: int) -> torch.Tensor:
        return self._episodes[index]

    def __repr__(self) -> str:
        how = f"stride={self.stride}" if self.stride is not None else "positions given"
        return (
            f"CoarseDemonstrations({how}, episodes={self.num_episodes}, "
            f"transitions={self.num_transitions})"
        )


def _kept_positions(positions, episodes: Sequence[torch.Tensor]) -> list[torch.Tensor]:
    """Per episode the sorted unique positions of ``positions``, with its first and last."""
    if isinstance(positions, (str, bytes, torch.Tensor)) or not isinstance(positions, Sequence):
        raise TypeError(
            "CoarseDemonstrations: positions must be a sequence with one sequence of positions "
            f"per episode, got {type(positions).__name__}"
        )
    if len(positions) != len(episodes):
        raise ValueError(
            f"CoarseDemonstrations: {len(positions)} lists of positions for {len(episodes)} "
            "episodes; give one per episode"
        )
    kept = []
    for e, (given, episode) in enumerate(zip(positions, episodes)):
        last = len(episode) - 1
        at = as_int_array(f"CoarseDemonstrations: positions[{e}]", given, 0, last)
        both_ends = torch.tensor([0, last], dtype=torch.int64)
        kept.append(torch.unique(torch.cat([torch.from_numpy(at).reshape(-1), both_ends])))
    return kept


def observe_every(
    demonstrations: Demonstrations, stride: int
) -> Demonstrations | CoarseDemonstrations:
    """``demonstrations`` as a learner seeing every ``stride``-th state sees them: the same
    object for ``stride = 1``, else :class:`CoarseDemonstrations`."""
    stride = as_int("observation stride", stride, 1, COUNT_MAX)
    return demonstrations if stride == 1 else CoarseDemonstrations(demonstrations, stride)


def observe_at_option_ends(rollout: MentorRollout, world) -> CoarseDemonstrations:
    """The mentor's episodes as a learner sees them that watches only where the mentor's options
    end — its subgoals (a doorway reached, a key picked up, a door opened) — and the first and
    last state: the paper's goal-based imitation, the subgoals without the movements.

    ``rollout`` is :func:`~himit_torch.mentor.policy.run_mentor`'s, whose ``decision_steps``
    say where each option began (and so where the one before it ended); ``world`` the world it
    ran in. Each observed move is one of the mentor's options, its duration known to the learner
    (:meth:`CoarseDemonstrations.durations`, read by ``LearnerConfig.mentor_segments``).

    >>> from himit_torch import MultiRooms, mentor_options, mentor_policy, run_mentor
    >>> world = MultiRooms(8, 2)
    >>> rollout = run_mentor(world, mentor_policy(world, mentor_options(world)), 1, seed=0)
    >>> seen = observe_at_option_ends(rollout, world)
    >>> seen.num_transitions < len(rollout.states[0]) - 1
    True
    """
    if not isinstance(rollout, MentorRollout):
        raise TypeError(
            f"observe_at_option_ends observes a MentorRollout (run_mentor's), got "
            f"{type(rollout).__name__}"
        )
    if len(rollout.decision_steps) != len(rollout.states):
        raise ValueError(
            "observe_at_option_ends: the rollout does not say where its options began "
            "(decision_steps); make it with run_mentor"
        )
    demonstrations = Demonstrations(list(rollout.states), world)
    return CoarseDemonstrations(demonstrations, positions=list(rollout.decision_steps))


def first_part(demonstrations: Demonstrations, coverage: float) -> Demonstrations:
    """Demonstrations that cover only part of the way: each episode's first
    ``⌈coverage · T⌉`` states (``T`` its states; at least two, one move), as
    :class:`~himit_torch.Demonstrations` of the same world. ``coverage = 1`` keeps everything.
    Anything but :class:`~himit_torch.Demonstrations` (a list, ``None``, a path) is a
    ``TypeError``; a coverage outside ``(0, 1]`` a ``ValueError``.

    >>> import torch
    >>> from himit_torch import Demonstrations, MultiRooms
    >>> demos = Demonstrations([torch.tensor([0, 1, 9, 10, 18])], MultiRooms(8, 2))
    >>> first_part(demos, 0.5).episodes[0].tolist()
    [0, 1, 9]
    """
    if not isinstance(demonstrations, Demonstrations):
        raise TypeError(
            f"first_part: demonstrations must be Demonstrations, got "
            f"{type(demonstrations).__name__}; read a file with Demonstrations.load(path)"
        )
    coverage = as_float("first_part: coverage", coverage, 0.0, 1.0, low_open=True)
    episodes = [
        e[: max(2, math.ceil(coverage * e.numel()))] if e.numel() > 2 else e
        for e in demonstrations.episodes
    ]
    return Demonstrations(episodes, demonstrations.world_description)
