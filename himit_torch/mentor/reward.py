"""Reward the learner assigns to the mentor's observed transitions (``R_m`` of eq. 2).

A reward module maps mentor transitions ``s → s'`` to rewards ``r_m(s, s')``, batched. The
mentor term at ``s`` is ``R_m(s) + γ Σ_{s'} p_m(s'|s) V(s')`` with
``R_m(s) = Σ_{s'} p_m(s'|s) r_m(s, s')`` (:class:`~himit_torch.Learner` computes it).

Soundness
    The mentor term enters a max with the learner's own option values and is never corrected by
    the learner's own experience. It is a sound *lower bound* on what the learner can achieve by
    repeating the mentor's moves only if ``r_m`` never overestimates the learner's real reward:
    ``r_m(s, s') ≤ r(s, s')`` on every transition (the paper, after eq. 2). Two checks follow
    from this, both done by the learner:

    * a module declares ``upper_bound`` (the most it ever returns), and the learner compares it
      with its best real reward for one step (``world.state_reward.max()``; +1.0 at the goal
      of :class:`~himit_torch.MultiRooms`; worlds without ``state_reward`` are not checked)
      — an error, a warning or nothing, as
      :attr:`LearnerConfig.reward_bound_check <himit_torch.LearnerConfig.reward_bound_check>`
      says;
    * a module that returns more than its own ``upper_bound``, NaN/∞, or the wrong shape is an
      error, always.

    The declared bound is a *necessary* condition only. An intrinsic module cannot know the real
    reward of each transition, so it must assume something; two levels:

    * **cycle safety** — no reward above 0 except where the mentor's episodes end. A positive
      reward on a transition the learner can come back to (a doorway it can step through and
      back) is a reward it can farm: its mentor term keeps promising it on every pass while the
      learner pays the real step cost, so it oscillates there for good.
    * **soundness** — every step costs at least the real step cost and the end pays at most the
      real goal reward. Then the mentor term is a pessimistic lower bound and the learner's own
      experience corrects it. :class:`SalienceReward` is sound for MultiRooms' default rewards
      (−0.01 a step, +1 at the goal) with its defaults, and cycle-safe
      (:attr:`SalienceReward.cycle_safe`).

    ``notebooks/intrinsic_reward.ipynb`` measures both on the 40×40 world: the more ``R_m``
    overestimates, the worse the learner does, and a reward it can farm stops it altogether.

Modules
    :class:`KnownReward` — the world's own reward (the paper's experiments, ``R_m = R_obs``).
    :class:`SalienceReward` — intrinsic reward from salient events in the mentor's states
    alone, with no knowledge of the world's reward.
    :class:`ZeroReward` — no reward of its own (``r_m = 0``): the mentor term only carries the
    values of the states the mentor moves to.
    Any object with ``upper_bound`` and ``transition_reward`` works (:class:`MentorReward`).
"""

from __future__ import annotations

import math
import operator
from collections.abc import Iterable, Mapping, Sequence
from typing import Protocol, runtime_checkable

import torch

__all__ = [
    "MentorReward",
    "KnownReward",
    "SalienceReward",
    "ZeroReward",
    "SALIENCE_EVENTS",
    "MENTOR_REWARDS",
    "mentor_reward_module",
]


@runtime_checkable
class MentorReward(Protocol):
    """What the learner needs from a reward module.

    Soundness condition: ``transition_reward`` must not overestimate the learner's real reward
    (see the module docstring); ``upper_bound`` declares the most it returns, and must not
    exceed the learner's best real reward for one step.
    """

    #: The largest reward the module can give; must not exceed the learner's real best reward.
    upper_bound: float

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        """``[n]`` finite rewards ``≤ upper_bound`` for the mentor transitions
        ``sources[i] → successors[i]`` (``[n]`` int64 states each)."""
        ...


class KnownReward:
    """The world's own reward (the paper's experiments: ``R_m = R_obs``): what the learner itself
    would get for the mentor's observed move ``s → s'``.

    Worlds with ``state_reward [S]`` (MultiRooms): the reward for entering ``s'``.

    Worlds with rewards per transition ``(s, a, s')`` (a ``dynamics_table()``: Gymnasium's
    Taxi, CliffWalking, …): the reward of the pair ``(s, s')`` where every action that can make
    that move pays the same. Where it depends on the unseen action — Taxi's illegal pick-up
    (−10) and a move into a wall (−1) both leave the taxi where it is — it takes the **least**
    reward among the actions (and outcomes) that make the move with positive probability. That
    never overestimates: whatever action the learner uses to reproduce the move, it gets at least
    this much, so the mentor term stays the sound lower bound eq. 2 needs (the maximum or the mean
    could promise more than the learner's action pays). ``ambiguous_pairs`` counts such
    pairs and ``note`` says what was done, from construction on; ``repr`` shows it.

    A pair ``(s, s')`` that no action can produce raises ``ValueError`` (demonstrations of
    another world).
    """

    def __init__(self, world):
        state_reward = getattr(world, "state_reward", None)
        self._pairs = None
        self.ambiguous_pairs = 0
        if state_reward is not None:
            self.state_reward = torch.as_tensor(state_reward).double()
            if not bool(torch.isfinite(self.state_reward).all()):
                raise ValueError(
                    "KnownReward: the world's state_reward holds NaN or infinite values"
                )
            self.upper_bound = float(self.state_reward.max())
            self.note = "reward for entering s' (the world's state_reward)"
            return
        if not hasattr(world, "dynamics_table"):
            raise ValueError(
                f"KnownReward: {type(world).__name__} has neither state_reward [S] nor "
                "a dynamics_table() with rewards per transition; give the learner "
                "another reward module (reward=…)"
            )
        self.state_reward = None
        keys, low, ambiguous = _pair_rewards(world)
        if not bool(torch.isfinite(low).all()):
            raise ValueError(
                "KnownReward: the world's transition rewards hold NaN or infinite values"
            )
        self._pairs = (keys, low, int(world.num_states))
        self.ambiguous_pairs = ambiguous
        if keys.numel() == 0:
            raise ValueError("KnownReward: the world has no transition out of a non-terminal state")
        self.upper_bound = float(low.max())
        self.note = (
            f"reward of the observed pair (s, s'); in {ambiguous} of {keys.numel()} possible "
            "pairs it depends on the unseen action, and there the least reward of the "
            "actions that make the move is used (never an overestimate)"
            if ambiguous
            else "reward of the observed pair (s, s'): it never depends on "
            "the unseen action in this world"
        )

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        if self._pairs is None:
            return self.state_reward.to(successors.device)[successors]
        keys, low, S = self._pairs
        dev = successors.device
        keys, low = keys.to(dev), low.to(dev)
        query = sources.to(torch.int64) * S + successors.to(torch.int64)
        pos = torch.searchsorted(keys, query).clamp(max=keys.numel() - 1)  # keys never empty
        found = keys[pos] == query
        if not bool(found.all()):
            i = int((~found).nonzero()[0, 0])
            raise ValueError(
                f"KnownReward: the mentor move {int(sources[i])} → {int(successors[i])} is "
                "impossible in this world (no action makes it); were the "
                "demonstrations recorded in another world?"
            )
        return low[pos]

    def __repr__(self) -> str:
        return f"KnownReward({self.note})"


def _pair_rewards(world) -> tuple[torch.Tensor, torch.Tensor, int]:
    """Sorted keys ``s·S + s'`` of every possible move out of a non-terminal state, the least
    reward of each, and how many pairs have more than one reward."""
    table = world.dynamics_table()
    S = int(world.num_states)
    prob = torch.diff(table.cdf, dim=-1, prepend=torch.zeros_like(table.cdf[..., :1])).cpu()
    terminal = torch.as_tensor(world.terminal_mask, dtype=torch.bool).cpu()
    live = (prob > 0) & ~terminal[:, None, None]
    src = torch.arange(S)[:, None, None].expand_as(prob)[live]
    key = src * S + table.successors.cpu()[live]
    reward = table.rewards.cpu().double()[live]
    keys, inverse = torch.unique(key, return_inverse=True)
    low = torch.full((keys.numel(),), float("inf"), dtype=torch.float64).scatter_reduce(
        0, inverse, reward, "amin"
    )
    high = torch.full_like(low, -float("inf")).scatter_reduce(0, inverse, reward, "amax")
    return keys, low, int((high > low).sum())


class ZeroReward:
    """No reward of the mentor's own: ``r_m(s, s') = 0`` on every mentor transition, so the
    mentor term at ``s`` is ``γ Σ_{s'} p_m(s'|s) V(s')`` — it passes on the values of the states
    the mentor moves to and nothing else (``upper_bound = 0``).

    Cycle-safe (nothing pays more than 0), but not sound where steps cost something: it
    overestimates every real step cost (MultiRooms' −0.01) by that cost. It is the "no reward
    model" control of the ``mentor_reward`` setting (:data:`MENTOR_REWARDS`).
    """

    upper_bound = 0.0

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        sources = torch.as_tensor(sources)
        if sources.shape != torch.as_tensor(successors).shape or sources.ndim != 1:
            raise ValueError(
                "ZeroReward.transition_reward: sources and successors must both be [n]"
            )
        return torch.zeros(sources.shape, dtype=torch.float64, device=sources.device)

    def __repr__(self) -> str:
        return "ZeroReward(r_m = 0)"


#: The mentor-reward modules an experiment can name (``ExperimentConfig.mentor_reward``,
#: ``himit run --mentor-reward``): ``"known"`` (:class:`KnownReward`, the paper's),
#: ``"salience"`` (:class:`SalienceReward` with its defaults, fitted on each run's own
#: demonstrations) and ``"none"`` (:class:`ZeroReward`).
MENTOR_REWARDS = ("known", "salience", "none")


def mentor_reward_module(name: str, world, demonstrations=None):
    """The reward module named ``name`` (one of :data:`MENTOR_REWARDS`) for ``world``;
    ``"salience"`` is fitted on ``demonstrations`` (required for it).

    Raises:
        ValueError: an unknown name, or ``"salience"`` without demonstrations.
    """
    if name == "known":
        return KnownReward(world)
    if name == "salience":
        if demonstrations is None:
            raise ValueError(
                "mentor_reward='salience' is fitted on the mentor's demonstrations; "
                "give demonstrations=…"
            )
        return SalienceReward(world, demonstrations)
    if name == "none":
        return ZeroReward()
    raise ValueError(f"mentor_reward={name!r} is unknown; use one of {list(MENTOR_REWARDS)}")


#: Salient event kinds of :class:`SalienceReward` (the keys of its ``weights``).
SALIENCE_EVENTS = ("room", "end", "novelty", "stimulus")

_DEFAULT_WEIGHTS = {"room": 1.0, "end": 1.0, "novelty": 0.25, "stimulus": 1.0}
_NOT_STIMULI = ("room", "doorway")  # descriptive columns, not stimulus channels by default
_SAME = 1e-9  # feature values closer than this are "unchanged"


class SalienceReward:
    """Intrinsic mentor reward from salient events in the mentor's states alone (Section II).

    As the mentor moves it triggers salient stimuli; the observer rewards the transitions where
    they happen. Nothing here uses the world's reward: the goal is learned from where the
    mentor's episodes stop.

    Events of a mentor transition ``s → s'``, each in ``[0, 1]``:

    * ``room`` — entering a room from outside it: ``room(s') ≠ 0`` and ``room(s') ≠ room(s)``
      (the ``"room"`` feature column; 0 = no room, e.g. a doorway). In MultiRooms this is the
      step from a doorway into a room.
    * ``end`` — ``ε(s')``: the share of the mentor's arrivals at ``s'`` that ended its episode
      (1 at the goal, 0 where it always went on).
    * ``novelty`` — ``decay ** (n(s') − 1)``, ``n`` = how often ``s'`` occurs in the mentor's
      episodes: a state seen once is fully novel, each further sighting multiplies by ``decay``
      (habituation); rare states — the mentor's slips — stand out.
    * ``stimulus`` — ``min(1, Σ_c |x_c(s') − x_c(s)|)`` over the stimulus channels ``c`` (by
      default every feature column but ``"room"`` and ``"doorway"``: MultiRooms' ``"light"``
      and ``"sound"``): a lamp switching on, a sound starting.

    With weights ``w``, the step salience and the end weight are
    ``σ = clip(w_room·room + w_novelty·novelty + w_stimulus·stimulus, 0, 1)`` and
    ``e = clip(w_end·ε(s'), 0, 1)``, and the reward interpolates between a terminal reward and a
    step reward::

        r_m(s, s') = min(bound, e · bound + (1 − e) · (scale · σ − step_cost))

    Defaults and soundness: ``bound = 0.5`` is the module's ``upper_bound``, the reward where the
    mentor's episodes end — safely below MultiRooms' +1.0 goal, so the learner's bound check
    passes; it must not exceed the learner's best real reward for one step. ``step_cost = 0.02,
    scale = 0.01``: an ordinary mentor step costs 0.02 and a fully salient one 0.01, never less
    than MultiRooms' real step cost of 0.01 — so with MultiRooms' default rewards the module never
    overestimates any transition (sound, see the module docstring), and no step but an episode's
    end pays more than 0 (:attr:`cycle_safe`). Salience makes the mentor's salient steps *less
    costly*, not rewarding. With ``scale = step_cost`` salient steps are free: cycle-safe, but
    optimistic; with ``scale > step_cost`` they pay, and a learner farms them by stepping back
    and forth (``notebooks/intrinsic_reward.ipynb`` shows both). For other worlds, choose
    ``step_cost − scale`` ≥ the real cost of a step. The end reward is only safe where episodes
    really end for the learner (its terminal states); demonstrations cut short elsewhere make
    their last state look like a goal.

    Args:
        world: the world (``num_states``; ``stimulus_features()`` and ``stimulus_feature_names``
            unless ``features`` is given; ``check_world`` of demonstrations is called with it).
        demonstrations: mentor episodes to fit on now (see :meth:`fit`); or call :meth:`fit`.
        features: ``[S, F]`` stimulus features of your own instead of the world's.
        feature_names: ``F`` column names of ``features`` (``"room"`` marks the room column);
            default for your own features: no room column, every column a stimulus channel.
        stimulus_channels: names of the columns whose changes are ``stimulus`` events (default:
            all but ``"room"`` and ``"doorway"``).
        weights: per event kind (:data:`SALIENCE_EVENTS`), ``≥ 0``; missing kinds keep their
            defaults (room 1, end 1, novelty 0.25, stimulus 1).
        scale: reward of a fully salient step (``σ = 1``) before the step cost, ``≥ 0``.
        step_cost: cost of every mentor step, ``≥ 0``; a step's reward lies in
            ``[−step_cost, scale − step_cost]`` (:attr:`step_reward_range`).
        decay: habituation factor of ``novelty`` per sighting, in ``[0, 1]``.
        bound: reward where episodes end, and the module's ``upper_bound``, ``≥ 0``.

    Raises:
        ValueError: naming ``SalienceReward`` and the problem (features of the wrong shape,
            unknown weights or channels, bad settings, demonstrations of another world).
    """

    def __init__(
        self,
        world,
        demonstrations=None,
        *,
        features: torch.Tensor | None = None,
        feature_names: Sequence[str] | None = None,
        stimulus_channels: Sequence[str] | None = None,
        weights: Mapping[str, float] | None = None,
        scale: float = 0.01,
        step_cost: float = 0.02,
        decay: float = 0.5,
        bound: float = 0.5,
    ):
        self.world = world
        S = self.num_states = _positive_int(getattr(world, "num_states", None))
        self.features, self.feature_names = _features(world, S, features, feature_names)
        names = list(self.feature_names)
        if stimulus_channels is None:
            stimulus_channels = [n for n in names if n not in _NOT_STIMULI]
        unknown = [c for c in stimulus_channels if c not in names]
        if unknown:
            raise ValueError(
                f"SalienceReward: stimulus_channels {unknown} are not feature columns; "
                f"the columns are {names}"
            )
        self.stimulus_channels = tuple(stimulus_channels)
        self._room_column = names.index("room") if "room" in names else None
        self._stimulus_columns = torch.tensor(
            [names.index(c) for c in self.stimulus_channels], dtype=torch.int64
        )
        self.weights = dict(_DEFAULT_WEIGHTS)
        for kind, w in (weights or {}).items():
            if kind not in SALIENCE_EVENTS:
                raise ValueError(
                    f"SalienceReward: unknown event kind {kind!r} in weights; use "
                    f"{list(SALIENCE_EVENTS)}"
                )
            self.weights[kind] = _non_negative(f"weights[{kind!r}]", w)
        self.scale = _non_negative("scale", scale)
        self.step_cost = _non_negative("step_cost", step_cost)
        self.bound = _non_negative("bound", bound)
        self.decay = _non_negative("decay", decay)
        if self.decay > 1.0:
            raise ValueError(f"SalienceReward: decay={decay!r} must lie in [0, 1]")
        self.upper_bound = self.bound
        self.num_episodes = 0
        self._visits = torch.zeros(S, dtype=torch.float64)
        self._arrivals = torch.zeros(S, dtype=torch.float64)
        self._ends = torch.zeros(S, dtype=torch.float64)
        empty = torch.zeros(0, dtype=torch.int64)
        self._arrival_pairs = (empty, empty)
        self._device_cache: dict[torch.device, tuple[torch.Tensor, ...]] = {}
        if demonstrations is not None:
            self.fit(demonstrations)

    # ------------------------------------------------------------------------------- fitting
    def fit(self, demonstrations) -> SalienceReward:
        """Estimate the mentor statistics (visits, arrivals, episode ends) from its episodes.

        ``demonstrations``: a :class:`~himit_torch.Demonstrations` (checked against the world),
        or any iterable of 1-D state sequences, one per episode. Replaces earlier fits. After
        adding demonstrations to a learner, fit the module on the same ones and call the
        learner's ``refresh_mentor_reward()``. Returns ``self``.
        """
        if hasattr(demonstrations, "check_world"):
            try:
                demonstrations.check_world(self.world)
            except ValueError as err:
                raise ValueError(f"SalienceReward.fit: {err}") from None
        episodes = getattr(demonstrations, "episodes", demonstrations)
        if not isinstance(episodes, Iterable):
            raise ValueError(
                "SalienceReward.fit: demonstrations must be Demonstrations or a list of "
                "1-D state sequences (one per episode)"
            )
        S = self.num_states
        visits = torch.zeros(S, dtype=torch.float64)
        arrivals, ends = torch.zeros_like(visits), torch.zeros_like(visits)
        pairs = []
        count = 0
        for i, ep in enumerate(episodes):
            ep = torch.as_tensor(ep)
            if ep.ndim != 1 or ep.numel() == 0 or ep.is_floating_point():
                raise ValueError(
                    f"SalienceReward.fit: episode {i} must be a non-empty 1-D sequence "
                    "of integer states"
                )
            ep = ep.to(torch.int64).cpu()
            if int(ep.min()) < 0 or int(ep.max()) >= S:
                raise ValueError(f"SalienceReward.fit: episode {i} holds states outside 0…{S - 1}")
            count += 1
            visits += torch.bincount(ep, minlength=S).double()
            if ep.numel() > 1:
                arrivals += torch.bincount(ep[1:], minlength=S).double()
                ends[ep[-1]] += 1
                pairs.append((ep[:-1], ep[1:]))
        if count == 0:
            raise ValueError("SalienceReward.fit: no episodes; give at least one mentor episode")
        self._visits, self._arrivals, self._ends = visits, arrivals, ends
        self.num_episodes = count
        self._device_cache.clear()
        empty = torch.zeros(0, dtype=torch.int64)
        self._arrival_pairs = (
            (torch.cat([p[0] for p in pairs]), torch.cat([p[1] for p in pairs]))
            if pairs
            else (empty, empty)
        )  # a refit replaces everything
        return self

    @property
    def fitted(self) -> bool:
        """Whether :meth:`fit` has seen demonstrations."""
        return self.num_episodes > 0

    # -------------------------------------------------------------------------------- events
    def end_rate(self) -> torch.Tensor:
        """``[S]`` ``ε(s)``: share of the mentor's arrivals at ``s`` that ended its episode."""
        return torch.where(
            self._arrivals > 0,
            self._ends / self._arrivals.clamp(min=1),
            torch.zeros_like(self._ends),
        )

    def novelty(self) -> torch.Tensor:
        """``[S]`` ``decay ** (n(s) − 1)`` (1 where the mentor never was)."""
        return self.decay ** (self._visits - 1).clamp(min=0)

    def events(self, sources: torch.Tensor, successors: torch.Tensor) -> dict[str, torch.Tensor]:
        """Per event kind (:data:`SALIENCE_EVENTS`) a ``[n]`` float64 tensor in ``[0, 1]`` for the
        transitions ``sources[i] → successors[i]`` (on the CPU)."""
        self._require_fitted()
        src, dst = self._check_states(sources, successors)
        src, dst = src.cpu(), dst.cpu()
        return self._events(src, dst, self.end_rate(), self.novelty())

    def _events(self, src, dst, end_rate, novelty) -> dict[str, torch.Tensor]:
        f = self.features.to(src.device)
        if self._room_column is None:
            room = torch.zeros(src.shape, dtype=torch.float64, device=src.device)
        else:
            r_from, r_to = f[src, self._room_column], f[dst, self._room_column]
            room = ((r_to.abs() > _SAME) & ((r_to - r_from).abs() > _SAME)).double()
        cols = self._stimulus_columns.to(src.device)
        change = (f[dst][:, cols] - f[src][:, cols]).abs().sum(1)
        stimulus = torch.where(change > _SAME, change, torch.zeros_like(change)).clamp(max=1.0)
        return {"room": room, "end": end_rate[dst], "novelty": novelty[dst], "stimulus": stimulus}

    def _step_and_end(self, ev: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        w = self.weights
        sigma = (
            w["room"] * ev["room"] + w["novelty"] * ev["novelty"] + w["stimulus"] * ev["stimulus"]
        ).clamp(0.0, 1.0)
        end = (w["end"] * ev["end"]).clamp(0.0, 1.0)
        return sigma, end

    # ------------------------------------------------------------------------------ rewards
    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        """``[n]`` float64 ``r_m(s, s')`` (class docstring) on the inputs' device; finite and
        ``≤ upper_bound``. Transitions the mentor never made get the same formula (their
        ``end`` and ``novelty`` come from the states' statistics)."""
        self._require_fitted()
        src, dst = self._check_states(sources, successors)
        device = dst.device
        tables = self._device_cache.get(device)
        if tables is None:
            tables = (self.end_rate().to(device), self.novelty().to(device))
            self._device_cache[device] = tables
        sigma, end = self._step_and_end(self._events(src, dst, *tables))
        reward = end * self.bound + (1.0 - end) * (self.scale * sigma - self.step_cost)
        return reward.clamp(max=self.bound)

    @property
    def step_reward_range(self) -> tuple[float, float]:
        """``(least, most)`` reward of a mentor step that ends no episode: ``(−step_cost,
        scale − step_cost)``. Sound if ``most`` ≤ the real reward of every step."""
        return (-self.step_cost, min(self.bound, self.scale - self.step_cost))

    @property
    def cycle_safe(self) -> bool:
        """True when no transition but an episode's end can pay more than 0
        (``scale ≤ step_cost``): a learner cannot farm the reward by stepping back and forth."""
        return self.scale <= self.step_cost

    # ----------------------------------------------------------------------------- plotting
    def salience_map(self) -> torch.Tensor:
        """``[S]`` float64 in ``[0, 1]``: the total salience ``clip(Σ_k w_k · event_k, 0, 1)`` of
        the mentor's arrivals at each state, averaged over them (0 where it never arrived)."""
        self._require_fitted()
        S = self.num_states
        src, dst = self._arrival_pairs
        ev = self._events(src, dst, self.end_rate(), self.novelty())
        total = (
            torch.stack([self.weights[k] * ev[k] for k in SALIENCE_EVENTS]).sum(0).clamp(0.0, 1.0)
        )
        return _mean_over_arrivals(total, dst, self._arrivals, S)

    def event_maps(self) -> dict[str, torch.Tensor]:
        """Per event kind a ``[S]`` map: the event's mean over the mentor's arrivals at each
        state (unweighted; 0 where it never arrived)."""
        self._require_fitted()
        src, dst = self._arrival_pairs
        ev = self._events(src, dst, self.end_rate(), self.novelty())
        return {
            k: _mean_over_arrivals(ev[k], dst, self._arrivals, self.num_states)
            for k in SALIENCE_EVENTS
        }

    # ------------------------------------------------------------------------------ checking
    def _require_fitted(self) -> None:
        if not self.fitted:
            raise ValueError(
                "SalienceReward: not fitted on any mentor episodes; pass "
                "demonstrations=… or call fit(demonstrations) first"
            )

    def _check_states(self, sources, successors) -> tuple[torch.Tensor, torch.Tensor]:
        src, dst = torch.as_tensor(sources), torch.as_tensor(successors)
        if src.ndim != 1 or src.shape != dst.shape:
            raise ValueError(
                f"SalienceReward.transition_reward: sources {tuple(src.shape)} and "
                f"successors {tuple(dst.shape)} must both be [n]"
            )
        if src.is_floating_point() or dst.is_floating_point():
            raise ValueError("SalienceReward.transition_reward: states must be integer tensors")
        src, dst = src.to(torch.int64), dst.to(device=src.device, dtype=torch.int64)
        if src.numel() and (
            int(torch.minimum(src.min(), dst.min())) < 0
            or int(torch.maximum(src.max(), dst.max())) >= self.num_states
        ):
            raise ValueError(
                f"SalienceReward.transition_reward: states outside 0…{self.num_states - 1}"
            )
        return src, dst

    def __repr__(self) -> str:
        w = ", ".join(f"{k}={v:g}" for k, v in self.weights.items())
        return (
            f"SalienceReward(bound={self.bound:g}, scale={self.scale:g}, "
            f"step_cost={self.step_cost:g}, decay={self.decay:g}, weights=({w}), "
            f"episodes={self.num_episodes})"
        )


def _mean_over_arrivals(
    values: torch.Tensor, dst: torch.Tensor, arrivals: torch.Tensor, S: int
) -> torch.Tensor:
    """``[S]``: ``values`` of the arrivals ``dst`` averaged per state (0 where none)."""
    total = torch.zeros(S, dtype=torch.float64).index_add_(0, dst, values.double())
    return torch.where(arrivals > 0, total / arrivals.clamp(min=1), total)


def _non_negative(name: str, value) -> float:
    """``value`` as a finite float ``≥ 0``, or a ValueError naming the setting."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        number = float("nan")
    if not (math.isfinite(number) and number >= 0):
        raise ValueError(f"SalienceReward: {name}={value!r} must be a finite number ≥ 0")
    return number


def _positive_int(value) -> int:
    try:
        n = operator.index(value)
    except TypeError:
        n = 0
    if isinstance(value, bool) or n < 1:
        raise ValueError(f"SalienceReward: the world must have num_states ≥ 1, got {value!r}")
    return n


def _features(world, S: int, features, names) -> tuple[torch.Tensor, tuple[str, ...]]:
    """The ``[S, F]`` float64 features and their column names, checked."""
    if features is None:
        if not hasattr(world, "stimulus_features"):
            raise ValueError(
                f"SalienceReward: {type(world).__name__} has no stimulus_features(); "
                f"give features=[S={S}, F] of your own"
            )
        features = world.stimulus_features()
        if names is None:
            names = getattr(world, "stimulus_feature_names", None)
    f = torch.as_tensor(features, dtype=torch.float64).detach().cpu()
    if f.ndim != 2 or f.shape[0] != S or f.shape[1] < 1:
        raise ValueError(
            f"SalienceReward: features have shape {tuple(f.shape)}, expected "
            f"[S={S}, F] (one row per state of the world, F ≥ 1 columns)"
        )
    if not bool(torch.isfinite(f).all()):
        raise ValueError("SalienceReward: features hold NaN or infinite values")
    F = f.shape[1]
    if names is None:
        names = tuple(f"channel{i}" for i in range(F))
    names = tuple(str(n) for n in names)
    if len(names) != F or len(set(names)) != F:
        raise ValueError(
            f"SalienceReward: feature_names {list(names)} must be {F} distinct names, "
            f"one per feature column"
        )
    return f, names
