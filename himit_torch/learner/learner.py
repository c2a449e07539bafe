"""The hierarchical imitation learner: ``B`` independent runs advancing together.

Each run executes its current option one primitive step per tick. Runs whose option ended this
tick update their Dirichlet SMDP model, plan with prioritized sweeping on the augmented Bellman
equation (the paper's eq. 2, or a baseline), and pick their next option ε-greedily.

The state has one owner per piece, each with its own ``state_dict``:

* :class:`~himit_torch.learner.rows.RowTable` — the available ``(s, o)`` rows and each run's variant
  (fixed);
* :class:`~himit_torch.DirichletSMDPModel`, :class:`~himit_torch.DirichletMentorModel` — the
  counts (only they write counts);
* :class:`~himit_torch.learner.values.ValueCache` — ``V`` and the cached numerators of eq. 2 (only it
  writes ``V``);
* :class:`~himit_torch.learner.posterior_sampling.PosteriorSample` — the sampled successor probabilities
  of the runs that plan on a posterior draw (the ``…_psrl`` agents);
* :class:`~himit_torch.learner.prioritized_sweeping.Sweeper` — the prioritized-sweeping queue and schedule (only it
  touches the queue);
* :class:`~himit_torch.learner.cloned_policy.ClonedPolicy` — the ``bco`` runs' cloned actions
  (refitted every ``bco_every`` ticks, between the engine's calls);
* :class:`~himit_torch.learner.run_state.RunState` — the executing options, exploration and counters;
  :class:`~himit_torch.learner.run_state.RunMetrics` — the per-window records.

What only reads that state — the counters, diagnostics and greedy policies
(``learner.views.goals``, ``learner.views.greedy_policy()``) — is one object,
:class:`~himit_torch.learner.inspect.LearnerViews` (``learner.views``).

An engine carries out the ticks on that state (:mod:`himit_torch.learner.engines`): ``"numba"``, a
compiled per-run loop (the default on a CPU), or ``"torch"``, batched tensor ops (any device;
the readable reference, read :meth:`TorchEngine.tick <himit_torch.learner.engines.TorchEngine.tick>`).

Shapes: ``B`` runs, ``S`` states, ``O`` options, ``M`` rows, ``E`` model edges per run.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import asdict
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import torch

from himit_torch.learner.agents import AGENTS
from himit_torch.learner.backups import segment_reward
from himit_torch.learner.cloned_policy import ClonedPolicy
from himit_torch.learner.engines import make_engine
from himit_torch.learner.engines.kernel.arrays import WINDOW_COUNTS
from himit_torch.learner.inspect import LearnerViews, mentor_win_share_of
from himit_torch.learner.models import DirichletMentorModel, DirichletSMDPModel
from himit_torch.learner.posterior_sampling import PosteriorSample
from himit_torch.learner.prioritized_sweeping import Sweeper
from himit_torch.learner.rows import RowTable
from himit_torch.learner.run_state import RunMetrics, RunState
from himit_torch.learner.state import LANES, BatchState, WorldTables
from himit_torch.learner.values import ValueCache
from himit_torch.mentor.potential import shaping_potential
from himit_torch.mentor.reward import KnownReward
from himit_torch.options.bundle import Options
from himit_torch.rng import seed_streams, uniforms
from himit_torch.state_checks import DamagedState, in_range, same_plain, section
from himit_torch.validation import (
    COUNT_MAX,
    as_choice,
    as_device,
    as_float,
    as_float_array,
    as_index_tensor,
    as_int,
    as_int_array,
    check_memory,
    settings_of,
)

if TYPE_CHECKING:
    from himit_torch.mentor.demonstrations import Demonstrations
    from himit_torch.mentor.reward import MentorReward
    from himit_torch.worlds.tabular import TabularWorld

from himit_torch.learner.config import CONFIG_SCHEMA_VERSION, LearnerConfig

__all__ = ["HasTransitions", "Learner"]


class HasTransitions(Protocol):
    """Demonstrations in any form: consecutive mentor states ``(from [T], to [T])``."""

    def transitions(self) -> tuple[torch.Tensor, torch.Tensor]: ...


class _NoMentorReward:
    """The mentor reward of runs that do not imitate: never used, zero."""

    upper_bound = 0.0

    def transition_reward(self, sources: torch.Tensor, successors: torch.Tensor) -> torch.Tensor:
        return torch.zeros(sources.shape, dtype=torch.float64, device=sources.device)

    def __repr__(self) -> str:
        return "no mentor reward"


_NO_MENTOR_REWARD = _NoMentorReward()


def _checked_runs(agents: Sequence[str], seeds: Sequence[int]) -> tuple[list[str], list[int]]:
    """The batch's agents and seeds, one per run, checked."""
    for name, what in (("agents", agents), ("seeds", seeds)):
        if isinstance(what, (str, bytes)) or not isinstance(what, Iterable):
            raise ValueError(f"{name} must be a list (one per run), got {what!r}")
    runs = list(agents)
    keys: list[int] = as_int_array("seeds", seeds, minimum=0).tolist()  # int64 stream keys
    B = len(runs)
    if B == 0:
        raise ValueError("a batch of 0 runs: give at least one agent (e.g. agents=['imitation'])")
    if len(keys) != B:
        raise ValueError(f"{B} agents but {len(keys)} seeds: give one seed per run")
    unknown = sorted({repr(a) for a in runs if not isinstance(a, str) or a not in AGENTS})
    if unknown:
        raise ValueError(f"unknown agent variant(s) {unknown}; use one of {sorted(AGENTS)}")
    return runs, keys


def _checked_world(world: TabularWorld, options: Options, config: LearnerConfig) -> int:
    """Check that ``world`` follows the protocol and ``options`` fit it; its action count."""
    missing = [
        m
        for m in ("num_states", "num_actions", "start_state", "gamma", "terminal_mask")
        if not hasattr(world, m)
    ]
    if missing:
        raise ValueError(
            f"world {type(world).__name__} lacks {missing}: a world must follow the "
            "TabularWorld protocol (himit_torch.TabularWorld)"
        )
    S = world.num_states
    if options.num_states != S:
        raise ValueError(f"options are over {options.num_states} states but the world has {S}")
    gamma = as_float("world.gamma", world.gamma)
    if not 0 < gamma <= 1:
        raise ValueError(f"world.gamma={world.gamma} must lie in (0, 1]")
    if config.mentor_segments and gamma == 1:
        raise ValueError(
            "LearnerConfig.mentor_segments needs a discounted world (γ < 1; this world's "
            "is 1): a mentor move of unseen steps cannot be summed undiscounted; set "
            "mentor_segments=False"
        )
    A = as_int("world.num_actions", world.num_actions, minimum=1)
    if options.stochastic and options.policy.shape[2] != A:
        raise ValueError(
            f"options' policy probabilities are over {options.policy.shape[2]} "
            f"actions but the world has {A}"
        )
    if not options.stochastic and int(options.policy[options.initiation].max()) >= A:
        raise ValueError(
            f"options' policy uses action {int(options.policy[options.initiation].max())}"
            f" but the world has actions 0…{A - 1}"
        )
    return A


#: The views' names on the learner itself, deprecated aliases of ``learner.views.NAME`` (they
#: warn; removed in the next version).
DEPRECATED_VIEW_NAMES = (
    "t",
    "goals",
    "episodes",
    "first_goal_step",
    "decisions",
    "backups_done",
    "epsilon",
    "found_goal",
    "sampling_runs",
    "mentor_win_share",
    "greedy_options",
    "greedy_policy",
    "visit_counts",
    "model_coverage",
    "greedy_trajectory",
    "state_values",
    "summary",
)


def _view_alias(name: str) -> property:
    """``learner.NAME``: ``learner.views.NAME`` with a ``DeprecationWarning``."""

    def read(self: Learner) -> Any:
        warnings.warn(
            f"Learner.{name} is deprecated and goes in the next version: use learner.views.{name}",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(self.views, name)

    return property(read, doc=f"Deprecated alias of ``learner.views.{name}``.")


class Learner:
    """``B`` runs of the hierarchical imitation learner (or its baselines) in one batch.

    Args:
        world: a :class:`~himit_torch.TabularWorld` (``num_states``, ``num_actions``,
            ``start_state``, ``gamma``, ``terminal_mask``, ``step``; optionally
            ``dynamics_table()``, which the compiled engine needs, and ``start_distribution``
            ``[S]``, from which each episode's start is drawn).
        options: the options of the batch (the union; :data:`AGENTS` restricts them per run).
        agents: one agent variant per run, from :data:`AGENTS`.
        seeds: one seed per run; run ``b``'s randomness depends only on ``seeds[b]``.
        config: :class:`LearnerConfig`.
        demonstrations: mentor demonstrations (anything with ``transitions()``, else a
            ``TypeError``), given to every run; more can be added with :meth:`add_demonstrations`.
        reward: the reward module for the mentor term, one for all runs or one per run
            (default :class:`~himit_torch.KnownReward` of the world; ``None`` in a per-run list
            for runs that do not imitate). A module fitted on demonstrations (e.g.
            :class:`~himit_torch.SalienceReward`) is not refitted by :meth:`add_demonstrations`:
            call its ``fit`` with all demonstrations, then :meth:`refresh_mentor_reward`.
        device: where all tensors live: ``cpu`` or a CUDA device this machine has (anything
            else, ``meta`` or ``cuda`` without CUDA, is a ``ValueError`` naming those that would
            work).
        engine: ``"auto"`` (the compiled ``"numba"`` engine on a CPU when it can run the world,
            else ``"torch"``), ``"numba"`` or ``"torch"``. Both give the same decisions; switch
            with :meth:`use_engine`.

    What it has learned is read through ``learner.views`` (:class:`~himit_torch.LearnerViews`:
    ``learner.views.goals``, ``learner.views.greedy_policy()``, …). The same names on the learner
    itself (``learner.goals``, …) are deprecated aliases of those: they warn
    (``DeprecationWarning``) and go in the next version.
    """

    #: Version of the layout of :meth:`state_dict` (1: batch-shared edge index, before engines).
    STATE_LAYOUT_VERSION = 2
    #: Uniforms per run and tick (:data:`himit_torch.learner.state.LANES`).
    LANES = LANES

    #: Bytes per run and state / per run and ``(s, o)`` row that the up-front size check of a
    #: batch multiplies by (the value cache, models, queue and engine tables at the start; the
    #: models' edge lists grow with experience beyond that).
    BYTES_PER_RUN_STATE = 128
    BYTES_PER_RUN_ROW = 96

    def __init__(
        self,
        world: TabularWorld,
        options: Options,
        agents: Sequence[str],
        seeds: Sequence[int],
        config: LearnerConfig | None = None,
        demonstrations: Demonstrations | HasTransitions | None = None,
        reward: MentorReward | Sequence[MentorReward | None] | None = None,
        device: str | torch.device = "cpu",
        engine: str = "auto",
    ):
        if config is not None and not isinstance(config, LearnerConfig):
            raise ValueError(f"config must be a LearnerConfig, got {type(config).__name__}")
        self.config = config = config or LearnerConfig()
        #: The read-only views: :class:`~himit_torch.LearnerViews`.
        self.views = LearnerViews(self)
        if not isinstance(options, Options):
            raise ValueError(f"options must be an Options bundle, got {type(options).__name__}")
        self.world, self.options = world, options
        self.device = dev = as_device("device", device)
        as_choice("engine", engine, ("auto", "numba", "torch"))
        agents, seeds = _checked_runs(agents, seeds)
        A = _checked_world(world, options, config)
        B, S, O = len(agents), world.num_states, options.num_options
        self._check_memory(B, S, options)
        self.batch, self.num_states, self.num_options = B, S, O
        self.agents, self.seeds = agents, seeds
        self._build_state(world, options, dev)
        first = uniforms(self.keys, -1, self.LANES)  # draw −1: the first start and option
        runs = torch.arange(B, device=dev)
        self._start_runs(first, runs, A, dev)
        self._add_rewards_and_demonstrations(world, reward, demonstrations)
        self.resample(self.views.sampling_runs())  # the sampling runs' first model
        self._choose_first_rows(first, runs)
        self.engine = make_engine(engine, self.state)

    # ---------------------------------------------------------------- __init__'s steps
    def _check_memory(self, B: int, S: int, options: Options) -> None:
        """Refuse a batch too large for the memory, before it is built."""
        M = int(options.initiation.sum())
        check_memory(
            f"a batch of {B} runs over {S:,} states and {M:,} (state, option) rows",
            B * (S * self.BYTES_PER_RUN_STATE + M * self.BYTES_PER_RUN_ROW),
            "run fewer runs at once (a smaller batch), or fewer options",
        )

    def _build_state(self, world: TabularWorld, options: Options, dev: torch.device) -> None:
        """The world and options as tables both engines read, and the state, one owner per
        piece: rows, models, random streams, posterior sample, value cache, sweeper."""
        config, B, S = self.config, self.batch, self.num_states
        self.tables = tables = WorldTables.build(world, options, dev)
        self.gamma = tables.gamma
        self.terminal = tables.terminal
        self.start_state = tables.start_state
        self.rows = RowTable(options, world.num_actions, self.agents, dev)
        if bool(self.rows.use_shaping.any()) and (
            config.concentration > 0 or config.untried_value is not None
        ):
            raise ValueError(
                "the shaping agents (pbrs…) need concentration=0 and untried_value=None: "
                "shaping is carried out as its equivalent start values v0 + Φ(s) (Wiewiora "
                "2003; backups.shaped_option_backup), and the prior's unseen outcome and "
                "untried options, which would need the same shift, are not shifted"
            )
        self.num_rows = M = self.rows.num_rows
        self.model = DirichletSMDPModel(M, S, B, dev, config.concentration)
        self.mentor = DirichletMentorModel(
            S, B, dev, config.mentor_concentration, mentors=config.mentors
        )
        self.keys: torch.Tensor = seed_streams(
            torch.tensor(self.seeds, dtype=torch.int64, device=dev)
        )
        self.sample = PosteriorSample(self.rows, self.model, self.mentor, self.keys, config)
        self.cache = ValueCache(
            config, self.rows, self.model, self.mentor, self.terminal, self.gamma, self.sample
        )
        self.sweeper = Sweeper(
            B,
            S,
            dev,
            config.backups,
            config.sweep_rounds,
            config.plan_every,
            config.priority_threshold,
        )

    def _start_runs(
        self, first: torch.Tensor, runs: torch.Tensor, A: int, dev: torch.device
    ) -> None:
        """Each run's first start, its cloned policy, metrics and the batch state the engines
        read."""
        config, B, S, M = self.config, self.batch, self.num_states, self.num_rows
        self.run_state = RunState(B, S, self.start_states(runs, first), M, config.eps_start, dev)
        self.cloning = ClonedPolicy(self.rows, A, config.bco_inverse_model, dev)
        self.metrics = RunMetrics()
        self.state: BatchState = BatchState(
            config,
            self.tables,
            self.rows,
            self.model,
            self.mentor,
            self.cache,
            self.sample,
            self.sweeper,
            self.run_state,
            self.keys,
            self.cloning,
        )

    def _add_rewards_and_demonstrations(self, world, reward, demonstrations) -> None:
        """Exact option models where asked, the mentor reward modules, and the demonstrations
        (one set per mentor)."""
        config, B = self.config, self.batch
        if config.option_models == "exact":
            self._load_exact_option_models()
        self.rewards = self._reward_modules(reward, world, B)
        self._check_world_rewards(world)
        if isinstance(demonstrations, (list, tuple)):  # one demonstration set per mentor
            if len(demonstrations) != config.mentors:
                raise ValueError(
                    f"{len(demonstrations)} demonstration sets for LearnerConfig.mentors="
                    f"{config.mentors}: give one set per mentor (or set mentors="
                    f"{len(demonstrations)})"
                )
            for k, demos in enumerate(demonstrations):
                self.add_demonstrations(demos, mentor=k)
        elif demonstrations is not None:
            self.add_demonstrations(demonstrations)

    def _choose_first_rows(self, first: torch.Tensor, runs: torch.Tensor) -> None:
        """Every run's first option at its start state."""
        config = self.config
        from himit_torch.learner.choice import choose_rows

        self.run_state.row = choose_rows(
            self.cache,
            runs,
            self.run_state.position,
            first[:, 3:5],
            self.run_state.epsilon,
            config.mentor_choice,
            config.tie_break,
            self.cloning.at(runs, self.run_state.position) if self.cloning.any else None,
        )

    # ============================================================================ engines
    def use_engine(self, engine: str) -> None:
        """Carry out the following ticks with ``engine`` (``"auto"``, ``"numba"``, ``"torch"``);
        the state is shared, so runs go on exactly where they are."""
        self.engine = make_engine(engine, self.state)

    def step_world(self, positions: torch.Tensor, actions: torch.Tensor, u: torch.Tensor):
        """One primitive step of the world for ``positions [B]`` (its table when it has one)."""
        return self.tables.step(positions, actions, u)

    def start_states(self, runs: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Start states of a new episode for ``runs [R]`` from their uniforms ``u [R, LANES]``
        (lane 5): ``start_state``, or a draw from the world's ``start_distribution``."""
        return self.tables.start_states(runs, u)

    # ==================================================================================== setup
    def _reward_modules(self, reward, world, B):
        modules = list(reward) if isinstance(reward, (list, tuple)) else [reward] * B
        if len(modules) != B:
            raise ValueError(
                f"{len(modules)} reward modules for {B} runs: give one, or one per run"
            )
        known = None
        for b, m in enumerate(modules):
            if m is None:
                if not AGENTS[self.agents[b]].uses_demonstrations:
                    modules[b] = _NO_MENTOR_REWARD  # no mentor term: its reward is never used
                    continue
                if getattr(world, "state_reward", None) is None and self.tables.dynamics is None:
                    raise ValueError(
                        f"run {b} ({self.agents[b]}) reads the demonstrations (mentor term or "
                        "shaping potential) but no reward module was "
                        "given and the world has neither a state_reward nor a "
                        "dynamics_table() for KnownReward; pass reward=… (e.g. a "
                        "SalienceReward or your own MentorReward)"
                    )
                known = known or KnownReward(world)
                modules[b] = known
            elif not hasattr(m, "transition_reward"):
                raise ValueError(
                    f"reward module {m!r} has no transition_reward(sources, successors)"
                )
        return modules

    def _load_exact_option_models(self) -> None:
        """Preload every run's option model with the exact models (``LearnerConfig.option_models
        = "exact"``; see there), fill the ``Q`` caches from them and queue the states whose value
        a backup would change."""
        from himit_torch.exact.option_models import option_models_and_durations

        N = float(self.config.exact_model_count)
        S, O, dev = self.num_states, self.num_options, self.device
        # Σγ^k weights and rewards; termination probabilities
        disc, prob = option_models_and_durations(self.world, self.options)
        # Row of the exact models → row of the learner (both enumerate the initiation sets).
        key = self.rows.row_state[:-1] * O + self.rows.row_option[:-1]
        order = torch.argsort(key)
        exact_rows = order[
            torch.searchsorted(key[order], (disc.row_state * O + disc.row_option).to(dev))
        ]
        coo_d = disc.transition.to_sparse_coo().coalesce()
        coo_p = prob.transition.to_sparse_coo().coalesce()
        # Union of the two supports, per (row, successor): weights, probabilities (0 if absent).
        Sp = S + 1
        kd = coo_d.indices()[0] * Sp + coo_d.indices()[1]
        kp = coo_p.indices()[0] * Sp + coo_p.indices()[1]
        keys, inv = torch.unique(torch.cat([kd, kp]), return_inverse=True)
        g = torch.zeros(keys.numel(), dtype=torch.float64).index_add_(
            0, inv[: kd.numel()], coo_d.values()
        )
        p = torch.zeros(keys.numel(), dtype=torch.float64).index_add_(
            0, inv[kd.numel() :], coo_p.values()
        )
        e_row = exact_rows[(keys // Sp).to(dev)]
        e_succ = (keys % Sp).to(dev)
        g, p = g.to(dev), p.to(dev)
        model, cache = self.model, self.cache
        exact_reward = disc.reward.to(dev)
        for b in range(self.batch):
            use = self.rows.row_enabled[b, e_row]
            enabled_exact = self.rows.row_enabled[b, exact_rows]
            model.preload(
                b,
                rows=e_row[use],
                successors=e_succ[use],
                counts=N * p[use],
                discounts=N * g[use],
                counted_rows=exact_rows[enabled_exact],
                row_counts=N,
                row_rewards=N * exact_reward[enabled_exact],
            )
        cache.rebuild_options()
        self.sweeper.push(*cache.value_changes())

    def _check_world_rewards(self, world) -> None:
        probe = torch.full((1,), self.start_state, dtype=torch.int64, device=self.device)
        for a in range(world.num_actions):
            _, r = self.step_world(
                probe,
                torch.tensor([a], device=self.device),
                torch.full((1,), 0.5, dtype=torch.float64, device=self.device),
            )
            if not bool(torch.isfinite(r).all()):
                raise ValueError(
                    "the world returned a NaN or infinite reward; rewards must be finite"
                )

    def add_demonstrations(
        self, demonstrations, runs: Sequence[int] | None = None, mentor: int = 0
    ) -> None:
        """Add mentor state sequences to the mentor model of ``runs`` (all by default): of
        mentor number ``mentor`` (``0 … LearnerConfig.mentors − 1``; each mentor has its own
        model, and eq. 2 takes the largest of their terms,
        :func:`~himit_torch.learner.backups.best_mentor`).

        ``demonstrations`` has ``transitions() -> (from [T], to [T])``; if it also has
        ``check_world(world)``, it is called first (demonstrations of another world are refused);
        if it has ``counts [T]`` (e.g. :func:`~himit_torch.mentor.policy.exact_mentor_transitions`, the
        mentor's exact model), each transition is counted that many times instead of once; if it
        has ``durations() -> [T]`` (:class:`~himit_torch.mentor.observation.CoarseDemonstrations`),
        each transition took that many primitive steps (else one), which the segment term reads
        (``LearnerConfig.mentor_segments``).

        Raises:
            TypeError: ``demonstrations`` has no ``transitions()``, or it returns no pair.
            ValueError: ``from`` and ``to`` not two 1-D columns of one length of whole state
                indices of this world (``9.5``, a bool or ``NaN`` is refused, never cast), a
                ``mentor`` outside ``0 … mentors − 1``, ``counts`` not ``[T]`` finite positive
                weights, or ``durations()`` not ``[T]`` whole numbers ≥ 1.
        """
        if not callable(getattr(demonstrations, "transitions", None)):
            raise TypeError(
                f"demonstrations must be Demonstrations (or anything with transitions() -> "
                f"(from [T], to [T])), got {type(demonstrations).__name__}; read a file with "
                "Demonstrations.load(path)"
            )
        if (
            isinstance(mentor, bool)
            or not isinstance(mentor, (int, np.integer))
            or not 0 <= mentor < self.config.mentors
        ):
            raise ValueError(
                f"mentor={mentor!r}: this learner watches LearnerConfig.mentors="
                f"{self.config.mentors} mentor(s), numbered 0…{self.config.mentors - 1}; "
                "raise mentors to watch more"
            )
        if hasattr(demonstrations, "check_world"):
            demonstrations.check_world(self.world)
        src, dst = self._demonstrated_moves(demonstrations)
        counts = getattr(demonstrations, "counts", None)
        if counts is not None:
            try:
                counts = as_float_array("demonstrations.counts", counts)
            except ValueError as err:
                raise ValueError(f"{err}; give [T={src.numel()}] finite positive weights") from None
            counts = torch.from_numpy(counts).to(self.device)
            if counts.shape != src.shape or not bool((counts > 0).all()):
                raise ValueError(
                    f"demonstrations.counts must be [T={src.numel()}] finite positive "
                    "weights, one per transition"
                )
        delays = None
        if callable(getattr(demonstrations, "durations", None)):
            steps = as_index_tensor(
                "demonstrations.durations()", demonstrations.durations(), 1, COUNT_MAX, dim=1
            ).to(self.device)
            if steps.shape != src.shape:
                raise ValueError(
                    f"demonstrations.durations() must be [T={src.numel()}] whole numbers ≥ 1, "
                    f"the primitive steps of each transition; got shape {list(steps.shape)}"
                )
            delays = self.gamma ** (steps.to(torch.float64) - 1)  # γ^(k−1)
        # Episodes end at a terminal state: a "transition" out of one is not the mentor's move.
        keep = ~self.terminal.index_select(0, src)
        src, dst = src[keep], dst[keep]
        counts = None if counts is None else counts[keep]
        delays = None if delays is None else delays[keep]
        run_idx = (
            None
            if runs is None
            else torch.as_tensor(
                as_int_array("add_demonstrations: runs", runs, 0, self.batch - 1),
                device=self.device,
            )
        )
        rows = src + int(mentor) * self.num_states  # mentor k's row of s (DirichletMentorModel)
        self.mentor.observe(rows, dst, run_idx, counts, delays)
        self.refresh_mentor_reward(run_idx)
        self.refit_cloned_policy(run_idx)

    def _demonstrated_moves(self, demonstrations) -> tuple[torch.Tensor, torch.Tensor]:
        """``demonstrations.transitions()`` checked: two 1-D sequences of one length of whole
        state indices of this world (never cast: ``9.5`` or a bool is refused)."""
        pair = demonstrations.transitions()
        if not isinstance(pair, (tuple, list)) or len(pair) != 2:
            raise TypeError(
                "demonstrations.transitions() must return the pair (from [T], to [T]), got "
                f"{type(pair).__name__}"
            )
        where = "demonstrations.transitions()"
        src, dst = (
            as_index_tensor(f"{where} {end}", column, dim=1).to(self.device)
            for end, column in zip(("from", "to"), pair)
        )
        if src.shape != dst.shape:
            raise ValueError(
                f"{where}: from {list(src.shape)} and to {list(dst.shape)} must be of one "
                "length T, a state pair per transition"
            )
        if src.numel() and (
            int(torch.minimum(src.min(), dst.min())) < 0
            or int(torch.maximum(src.max(), dst.max())) >= self.num_states
        ):
            raise ValueError(
                f"demonstrations hold states outside 0…{self.num_states - 1}: they come "
                "from another world"
            )
        return src, dst

    def refit_cloned_policy(self, runs: torch.Tensor | None = None) -> None:
        """Relabel the demonstrations with the inverse model of each ``bco`` run among ``runs``
        (default: all) and clone its policy anew
        (:meth:`~himit_torch.learner.cloned_policy.ClonedPolicy.refit`); :meth:`run` calls it
        every ``LearnerConfig.bco_every`` ticks, :meth:`add_demonstrations` at once."""
        if not self.cloning.any:
            return
        if runs is None:
            runs = torch.arange(self.batch, device=self.device)
        self.cloning.refit(runs, self.model, self.mentor)

    def refresh_mentor_reward(self, changed: torch.Tensor | None = None) -> None:
        """Recompute the mentor-edge rewards of the runs in ``changed`` (default: all) from their
        reward modules, rebuild their mentor caches and queue their mentor states (after
        demonstrations were added or a reward module changed); the sampling runs among them draw
        a new model. Other runs are left exactly as they are, so that a run never depends on
        demonstrations given to other runs of its batch."""
        real_best = self._real_reward_bound()
        mentor = self.mentor
        if changed is None:
            changed = torch.arange(self.batch, device=self.device)
        changed = torch.as_tensor(changed, dtype=torch.int64, device=self.device).reshape(-1)
        for b in changed.tolist():
            module = self.rewards[b]
            E = int(mentor.num_edges[b])
            if module is _NO_MENTOR_REWARD:  # a run without a mentor term: nothing to check
                self.cache.mentor_edge_reward[b, :E] = 0.0
                continue
            bound = float(getattr(module, "upper_bound", float("inf")))
            if (
                real_best is not None
                and bound > real_best + 1e-12
                and self.config.reward_bound_check != "off"
            ):
                message = (
                    f"reward module {module!r} declares upper_bound={bound:g}, above the "
                    f"learner's best real reward per step {real_best:g}: R_m must not "
                    "overestimate the real reward (eq. 2's guarantee); lower the module's "
                    "scale/bound or set LearnerConfig.reward_bound_check='warn'/'off'"
                )
                if self.config.reward_bound_check == "error":
                    raise ValueError(message)
                warnings.warn(message, stacklevel=3)
            src = mentor.row_states(mentor.edge_row[b, :E])
            dst = mentor.edge_successor[b, :E]
            r = torch.as_tensor(
                module.transition_reward(src, dst), dtype=torch.float64, device=self.device
            )
            if r.shape != (E,):
                raise ValueError(
                    f"reward module {module!r} returned shape {tuple(r.shape)} for {E} "
                    "transitions; it must return one reward per transition"
                )
            if not bool(torch.isfinite(r).all()):
                raise ValueError(f"reward module {module!r} returned NaN or infinite rewards")
            if E and float(r.max()) > bound + 1e-12:
                raise ValueError(
                    f"reward module {module!r} returned {float(r.max()):g}, above its "
                    f"declared upper_bound={bound:g}"
                )
            if self.config.mentor_segments and E:
                # each move scored as the segment it is; its unseen steps at the least reward
                # the module gives any of the run's observed moves
                delay = mentor.edge_delay[b, :E] / mentor.edge_count[b, :E]
                r = segment_reward(r, delay, r.min(), self.gamma)
            self.cache.mentor_edge_reward[b, :E] = r
        self.cache.refresh_mentor_discount(changed)
        self.cache.rebuild_mentor(changed)
        # Every mentor state of the changed runs is worth a backup now.
        observed = mentor.observed().index_select(0, changed)
        observed &= self.rows.use_mentor.index_select(0, changed)[:, None]
        ri, states = observed.nonzero(as_tuple=True)
        self.sweeper.push(
            changed[ri], states, torch.ones(states.numel(), dtype=torch.float64, device=self.device)
        )
        # The shaping runs among them: the new potential, and the states it leaves to back up.
        shaping = changed[self.rows.use_shaping.index_select(0, changed)]
        if shaping.numel():
            self.sweeper.push(*self.cache.set_potential(shaping, self.shaping_potential(shaping)))
        # New mentor evidence: the sampling runs among them draw from their new posterior.
        self.resample(changed)

    def shaping_potential(self, runs: torch.Tensor | None = None) -> torch.Tensor:
        """``[R, S + 1]`` the shaping potential of ``runs`` (default: all) from their mentor
        model and mentor-edge rewards (:func:`~himit_torch.mentor.potential.shaping_potential`;
        the padding state 0). Computed for any run; only the ``pbrs…`` runs use it."""
        if runs is None:
            runs = torch.arange(self.batch, device=self.device)
        mentor, S = self.mentor, self.num_states
        out = torch.zeros(runs.numel(), S + 1, dtype=torch.float64, device=self.device)
        for i, b in enumerate(runs.tolist()):
            E = int(mentor.num_edges[b])
            out[i, :S] = shaping_potential(  # (several mentors: their moves pooled)
                mentor.row_states(mentor.edge_row[b, :E]),
                mentor.edge_successor[b, :E],
                mentor.edge_count[b, :E],
                self.cache.mentor_edge_reward[b, :E],
                self.gamma,
                self.terminal[:S],
                self.config.initial_value,
            ).to(self.device)
        return out

    def resample(self, runs: torch.Tensor) -> None:
        """Draw a fresh model from the posteriors of ``runs`` (sampling runs), rebuild their value
        caches from it and queue the states whose values it changes (posterior sampling; the
        engines call this at each episode start or every ``resample_every`` decisions). Runs
        that do not sample are left alone (their caches hold the posterior means)."""
        self.state.resample(runs)

    def _real_reward_bound(self) -> float | None:
        """The learner's best real reward for one step (``None`` if the world does not say)."""
        reward = getattr(self.world, "state_reward", None)
        if reward is None and self.tables.dynamics is not None:
            reward = self.tables.dynamics.rewards
        return None if reward is None else float(torch.as_tensor(reward).max())

    # ================================================================================ running
    def step(self) -> None:
        """Advance every run one primitive step (one tick)."""
        self.run(1)

    def run(self, steps: int, progress: bool = False) -> RunMetrics:
        """Advance all runs ``steps`` primitive steps; returns the metrics so far."""
        steps = as_int("Learner.run: steps", steps, 0, COUNT_MAX)
        window = self.config.window
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=steps, desc=f"{self.batch} runs", unit="step", mininterval=1.0)
        # the bco runs relabel and re-clone between the engine's calls, at every bco_every ticks
        every = self.config.bco_every if self.cloning.any else None
        # the compiled engine closes the windows it crosses; with the torch engine (or a
        # progress bar to update) the calls end at each window's end
        per_window = not self.engine.closes_windows or bar is not None
        left = steps
        while left > 0:
            ticks = min(left, window - self.run_state.t % window) if per_window else left
            if every is not None:
                ticks = min(ticks, every - self.run_state.t % every)
            closed = self.engine.advance(ticks)
            left -= ticks
            if bar is not None:
                bar.update(ticks)
            if every is not None and self.run_state.t % every == 0:
                self.refit_cloned_policy()
            if closed is not None:
                self._record_closed(*closed)
            elif self.run_state.t % window == 0:
                self.metrics.record(self.run_state.t, self.run_state, self.views.mentor_win_share())
        if bar is not None:
            bar.close()
        return self.metrics

    def _record_closed(self, ends: list[int], counts: np.ndarray, epsilon: np.ndarray) -> None:
        """Record the windows the compiled engine closed (:meth:`NumbaEngine.advance
        <himit_torch.learner.engines.NumbaEngine.advance>`'s counts, named by ``WINDOW_COUNTS``)."""
        if not ends:
            return
        named = {
            name: torch.from_numpy(np.ascontiguousarray(counts[..., k]))
            for k, name in enumerate(WINDOW_COUNTS)
        }
        wins, seen = named.pop("mentor_wins"), named.pop("mentor_seen")
        named["epsilon"] = torch.from_numpy(np.ascontiguousarray(epsilon))
        share = mentor_win_share_of(wins.numpy(), seen.numpy(), self.rows.use_mentor.numpy())
        self.metrics.record_closed(ends, named, torch.from_numpy(share))

    def plan(self, max_rounds: int = 1_000_000) -> int:
        """Sweep every run until its queue is empty (or ``max_rounds`` rounds of ``backups``
        states): the exhaustive path, for checks. Returns the number of rounds."""
        runs = torch.arange(self.batch, device=self.device)
        budget = torch.full((self.batch,), self.config.backups * max_rounds, device=self.device)
        done = self.sweeper.sweep(
            runs, budget, self.cache.backup_and_propagate, round_size=self.config.backups
        )
        self.engine.invalidate()
        return -(-int(done.max()) // self.config.backups) if done.numel() else 0

    # ============================================================================ checkpoints
    def _identity(self) -> dict:
        return {
            "agents": self.agents,
            "seeds": self.seeds,
            "num_states": self.num_states,
            "num_options": self.num_options,
            "num_rows": self.num_rows,
            "config": asdict(self.config),
        }

    def state_dict(self, copy: bool = True) -> dict:
        """Everything that changes while learning (models, values, queue, run state, metrics):
        with the same world, options, agents, seeds and config, :meth:`load_state_dict` continues
        exactly where this left off (on either engine). Plain tensors, numbers, strings, lists
        and dicts only.

        ``copy=False``: the learner's own tensors and views of them instead of copies, for a
        state written out before the learner runs again — a checkpoint, whose writer stores
        most of it sparse and a view as the slice it is: copies (≈ 100 MB on exp1, ≈ 50 ms a
        save) would be read once and dropped. The same values either way."""
        return {
            "layout": self.STATE_LAYOUT_VERSION,
            "config_schema": CONFIG_SCHEMA_VERSION,
            "identity": self._identity(),
            "run": self.run_state.state_dict(copy),
            "model": self.model.state_dict(copy),
            "mentor": self.mentor.state_dict(copy),
            "cache": self.cache.state_dict(copy),
            "sweeper": self.sweeper.state_dict(copy),
            "metrics": self.metrics.state_dict(),  # (new lists of its records either way)
            "sample": self.sample.state_dict(copy),
            "cloning": self.cloning.state_dict(copy),
        }

    #: The pieces of a :meth:`state_dict` (``sample`` is missing in those from before posterior
    #: sampling, ``cloning`` in those from before the ``bco`` agent).
    _STATE_KEYS = ("layout", "identity", "run", "model", "mentor", "cache", "sweeper", "metrics")

    def _config_differences(self, saved: Any) -> list[str]:
        """The settings a checkpoint's config differs in from this learner's, read through the
        schema: a setting the checkpoint does not name takes its declared default (a checkpoint
        written before the setting existed ran with what the default does), a setting this
        code does not know is a difference."""
        if not isinstance(saved, dict):
            raise DamagedState("identity.config", f"is a {type(saved).__name__}, not a dict")
        mine = asdict(self.config)
        defaults = {s.name: s.default for s in settings_of(LearnerConfig)}
        out = [f"config.{k}" for k in saved if k not in mine]
        out += [
            f"config.{k}"
            for k, value in mine.items()
            if not same_plain(value, saved.get(k, defaults.get(k)))
        ]
        return out

    def check_state(self, state: dict) -> RunMetrics:
        """Check a :meth:`state_dict` read back, in full, before any of it is restored: each
        owner checks its own piece (``check_state``: dtypes, shapes, indices within their tables,
        counts within their capacities), then what ties the pieces together — the run's option
        row at the state it started in, the posterior draws as long as the models' edge lists,
        one metrics record per window. Returns the metrics (checked, ready to keep).

        Raises:
            DamagedState: naming the field and what is wrong with it (a file altered with its
                checksum recomputed, or a state this code did not write).
            ValueError: a state of another layout, or of another batch or configuration.
        """
        if not isinstance(state, dict):
            raise DamagedState("learner state", f"is a {type(state).__name__}, not a dict")
        layout = state.get("layout", 1)
        if layout != self.STATE_LAYOUT_VERSION:
            raise ValueError(
                f"state layout {layout} cannot be loaded by this learner (layout "
                f"{self.STATE_LAYOUT_VERSION}); start the run again"
            )
        section(
            state,
            "learner state",
            self._STATE_KEYS,
            optional=("sample", "cloning", "config_schema"),
        )
        schema = state.get("config_schema", 1)  # (1: written before the schema was recorded)
        if isinstance(schema, bool) or not isinstance(schema, int) or schema < 1:
            raise DamagedState("config_schema", f"is {schema!r}, not a version number ≥ 1")
        if schema > CONFIG_SCHEMA_VERSION:
            raise ValueError(
                f"checkpoint written with config schema {schema}, newer than this "
                f"himit_torch's ({CONFIG_SCHEMA_VERSION}): resume it with the version that "
                "wrote it, or a newer one"
            )
        ident, mine = state["identity"], self._identity()
        if not isinstance(ident, dict):
            raise DamagedState("identity", f"is a {type(ident).__name__}, not a dict")
        differ = [k for k in mine if k != "config" and not same_plain(mine[k], ident.get(k))]
        differ += self._config_differences(ident.get("config"))
        if differ:
            raise ValueError(f"checkpoint does not match this learner: {sorted(differ)} differ")
        if "sample" not in state and self.sample.any:
            # (a checkpoint from before posterior sampling has no draws)
            raise ValueError("checkpoint has no posterior sample for this learner's psrl runs")
        if "cloning" not in state and self.cloning.any:
            raise ValueError("checkpoint has no cloned policy for this learner's bco runs")
        edges = self.model.check_state(state["model"], "model")
        mentor_edges = self.mentor.check_state(state["mentor"], "mentor")
        self.cache.check_state(state["cache"], mentor_edges, "cache")
        self.sweeper.check_state(state["sweeper"], "sweeper")
        if "sample" in state:
            self.sample.check_state(state["sample"], edges, mentor_edges, "sample")
        if "cloning" in state:
            self.cloning.check_state(state["cloning"], "cloning")
        run = state["run"]
        t = self.run_state.check_state(run, "run")
        # the executing option's row is one of the state it started in (or none: the padding)
        row, start = run["row"], run["option_start"]
        at = self.rows.row_state.to(row.device).index_select(0, row)
        wrong = (row < self.num_rows) & (at != start)
        if bool(wrong.any()):
            b = int(wrong.nonzero()[0, 0])
            raise DamagedState(
                "run.row",
                f"run {b} executes row {int(row[b])}, an option at state {int(at[b])}, but its "
                f"option started at state {int(start[b])} (run.option_start)",
            )
        in_range(
            run["duration"],
            "run.duration",
            0,
            self.config.max_option_steps,
            "steps of the option so far, at most max_option_steps",
        )
        return RunMetrics.from_state_dict(
            state["metrics"], self.batch, self.config.window, t, "metrics"
        )

    def load_state_dict(self, state: dict) -> None:
        """Restore a :meth:`state_dict`, checked in full first (:meth:`check_state`): a state that
        fails a check is refused before anything is restored, the learner left as it was.

        Raises:
            DamagedState: a piece of the state is not one this code writes (named).
            ValueError: a state of another layout, batch or configuration.
        """
        metrics = self.check_state(state)
        edges, mentor_edges = (state[k]["edge_row"].shape[1] for k in ("model", "mentor"))
        self.model.load_state_dict(state["model"], checked=True)
        self.mentor.load_state_dict(state["mentor"], checked=True)
        self.cache.load_state_dict(state["cache"], mentor_edges, checked=True)
        self.sweeper.load_state_dict(state["sweeper"], checked=True)
        if "sample" in state:
            self.sample.load_state_dict(state["sample"], edges, mentor_edges, checked=True)
        self.run_state.load_state_dict(state["run"], checked=True)
        if "cloning" in state:  # (none before the bco agent: no run clones then)
            self.cloning.load_state_dict(state["cloning"], checked=True)
        self.metrics = metrics
        self.sync_potential()
        self.engine.invalidate()

    def sync_potential(self) -> None:
        """Record the shaping runs' potential as their mentor model gives it, without moving
        ``V`` (which already holds it: after its mentor model and value cache were read back)."""
        shaping = self.rows.use_shaping.nonzero()[:, 0]
        if shaping.numel():
            self.cache.set_potential(shaping, self.shaping_potential(shaping), shift=False)


for _name in DEPRECATED_VIEW_NAMES:
    setattr(Learner, _name, _view_alias(_name))
