"""The typed state an engine works on: the world's tables and the batch's owners of state.

:class:`~himit_torch.Learner` builds one :class:`BatchState` and hands it to its engine
(:mod:`himit_torch.learner.engines`); an engine sees this state and nothing of the learner. Each
piece keeps one owner (the models write counts, the value cache writes ``V``, the sweeper the
queue, :class:`~himit_torch.learner.run_state.RunState` the runs' positions and counters).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch

from himit_torch.learner.cloned_policy import ClonedPolicy
from himit_torch.learner.config import LearnerConfig
from himit_torch.learner.models import DirichletMentorModel, DirichletSMDPModel
from himit_torch.learner.posterior_sampling import PosteriorSample
from himit_torch.learner.prioritized_sweeping import Sweeper
from himit_torch.learner.rows import RowTable
from himit_torch.learner.run_state import RunState
from himit_torch.learner.values import ValueCache
from himit_torch.options.bundle import Options, action_dtype
from himit_torch.options.execution import OptionTables

if TYPE_CHECKING:
    from himit_torch.worlds.tabular import DynamicsTable, TabularWorld

__all__ = ["WorldTables", "BatchState", "LANES"]

#: Uniforms per run and tick: 0 slip, 1 termination or action, 2 termination (stochastic
#: policies), 3 ε, 4 which candidate option, 5 the next episode's start state.
LANES = 6


@dataclass
class WorldTables:
    """The world and the options of a batch as the tables both engines read (fixed).

    Shapes: ``S`` states (index ``S`` is padding, terminal), ``O`` options, ``A`` actions."""

    world: TabularWorld
    """The world itself (its ``step`` serves worlds without a :attr:`dynamics` table)."""
    num_states: int
    gamma: float
    terminal: torch.Tensor
    """``[S + 1]`` bool: terminal states (the padding state ``S`` counts as terminal)."""
    start_state: int
    start_cdf: torch.Tensor | None
    """``[S]`` cumulative start distribution, or ``None``: every episode starts at
    :attr:`start_state`."""
    dynamics: DynamicsTable | None
    """The world's :class:`~himit_torch.DynamicsTable` (``None``: the world has none)."""
    options: OptionTables
    """The options as flat tables (β, and the policy or its cdf, of option ``o`` at state ``s``
    at ``o · S + s``), as :func:`~himit_torch.options.execution.option_step` reads them."""

    @classmethod
    def build(cls, world: TabularWorld, options: Options, device: torch.device) -> WorldTables:
        S, O = world.num_states, options.num_options
        terminal = torch.cat(
            [world.terminal_mask.to(device), torch.ones(1, dtype=torch.bool, device=device)]
        )
        table = getattr(world, "dynamics_table", None)
        policy: torch.Tensor | None = None
        policy_cdf: torch.Tensor | None = None
        if options.stochastic:
            policy_cdf = options.policy.to(device).double().cumsum(-1).reshape(O * S, -1)
            policy_cdf = policy_cdf.contiguous()
        else:
            if int(options.policy.max()) >= world.num_actions:
                raise ValueError(
                    f"Options.policy holds action {int(options.policy.max())}; the "
                    f"world has actions 0…{world.num_actions - 1}"
                )
            # one action dtype for every bundle (no copy of the builders' int8 tables), so the
            # compiled kernel is specialised once
            actions = action_dtype(world.num_actions)
            policy = options.policy.to(device, actions).reshape(-1).contiguous()
        return cls(
            world=world,
            num_states=S,
            gamma=float(world.gamma),
            terminal=terminal,
            start_state=int(world.start_state),
            start_cdf=_start_cdf(world, terminal, device),
            dynamics=table().to(device) if callable(table) else None,
            options=OptionTables(
                S,
                # β as given (float32 compares with the float64 uniforms exactly as float64
                # would)
                options.termination.to(device).reshape(-1).contiguous(),
                policy,
                policy_cdf,
            ),
        )

    def step(self, positions: torch.Tensor, actions: torch.Tensor, u: torch.Tensor):
        """One primitive step of the world for ``positions [B]`` (its table when it has one):
        ``(successors [B], rewards [B])``."""
        if self.dynamics is not None:
            return self.dynamics.step(positions, actions, u)
        return self.world.step(positions, actions, u)

    def start_states(self, runs: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        """Start states of a new episode for ``runs [R]`` from their uniforms ``u [R, LANES]``
        (lane 5): :attr:`start_state`, or a draw from the world's start distribution."""
        if self.start_cdf is None:
            return torch.full_like(runs, self.start_state)
        return torch.searchsorted(self.start_cdf, u[:, 5].contiguous(), right=True).clamp(
            max=self.num_states - 1
        )


def _start_cdf(world, terminal: torch.Tensor, device: torch.device) -> torch.Tensor | None:
    dist = getattr(world, "start_distribution", None)
    if dist is None:
        return None
    S = world.num_states
    dist = torch.as_tensor(dist, dtype=torch.float64, device=device)
    if (
        dist.shape != (S,)
        or not bool(torch.isfinite(dist).all())
        or bool((dist < 0).any())
        or abs(float(dist.sum()) - 1.0) > 1e-6
    ):
        raise ValueError(
            f"world.start_distribution must be [S={S}] probabilities summing to 1 (or None)"
        )
    if bool((dist[terminal[:-1]] > 0).any()):
        raise ValueError("world.start_distribution puts mass on a terminal state")
    cdf = dist.cumsum(0)
    # From the last possible start on the cdf is exactly 1, so rounding can never draw a state of
    # probability 0 beyond it.
    cdf[int(dist.nonzero().max()) :] = 1.0
    return cdf


@dataclass
class BatchState:
    """Everything an engine reads and writes for a batch of ``B`` runs, one owner per piece."""

    config: LearnerConfig
    tables: WorldTables
    rows: RowTable
    model: DirichletSMDPModel
    mentor: DirichletMentorModel
    cache: ValueCache
    sample: PosteriorSample
    sweeper: Sweeper
    run: RunState
    keys: torch.Tensor
    """``[B]`` int64: each run's random stream (:func:`himit_torch.rng.seed_streams`)."""
    cloning: ClonedPolicy
    """The ``bco`` runs' cloned actions (read when a run chooses; refitted by the learner)."""

    @property
    def batch(self) -> int:
        return self.keys.shape[0]

    @property
    def device(self) -> torch.device:
        return self.keys.device

    def resample(self, runs: torch.Tensor) -> None:
        """Draw a fresh model from the posteriors of ``runs`` (sampling runs), rebuild their value
        caches from it and queue the states whose values it changes (posterior sampling; the
        engines call this at each episode start or every ``resample_every`` decisions). Runs
        that do not sample are left alone (their caches hold the posterior means)."""
        runs = torch.as_tensor(runs, dtype=torch.int64, device=self.device).reshape(-1)
        runs = runs[self.rows.use_sampling.index_select(0, runs)]
        if runs.numel() == 0:
            return
        self.sample.draw(runs)
        rr, ss, change = self.cache.apply_sample(runs)
        self.sweeper.push(rr, ss, change)
