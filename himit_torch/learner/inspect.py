"""The read-only views of a :class:`~himit_torch.Learner`: its counters, diagnostics and greedy
policies, read from the state it owns and never written (:class:`LearnerViews`, one object per
learner: ``learner.views.goals``, ``learner.views.greedy_policy()``).

Shapes: ``B`` runs, ``S`` states, ``M`` rows, as in :mod:`himit_torch.learner.learner`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
import torch

from himit_torch.exact.greedy_evaluation import OptionPolicy, check_untried_rule
from himit_torch.learner.choice import greedy_rows
from himit_torch.options.execution import option_step, option_step_in_numbers

if TYPE_CHECKING:
    from himit_torch.learner.cloned_policy import ClonedPolicy
    from himit_torch.learner.config import LearnerConfig
    from himit_torch.learner.models import DirichletMentorModel, DirichletSMDPModel
    from himit_torch.learner.rows import RowTable
    from himit_torch.learner.run_state import RunState
    from himit_torch.learner.state import WorldTables
    from himit_torch.learner.values import ValueCache

__all__ = ["tried_share", "mentor_win_share_of", "LearnerViews"]


def mentor_win_share_of(wins: np.ndarray, seen: np.ndarray, use_mentor: np.ndarray) -> np.ndarray:
    """The compiled engine's mentor-win counts as shares: ``wins / seen`` per run (the last
    axis, ``B``), NaN for the runs that do not use the mentor term (``use_mentor [B]``), and
    NaN for every run of a record in which no run has seen a mentor (float64, ``wins``' shape:
    ``[B]``, or ``[W, B]`` for ``W`` windows)."""
    frac = wins.astype(np.float64) / np.maximum(seen, 1)
    frac[..., ~use_mentor] = np.nan
    frac[~seen.any(-1)] = np.nan
    return frac


def tried_share(row_count: torch.Tensor, enabled: torch.Tensor) -> torch.Tensor:
    """``[B]`` share of the usable rows (``enabled [B, M]``) tried at least once
    (``row_count [B, M] > 0``); 0 for a run with no usable row.

    On a CPU the two counts are numpy's ``count_nonzero`` over views of the same memory: one
    pass each, on one thread — 10-30× faster than torch's reductions, which on a busy 2-core
    machine wait for their second thread (a [20, 82282] batch: ≈ 2 ms instead of 40-80 ms). The
    counts are the same integers either way, so the shares are bit-identical."""
    if row_count.device.type == "cpu":
        usable_np = enabled.numpy()
        n_tried = torch.from_numpy(np.count_nonzero((row_count.numpy() > 0) & usable_np, axis=1))
        n_usable = torch.from_numpy(np.count_nonzero(usable_np, axis=1))
    else:
        # (counted in int32: exact, and ≈ 4× faster than torch's default int64 sum of bools)
        n_tried = ((row_count > 0) & enabled).sum(1, dtype=torch.int32)
        n_usable = enabled.sum(1, dtype=torch.int32)
    return n_tried.double() / n_usable.clamp(min=1)


class _ViewedState(Protocol):
    """What the views read of a :class:`~himit_torch.Learner` (set by its ``__init__``)."""

    config: LearnerConfig
    batch: int
    num_states: int
    num_rows: int
    device: torch.device
    start_state: int
    terminal: torch.Tensor
    tables: WorldTables
    rows: RowTable
    model: DirichletSMDPModel
    mentor: DirichletMentorModel
    cache: ValueCache
    cloning: ClonedPolicy
    run_state: RunState
    engine: Any


class LearnerViews:
    """The read-only views of a :class:`~himit_torch.Learner`, reached as ``learner.views``:
    counters of the runs (``learner.views.goals``), diagnostics and each run's greedy policy now
    (``learner.views.greedy_policy()``). Each reads the state the learner owns and changes
    nothing; the learner's facade keeps what changes or runs it (``run``, ``state_dict``, …)."""

    _learner: _ViewedState

    def __init__(self, learner: Any):
        """``learner``: the :class:`~himit_torch.Learner` whose state the views read."""
        self._learner = learner

    # ========================================================================= run state views
    @property
    def t(self) -> int:
        """Ticks (primitive steps per run) so far."""
        return self._learner.run_state.t

    @property
    def goals(self) -> torch.Tensor:
        """``[B]`` goals reached so far."""
        return self._learner.run_state.goals

    @property
    def episodes(self) -> torch.Tensor:
        """``[B]`` episodes begun so far."""
        return self._learner.run_state.episodes

    @property
    def first_goal_step(self) -> torch.Tensor:
        """``[B]`` tick of each run's first goal (−1: none yet)."""
        return self._learner.run_state.first_goal_step

    @property
    def decisions(self) -> torch.Tensor:
        """``[B]`` options chosen so far."""
        return self._learner.run_state.decisions

    @property
    def backups_done(self) -> torch.Tensor:
        """``[B]`` state backups of prioritized sweeping so far."""
        return self._learner.run_state.backups_done

    @property
    def epsilon(self) -> torch.Tensor:
        """``[B]`` each run's exploration rate now."""
        return self._learner.run_state.epsilon

    @property
    def found_goal(self) -> torch.Tensor:
        """``[B]`` bool: whether each run has reached a goal."""
        return self._learner.run_state.found_goal

    # =============================================================================== diagnostics
    def sampling_runs(self) -> torch.Tensor:
        """``[R]`` the runs that plan on a posterior sample (the ``…_psrl`` agents)."""
        return self._learner.rows.use_sampling.nonzero()[:, 0]

    def mentor_win_share(self) -> torch.Tensor:
        """``[B]`` share of mentor-observed states where the mentor term is the max of eq. 2
        (NaN for runs that do not imitate)."""
        if hasattr(self._learner.engine, "mentor_wins"):
            # the compiled backup, counted in NumPy: ~1000× faster than the batched backup, and
            # no torch op (it runs at every window's end)
            wins, seen = self._learner.engine.mentor_wins()
            frac = mentor_win_share_of(wins, seen, self._learner.rows.use_mentor.cpu().numpy())
            return torch.from_numpy(frac).to(self._learner.device)
        observed = self._learner.mentor.observed()
        out = torch.full(
            (self._learner.batch,), float("nan"), dtype=torch.float64, device=self._learner.device
        )
        if not bool(observed.any()):
            return out
        states = observed.any(0).nonzero()[:, 0]
        runs = torch.arange(self._learner.batch, device=self._learner.device)
        _, _, won = self._learner.cache.state_backup(
            runs[:, None], states[None].expand(self._learner.batch, -1)
        )
        wins_t = (won & observed[:, states]).sum(1)
        frac_t = wins_t.double() / observed.sum(1).clamp(min=1)
        return torch.where(self._learner.rows.use_mentor, frac_t, out)

    def greedy_options(self, runs: Sequence[int] | torch.Tensor | None = None) -> torch.Tensor:
        """``[B, S]`` greedy option per state (−1 where none is usable), ties to the lowest row;
        ``runs``: those runs' rows only (``[len(runs), S]``; default all). A ``bco`` run's is its
        cloned action's primitive option where it has one."""
        which = torch.arange(self._learner.batch) if runs is None else runs
        r = torch.as_tensor(which, dtype=torch.int64, device=self._learner.device).reshape(-1, 1, 1)
        R = r.shape[0]
        rows = self._learner.rows.state_rows[: self._learner.num_states][None]
        q = self._learner.cache.row_q(r, rows)
        usable = self._learner.rows.row_enabled[r, rows] & (
            self._learner.model.row_count[r, rows] > 0
        )
        q = torch.where(usable, q, torch.full_like(q, float("-inf")))
        best = q.argmax(-1)
        option = self._learner.rows.row_option[
            rows.expand(R, -1, -1).gather(2, best[..., None])[..., 0]
        ]
        option = torch.where(usable.any(-1), option, torch.full_like(option, -1))
        if self._learner.cloning.any:
            S = self._learner.num_states
            cloned = self._learner.cloning.action[r[:, 0, 0], :S]  # [R, S]
            clone_row = self._learner.rows.primitive_rows[
                torch.arange(S, device=self._learner.device), cloned.clamp(min=0)
            ]
            use = (cloned >= 0) & (clone_row < self._learner.num_rows)
            option = torch.where(use, self._learner.rows.row_option[clone_row], option)
        return option

    def greedy_policy(
        self, runs: Sequence[int] | torch.Tensor | None = None, untried: str = "uniform"
    ) -> OptionPolicy:
        """Each run's frozen greedy policy now: ε = 0 over its own options, as it would choose
        (:func:`~himit_torch.learner.choice.greedy_rows`, ``mentor_choice`` and a ``bco`` run's
        cloned actions included). Where
        options tie (or none is usable yet: every enabled option), ``tie_break="random"``
        takes each with equal probability — a stochastic option policy — and ``"first"`` the
        lowest option. Evaluate it exactly with
        :class:`~himit_torch.exact.greedy_evaluation.PolicyEvaluator` over ``learner.options``.

        ``untried`` (:data:`~himit_torch.exact.greedy_evaluation.UNTRIED_RULES`) is the rule at a
        live state where the run has tried none of its enabled options (and has no cloned
        action there): ``"uniform"`` (default) chooses as the run would act, among every
        enabled option; ``"stuck"`` gives that state no option (its row sums to 0: an episode
        that gets there never ends). Definitions: :mod:`himit_torch.exact.greedy_evaluation`.

        Returns:
            :class:`~himit_torch.exact.greedy_evaluation.OptionPolicy` on the CPU, ``option [S,
            J]`` the rows of each state, ``probability [len(runs), S, J]``; terminal states
            have no option.

        Raises:
            ValueError: ``untried`` is not one of the rules.
        """
        check_untried_rule(untried)
        which = torch.arange(self._learner.batch) if runs is None else runs
        which = torch.as_tensor(which, dtype=torch.int64, device=self._learner.device).reshape(-1)
        S, M = self._learner.num_states, self._learner.num_rows
        live = (~self._learner.terminal[:S]).nonzero()[:, 0]
        rows = self._learner.rows.state_rows[:S]
        J = rows.shape[1]
        probability = torch.zeros(which.numel(), S, J, dtype=torch.float64)
        for i, b in enumerate(which.tolist()):
            runs_b = torch.full_like(live, b)
            cloned = self._learner.cloning.at(runs_b, live) if self._learner.cloning.any else None
            rows_b, greedy, _ = greedy_rows(
                self._learner.cache, runs_b, live, self._learner.config.mentor_choice, cloned
            )
            if self._learner.config.tie_break == "first":
                greedy = greedy & (greedy.cumsum(1) == 1)
            p = greedy.double() / greedy.sum(1, keepdim=True).clamp(min=1)
            if untried == "stuck":
                # Tried = counted in the run's own model, whatever a prior or untried_value
                # makes usable (the same test as greedy_options' −1); a cloned action is a
                # choice the run has, tried or not (greedy_rows takes it).
                tried = self._learner.rows.row_enabled[b, rows_b] & (
                    self._learner.model.row_count[b, rows_b] > 0
                )
                chosen = tried.any(1)
                if cloned is not None:
                    clone_row = self._learner.rows.primitive_rows[live, cloned.clamp(min=0)]
                    chosen |= (cloned >= 0) & (clone_row < M)
                p = torch.where(chosen[:, None], p, torch.zeros_like(p))
            probability[i, live.cpu()] = p.cpu()
        option = torch.where(
            rows < M, self._learner.rows.row_option[rows], torch.full_like(rows, -1)
        )
        return OptionPolicy(option.cpu(), probability)

    def visit_counts(self) -> torch.Tensor:
        """``[B, S]`` how often each run has been in each state (after each primitive step)."""
        return self._learner.run_state.visits[:, : self._learner.num_states]

    def model_coverage(self) -> torch.Tensor:
        """``[B]`` share of the run's usable ``(s, o)`` rows it has tried at least once."""
        M = self._learner.num_rows
        return tried_share(
            self._learner.model.row_count[:, :M], self._learner.rows.row_enabled[:, :M]
        )

    def greedy_trajectory(self, run: int, max_steps: int, seed: int = 0) -> torch.Tensor:
        """States of one episode from the start following run ``run``'s greedy options (ε = 0,
        untried options at random), with the world's slip; stops at the goal or after
        ``max_steps``. For pictures like the paper's Fig. 2.

        The draws of ``torch.Generator(seed)`` on the learner's device, per step in this order:
        a stochastic option's action, the slip's uniform, the termination's uniform; and where
        the run has tried nothing, the option (uniform over the run's enabled ones)."""
        gen = torch.Generator(device=self._learner.device).manual_seed(seed)
        greedy = self.greedy_options([run])[0].tolist()
        terminal = self._learner.terminal.tolist()
        move = self._trajectory_move(gen, terminal)
        s = self._learner.start_state
        states = [s]
        option, steps = -1, 0
        while steps < max_steps and not terminal[s]:
            if option < 0:
                option = greedy[s]
                if option < 0:  # nothing tried here: any usable option
                    rows = self._learner.rows.state_rows[s]
                    rows = rows[self._learner.rows.row_enabled[run, rows]]
                    pick = torch.randint(
                        len(rows), (1,), generator=gen, device=self._learner.device
                    )
                    option = int(self._learner.rows.row_option[rows[pick]])
            s, stopped = move(option, s)
            steps += 1
            states.append(s)
            if stopped:
                option = -1
        return torch.tensor(states)

    def _trajectory_move(self, gen: torch.Generator, terminal: list[bool]):
        """``move(option, s) -> (s', stopped)``: one primitive step of ``option`` from ``s``
        (:func:`~himit_torch.options.execution.option_step`) with uniforms drawn from ``gen``;
        ``terminal``: :attr:`terminal` as a list.

        Deterministic options on a world with a :class:`~himit_torch.DynamicsTable` step in
        Python numbers (:func:`~himit_torch.options.execution.option_step_in_numbers`, the same
        step to the bit): a step of torch ops on one state costs ≈ 0.2 ms, and a world figure's
        path on 120×120 is up to 28,800 steps (≈ 6 s that way, ≈ 0.4 s this way,
        ``benchmarks/bench_greedy_path.py``). Other options and worlds step by
        :func:`option_step` itself."""
        tables, device, S = self._learner.tables, self._learner.device, self._learner.num_states

        def uniform() -> torch.Tensor:
            return torch.rand(1, generator=gen, device=device, dtype=torch.float64)

        dynamics, policy = tables.dynamics, tables.options.policy
        if dynamics is None or policy is None:
            cdf = tables.options.policy_cdf

            def move_by_tensors(option: int, s: int) -> tuple[int, bool]:
                state = torch.tensor([s], device=device)
                actions = None
                if cdf is not None:  # stochastic options: drawn here, as always
                    probability = torch.diff(
                        cdf[option * S + state],
                        prepend=torch.zeros(1, 1, dtype=torch.float64, device=device),
                    )
                    actions = torch.multinomial(probability, 1, generator=gen)[:, 0]
                u = uniform()
                moved = option_step(
                    tables.options,
                    torch.tensor([option], device=device),
                    state,
                    tables.step,
                    self._learner.terminal,
                    slip_u=u,
                    stop_u=uniform(),
                    actions=actions,
                )
                return int(moved.successors), bool(moved.stopped)

            return move_by_tensors

        move = option_step_in_numbers(tables.options, dynamics, terminal)

        def move_by_numbers(option: int, s: int) -> tuple[int, bool]:
            u = uniform().item()
            return move(option, s, u, uniform().item())

        return move_by_numbers

    def state_values(self) -> torch.Tensor:
        """``[B, S]`` current value estimates."""
        return self._learner.cache.values[:, : self._learner.num_states]

    def summary(self) -> dict:
        """Plain numbers for a report: ticks, each run's goals, episodes, first goal,
        exploration rate, backups and decisions, the engine and the settings."""
        run = self._learner.run_state
        return {
            "steps": self.t,
            "goals": run.goals.tolist(),
            "episodes": run.episodes.tolist(),
            "first_goal_step": run.first_goal_step.tolist(),
            "epsilon": run.epsilon.tolist(),
            "backups": run.backups_done.tolist(),
            "decisions": run.decisions.tolist(),
            "engine": self._learner.engine.name,
            "config": asdict(self._learner.config),
        }
