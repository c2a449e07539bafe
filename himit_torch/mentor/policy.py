"""The mentor: an optimal policy over its own options, and state-only demonstrations of it.

The paper's mentor "executes an optimal policy (with respect to its given options) which takes it
along the diagonal from the top-left state to the bottom-right state along the walls of the
rooms" (Section III, Fig. 2). Its options are :func:`~himit_torch.mentor_options`: primitives plus
doorway options that travel along each room's walls.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from himit_torch.exact.option_models import option_models
from himit_torch.exact.planning import greedy_option_policy, smdp_value_iteration
from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.options.builders import mentor_options
from himit_torch.options.bundle import Options
from himit_torch.options.execution import OptionTables, option_step, option_step_in_numbers
from himit_torch.validation import COUNT_MAX, as_float, as_int, check_memory
from himit_torch.worlds.multirooms import MultiRooms, detour_waypoint
from himit_torch.worlds.tabular import DynamicsTable, TabularWorld

__all__ = [
    "MentorPolicy",
    "MentorRollout",
    "mentor_policy",
    "run_mentor",
    "record_demonstrations",
    "MentorDetour",
    "mentor_detour",
    "ExactMentorTransitions",
    "exact_mentor_transitions",
]


@dataclass(frozen=True)
class MentorPolicy:
    """An option per state for the mentor.

    Attributes:
        options: the mentor's own options (``O`` of them).
        option: ``[S]`` int64 option chosen in each state; −1 where none is available (walls,
            the goal).
        values: ``[S]`` float64 optimal values ``V*`` of the mentor's option SMDP.
        tolerance: how far below ``V*(s)`` an extended option's value may be and still be chosen
            over a better primitive (see :func:`mentor_policy`).
    """

    options: Options
    option: torch.Tensor
    values: torch.Tensor
    tolerance: float

    @property
    def extended(self) -> torch.Tensor:
        """``[S]`` bool, True where the chosen option is extended (not primitive)."""
        ext = ~self.options.is_primitive
        return (self.option >= 0) & ext[self.option.clamp(min=0)]


def mentor_policy(
    world: MultiRooms | TabularWorld,
    options: Options,
    prefer_extended_within: float | None = None,
    *,
    break_cycles: bool = False,
) -> MentorPolicy:
    """The mentor's optimal policy for its own options, by exact SMDP value iteration.

    Why the preference: with primitives among its options, the strictly optimal choice is often
    a primitive, better than the extended option by a hair (a wall-following doorway option has
    the same length as the direct route but slips cost it slightly more), and a mentor stepping
    by primitives would not show the paper's behaviour of "travelling along the walls". So in each
    state the mentor takes an extended option whose value is within ``prefer_extended_within`` of
    the state's optimal value ``V*(s)``, and the strict greedy option otherwise. Among several
    such extended options the one with the highest value wins (then the lowest index).

    Cycles (``break_cycles``): far from the goal values are negative and discounting makes a
    delayed cost cheaper, so stepping back a cell and returning can cost less than one step's
    cost in value (at ``V* ≈ −0.74``, ``γ = 0.99``: ≈ 0.005), and the preferred choices can
    form a cycle that only a slip leaves. Of the paper's worlds, exp1's and exp3's 80×80, 96×96
    and 120×120 have two such 2-cycles each, in a room of the top row and one of the left
    column (80×80: (1, 18)–(2, 18) and (18, 1)–(18, 2)), off the mentor's diagonal path; exp2's
    and exp3's 64×64 have none. The default keeps them (the mentor of every earlier run).
    Experiment 1's world made into a maze had one on the mentor's own path (an option back to
    the doorway just passed, then the primitive forward again), and its mentor never reached the
    goal. With ``break_cycles=True`` (MultiRooms, deterministic options) the states on a cycle of
    the preferred choices without slips (each state's option followed to where it may first
    stop) take the strict greedy option instead, until no cycle is left.

    Args:
        world: the world the mentor acts in.
        options: the mentor's options, e.g. ``mentor_options(world)``.
        prefer_extended_within: the tolerance, ``≥ 0``; by default one step's cost,
            ``abs(world.step_reward)`` (0.01), or 0 for worlds without a ``step_reward``. ``0``
            gives the strict greedy optimum.
        break_cycles: replace the preferred choices' slip-free cycles by the strict optimum
            (above); what the runs do in worlds other than the paper's (a maze, a moved goal, a
            detour's first leg).

    Returns:
        :class:`MentorPolicy`; its values are the optimal ``V*`` (the preference changes which
        option is taken, not the values reported).
    """
    if prefer_extended_within is None:
        prefer_extended_within = abs(getattr(world, "step_reward", 0.0))
    tolerance = float(prefer_extended_within)
    if not tolerance >= 0.0:  # also rejects NaN
        raise ValueError(
            f"prefer_extended_within={prefer_extended_within} must be ≥ 0 (a value "
            "tolerance; 0 gives the strict optimum)"
        )
    if options.num_states != world.num_states:
        raise ValueError(
            f"options are over {options.num_states} states but the world has {world.num_states}"
        )
    models = option_models(world, options)
    plan = smdp_value_iteration(models)
    extended = ~options.is_primitive
    if tolerance > 0:
        # Best extended option first, by value: rank extended rows above the rest by their q,
        # keeping only those within the tolerance (greedy_option_policy breaks ties by index).
        q = plan.q
        within = extended[models.row_option] & (q >= plan.values[models.row_state] - tolerance)
        score = torch.where(within, q + (q.abs().max() + 1.0) * 4, q)
        policy = greedy_option_policy(models, score, plan.values)
        if break_cycles and isinstance(world, MultiRooms) and not options.stochastic:
            policy = _break_cycles(world, options, policy, plan.policy)
    else:
        policy = plan.policy
    return MentorPolicy(options=options, option=policy, values=plan.values, tolerance=tolerance)


def _nominal_ends(world: MultiRooms, options: Options, choice: torch.Tensor) -> torch.Tensor:
    """``[S]`` where each state's chosen option first may stop when nothing slips: followed
    from the state until ``β > 0``, the goal, or a bump into a wall; −1 where no option."""
    nxt, goal = world.next_state_table, world.goal_state
    states = torch.nonzero(choice >= 0).flatten()
    opt, pos = choice[states], states.clone()
    moving = torch.ones_like(states, dtype=torch.bool)
    for _ in range(world.num_states):
        new = nxt[pos, options.policy[opt, pos].long()]
        stop = (new == pos) | (new == goal) | (options.termination[opt, new] > 0)
        pos = torch.where(moving, new, pos)
        moving &= ~stop
        if not moving.any():
            break
    ends = torch.full_like(choice, -1)
    ends[states] = pos
    return ends


def _on_cycles(ends: torch.Tensor) -> list[int]:
    """States on a cycle of the functional graph ``s → ends[s]`` (−1: none)."""
    nodes = ends.tolist()
    state = [0] * len(nodes)  # 0 unseen, 1 on the current walk, 2 done
    out: list[int] = []
    for first in range(len(nodes)):
        walk, s = [], first
        while s >= 0 and state[s] == 0:
            state[s] = 1
            walk.append(s)
            s = nodes[s]
        if s >= 0 and state[s] == 1:  # the walk closed a loop at s
            out.extend(walk[walk.index(s) :])
        for w in walk:
            state[w] = 2
    return out


def _break_cycles(
    world: MultiRooms, options: Options, preferred: torch.Tensor, strict: torch.Tensor
) -> torch.Tensor:
    """``preferred`` with the strict greedy option at the states of its slip-free cycles, until
    none is left (see :func:`mentor_policy`)."""
    policy = preferred.clone()
    while True:
        cycle = [
            s for s in _on_cycles(_nominal_ends(world, options, policy)) if policy[s] != strict[s]
        ]
        if not cycle:
            return policy
        policy[cycle] = strict[cycle]


@dataclass(frozen=True)
class MentorRollout:
    """What happened when the mentor ran: its states, and (for diagnostics only) its decisions.

    Attributes:
        states: per episode an int64 ``[T_e + 1]`` tensor: the start and every step's state.
        decisions: per episode an int64 tensor of the options it chose, in order.
        options: the mentor's options (to read the decisions' kinds).
        decision_states: per episode an int64 tensor of the state of each decision.
        randomised: per episode a bool tensor, True where the decision was a random primitive
            (``run_mentor(noise=…)``) instead of the policy's own option.
        decision_steps: per episode an int64 tensor of each decision's position in ``states``
            (``states[e][decision_steps[e]] == decision_states[e]``): 0 for the first, then
            where each option ended and the next began. With the episode's last position, where
            the last option ended, these are the states a learner seeing the mentor only at its
            subgoals sees (:func:`~himit_torch.mentor.observation.observe_at_option_ends`).
    """

    states: tuple[torch.Tensor, ...]
    decisions: tuple[torch.Tensor, ...]
    options: Options
    decision_states: tuple[torch.Tensor, ...] = ()
    randomised: tuple[torch.Tensor, ...] = ()
    decision_steps: tuple[torch.Tensor, ...] = ()

    def decision_counts(self) -> dict[str, int]:
        """Number of decisions per option kind over all episodes, e.g. ``{"doorway": 40, ...}``."""
        counts: dict[str, int] = {}
        for d in self.decisions:
            for o in d.tolist():
                kind = self.options.kinds[o]
                counts[kind] = counts.get(kind, 0) + 1
        return counts


def run_mentor(
    world: MultiRooms | TabularWorld,
    mentor: MentorPolicy | Options,
    episodes: int = 20,
    *,
    generator: torch.Generator | None = None,
    seed: int | None = None,
    max_steps_per_episode: int | None = None,
    noise: float = 0.0,
) -> MentorRollout:
    """Run the mentor's policy from the start until a terminal state, ``episodes`` times.

    Episodes start at ``world.start_state``, or, for a world with a ``start_distribution``, at
    states drawn from it (one draw per episode from ``generator``, before the steps).

    All episodes run together, one primitive step at a time. Where an episode needs a decision
    the mentor picks ``mentor.option[s]``; the option acts by its policy; on arriving in ``s'`` it
    terminates with probability ``β(s')`` (a uniform draw) and always at the goal. Each step
    draws three uniforms per episode (action for stochastic option policies, slip, termination),
    so the result depends only on the seed.

    A mentor that errs (``noise > 0``): at each decision, with probability ``noise``, the mentor
    takes a primitive option drawn uniformly from the primitives usable at its state (all four
    in MultiRooms) instead of its policy's option; the primitive acts for one step and the next
    decision follows. Two draws per decision from ``generator`` (a uniform, then the primitive),
    made only when ``noise > 0``, so ``noise = 0`` gives exactly the episodes of a mentor
    without it.

    Args:
        world: the world (its ``step`` with explicit uniforms is used).
        mentor: a :class:`MentorPolicy`, or options to build one with :func:`mentor_policy`.
        episodes: number of episodes, ``≥ 1``.
        generator: a CPU ``torch.Generator``; or give ``seed`` (default 0).
        max_steps_per_episode: give up (``ValueError``) if an episode has not reached the goal
            after this many primitive steps; default ``10 · S``.
        noise: the probability, in ``[0, 1)``, that a decision is a uniformly random primitive.
    """
    noise = as_float("run_mentor noise", noise, 0.0, 1.0, high_open=True)
    if isinstance(mentor, Options):
        mentor = mentor_policy(world, mentor)
    if not isinstance(mentor, MentorPolicy):
        raise ValueError(f"mentor must be a MentorPolicy or Options, got {type(mentor).__name__}")
    episodes = as_int("episodes", episodes, 1, COUNT_MAX)
    # All episodes step together: their positions, flags and option state, and a state per step.
    check_memory(f"run_mentor: {episodes} episodes at once", 64 * episodes, "record fewer")
    generator = _generator(generator, seed)
    S = world.num_states
    max_steps = (
        10 * S
        if max_steps_per_episode is None
        else as_int("max_steps_per_episode", max_steps_per_episode, 1, COUNT_MAX)
    )
    options = mentor.options
    choice = mentor.option
    cdf_total = None
    if options.stochastic:
        cdf = options.action_probabilities(world.num_actions).double().cumsum(-1).flatten(0, 1)
        tables = OptionTables(S, options.termination.reshape(-1), None, cdf)
        cdf_total = cdf[:, -1]
    else:
        tables = OptionTables(S, options.termination.reshape(-1), options.policy.reshape(-1), None)
    primitives = torch.nonzero(options.is_primitive).flatten()
    if noise > 0 and primitives.numel() == 0:
        raise ValueError(
            f"run_mentor: noise={noise} replaces decisions with primitive options, but the "
            f"mentor's {options.num_options} options hold none; give it primitives "
            "(primitive_options(world)) or use noise=0"
        )

    E = episodes
    start_distribution = getattr(world, "start_distribution", None)
    if start_distribution is None:
        pos = torch.full((E,), int(world.start_state), dtype=torch.int64)
    else:
        pos = torch.multinomial(
            torch.as_tensor(start_distribution, dtype=torch.float64),
            E,
            replacement=True,
            generator=generator,
        )
    if bool((choice[pos] < 0).any()):
        bad = int(pos[choice[pos] < 0][0])
        raise ValueError(f"the mentor has no option at the start state {_where(world, bad)}")
    dynamics = _steps_by_table(world)
    if noise == 0 and tables.policy is not None and dynamics is not None:
        # (one episode's step in Python numbers: the same episodes, ≈ 3× faster than the
        # batch's torch ops on the few episodes a study records)
        return _rollout_in_numbers(
            world, options, choice, tables, dynamics, pos, generator, max_steps
        )
    return _rollout_in_tensors(
        world, options, choice, tables, cdf_total, primitives, pos, generator, max_steps, noise
    )


def _steps_by_table(world) -> DynamicsTable | None:
    """The world's :class:`~himit_torch.DynamicsTable` (a world that has one steps by it), or
    ``None``."""
    table = getattr(world, "dynamics_table", None)
    return table() if callable(table) else None


def _rollout_in_numbers(
    world,
    options: Options,
    choice: torch.Tensor,
    tables: OptionTables,
    dynamics: DynamicsTable,
    start: torch.Tensor,
    generator: torch.Generator,
    max_steps: int,
) -> MentorRollout:
    """:func:`run_mentor`'s episodes (deterministic options, no noise) one state at a time in
    Python numbers (:func:`~himit_torch.options.execution.option_step_in_numbers`), with the
    same draws as :func:`_rollout_in_tensors`: three uniforms per episode at every step, active
    or not. The same rollout to the bit (``tests/mentor/test_policy.py``)."""
    E = start.numel()
    terminal = world.terminal_mask.tolist()
    move = option_step_in_numbers(tables, dynamics, terminal)
    chosen, usable = choice.tolist(), options.initiation.numpy()
    pos = start.tolist()
    active, current = [True] * E, [-1] * E
    states: list[list[int]] = [[s] for s in pos]
    decisions: list[list[int]] = [[] for _ in range(E)]
    decided_at: list[list[int]] = [[] for _ in range(E)]
    decided_step: list[list[int]] = [[] for _ in range(E)]
    for _ in range(max_steps):
        need = [e for e in range(E) if active[e] and current[e] < 0]
        for e in need:
            o = chosen[pos[e]]
            if o < 0 or not usable[o, pos[e]]:
                raise _no_usable_option(world, pos[e])
        for e in need:
            current[e] = chosen[pos[e]]
            decisions[e].append(current[e])
            decided_at[e].append(pos[e])
            decided_step[e].append(len(states[e]) - 1)
        u = torch.rand(3, E, generator=generator, dtype=torch.float64)
        slip_u, stop_u = u[1].float().tolist(), u[2].tolist()  # (the slip's uniform in float32)
        for e in range(E):
            if active[e]:
                pos[e], stopped = move(current[e], pos[e], slip_u[e], stop_u[e])
                states[e].append(pos[e])
                if stopped:
                    current[e] = -1
                active[e] = not terminal[pos[e]]
        if not any(active):
            break
    if any(active):
        raise _goal_not_reached(max_steps, sum(active), E)
    # each episode up to its first arrival at the goal (the start's own, if it is one)
    ends = [next(i for i, s in enumerate(path) if terminal[s]) for path in states]
    return MentorRollout(
        states=tuple(torch.tensor(path[: end + 1]) for path, end in zip(states, ends)),
        decisions=tuple(torch.tensor(d, dtype=torch.int64) for d in decisions),
        options=options,
        decision_states=tuple(torch.tensor(d, dtype=torch.int64) for d in decided_at),
        randomised=tuple(torch.zeros(len(d), dtype=torch.bool) for d in decisions),
        decision_steps=tuple(torch.tensor(d, dtype=torch.int64) for d in decided_step),
    )


def _no_usable_option(world, state: int) -> ValueError:
    return ValueError(f"the mentor's policy has no usable option at state {_where(world, state)}")


def _goal_not_reached(max_steps: int, left: int, episodes: int) -> ValueError:
    return ValueError(
        f"the mentor did not reach the goal within max_steps_per_episode={max_steps} steps in "
        f"{left} of {episodes} episodes; is its policy able to reach the goal?"
    )


def _rollout_in_tensors(
    world,
    options: Options,
    choice: torch.Tensor,
    tables: OptionTables,
    cdf_total: torch.Tensor | None,
    primitives: torch.Tensor,
    pos: torch.Tensor,
    generator: torch.Generator,
    max_steps: int,
    noise: float,
) -> MentorRollout:
    """:func:`run_mentor`'s episodes all together, one primitive step of torch ops at a time."""
    S, E = world.num_states, pos.numel()
    init, terminal = options.initiation, world.terminal_mask

    def step(positions, actions, slip_u):
        return world.step(positions, actions, uniforms=slip_u)

    active = torch.ones(E, dtype=torch.bool)
    current = torch.full((E,), -1, dtype=torch.int64)
    history = [pos.clone()]
    decided_episode, decided_option, decided_random, decided_state = [], [], [], []
    decided_step = []
    for _ in range(max_steps):
        need = active & (current < 0)
        if need.any():
            picked = choice[pos[need]]
            randomised = torch.zeros_like(picked, dtype=torch.bool)
            if noise > 0:
                at = pos[need]
                randomised = torch.rand(at.shape, generator=generator, dtype=torch.float64) < noise
                usable = init[primitives][:, at].T.double()  # [n, primitives]
                if not bool((usable.sum(1) > 0).all()):
                    bad = int(at[usable.sum(1) == 0][0])
                    raise ValueError(
                        f"run_mentor: noise={noise}, but no primitive is usable at state "
                        f"{_where(world, bad)}"
                    )
                drawn = primitives[torch.multinomial(usable, 1, generator=generator).flatten()]
                picked = torch.where(randomised, drawn, picked)
            if (picked < 0).any() or not init[picked, pos[need]].all():
                bad = int(pos[need][(picked < 0) | ~init[picked.clamp(min=0), pos[need]]][0])
                raise _no_usable_option(world, bad)
            current[need] = picked
            decided_episode.append(torch.nonzero(need).flatten())
            decided_option.append(picked)
            decided_random.append(randomised)
            decided_state.append(pos[need])
            decided_step.append(torch.full_like(picked, len(history) - 1))
        u = torch.rand(3, E, generator=generator, dtype=torch.float64)
        o = current.clamp(min=0)
        # (the cdf's rows need not end at exactly 1: the action uniform is scaled to the row)
        action_u = None if cdf_total is None else u[0] * cdf_total[o * S + pos]
        moved = option_step(
            tables, o, pos, step, terminal, slip_u=u[1].float(), stop_u=u[2], action_u=action_u
        )
        # finished episodes stay where they are
        nxt = torch.where(active, moved.successors, pos)
        current = torch.where(active & moved.stopped, torch.full_like(current, -1), current)
        pos = nxt
        history.append(pos.clone())
        active = active & ~terminal[pos]
        if not active.any():
            break
    if active.any():
        raise _goal_not_reached(max_steps, int(active.sum()), E)
    hist = torch.stack(history)  # [T + 1, E]
    reached = terminal[hist].int().argmax(0)  # first arrival at the goal
    states = tuple(hist[: int(reached[e]) + 1, e].clone() for e in range(E))
    ep = torch.cat(decided_episode)
    opt = torch.cat(decided_option)
    rand = torch.cat(decided_random)
    where_decided = torch.cat(decided_state)
    when_decided = torch.cat(decided_step)
    return MentorRollout(
        states=states,
        decisions=tuple(opt[ep == e] for e in range(E)),
        options=options,
        decision_states=tuple(where_decided[ep == e] for e in range(E)),
        randomised=tuple(rand[ep == e] for e in range(E)),
        decision_steps=tuple(when_decided[ep == e] for e in range(E)),
    )


@dataclass(frozen=True)
class MentorDetour:
    """A needless detour for the mentor (:func:`mentor_detour`): it first walks to ``waypoint``,
    then to the goal.

    Attributes:
        waypoint: the cell visited on the way.
        to_waypoint: the mentor's optimal policy (same options' kinds and preference) in
            ``first_leg``.
        first_leg: the world with the waypoint as its goal (same layout, slip and start).
        second_leg: the world with the waypoint as its start (same goal).
    """

    waypoint: int
    to_waypoint: MentorPolicy
    first_leg: MultiRooms
    second_leg: MultiRooms


def mentor_detour(
    world: MultiRooms,
    waypoint: int | None = None,
    *,
    corners: bool = False,
    prefer_extended_within: float | None = None,
) -> MentorDetour:
    """The :class:`MentorDetour` of ``world`` through ``waypoint`` (default:
    :func:`~himit_torch.worlds.multirooms.detour_waypoint`, the top-right corner cell).

    The first leg's mentor is built as the experiments build the mentor
    (:func:`mentor_options` with ``corners``, :func:`mentor_policy` with
    ``prefer_extended_within`` and ``break_cycles``), in a copy of the world whose goal is the waypoint; the second
    leg is the world's own mentor started at the waypoint (give it to
    :func:`record_demonstrations`).
    """
    if not isinstance(world, MultiRooms):
        raise ValueError(
            f"mentor_detour: a detour needs a MultiRooms world (cells and options to walk "
            f"them), got {type(world).__name__}"
        )
    waypoint = detour_waypoint(world) if waypoint is None else world._cell("waypoint", waypoint)
    if waypoint in (world.start_state, world.goal_state):
        raise ValueError(
            f"mentor_detour: the waypoint {world.coords(waypoint)} is the world's start or goal"
        )
    desc = world.describe()
    first_leg = MultiRooms.from_description({**desc, "goal": waypoint})
    second_leg = MultiRooms.from_description({**desc, "start": waypoint})
    to_waypoint = mentor_policy(
        first_leg,
        mentor_options(first_leg, corners=corners),
        prefer_extended_within,
        break_cycles=True,
    )
    return MentorDetour(waypoint, to_waypoint, first_leg, second_leg)


def record_demonstrations(
    world: MultiRooms | TabularWorld,
    mentor: MentorPolicy | Options,
    episodes: int = 20,
    *,
    generator: torch.Generator | None = None,
    seed: int | None = None,
    max_steps_per_episode: int | None = None,
    noise: float = 0.0,
    detour: MentorDetour | None = None,
) -> Demonstrations:
    """State-only demonstrations of the mentor: :func:`run_mentor`, keeping the states only.

    The learner sees nothing of the mentor's actions, options or rewards; the returned
    :class:`~himit_torch.Demonstrations` holds each episode's states and the world's description.
    Arguments as for :func:`run_mentor` (``noise``: a mentor that errs).

    With a ``detour`` (:func:`mentor_detour` of this world) every episode is the mentor's walk
    to ``detour.waypoint`` (``detour.to_waypoint`` in ``detour.first_leg``) followed by its walk
    from there to the goal (``mentor`` in ``detour.second_leg``), joined at the waypoint: all
    episodes' first legs are run, then all second legs, from one generator (made from ``seed``
    if no ``generator`` is given). An episode whose first leg enters the goal ends there, as
    every episode does, and keeps no second leg (possible only where the route to the waypoint
    passes next to the goal, as in some mazes).
    """
    if detour is None:
        rollout = run_mentor(
            world,
            mentor,
            episodes,
            generator=generator,
            seed=seed,
            max_steps_per_episode=max_steps_per_episode,
            noise=noise,
        )
        return Demonstrations(list(rollout.states), world)
    if not isinstance(detour, MentorDetour):
        raise TypeError(
            f"record_demonstrations: detour must be a MentorDetour (mentor_detour(world)) or "
            f"None, got {type(detour).__name__}"
        )
    if not isinstance(world, MultiRooms) or detour.second_leg.describe() != {
        **world.describe(),
        "start": detour.waypoint,
    }:
        raise ValueError(
            "record_demonstrations: the detour was made for another world; build it with "
            "mentor_detour(world)"
        )
    generator = _generator(generator, seed)
    legs = [
        run_mentor(
            leg,
            policy,
            episodes,
            generator=generator,
            max_steps_per_episode=max_steps_per_episode,
            noise=noise,
        ).states
        for leg, policy in (
            (detour.first_leg, detour.to_waypoint),
            (detour.second_leg, mentor),
        )
    ]
    goal = world.goal_state
    joined = []
    for first, second in zip(*legs):
        reached = torch.nonzero(first == goal).flatten()
        if reached.numel():
            joined.append(first[: int(reached[0]) + 1])
        else:
            joined.append(torch.cat([first, second[1:]]))
    return Demonstrations(joined, world)


def _generator(generator: torch.Generator | None, seed: int | None) -> torch.Generator:
    """The given generator, or a new one seeded with ``seed`` (default 0)."""
    if generator is not None and seed is not None:
        raise ValueError("give either generator or seed, not both")
    if generator is not None:
        return generator
    return torch.Generator().manual_seed(
        0 if seed is None else as_int("seed", seed, -(2**63), 2**64 - 1)
    )


def _where(world, state: int) -> str:
    """A state for messages: its cell in MultiRooms, its index elsewhere."""
    return str(world.coords(state)) if hasattr(world, "coords") else str(state)


@dataclass(frozen=True)
class ExactMentorTransitions:
    """The mentor's exact state-transition model as expected counts: what infinitely many
    demonstrations would show, scaled to ``episodes`` episodes.

    ``counts[i]`` is the expected number of primitive steps ``sources[i] → successors[i]`` the
    mentor makes in ``episodes`` episodes, so ``p_m(s'|s) = counts / Σ_{s'} counts`` exactly
    (:func:`exact_mentor_transitions`). Give it to :meth:`Learner.add_demonstrations
    <himit_torch.Learner.add_demonstrations>` in place of recorded demonstrations: its
    ``transitions()`` and ``counts`` are read, and the mentor model holds these (fractional)
    counts.
    """

    sources: torch.Tensor
    successors: torch.Tensor
    counts: torch.Tensor

    def transitions(self) -> tuple[torch.Tensor, torch.Tensor]:
        return self.sources, self.successors


def exact_mentor_transitions(
    world, mentor: MentorPolicy, episodes: float = 1.0
) -> ExactMentorTransitions:
    """The exact one-step model ``p_m(s'|s)`` of the mentor of :func:`run_mentor`, as expected
    transition counts over ``episodes`` episodes.

    The mentor is Markov in the pair (state, executing option), not in the state alone: at a
    decision in ``s`` it starts ``mentor.option[s]``; the option acts by its policy, the world
    moves to ``s'``, and the option stops there with probability ``β_o(s')`` (always at a
    terminal state), when a new decision is made at ``s'``. With ``T`` that chain's transient
    kernel over reachable pairs and ``x0`` the start distribution over pairs, the expected visits
    are ``x = x0 (I − T)⁻¹`` (one sparse solve), and the expected count of ``s → s'`` is
    ``Σ_o x(s, o) P(s' | s, π_o(s))`` — what the learned counts converge to, divided by the
    number of episodes. Every state the mentor reaches with positive probability (with slips,
    far more than a few demonstrations visit) gets its exact ``p_m(·|s)``.

    Args:
        world: a world with a true model (:func:`~himit_torch.worlds.table_world.world_model`).
        mentor: the mentor's :class:`MentorPolicy` (deterministic or stochastic option policies).
        episodes: scale of the counts (``> 0``): the expected counts of this many episodes.
    """
    import numpy as np
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from himit_torch.worlds.table_world import world_model

    if not episodes > 0:
        raise ValueError(f"episodes={episodes!r} must be > 0 (the scale of the expected counts)")
    P, _ = world_model(world)
    A, S, _ = P.shape
    idx, val = P.indices().numpy(), P.values().numpy()
    # One-step kernel per (action, state): CSR over rows a·S + s.
    K = sp.csr_matrix((val, (idx[0] * S + idx[1], idx[2])), shape=(A * S, S))
    options = mentor.options
    probs = options.action_probabilities(A).double().numpy() if options.stochastic else None
    policy = None if options.stochastic else options.policy.numpy()
    beta = options.termination.double().numpy()
    choice = mentor.option.numpy()
    terminal = world.terminal_mask.numpy()

    def actions(o: int, s: int):
        if probs is None:
            assert policy is not None  # deterministic options have a policy table
            return [(int(policy[o, s]), 1.0)]
        return [(a, float(p)) for a, p in enumerate(probs[o, s]) if p > 0]

    start = getattr(world, "start_distribution", None)
    start = (
        np.eye(S)[int(world.start_state)]
        if start is None
        else torch.as_tensor(start, dtype=torch.float64).numpy()
    )
    pair_id: dict[tuple[int, int], int] = {}
    pairs: list[tuple[int, int]] = []

    def pair(s: int, o: int) -> int:
        key = (s, o)
        if key not in pair_id:
            if o < 0:
                raise ValueError(
                    f"the mentor's policy has no option at state {_where(world, s)}, "
                    "which it can reach"
                )
            pair_id[key] = len(pairs)
            pairs.append(key)
        return pair_id[key]

    starts = {pair(int(s), int(choice[s])): float(start[s]) for s in np.flatnonzero(start > 0)}
    rows, cols, vals = [], [], []  # transient kernel T between pairs
    edge_pair, edge_succ, edge_prob = [], [], []  # pair → next state, per-step probability
    i = 0
    while i < len(pairs):
        s, o = pairs[i]
        for a, pa in actions(o, s):
            lo, hi = K.indptr[a * S + s], K.indptr[a * S + s + 1]
            for s2, p in zip(K.indices[lo:hi], K.data[lo:hi]):
                p = pa * p
                if p <= 0:
                    continue
                edge_pair.append(i)
                edge_succ.append(int(s2))
                edge_prob.append(p)
                if terminal[s2]:
                    continue
                b = float(beta[o, s2])
                if b > 0:
                    rows.append(i)
                    cols.append(pair(int(s2), int(choice[s2])))
                    vals.append(p * b)
                if b < 1:
                    rows.append(i)
                    cols.append(pair(int(s2), o))
                    vals.append(p * (1 - b))
        i += 1
    n = len(pairs)
    T = sp.csr_matrix((vals, (rows, cols)), shape=(n, n))
    x0 = np.zeros(n)
    x0[list(starts)] = list(starts.values())
    visits = spla.spsolve((sp.identity(n, format="csc") - T).T.tocsc(), x0)
    counts = episodes * visits[np.array(edge_pair)] * np.array(edge_prob)
    src = np.array([pairs[j][0] for j in edge_pair], dtype=np.int64)
    dst = np.array(edge_succ, dtype=np.int64)
    # One entry per (s, s'): sum over the options executing at s.
    key = src * S + dst
    uniq, inv = np.unique(key, return_inverse=True)
    summed = np.bincount(inv, weights=counts)
    keep = summed > 0
    return ExactMentorTransitions(
        torch.from_numpy(uniq[keep] // S),
        torch.from_numpy(uniq[keep] % S),
        torch.from_numpy(summed[keep]),
    )
