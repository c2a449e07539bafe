"""The hierarchical imitation learner: ``B`` independent runs advancing together.

Each run executes its current option one primitive step per tick. Runs whose option ended this
tick update their Dirichlet SMDP model, plan with prioritized sweeping on the augmented Bellman
equation (the paper's eq. 2, or a baseline), and pick their next option ε-greedily.

Shapes: ``B`` runs, ``S`` states, ``O`` options, ``M`` available ``(s, o)`` rows (shared by the
batch, grouped by state: ``state_rows [S, J]``), ``E`` observed model edges.

How values are kept (the fast path; :meth:`Learner.plan` sweeps to convergence for checks, and
the pure functions of :mod:`himit_torch.backups` are the slow reference the tests compare with):

* ``q_numerator [B, M]`` holds ``Σ r + Σ_{s'} Σγ^k V(s')`` of every row, so that
  ``Q = (q_numerator + α v0) / (n + α)`` is the posterior-mean option backup
  (:func:`himit_torch.backups.option_backup` on the model's means). When ``V(x)`` changes by ``δ`` in a backup, every
  row with an edge to ``x`` gets ``+ Σγ^k · δ`` — along the reverse edge lists, which also yield
  the prioritized-sweeping priorities ``|ΔQ|`` of the predecessor states.
* ``mentor_numerator [B, S]`` likewise holds ``Σ_{s'} c(s→s') (r_m + γ V(s'))``.
* A backup of ``x`` is then a max over its ``J`` cached rows and the mentor term (eq. 2).
"""

from __future__ import annotations

import warnings
from dataclasses import asdict, dataclass, field
from typing import Sequence

import torch

from .dirichlet_models import DirichletMentorModel, DirichletSMDPModel
from .options import Options
from .sweep_queue import BlockPriorityQueue
from .reward import KnownReward
from .rng import seed_streams, uniforms

__all__ = ["Learner", "LearnerConfig", "AGENTS"]

#: Agent variants: which options a run may use, whether it imitates, and whether its mentor term
#: is confidence-tested. ``imitation`` — options + mentor (eq. 2); ``options`` — options only;
#: ``primitives`` — primitive options only; ``imitation_primitives`` — primitives + mentor (eq. 1,
#: Price & Boutilier); ``…_confident`` — the same with Price & Boutilier's confidence test
#: (:attr:`LearnerConfig.confidence_z`).
AGENTS = {
    "imitation": ("all", True, False),
    "imitation_confident": ("all", True, True),
    "options": ("all", False, False),
    "primitives": ("primitive", False, False),
    "imitation_primitives": ("primitive", True, False),
    "imitation_primitives_confident": ("primitive", True, True),
}


@dataclass
class LearnerConfig:
    """Settings of the learner. Defaults follow the paper where it speaks (ε, γ from the world) and
    ``shared/docs/REPRODUCTION-NOTES.md`` where it is silent."""

    backups: int = 10
    """Prioritized-sweeping backups per decision (the paper: about the number of options needed to
    reach the goal). The option's start state is always backed up first, within this budget."""
    sweep_rounds: int = 2
    """The backups of one planning step run in this many rounds; the states of one round (the
    highest priorities) are backed up together, and their changes propagate before the next
    round. ``sweep_rounds = backups`` is classic one-at-a-time sweeping (slowest)."""
    plan_every: int = 1
    """Sweep every this many ticks, for all runs that decided since the last sweep, with
    ``backups`` per decision they made, in ``sweep_rounds`` rounds of up to
    ``plan_every · backups / sweep_rounds`` states. 1 = plan at every decision (the paper's loop).
    Larger values trade a few ticks of planning delay for speed (fewer, larger tensor ops): a
    sweep after a decision at ``s`` updates ``s`` and the states *behind* it, not the state the
    next choice is made in. Models are still updated at every decision."""
    rng_chunk: int = 256
    """Per-run uniforms are drawn for this many ticks at once (speed only; results identical)."""
    priority_threshold: float = 1e-6
    """A state enters the sweeping queue only with a priority ``|ΔQ|`` above this."""
    initial_value: float = -1.0
    """Initial ``V`` of every non-terminal state, and the value of the prior's unseen outcome.
    −1 = step reward / (1 − γ), the value of never reaching the goal in the paper's worlds: a
    neutral start. 0 is optimistic there (true values are negative), which turns ε-greedy into
    systematic exploration."""
    untried_value: float | None = None
    """Value of an option never tried in a state: ``None`` leaves it out of the max (and out of
    greedy choice unless nothing was tried there); a number counts it with that ``Q`` (0 =
    the optimistic "Q = 0 for untried options" of a straightforward implementation)."""
    concentration: float = 0.0
    """Dirichlet prior mass of the option model on the unseen-successor outcome (0 = the
    maximum-likelihood model)."""
    mentor_concentration: float = 0.0
    """Same for the mentor model (only in states where the mentor was seen: the prior never
    creates a mentor term elsewhere)."""
    confidence_z: float = 1.0
    """Width of Price & Boutilier's confidence test, used by the ``…_confident`` agents: the
    mentor term at ``s`` counts only where its lower bound (mean − z·sd, from the Dirichlet
    variances) beats the upper bound (mean + z·sd) of every own option."""
    mentor_override_after: int | None = None
    """Ignore the mentor term at ``s`` once the run has executed its own options there this many
    times (own experience overrides the mentor); ``None`` = never."""
    eps_start: float = 0.75
    """ε until the run's first goal."""
    eps_decay: float = 0.999
    """After the first goal, ε is multiplied by this at every decision…"""
    eps_min: float = 0.01
    """…down to this floor."""
    mentor_choice: str = "greedy"
    """How a run picks its own option (greedy choices only) in a state where the mentor term wins
    eq. 2. ``"greedy"``: the best own option by its ``Q`` — values that the mentor term has already
    raised downstream. ``"match"`` (Price & Boutilier's rule, for options): the own options whose
    first action's learned one-step model best reproduces the mentor's observed move,
    ``Σ_s' p̂(s'|s, π_o(s)) p_m(s'|s)``, best ``Q`` among those; greedy where no tried action
    matches."""
    tie_break: str = "random"
    """Greedy ties (|ΔQ| ≤ 1e-12): ``"random"`` among the best, or ``"first"`` (lowest option)."""
    window: int = 5000
    """Steps per window of the ``goals_in_window`` metric."""
    max_option_steps: int = 100_000
    """An option still running after this many primitive steps is stopped (and learned from as
    if it had terminated there), so an option that never terminates cannot freeze its run."""
    reward_bound_check: str = "error"
    """What to do when a mentor-reward module's declared ``upper_bound`` exceeds the learner's
    real best reward per step (the guarantee of eq. 2 needs ``R_m`` not to overestimate it):
    ``"error"`` (ValueError), ``"warn"`` (a warning) or ``"off"``. Values above a module's own
    declared bound are always an error."""

    def __post_init__(self):
        def bad(name, why):
            raise ValueError(f"LearnerConfig.{name}={getattr(self, name)!r}: {why}")
        if self.backups < 1:
            bad("backups", "needs at least 1 backup per decision")
        if not 1 <= self.sweep_rounds <= self.backups:
            bad("sweep_rounds", f"must lie in 1…backups ({self.backups})")
        for name in ("concentration", "mentor_concentration", "priority_threshold"):
            if not getattr(self, name) >= 0:
                bad(name, "must be ≥ 0")
        for name in ("eps_start", "eps_min", "eps_decay"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                bad(name, "must lie in [0, 1]")
        if self.eps_min > self.eps_start:
            bad("eps_min", f"must not exceed eps_start={self.eps_start}")
        if not self.confidence_z >= 0:
            bad("confidence_z", "must be ≥ 0")
        if self.mentor_choice not in ("greedy", "match"):
            bad("mentor_choice", "use 'greedy' or 'match'")
        if self.tie_break not in ("random", "first"):
            bad("tie_break", "use 'random' or 'first'")
        if self.window < 1:
            bad("window", "must be ≥ 1 step")
        if self.plan_every < 1:
            bad("plan_every", "must be ≥ 1 tick")
        if self.reward_bound_check not in ("error", "warn", "off"):
            bad("reward_bound_check", "use 'error', 'warn' or 'off'")
        if self.rng_chunk < 1:
            bad("rng_chunk", "must be ≥ 1 tick")
        if self.max_option_steps < 1:
            bad("max_option_steps", "must be ≥ 1 step")
        if not torch.isfinite(torch.tensor(float(self.initial_value))):
            bad("initial_value", "must be finite")


_TIE = 1e-12


class _NoMentorReward:
    """The mentor reward of runs that do not imitate: never used, zero."""

    upper_bound = 0.0

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        return torch.zeros(sources.shape, dtype=torch.float64, device=sources.device)

    def __repr__(self) -> str:
        return "no mentor reward"


_NO_MENTOR_REWARD = _NoMentorReward()


def _take(x: torch.Tensor, flat: torch.Tensor) -> torch.Tensor:
    """``x`` (contiguous) read at flat indices of any shape: one ``index_select``, far cheaper
    than multi-tensor advanced indexing."""
    return x.view(-1).index_select(0, flat.reshape(-1)).view(flat.shape)


@dataclass
class RunMetrics:
    """Per-window metrics of every run (lists over windows of ``[B]`` tensors)."""

    steps: list[int] = field(default_factory=list)
    goals_in_window: list[torch.Tensor] = field(default_factory=list)
    epsilon: list[torch.Tensor] = field(default_factory=list)
    episodes: list[torch.Tensor] = field(default_factory=list)
    mean_episode_steps: list[torch.Tensor] = field(default_factory=list)
    backups: list[torch.Tensor] = field(default_factory=list)
    decisions: list[torch.Tensor] = field(default_factory=list)
    mentor_term_wins: list[torch.Tensor] = field(default_factory=list)

    def curve(self) -> torch.Tensor:
        """``[windows, B]`` goals per window."""
        if not self.goals_in_window:
            return torch.zeros(0, 0)
        return torch.stack(self.goals_in_window)


class Learner:
    """``B`` runs of the hierarchical imitation learner (or its baselines) in one batch.

    Args:
        world: a :class:`~himit_torch.TabularWorld` (``num_states``, ``num_actions``,
            ``start_state``, ``gamma``, ``terminal_mask``, ``step``).
        options: the options of the batch (the union; :data:`AGENTS` restricts them per run).
        agents: one agent variant per run, from :data:`AGENTS`.
        seeds: one seed per run; run ``b``'s randomness depends only on ``seeds[b]``.
        config: :class:`LearnerConfig`.
        demonstrations: mentor demonstrations (anything with ``transitions()``), given to every
            run; more can be added with :meth:`add_demonstrations`.
        reward: the reward module for the mentor term, one for all runs or one per run
            (default :class:`~himit_torch.KnownReward` of the world; ``None`` in a per-run list
            for runs that do not imitate). A module fitted on demonstrations (e.g.
            :class:`~himit_torch.SalienceReward`) is not refitted by :meth:`add_demonstrations`:
            call its ``fit`` with all demonstrations, then :meth:`refresh_mentor_reward`.
        device: where all tensors live.
    """

    def __init__(self, world, options: Options, agents: Sequence[str], seeds: Sequence[int],
                 config: LearnerConfig | None = None, demonstrations=None, reward=None,
                 device: str | torch.device = "cpu"):
        self.config = config = config or LearnerConfig()
        self.world, self.options = world, options
        self.device = dev = torch.device(device)
        agents, seeds = list(agents), [int(s) for s in seeds]
        B = len(agents)
        if B == 0:
            raise ValueError("a batch of 0 runs: give at least one agent (e.g. agents=['imitation'])")
        if len(seeds) != B:
            raise ValueError(f"{B} agents but {len(seeds)} seeds: give one seed per run")
        unknown = sorted(set(agents) - set(AGENTS))
        if unknown:
            raise ValueError(f"unknown agent variant(s) {unknown}; use one of {sorted(AGENTS)}")
        S, O = world.num_states, options.num_options
        if options.num_states != S:
            raise ValueError(f"options are over {options.num_states} states but the world has {S}")
        if not 0 < world.gamma <= 1:
            raise ValueError(f"world.gamma={world.gamma} must lie in (0, 1]")
        self.batch, self.num_states, self.num_options = B, S, O
        self.agents, self.seeds = agents, seeds
        self.gamma = float(world.gamma)
        self.terminal = torch.cat([world.terminal_mask.to(dev), torch.ones(1, dtype=torch.bool,
                                                                            device=dev)])
        self.start_state = int(world.start_state)

        # ---- rows: the available (s, o) pairs, grouped by state ---------------------------
        init = options.initiation.to(dev)
        opt_idx, state_idx = init.nonzero(as_tuple=True)
        order = torch.argsort(state_idx * O + opt_idx)
        row_state, row_option = state_idx[order], opt_idx[order]
        M = row_state.numel()
        self.num_rows = M
        first = torch.ones(M, dtype=torch.bool, device=dev)
        first[1:] = row_state[1:] != row_state[:-1]
        starts = torch.cummax(torch.where(first, torch.arange(M, device=dev),
                                          torch.zeros_like(row_state)), 0).values
        rank = torch.arange(M, device=dev) - starts
        J = int(rank.max()) + 1
        self.state_rows = torch.full((S + 1, J), M, dtype=torch.int64, device=dev)
        self.state_rows[row_state, rank] = torch.arange(M, device=dev)
        pad = torch.tensor([S], device=dev)
        self.row_state = torch.cat([row_state, pad])
        self.row_option = torch.cat([row_option, torch.zeros(1, dtype=torch.int64, device=dev)])

        # Row of each primitive action at each state (M where that primitive is unavailable), for
        # mentor_choice="match".
        prim_option = torch.full((world.num_actions,), -1, dtype=torch.int64)
        first_state = options.initiation.float().argmax(1)
        for o, kind in enumerate(options.kinds):
            if kind == "primitive":
                probs = options.action_probabilities(world.num_actions)[o, first_state[o]]
                prim_option[int(probs.argmax())] = o
        self.primitive_rows = torch.full((S + 1, world.num_actions), M, dtype=torch.int64, device=dev)
        for a, o in enumerate(prim_option.tolist()):
            if o >= 0:
                is_o = row_option == o
                self.primitive_rows[row_state[is_o], a] = torch.arange(M, device=dev)[is_o]

        # ---- option execution tables -------------------------------------------------------
        self.termination = options.termination.to(dev).double().reshape(-1)
        if options.stochastic:
            self.policy_cdf = options.policy.to(dev).double().cumsum(-1).reshape(O * S, -1)
            self.policy = None
        else:
            self.policy = options.policy.to(dev).reshape(-1)
            self.policy_cdf = None

        # ---- per-run variant masks ----------------------------------------------------------
        primitive = options.is_primitive.to(dev)
        enabled = torch.zeros(B, O, dtype=torch.bool, device=dev)
        self.use_mentor = torch.zeros(B, dtype=torch.bool, device=dev)
        self.use_confidence = torch.zeros(B, dtype=torch.bool, device=dev)
        for b, agent in enumerate(agents):
            which, mentor, confident = AGENTS[agent]
            enabled[b] = True if which == "all" else primitive
            self.use_mentor[b] = mentor
            self.use_confidence[b] = confident
        self._any_confidence = bool(self.use_confidence.any())
        if not bool(enabled.any(1).all()):
            raise ValueError("an agent variant has no usable option (e.g. 'primitives' with no "
                             "primitive options in the set)")
        self.row_enabled = torch.cat([enabled[:, row_option], torch.zeros(B, 1, dtype=torch.bool,
                                                                          device=dev)], 1)

        # ---- models, values, caches -----------------------------------------------------------
        self.model = DirichletSMDPModel(M, S, B, dev, config.concentration)
        self.mentor = DirichletMentorModel(S, B, dev, config.mentor_concentration)
        v0 = float(config.initial_value)
        self.values = torch.full((B, S + 1), v0, dtype=torch.float64, device=dev)
        self.values[:, self.terminal] = 0.0
        self.q_numerator = torch.zeros(B, M + 1, dtype=torch.float64, device=dev)
        self.q_second = torch.zeros_like(self.q_numerator)            # Σ (γ^k)² V² / c per row
        self.mentor_numerator = torch.zeros(B, S + 1, dtype=torch.float64, device=dev)
        self.mentor_second = torch.zeros_like(self.mentor_numerator)
        self.mentor_edge_reward = torch.zeros(B, self.mentor.edges.capacity, dtype=torch.float64,
                                              device=dev)
        self.mentor.edges.on_grow.append(self._grow_mentor_reward)
        self.state_tries = torch.zeros(B, S + 1, dtype=torch.float64, device=dev)
        self.visits = torch.zeros(B, S + 1, dtype=torch.int64, device=dev)
        self.queue = BlockPriorityQueue(B, S + 1, dev, typical_pop=max(1, config.backups // config.sweep_rounds))

        self.rewards = self._reward_modules(reward, world, B)
        self._check_world_rewards(world)

        # ---- run state -------------------------------------------------------------------------
        self.keys = seed_streams(torch.tensor(seeds, dtype=torch.int64, device=dev))
        self.t = 0
        self.position = torch.full((B,), self.start_state, dtype=torch.int64, device=dev)
        self.option_start = self.position.clone()
        self.row = torch.full((B,), M, dtype=torch.int64, device=dev)
        self.duration = torch.zeros(B, dtype=torch.int64, device=dev)
        self.discounted_return = torch.zeros(B, dtype=torch.float64, device=dev)
        self.discount = torch.ones(B, dtype=torch.float64, device=dev)
        self.epsilon = torch.full((B,), config.eps_start, dtype=torch.float64, device=dev)
        self.found_goal = torch.zeros(B, dtype=torch.bool, device=dev)
        self.goals = torch.zeros(B, dtype=torch.int64, device=dev)
        self.window_goals = torch.zeros(B, dtype=torch.int64, device=dev)
        self.episodes = torch.zeros(B, dtype=torch.int64, device=dev)
        self.episode_start = torch.zeros(B, dtype=torch.int64, device=dev)
        self.window_episode_steps = torch.zeros(B, dtype=torch.int64, device=dev)
        self.window_episodes = torch.zeros(B, dtype=torch.int64, device=dev)
        self.backups_done = torch.zeros(B, dtype=torch.int64, device=dev)
        self.decisions = torch.zeros(B, dtype=torch.int64, device=dev)
        self.first_goal_step = torch.full((B,), -1, dtype=torch.int64, device=dev)
        self.pending_decisions = torch.zeros(B, dtype=torch.int64, device=dev)
        self._pending = False
        self.metrics = RunMetrics()
        self._pad_state = torch.tensor(S, device=dev)
        self._start_tensor = torch.tensor(self.start_state, device=dev)
        # A world's start distribution [S] (optional): episodes start at a draw from its cdf,
        # using lane 5 of the run's own stream (see _start_states).
        start_distribution = getattr(world, "start_distribution", None)
        self._start_cdf = None
        if start_distribution is not None:
            p = torch.as_tensor(start_distribution, dtype=torch.float64, device=dev)
            if p.shape != (S,) or not bool(torch.isfinite(p).all()) or bool((p < 0).any()) \
                    or abs(float(p.sum()) - 1.0) > 1e-6:
                raise ValueError(f"world.start_distribution must be [S] = [{S}] probabilities "
                                 "summing to 1 (or None)")
            self._start_cdf = p.cumsum(0)
        self._lanes = 6
        # States backed up together per round: a decision's budget in sweep_rounds rounds; with
        # plan_every > 1, the budget of plan_every decisions in as many rounds.
        self._round_size = -(-config.plan_every * config.backups // config.sweep_rounds)
        self._zero = torch.zeros((), dtype=torch.float64, device=dev)
        self._neg_inf = torch.tensor(float("-inf"), dtype=torch.float64, device=dev)
        self._untried = torch.tensor(float(config.untried_value if config.untried_value is not None
                                           else 0.0), dtype=torch.float64, device=dev)
        self._pad_row = torch.tensor(M, device=dev)
        self._any_mentor = bool(self.use_mentor.any())
        self._visit_base = torch.arange(B, device=dev) * (S + 1)
        self._ones_b = torch.ones(B, dtype=torch.int64, device=dev)
        self._u_chunk, self._u_chunk_start = None, -1
        if demonstrations is not None:
            self.add_demonstrations(demonstrations)
        # First starts and options, from draw −1 of each stream (ticks use draws 0, 1, …).
        first = uniforms(self.keys, -1, self._lanes)
        runs = torch.arange(B, device=dev)
        self.position = self._start_states(runs, first).clone()
        self.option_start = self.position.clone()
        self.row = self._choose(runs, self.position, first[:, 3:])

    # ==================================================================================== setup
    def _reward_modules(self, reward, world, B):
        modules = list(reward) if isinstance(reward, (list, tuple)) else [reward] * B
        if len(modules) != B:
            raise ValueError(f"{len(modules)} reward modules for {B} runs: give one, or one per run")
        known = None
        for b, m in enumerate(modules):
            if m is None:
                if not bool(self.use_mentor[b]):
                    modules[b] = _NO_MENTOR_REWARD   # no mentor term: its reward is never used
                    continue
                if getattr(world, "state_reward", None) is None:
                    raise ValueError(f"run {b} ({self.agents[b]}) imitates but no reward module was "
                                     "given and the world has no state_reward for KnownReward; pass "
                                     "reward=… (e.g. a SalienceReward or your own MentorReward)")
                known = known or KnownReward(world)
                modules[b] = known
            elif not hasattr(m, "transition_reward"):
                raise ValueError(f"reward module {m!r} has no transition_reward(sources, successors)")
        return modules

    def _check_world_rewards(self, world) -> None:
        probe = torch.full((1,), self.start_state, dtype=torch.int64, device=self.device)
        for a in range(world.num_actions):
            _, r = world.step(probe, torch.tensor([a], device=self.device),
                              torch.full((1,), 0.5, dtype=torch.float32, device=self.device))
            if not bool(torch.isfinite(r).all()):
                raise ValueError("the world returned a NaN or infinite reward; rewards must be finite")

    def _grow_mentor_reward(self, capacity: int) -> None:
        grown = torch.zeros(self.batch, capacity, dtype=torch.float64, device=self.device)
        grown[:, :self.mentor_edge_reward.shape[1]] = self.mentor_edge_reward
        self.mentor_edge_reward = grown

    def add_demonstrations(self, demonstrations, runs: Sequence[int] | None = None) -> None:
        """Add mentor state sequences to the mentor model of ``runs`` (all by default).

        ``demonstrations`` has ``transitions() -> (from [T], to [T])``; if it also has
        ``check_world(world)``, it is called first (demonstrations of another world are refused).
        """
        if hasattr(demonstrations, "check_world"):
            demonstrations.check_world(self.world)
        src, dst = demonstrations.transitions()
        src = torch.as_tensor(src, dtype=torch.int64, device=self.device)
        dst = torch.as_tensor(dst, dtype=torch.int64, device=self.device)
        if src.numel() and (int(src.min()) < 0 or int(max(src.max(), dst.max())) >= self.num_states):
            raise ValueError(f"demonstrations hold states outside 0…{self.num_states - 1}: they come "
                             "from another world")
        # Episodes end at a terminal state: a "transition" out of one is not the mentor's move.
        keep = ~self.terminal.index_select(0, src)
        src, dst = src[keep], dst[keep]
        run_idx = torch.arange(self.batch, device=self.device) if runs is None else \
            torch.as_tensor(list(runs), dtype=torch.int64, device=self.device)
        self.mentor.observe(src, dst, run_idx)
        self.refresh_mentor_reward()

    def refresh_mentor_reward(self) -> None:
        """Recompute every run's mentor-edge rewards from its reward module and rebuild the mentor
        caches (after demonstrations were added or a reward module changed)."""
        E = self.mentor.edges.num_edges
        src, dst = self.mentor.edges.edge_row[:E], self.mentor.edges.edge_successor[:E]
        real_best = self._real_reward_bound()
        for b, module in enumerate(self.rewards):
            if module is _NO_MENTOR_REWARD:   # a run without a mentor term: nothing to check
                self.mentor_edge_reward[b, :E] = 0.0
                continue
            bound = float(getattr(module, "upper_bound", float("inf")))
            if real_best is not None and bound > real_best + 1e-12 and self.config.reward_bound_check != "off":
                message = (f"reward module {module!r} declares upper_bound={bound:g}, above the "
                           f"learner's best real reward per step {real_best:g}: R_m must not "
                           "overestimate the real reward (eq. 2's guarantee); lower the module's "
                           "scale/bound or set LearnerConfig.reward_bound_check='warn'/'off'")
                if self.config.reward_bound_check == "error":
                    raise ValueError(message)
                warnings.warn(message, stacklevel=3)
            r = torch.as_tensor(module.transition_reward(src, dst), dtype=torch.float64,
                                device=self.device)
            if r.shape != (E,):
                raise ValueError(f"reward module {module!r} returned shape {tuple(r.shape)} for {E} "
                                 "transitions; it must return one reward per transition")
            if not bool(torch.isfinite(r).all()):
                raise ValueError(f"reward module {module!r} returned NaN or infinite rewards")
            if E and float(r.max()) > bound + 1e-12:
                raise ValueError(f"reward module {module!r} returned {float(r.max()):g}, above its "
                                 f"declared upper_bound={bound:g}")
            self.mentor_edge_reward[b, :E] = r
        self._rebuild_mentor_cache()

    def _real_reward_bound(self) -> float | None:
        """The learner's best real reward for one step (``None`` if the world does not say)."""
        reward = getattr(self.world, "state_reward", None)
        return None if reward is None else float(torch.as_tensor(reward).max())

    def _rebuild_mentor_cache(self) -> None:
        E = self.mentor.edges.num_edges
        src, dst = self.mentor.edges.edge_row[:E], self.mentor.edges.edge_successor[:E]
        c = self.mentor.edge_count[:, :E]
        u = self.mentor_edge_reward[:, :E] + self.gamma * self.values[:, dst]
        self.mentor_numerator.zero_()
        self.mentor_second.zero_()
        self.mentor_numerator.index_add_(1, src, c * u)
        self.mentor_second.index_add_(1, src, c * u * u)
        # Every mentor state is worth a backup now.
        observed = self.mentor.observed()
        runs, states = observed.nonzero(as_tuple=True)
        keep = self.use_mentor[runs]
        self.queue.push(runs[keep], states[keep], torch.full_like(states[keep], 1.0, dtype=torch.float64))

    # ============================================================================ value queries
    def _row_flat(self, runs: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        return runs * (self.num_rows + 1) + rows

    def _state_flat(self, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        return runs * (self.num_states + 1) + states

    def row_q(self, runs: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        """Posterior-mean option values ``Q`` of ``rows`` (``runs`` broadcast against them), from
        the cache; untried rows give the prior value ``v0`` if ``concentration > 0`` else ``NaN``."""
        flat = self._row_flat(runs, rows)
        return self._q_at(flat, _take(self.model.row_count, flat))

    def _q_at(self, flat: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
        a, v0 = self.config.concentration, self.config.initial_value
        return (_take(self.q_numerator, flat) + a * v0) / (n + a)

    def mentor_term(self, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        """Posterior-mean mentor term ``R_m(s) + γ Σ p_m(s'|s) V(s')`` (NaN where not observed
        and no prior)."""
        flat = self._state_flat(runs, states)
        return self._mentor_at(flat, _take(self.mentor.row_count, flat))

    def _mentor_at(self, flat: torch.Tensor, n: torch.Tensor) -> torch.Tensor:
        a, v0 = self.config.mentor_concentration, self.config.initial_value
        return (_take(self.mentor_numerator, flat) + a * v0) / (n + a)

    def _row_variance(self, flat, n, q):
        a, v0 = self.config.concentration, self.config.initial_value
        rsum = _take(self.model.row_reward, flat)
        rbar = torch.where(n > 0, rsum / n.clamp(min=1), torch.zeros_like(n))
        cont = _take(self.q_numerator, flat) - rsum
        second = (n * rbar * rbar + 2 * rbar * cont + _take(self.q_second, flat) + a * v0 * v0) / (n + a)
        return (second - q * q).clamp(min=0) / (n + a + 1)

    def _mentor_variance(self, flat, n, m):
        a, v0 = self.config.mentor_concentration, self.config.initial_value
        second = (_take(self.mentor_second, flat) + a * v0 * v0) / (n + a)
        return (second - m * m).clamp(min=0) / (n + a + 1)

    def _own_values(self, runs: torch.Tensor, states: torch.Tensor):
        """Cached ``Q`` of the rows at ``states`` (``runs`` broadcast, ``[..., J]`` out), which rows
        the run may use (``usable``) and the flat row index and counts for further lookups."""
        cfg = self.config
        rows = self.state_rows.index_select(0, states.reshape(-1)).view(*states.shape, -1)
        flat = self._row_flat(runs[..., None], rows)
        n = _take(self.model.row_count, flat)
        q = self._q_at(flat, n)
        enabled = _take(self.row_enabled, flat)
        if cfg.concentration > 0:
            usable = enabled
        elif cfg.untried_value is None:
            usable = enabled & (n > 0)
        else:
            q = torch.where(n > 0, q, self._untried)
            usable = enabled
        return rows, q, usable, enabled, flat, n

    def _state_backup(self, runs: torch.Tensor, states: torch.Tensor):
        """Eq. 2 for ``states [R, n]`` of ``runs [R, 1]`` (or broadcastable): returns
        ``(new V, has_value, mentor_won)``; ``-inf`` where nothing is known."""
        cfg = self.config
        _, q, usable, _, flat_rows, n_rows = self._own_values(runs, states)
        own = torch.where(usable, q, self._neg_inf).amax(-1)
        flat = self._state_flat(runs, states)
        n_m = _take(self.mentor.row_count, flat)
        # The mentor term exists only where the mentor was seen (a prior does not create one).
        mentor_ok = self.use_mentor[runs] & (n_m > 0)
        m = self._mentor_at(flat, n_m)
        if cfg.mentor_override_after is not None:
            mentor_ok = mentor_ok & (_take(self.state_tries, flat) < cfg.mentor_override_after)
        if self._any_confidence and bool(self.use_confidence[runs].any()):
            z = cfg.confidence_z
            var = self._row_variance(flat_rows, n_rows, q)
            upper = torch.where(usable, q + z * var.sqrt(), self._neg_inf).amax(-1)
            confident = (m - z * self._mentor_variance(flat, n_m, m).sqrt()) > upper
            mentor_ok = mentor_ok & (confident | ~self.use_confidence[runs])
        m = torch.where(mentor_ok, m, self._neg_inf)
        best = torch.maximum(own, m)
        # Terminal states (and the padding state) keep V = 0.
        has_value = torch.isfinite(best) & ~self.terminal.index_select(0, states.reshape(-1)).view_as(states)
        return best, has_value, mentor_ok & (m > own)

    # ================================================================================ planning
    def _backup_and_propagate(self, runs: torch.Tensor, states: torch.Tensor, valid: torch.Tensor):
        """Back up ``states [R, n]`` together, then push ``δ`` to the caches of their predecessors
        and raise those predecessors' priorities."""
        best, has_value, _ = self._state_backup(runs[:, None], states)
        flat = self._state_flat(runs[:, None], states)
        old = _take(self.values, flat)
        keep = valid & has_value
        delta = torch.where(keep, best - old, self._zero)
        self.values.view(-1).index_put_((flat[keep],), best[keep])
        self.backups_done.index_add_(0, runs, valid.sum(1))
        changed = delta != 0
        if not bool(changed.any()):
            return
        rr = runs[:, None].expand_as(states)[changed]
        xs, dd, vo = states[changed], delta[changed], old[changed]
        self._propagate_options(rr, xs, dd, vo)
        if self._any_mentor:
            self._propagate_mentor(rr, xs, dd, vo)

    def _propagate_options(self, runs, states, delta, old):
        """``V(x) += δ`` for ``states`` of ``runs``: update the ``Q`` caches of every row with an
        edge to ``x`` and queue the rows' states with priority ``|ΔQ|``."""
        edges, model = self.model.edges, self.model
        owner, e = edges.incoming(states)
        r = runs.index_select(0, owner)
        d = delta.index_select(0, owner)
        rows = edges.edge_row.index_select(0, e)
        flat_e = r * model.edge_count.shape[1] + e
        g = _take(model.edge_discount, flat_e)
        gd = g * d
        flat = self._row_flat(r, rows)
        self.q_numerator.view(-1).index_add_(0, flat, gd)
        if self._any_confidence:
            c = _take(model.edge_count, flat_e).clamp(min=1)
            v_old = old.index_select(0, owner)
            self.q_second.view(-1).index_add_(0, flat, g * g / c * ((v_old + d) ** 2 - v_old ** 2))
        prio = gd.abs() / (_take(model.row_count, flat) + self.config.concentration).clamp(min=1e-300)
        push = (prio > self.config.priority_threshold) & _take(self.row_enabled, flat)
        self.queue.push(r[push], self.row_state.index_select(0, rows[push]), prio[push])

    def _propagate_mentor(self, runs, states, delta, old):
        """The same for the mentor term of every state the mentor left towards ``x``."""
        keep = self.use_mentor.index_select(0, runs)
        runs, states, delta, old = runs[keep], states[keep], delta[keep], old[keep]
        edges, mentor = self.mentor.edges, self.mentor
        owner, e = edges.incoming(states)
        r = runs.index_select(0, owner)
        gd = self.gamma * delta.index_select(0, owner)
        src = edges.edge_row.index_select(0, e)
        flat_e = r * mentor.edge_count.shape[1] + e
        c = _take(mentor.edge_count, flat_e)
        cd = c * gd
        flat = self._state_flat(r, src)
        self.mentor_numerator.view(-1).index_add_(0, flat, cd)
        if self._any_confidence:
            u_old = _take(self.mentor_edge_reward, flat_e) + self.gamma * old.index_select(0, owner)
            self.mentor_second.view(-1).index_add_(0, flat, c * ((u_old + gd) ** 2 - u_old ** 2))
        prio = cd.abs() / (_take(mentor.row_count, flat) + self.config.mentor_concentration).clamp(min=1e-300)
        push = prio > self.config.priority_threshold
        self.queue.push(r[push], src[push], prio[push])

    def _sweep(self, runs: torch.Tensor, budget: torch.Tensor, round_size: int) -> None:
        """Prioritized sweeping for ``runs [R]``: up to ``budget [R]`` backups each, in rounds of
        at most ``round_size`` states per run backed up together. ``round_size`` depends on the
        configuration only, never on the other runs, so a run's sweep is the same in any batch."""
        cfg = self.config
        most = int(budget.max())
        done = 0
        while done < most:
            states, valid = self.queue.pop(runs, round_size, cfg.priority_threshold,
                                           limit=budget - done)
            if not bool(valid.any()):
                break
            self._backup_and_propagate(runs, torch.where(valid, states, self._pad_state), valid)
            done += round_size

    def plan(self, max_rounds: int = 1_000_000) -> int:
        """Sweep every run until its queue is empty (or ``max_rounds`` rounds of ``backups``
        states): the exhaustive path, for checks. Returns the number of rounds."""
        runs = torch.arange(self.batch, device=self.device)
        for i in range(max_rounds):
            states, valid = self.queue.pop(runs, self.config.backups, self.config.priority_threshold)
            if not bool(valid.any()):
                return i
            self._backup_and_propagate(runs, torch.where(valid, states, self._pad_state), valid)
        return max_rounds

    # ============================================================================ model update
    def _update_model(self, runs, rows, starts, ends, durations, returns):
        """Count one executed option per run (Dirichlet update) and fold it into the ``Q`` cache."""
        model = self.model
        e = model.edges.find_or_add(rows, ends)
        discount = self.gamma ** durations.double()
        v_end = _take(self.values, self._state_flat(runs, ends))
        flat_e = runs * model.edge_count.shape[1] + e
        c_old = _take(model.edge_count, flat_e)
        g_old = _take(model.edge_discount, flat_e)
        c_new, g_new = c_old + 1, g_old + discount
        model.edge_count.view(-1).index_put_((flat_e,), c_new)
        model.edge_discount.view(-1).index_put_((flat_e,), g_new)
        flat_r = self._row_flat(runs, rows)
        model.row_count.view(-1).index_add_(0, flat_r, torch.ones_like(discount))
        model.row_reward.view(-1).index_add_(0, flat_r, returns)
        self.q_numerator.view(-1).index_add_(0, flat_r, returns + discount * v_end)
        if self._any_confidence:
            old_term = torch.where(c_old > 0, g_old * g_old / c_old.clamp(min=1), self._zero)
            self.q_second.view(-1).index_add_(0, flat_r, (g_new * g_new / c_new - old_term) * v_end * v_end)
        self.state_tries.view(-1).index_add_(0, self._state_flat(runs, starts), torch.ones_like(discount))
        # The changed state goes first in this decision's sweep.
        self.queue.push(runs, starts, torch.full_like(returns, float("inf")))

    # =================================================================================== choice
    def _choose(self, runs: torch.Tensor, states: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """ε-greedy choice of a row at ``states`` for ``runs``; ``u [R, 2]`` uniforms (ε, pick).

        Greedy: the best usable rows (within 1e-12), one of them uniformly (or the first, with
        ``tie_break="first"``); if none is usable yet (nothing tried here), any enabled row.
        Exploring: any enabled row, uniformly.
        """
        rows, q, usable, enabled, _, _ = self._own_values(runs, states)
        q = torch.where(usable, q, self._neg_inf)
        if self.config.mentor_choice == "match" and self._any_mentor:
            q = self._match_mentor(runs, states, rows, q, usable)
        greedy = usable & (q >= q.amax(1, keepdim=True) - _TIE)
        greedy = torch.where(greedy.any(1, keepdim=True), greedy, enabled)
        explore = u[:, 0] < self.epsilon[runs]
        candidates = torch.where(explore[:, None], enabled, greedy)
        count = candidates.sum(1)
        pick = (u[:, 1] * count).long().clamp(max=count - 1)                # k-th candidate
        if self.config.tie_break == "first":
            pick = torch.where(explore, pick, torch.zeros_like(pick))
        slot = ((candidates.cumsum(1) == (pick + 1)[:, None]) & candidates).long().argmax(1)
        return rows.gather(1, slot[:, None])[:, 0]

    def _match_mentor(self, runs, states, rows, q, usable):
        """``mentor_choice="match"``: where the mentor term wins, rank own options first by how
        well their first action's learned one-step model reproduces the mentor's move, then by
        ``Q`` (returned as a score with the same shape as ``q``)."""
        _, _, won = self._state_backup(runs[:, None], states[:, None])
        won = won[:, 0]
        if not bool(won.any()):
            return q
        S, A = self.num_states, self.world.num_actions
        # One-step model p̂(s'|s,a) of each primitive at s, and the mentor's p_m(s'|s).
        prim = self.primitive_rows.index_select(0, states)                         # [R, A]
        p_succ, p_w = self._successor_probs(self.model, runs[:, None], prim)       # [R, A, K]
        m_succ, m_w = self._successor_probs(self.mentor, runs, states)             # [R, Km]
        same = p_succ[..., :, None] == m_succ[:, None, None, :]                   # [R, A, K, Km]
        score_a = (same * p_w[..., None] * m_w[:, None, None, :]).sum((-1, -2))   # [R, A]
        flat = self.row_option.index_select(0, rows.view(-1)).view_as(rows) * S + states[:, None]
        first = self.policy.index_select(0, flat.view(-1)).view_as(rows) if self.policy is not None \
            else self.policy_cdf.index_select(0, flat.view(-1)).diff(
                dim=-1, prepend=torch.zeros(flat.numel(), 1, dtype=torch.float64, device=self.device)
            ).argmax(-1).view_as(rows)
        score = score_a.gather(1, first.clamp(max=A - 1))                          # [R, J]
        score = torch.where(usable, score, torch.zeros_like(score))
        best = score.amax(1, keepdim=True)
        use = won[:, None] & (best > 0)
        # Matching options outrank the rest; among them, Q decides.
        lifted = torch.where(score >= best - _TIE, q + 1e6, q)
        return torch.where(use, lifted, q)

    @staticmethod
    def _successor_probs(model, runs, rows):
        """Posterior-mean successor probabilities ``(successors [..., K], probs [..., K])`` of
        ``rows`` (shape ``[...]``, ``runs`` broadcast) in a count model (maximum likelihood)."""
        edges = model.edges
        e = edges.forward.index_select(0, rows.reshape(-1)).view(*rows.shape, -1)
        ok = e >= 0
        ec = e.clamp(min=0)
        r = runs.expand_as(rows)[..., None]
        counts = torch.where(ok, _take(model.edge_count, r * model.edge_count.shape[1] + ec),
                             torch.zeros((), dtype=torch.float64, device=e.device))
        n = _take(model.row_count, runs.expand_as(rows) * model.row_count.shape[1] + rows)
        succ = torch.where(ok, edges.edge_successor.index_select(0, ec.view(-1)).view_as(ec),
                           torch.full_like(e, -1))
        return succ, counts / n.clamp(min=1)[..., None]

    # ================================================================================ stepping
    def _tick_uniforms(self) -> torch.Tensor:
        """``[B, 6]`` uniforms of tick ``t``: 0 slip, 1 termination or action, 2 termination
        (stochastic policies), 3 ε, 4 which of the candidate options, 5 the start state after a
        goal (worlds with a start distribution)."""
        chunk = self.config.rng_chunk
        i = self.t % chunk
        if self._u_chunk is None or self._u_chunk_start != self.t - i:
            self._u_chunk_start = self.t - i
            counters = torch.arange(self._u_chunk_start, self._u_chunk_start + chunk,
                                    device=self.device)
            self._u_chunk = uniforms(self.keys, counters, self._lanes)
        return self._u_chunk[i]

    def step(self) -> None:
        """Advance every run one primitive step (one tick)."""
        cfg, S = self.config, self.num_states
        u = self._tick_uniforms()
        option = self.row_option[self.row]
        flat = option * S + self.position
        if self.policy is not None:
            action = self.policy[flat]
            stop_u = u[:, 1]
        else:
            action = torch.searchsorted(self.policy_cdf[flat], u[:, 1:2].contiguous()).squeeze(1)
            action = action.clamp(max=self.policy_cdf.shape[1] - 1)
            stop_u = u[:, 2]
        nxt, reward = self.world.step(self.position, action, u[:, 0])
        self.discounted_return += self.discount * reward
        self.discount *= self.gamma
        self.duration += 1
        self.t += 1
        at_goal = self.terminal[nxt]
        ended = at_goal | (self.termination[option * S + nxt] > stop_u) \
            | (self.duration >= cfg.max_option_steps)
        self.position = nxt
        self.visits.view(-1).index_add_(0, self._visit_base + nxt, self._ones_b)
        if bool(at_goal.any()):
            self._goal_reached(at_goal)
        if bool(ended.any()):
            runs = ended.nonzero()[:, 0]
            self._decide(runs, at_goal[runs], u[runs])
        if self._pending and self.t % cfg.plan_every == 0:
            runs = (self.pending_decisions > 0).nonzero()[:, 0]
            self._sweep(runs, self.pending_decisions[runs] * cfg.backups, self._round_size)
            self.pending_decisions.zero_()
            self._pending = False
        if self.t % cfg.window == 0:
            self._close_window()

    def _decide(self, runs: torch.Tensor, at_goal: torch.Tensor, u: torch.Tensor) -> None:
        """Runs whose option just ended: learn from it, plan, choose the next option."""
        cfg = self.config
        end = self.position[runs]
        self._update_model(runs, self.row[runs], self.option_start[runs], end,
                           self.duration[runs], self.discounted_return[runs])
        if cfg.plan_every == 1:
            self._sweep(runs, torch.full_like(runs, cfg.backups), self._round_size)
        else:
            self.pending_decisions[runs] += 1
            self._pending = True
        self.decisions[runs] += 1
        eps = self.epsilon[runs]
        self.epsilon[runs] = torch.where(self.found_goal[runs], (eps * cfg.eps_decay).clamp(min=cfg.eps_min), eps)
        self.duration[runs] = 0
        self.discounted_return[runs] = 0.0
        self.discount[runs] = 1.0
        here = torch.where(at_goal, self._start_states(runs, u), end)
        self.position[runs] = here
        self.option_start[runs] = here
        self.row[runs] = self._choose(runs, here, u[:, 3:])

    def _start_states(self, runs: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """``[R]`` states where new episodes of ``runs`` start: ``world.start_state``, or for a
        world with a ``start_distribution`` the state whose cdf interval holds ``u[:, 5]`` (lane 5
        of the run's uniforms ``u [R, lanes]``: of draw −1 for the first start, of the tick at a
        goal), so starts depend on the run's seed alone."""
        if self._start_cdf is None:
            return self._start_tensor.expand(runs.shape[0])
        picked = torch.searchsorted(self._start_cdf, u[:, 5].contiguous(), right=True)
        return picked.clamp(max=self.num_states - 1)

    def _goal_reached(self, at_goal: torch.Tensor) -> None:
        self.goals += at_goal
        self.window_goals += at_goal
        first = at_goal & ~self.found_goal
        self.first_goal_step = torch.where(first, torch.full_like(self.first_goal_step, self.t),
                                           self.first_goal_step)
        self.found_goal |= at_goal
        self.episodes += at_goal
        length = self.t - self.episode_start
        self.window_episode_steps += torch.where(at_goal, length, torch.zeros_like(length))
        self.window_episodes += at_goal
        self.episode_start = torch.where(at_goal, torch.full_like(self.episode_start, self.t),
                                         self.episode_start)

    def _close_window(self) -> None:
        m = self.metrics
        m.steps.append(self.t)
        m.goals_in_window.append(self.window_goals.cpu().clone())
        m.epsilon.append(self.epsilon.cpu().clone())
        m.episodes.append(self.episodes.cpu().clone())
        m.mean_episode_steps.append(torch.where(
            self.window_episodes > 0, self.window_episode_steps / self.window_episodes.clamp(min=1),
            torch.full((self.batch,), float("nan"), dtype=torch.float64, device=self.device)).cpu())
        m.backups.append(self.backups_done.cpu().clone())
        m.decisions.append(self.decisions.cpu().clone())
        m.mentor_term_wins.append(self.mentor_win_share().cpu())
        self.window_goals.zero_()
        self.window_episode_steps.zero_()
        self.window_episodes.zero_()

    def run(self, steps: int, progress: bool = False) -> RunMetrics:
        """Advance all runs ``steps`` primitive steps; returns the metrics so far."""
        if steps < 0:
            raise ValueError(f"steps={steps} must be ≥ 0")
        iterator = range(steps)
        if progress:
            from tqdm.auto import tqdm
            iterator = tqdm(iterator, desc=f"{self.batch} runs", unit="step", mininterval=1.0)
        for _ in iterator:
            self.step()
        return self.metrics

    # ============================================================================ checkpoints
    _STATE = ("values", "q_numerator", "q_second", "mentor_numerator", "mentor_second",
              "mentor_edge_reward", "state_tries", "position", "option_start", "row", "duration",
              "discounted_return", "discount", "epsilon", "found_goal", "goals", "window_goals",
              "episodes", "episode_start", "window_episode_steps", "window_episodes",
              "backups_done", "decisions", "first_goal_step", "pending_decisions", "visits")

    def state_dict(self) -> dict:
        """Everything that changes while learning (models, values, queue, run state, metrics):
        with the same world, options, agents, seeds and config, :meth:`load_state_dict` continues
        exactly where this left off."""
        state = {name: getattr(self, name).clone() for name in self._STATE}
        state.update(t=self.t, pending=self._pending, model=self.model.state_dict(),
                     mentor=self.mentor.state_dict(),
                     queue={"priority": self.queue.priority.clone(),
                            "block_max": self.queue.block_max.clone()},
                     metrics={k: list(v) for k, v in vars(self.metrics).items()},
                     identity={"agents": self.agents, "seeds": self.seeds,
                               "num_states": self.num_states, "num_options": self.num_options,
                               "num_rows": self.num_rows, "config": asdict(self.config)})
        return state

    def load_state_dict(self, state: dict) -> None:
        """Restore a :meth:`state_dict` (refuses one from a different batch or configuration)."""
        ident = state["identity"]
        mine = {"agents": self.agents, "seeds": self.seeds, "num_states": self.num_states,
                "num_options": self.num_options, "num_rows": self.num_rows,
                "config": asdict(self.config)}
        differ = sorted(k for k in mine if mine[k] != ident.get(k))
        if differ:
            raise ValueError(f"checkpoint does not match this learner: {differ} differ")
        self.model.load_state_dict(state["model"])
        self.mentor.load_state_dict(state["mentor"])
        for name in self._STATE:
            setattr(self, name, state[name].to(self.device).clone())
        self.queue.priority = state["queue"]["priority"].to(self.device).clone()
        self.queue.block_max = state["queue"]["block_max"].to(self.device).clone()
        self.t, self._pending = int(state["t"]), bool(state["pending"])
        self.metrics = RunMetrics(**{k: list(v) for k, v in state["metrics"].items()})
        self._u_chunk, self._u_chunk_start = None, -1

    # =============================================================================== diagnostics
    def mentor_win_share(self) -> torch.Tensor:
        """``[B]`` share of mentor-observed states where the mentor term is the max of eq. 2
        (NaN for runs that do not imitate)."""
        observed = self.mentor.observed()
        out = torch.full((self.batch,), float("nan"), dtype=torch.float64, device=self.device)
        if not bool(observed.any()):
            return out
        states = observed.any(0).nonzero()[:, 0]
        runs = torch.arange(self.batch, device=self.device)
        _, _, won = self._state_backup(runs[:, None], states[None].expand(self.batch, -1))
        frac = (won & observed[:, states]).sum(1).double() / observed.sum(1).clamp(min=1)
        return torch.where(self.use_mentor, frac, out)

    def greedy_options(self) -> torch.Tensor:
        """``[B, S]`` greedy option per state (−1 where none is usable), ties to the lowest row."""
        runs = torch.arange(self.batch, device=self.device)[:, None, None]
        rows = self.state_rows[:self.num_states][None]
        q = self.row_q(runs, rows)
        usable = self.row_enabled[runs, rows] & (self.model.row_count[runs, rows] > 0)
        q = torch.where(usable, q, torch.full_like(q, float("-inf")))
        best = q.argmax(-1)
        option = self.row_option[rows.expand(self.batch, -1, -1).gather(2, best[..., None])[..., 0]]
        return torch.where(usable.any(-1), option, torch.full_like(option, -1))

    def visit_counts(self) -> torch.Tensor:
        """``[B, S]`` how often each run has been in each state (after each primitive step)."""
        return self.visits[:, :self.num_states]

    def model_coverage(self) -> torch.Tensor:
        """``[B]`` share of the run's usable ``(s, o)`` rows it has tried at least once."""
        enabled = self.row_enabled[:, :self.num_rows]
        tried = (self.model.row_count[:, :self.num_rows] > 0) & enabled
        return tried.sum(1).double() / enabled.sum(1).clamp(min=1)

    def greedy_trajectory(self, run: int, max_steps: int, seed: int = 0) -> torch.Tensor:
        """States of one episode from the start following run ``run``'s greedy options (ε = 0,
        untried options at random), with the world's slip; stops at the goal or after
        ``max_steps``. For pictures like the paper's Fig. 2."""
        gen = torch.Generator(device=self.device).manual_seed(seed)
        greedy = self.greedy_options()[run]
        S = self.num_states
        s = torch.tensor([self.start_state], device=self.device)
        states = [int(s)]
        option, steps = -1, 0
        while steps < max_steps and not bool(self.terminal[s]):
            if option < 0:
                option = int(greedy[s])
                if option < 0:   # nothing tried here: any usable option
                    rows = self.state_rows[s][0]
                    rows = rows[self.row_enabled[run, rows]]
                    option = int(self.row_option[rows[torch.randint(len(rows), (1,), generator=gen,
                                                                    device=self.device)]])
            flat = option * S + s
            if self.policy is not None:
                action = self.policy[flat]
            else:
                action = torch.multinomial(torch.diff(self.policy_cdf[flat], prepend=torch.zeros(
                    1, 1, dtype=torch.float64, device=self.device)), 1, generator=gen)[:, 0]
            u = torch.rand(s.shape, generator=gen, device=self.device)  # the world's slip draw
            s, _ = self.world.step(s, action, u)
            steps += 1
            states.append(int(s))
            stop = torch.rand(1, generator=gen, device=self.device, dtype=torch.float64)
            if bool(self.terminal[s]) or bool(self.termination[option * S + s] > stop):
                option = -1
        return torch.tensor(states)

    def state_values(self) -> torch.Tensor:
        """``[B, S]`` current value estimates."""
        return self.values[:, :self.num_states]

    def summary(self) -> dict:
        return {"steps": self.t, "goals": self.goals.tolist(), "episodes": self.episodes.tolist(),
                "first_goal_step": self.first_goal_step.tolist(), "epsilon": self.epsilon.tolist(),
                "backups": self.backups_done.tolist(), "decisions": self.decisions.tolist(),
                "config": asdict(self.config)}
