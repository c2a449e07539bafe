"""The torch engine: one tick for all runs of a batch as a fixed sequence of tensor ops."""

from __future__ import annotations

import torch

from himit_torch.learner.choice import choose_rows
from himit_torch.learner.state import LANES, BatchState
from himit_torch.options.execution import option_step
from himit_torch.rng import uniforms

__all__ = ["TorchEngine"]


class TorchEngine:
    """Batched tensor ops: the readable reference, and the engine for CUDA devices."""

    name = "torch"

    #: :meth:`advance` never crosses a window's end: ``Learner.run`` closes the windows.
    closes_windows = False

    def __init__(self, state: BatchState):
        self.state = state
        B, S = state.batch, state.tables.num_states
        self._visit_base = torch.arange(B, device=state.device) * (S + 1)
        self._ones_b = torch.ones(B, dtype=torch.int64, device=state.device)
        self._u_chunk: torch.Tensor | None = None
        self._u_chunk_start = -1

    def advance(self, ticks: int) -> None:
        """Carry out ``ticks`` ticks (no window boundary inside: the learner closes windows)."""
        for _ in range(ticks):
            self.tick()

    def invalidate(self) -> None:
        """The state was changed outside this engine (loaded, or advanced by another engine)."""
        self._u_chunk, self._u_chunk_start = None, -1

    def _tick_uniforms(self, t: int) -> torch.Tensor:
        """``[B, lanes]`` uniforms of tick ``t``: 0 slip, 1 termination or action, 2 termination
        (stochastic policies), 3 ε, 4 which of the candidate options."""
        L = self.state
        chunk = L.config.rng_chunk
        i = t % chunk
        if self._u_chunk is None or self._u_chunk_start != t - i:
            self._u_chunk_start = t - i
            counters = torch.arange(t - i, t - i + chunk, device=L.device)
            self._u_chunk = uniforms(L.keys, counters, LANES)
        return self._u_chunk[i]

    def tick(self) -> None:
        """Advance every run one primitive step: act; where an option ended, learn from it;
        plan (prioritized sweeping, every ``plan_every`` ticks); and choose the next option."""
        L = self.state
        cfg, run = L.config, L.run
        u = self._tick_uniforms(run.t)
        at_goal, ended = self._act(u)
        if cfg.eps_schedule != "decision":
            self._eps_tick(at_goal)
        runs = ended.nonzero()[:, 0] if bool(ended.any()) else None
        if runs is not None:
            self._learn(runs)
            if L.sample.any:
                self._resample(runs, at_goal[runs])
        if run.t % cfg.plan_every == 0 and bool((L.sweeper.pending > 0).any()):
            self._plan()
        if runs is not None:
            self._choose(runs, at_goal[runs], u[runs])

    def _act(self, u: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """One primitive step of every run's option: ``(at_goal [B], option ended [B])``."""
        L = self.state
        cfg, run = L.config, L.run
        option = L.rows.row_option[run.row]
        # lanes: 0 slip; deterministic options stop on lane 1, stochastic ones act on lane 1
        # and stop on lane 2
        stop_lane = 1 if L.tables.options.policy is not None else 2
        moved = option_step(
            L.tables.options,
            option,
            run.position,
            L.tables.step,
            L.tables.terminal,
            slip_u=u[:, 0],
            stop_u=u[:, stop_lane],
            action_u=u[:, 1],
        )
        nxt, reward, at_goal = moved.successors, moved.rewards, moved.at_terminal
        run.discounted_return += run.discount * reward
        run.discount *= L.tables.gamma
        run.duration += 1
        run.t += 1
        ended = moved.stopped | (run.duration >= cfg.max_option_steps)
        run.position = nxt
        run.visits.view(-1).index_add_(0, self._visit_base + nxt, self._ones_b)
        if bool(at_goal.any()):
            self._goal_reached(at_goal)
        return at_goal, ended

    def _eps_tick(self, at_goal: torch.Tensor) -> None:
        """ε schedules that change ε at steps or goals, not decisions
        (``LearnerConfig.eps_schedule``): "step" decays at every step once the goal was found,
        "goals" drops to the floor at the ``eps_goals``-th goal, "paper" decays at every goal."""
        L = self.state
        cfg, run = L.config, L.run
        decayed = (run.epsilon * cfg.eps_decay).clamp(min=cfg.eps_min)
        if cfg.eps_schedule == "step":
            run.epsilon = torch.where(run.found_goal, decayed, run.epsilon)
        elif cfg.eps_schedule == "goals":
            drop = at_goal & (run.goals >= cfg.eps_goals)
            run.epsilon = torch.where(drop, torch.full_like(run.epsilon, cfg.eps_min), run.epsilon)
        elif cfg.eps_schedule == "paper":
            run.epsilon = torch.where(at_goal, decayed, run.epsilon)

    def _learn(self, runs: torch.Tensor) -> None:
        """Runs whose option just ended count its outcome and queue its start state first."""
        L = self.state
        run = L.run
        end, rows, starts = run.position[runs], run.row[runs], run.option_start[runs]
        discounts, returns = run.discount[runs], run.discounted_return[runs]
        n_old = L.model.row_count[runs, rows]
        edges, c_old, g_old = L.model.update(runs, rows, starts, end, discounts, returns)
        if not L.sample.any:
            L.cache.add_outcome(runs, rows, end, discounts, returns, c_old, g_old)
        else:
            # Mean runs fold the outcome into their caches; sampling runs move their sample to
            # the updated posterior and rebuild the row from it (posterior_sampling).
            s = L.rows.use_sampling[runs]
            m = ~s
            L.cache.add_outcome(
                runs[m], rows[m], end[m], discounts[m], returns[m], c_old[m], g_old[m]
            )
            if bool(s.any()):
                L.sample.absorb(runs[s], rows[s], edges[s], n_old[s], run.decisions[runs[s]])
                L.cache.apply_sample_rows(runs[s], rows[s])
        L.sweeper.push(runs, starts, torch.full_like(returns, float("inf")))
        L.sweeper.pending[runs] += 1
        run.decisions[runs] += 1

    def _resample(self, runs: torch.Tensor, at_goal: torch.Tensor) -> None:
        """Sampling runs draw a fresh model at an episode start (``resample_every = 0``) or every
        ``resample_every`` decisions, before this tick's sweep (so it plans on the new draw)."""
        L = self.state
        every = L.config.resample_every
        due = at_goal if every == 0 else (L.run.decisions[runs] % every == 0)
        due = due & L.rows.use_sampling[runs]
        if bool(due.any()):
            L.resample(runs[due])

    def _plan(self) -> None:
        """Runs with pending decisions sweep ``backups`` per decision."""
        L = self.state
        sweeper = L.sweeper
        runs = (sweeper.pending > 0).nonzero()[:, 0]
        done = sweeper.sweep(
            runs, sweeper.pending[runs] * L.config.backups, L.cache.backup_and_propagate
        )
        sweeper.pending[runs] = 0
        L.run.backups_done.index_add_(0, runs, done)

    def _choose(self, runs: torch.Tensor, at_goal: torch.Tensor, u: torch.Tensor) -> None:
        """Runs whose option ended start the next one (at a new episode's start after a goal)."""
        L = self.state
        cfg, run = L.config, L.run
        if cfg.eps_schedule == "decision":
            eps = run.epsilon[runs]
            run.epsilon[runs] = torch.where(
                run.found_goal[runs], (eps * cfg.eps_decay).clamp(min=cfg.eps_min), eps
            )
        run.duration[runs] = 0
        run.discounted_return[runs] = 0.0
        run.discount[runs] = 1.0
        here = torch.where(at_goal, L.tables.start_states(runs, u), run.position[runs])
        run.position[runs] = here
        run.option_start[runs] = here
        run.row[runs] = choose_rows(
            L.cache,
            runs,
            here,
            u[:, 3:5],
            run.epsilon[runs],
            cfg.mentor_choice,
            cfg.tie_break,
            L.cloning.at(runs, here) if L.cloning.any else None,
        )

    def _goal_reached(self, at_goal: torch.Tensor) -> None:
        run = self.state.run
        run.goals += at_goal
        run.window_goals += at_goal
        first = at_goal & ~run.found_goal
        run.first_goal_step = torch.where(
            first, torch.full_like(run.first_goal_step, run.t), run.first_goal_step
        )
        run.found_goal |= at_goal
        run.episodes += at_goal
        length = run.t - run.episode_start
        run.window_episode_steps += torch.where(at_goal, length, torch.zeros_like(length))
        run.window_episodes += at_goal
        run.episode_start = torch.where(
            at_goal, torch.full_like(run.episode_start, run.t), run.episode_start
        )
