"""The value caches: ``V`` and the cached numerators of eq. 2, the only writer of ``V``.

The paper's eq. 2 (the augmented Bellman equation with options)::

    V(s) = max( max_o [ r(s,o) + Σ_s' p^o_ss' V(s') ],  R_m(s) + γ Σ_s' p_m(s'|s) V(s') )

is evaluated from caches rather than from the models' successor lists (the pure functions of
:mod:`himit_torch.learner.backups` are the slow reference the tests compare these with):

* ``q_numerator [B, M + 1]`` holds ``Σ r + Σ_{s'} Σγ^k V(s')`` of every row, so that
  ``Q = (q_numerator + α v0) / (n + α)`` is :func:`~himit_torch.learner.backups.option_backup` on the
  posterior mean. When ``V(x)`` changes by ``δ``, every row with an edge to ``x`` gets
  ``+ Σγ^k · δ`` (along the reverse edges), which also yields the prioritized-sweeping priority
  ``|ΔQ|`` of the row's state.
* ``mentor_numerator [B, R_m + 1]`` likewise holds ``Σ_{s'} c(s→s') (r_m + γ V(s'))`` per
  mentor row (``R_m = K·S`` for ``K`` mentors, :class:`~himit_torch.DirichletMentorModel`; one
  mentor: a row per state). With several mentors, eq. 2 takes the largest of their terms
  (:func:`~himit_torch.learner.backups.best_mentor`).
* ``q_second``/``mentor_second`` hold the second moments the confidence test needs.

Runs that plan on a posterior sample (the ``…_psrl`` agents, :mod:`himit_torch.learner.posterior_sampling`)
keep the same caches in the same form — ``q_numerator = (n + α)·Q̃ − α v0``, so that the formula
above yields the sampled value ``Q̃`` and every reader (backups, choice, diagnostics) is unchanged
— and propagate along the sampled weights ``(n + α) w_e Σγ^k/c_e`` (mentor: ``(n + α) w_e``)
instead of ``Σγ^k`` (``c``). A row's numerator is rebuilt from the sample whenever the sample
changes (:meth:`ValueCache.apply_sample_rows`, :meth:`ValueCache.apply_sample`).

A backup of ``s`` is then a max over its cached rows and its mentor term. The functions here are
the batched tensor-op path (the torch engine, diagnostics); the compiled engine computes the same
numbers in the same order on the same arrays.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

from himit_torch.learner.backups import (
    MentorConfidence,
    best_mentor,
    dirichlet_variance,
    feasible_mentor,
    mentor_backup_edges,
    option_backup_edges,
    segment_discount,
    trusted_augmented_backup,
)
from himit_torch.learner.models import DirichletMentorModel, DirichletSMDPModel
from himit_torch.learner.rows import RowTable
from himit_torch.state_checks import all_finite, private_copy, saved, section, tensor

if TYPE_CHECKING:
    from himit_torch.learner.config import LearnerConfig
    from himit_torch.learner.posterior_sampling import PosteriorSample

__all__ = ["ValueCache", "TIE"]

#: Two values within this distance are a tie (greedy choice, mentor matching).
TIE = 1e-12


def _take(x: torch.Tensor, flat: torch.Tensor) -> torch.Tensor:
    """``x`` (contiguous) read at flat indices of any shape: one ``index_select``, far cheaper
    than multi-tensor advanced indexing."""
    return x.view(-1).index_select(0, flat.reshape(-1)).view(flat.shape)


class ValueCache:
    """``V [B, S + 1]`` and the caches of eq. 2 for a batch, over its models and row table."""

    def __init__(
        self,
        config: LearnerConfig,
        rows: RowTable,
        model: DirichletSMDPModel,
        mentor: DirichletMentorModel,
        terminal: torch.Tensor,
        gamma: float,
        sample: PosteriorSample | None = None,
    ):
        self.config, self.rows, self.model, self.mentor = config, rows, model, mentor
        self.sample = sample
        self.any_sampling = sample is not None and sample.any
        self.terminal, self.gamma = terminal, gamma
        B, S, M = model.batch, rows.num_states, rows.num_rows
        dev = terminal.device
        self.batch, self.num_states, self.num_rows, self.device = B, S, M, dev
        self.values = torch.full(
            (B, S + 1), float(config.initial_value), dtype=torch.float64, device=dev
        )
        self.values[:, terminal] = 0.0
        # The shaping potential Φ each run's V holds (0 for runs that do not shape): derived from
        # the mentor model, so not part of the state (the learner recomputes it on loading).
        self.potential = torch.zeros(B, S + 1, dtype=torch.float64, device=dev)
        self.q_numerator = torch.zeros(B, M + 1, dtype=torch.float64, device=dev)
        self.q_second = torch.zeros_like(self.q_numerator)  # Σ (γ^k)² V² / c per row
        self.mentor_numerator = torch.zeros(B, mentor.num_rows + 1, dtype=torch.float64, device=dev)
        self.mentor_second = torch.zeros_like(self.mentor_numerator)
        self.mentor_edge_reward = torch.zeros(B, mentor.capacity, dtype=torch.float64, device=dev)
        # E[γ^k] per mentor edge (γ: one-step moves; LearnerConfig.mentor_segments: the edge's
        # own), derived from the mentor model and the config, so not part of the state.
        self.mentor_edge_discount = torch.full(
            (B, mentor.capacity), float(gamma), dtype=torch.float64, device=dev
        )
        mentor.on_grow.append(self._grow_mentor_reward)
        self.any_confidence = bool(rows.use_confidence.any())
        self.any_mentor = bool(rows.use_mentor.any())
        self._neg_inf = torch.tensor(float("-inf"), dtype=torch.float64, device=dev)
        self._zero = torch.zeros((), dtype=torch.float64, device=dev)
        self._untried = torch.tensor(
            float(config.untried_value if config.untried_value is not None else 0.0),
            dtype=torch.float64,
            device=dev,
        )

    _STATE = (
        "values",
        "q_numerator",
        "q_second",
        "mentor_numerator",
        "mentor_second",
        "mentor_edge_reward",
    )

    def state_dict(self, copy: bool = True) -> dict:
        """The cache, the mentor's edge rewards only in the slots the mentor model uses;
        ``copy=False``: the live tensors (and a view of the edge rewards), not copies (see
        :meth:`~himit_torch.Learner.state_dict`)."""
        out = {name: getattr(self, name) for name in self._STATE}
        # (the slots in use only: sliced before any copy, so the whole table is never copied)
        out["mentor_edge_reward"] = self.mentor_edge_reward[:, : self.mentor.used]
        return saved(out, copy)

    def check_state(self, state: dict, mentor_edges: int, where: str = "cache") -> None:
        """Check a :meth:`state_dict` read back (``mentor_edges``: the length of the mentor
        model's saved edge lists, which the edge rewards follow): every cache float64, of this
        batch's shape and finite.

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, self._STATE)
        for name in self._STATE:
            current = getattr(self, name)
            width = mentor_edges if name == "mentor_edge_reward" else current.shape[1]
            value = tensor(state, name, where, torch.float64, (self.batch, width))
            all_finite(value, f"{where}.{name}")

    def load_state_dict(
        self, state: dict, mentor_edges: int, where: str = "cache", *, checked: bool = False
    ) -> None:
        """Restore (after the mentor model, whose capacity the edge rewards follow), checked
        first (:meth:`check_state`) unless ``checked`` says it was."""
        if not checked:
            self.check_state(state, mentor_edges, where)
        for name in self._STATE:
            setattr(self, name, private_copy(state[name], self.device))
        self._grow_mentor_reward(self.mentor.capacity)
        self.refresh_mentor_discount()

    def _grow_mentor_reward(self, capacity: int) -> None:
        """Keep one edge reward and discount per slot of the mentor model's edge lists."""
        if capacity != self.mentor_edge_reward.shape[1]:
            grown = torch.zeros(self.batch, capacity, dtype=torch.float64, device=self.device)
            keep = min(capacity, self.mentor_edge_reward.shape[1])
            grown[:, :keep] = self.mentor_edge_reward[:, :keep]
            self.mentor_edge_reward = grown
        if capacity != self.mentor_edge_discount.shape[1]:
            grown = torch.full(
                (self.batch, capacity), float(self.gamma), dtype=torch.float64, device=self.device
            )
            keep = min(capacity, self.mentor_edge_discount.shape[1])
            grown[:, :keep] = self.mentor_edge_discount[:, :keep]
            self.mentor_edge_discount = grown

    def refresh_mentor_discount(self, runs: torch.Tensor | None = None) -> None:
        """Set ``E[γ^k]`` of every mentor edge of ``runs`` (default: all): ``γ``, or with
        ``LearnerConfig.mentor_segments`` :func:`~himit_torch.learner.backups.segment_discount`
        of the edge's mean delay (``edge_delay / edge_count``; ``γ`` for one-step moves)."""
        if runs is None:
            runs = torch.arange(self.batch, device=self.device)
        mentor = self.mentor
        discount = torch.full(
            (runs.numel(), mentor.capacity), float(self.gamma), dtype=torch.float64,
            device=self.device,
        )  # fmt: skip
        if self.config.mentor_segments:
            count = mentor.edge_count.index_select(0, runs)
            delay = mentor.edge_delay.index_select(0, runs)
            seen = count > 0
            mean_delay = delay / torch.where(seen, count, torch.ones_like(count))
            discount = torch.where(seen, segment_discount(mean_delay, self.gamma), discount)
        self.mentor_edge_discount.index_copy_(0, runs, discount)

    # ============================================================================ value queries
    def _row_flat(self, runs, rows):
        return runs * (self.num_rows + 1) + rows

    def _state_flat(self, runs, states):
        return runs * (self.num_states + 1) + states

    def _mentor_flat(self, runs, mentor_rows):
        return runs * (self.mentor.num_rows + 1) + mentor_rows

    def row_q(self, runs: torch.Tensor, rows: torch.Tensor) -> torch.Tensor:
        """Posterior-mean option values ``Q`` of ``rows`` (``runs`` broadcast against them);
        untried rows give the prior value ``v0`` if ``concentration > 0`` else ``NaN``."""
        flat = self._row_flat(runs, rows)
        return self._q_at(flat, _take(self.model.row_count, flat))

    def _q_at(self, flat, n):
        a, v0 = self.config.concentration, self.config.initial_value
        return (_take(self.q_numerator, flat) + a * v0) / (n + a)

    def mentor_term(self, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        """Posterior-mean mentor term ``R_m(s) + γ Σ p_m(s'|s) V(s')`` (NaN where not observed
        and no prior); with several mentors, the one eq. 2 takes (:meth:`mentor_rows`)."""
        flat = self._mentor_flat(runs, self.mentor_rows(runs, states))
        return self._mentor_at(flat, _take(self.mentor.row_count, flat))

    def mentor_rows(self, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        """The mentor row whose term enters eq. 2 at ``states`` (``runs`` broadcast): the state
        itself with one mentor; with several, the observed mentor with the largest term
        (:func:`~himit_torch.learner.backups.best_mentor`, after feasibility testing where it
        is on), mentor 0's row where none was seen."""
        if self.mentor.mentors == 1:
            return states
        rows = self.rows.state_rows.index_select(0, states.reshape(-1)).view(*states.shape, -1)
        flat_rows = self._row_flat(runs[..., None], rows)
        n_rows = _take(self.model.row_count, flat_rows)
        enabled = _take(self.rows.row_enabled, flat_rows)
        return self._chosen_mentor(runs, states, rows, n_rows, enabled)[0]

    def _chosen_mentor(self, runs, states, rows, n_rows, enabled):
        """``(mentor row, flat index, count, posterior-mean term, observed)`` of the mentor term
        that enters eq. 2 at ``states`` (:meth:`mentor_rows`): observed where the run imitates,
        the mentor was seen there and (with ``mentor_feasibility``) its move is not shown
        infeasible."""
        cfg, mentor = self.config, self.mentor
        imitates = self.rows.use_mentor[runs]
        runs_b = runs.expand_as(states)
        m_rows = mentor.rows_of(states)  # [..., K]
        flat = self._mentor_flat(runs_b[..., None], m_rows)
        n_m = _take(mentor.row_count, flat)
        # A mentor term exists only where that mentor was seen (a prior does not create one).
        observed = imitates.expand_as(states)[..., None] & (n_m > 0)
        if cfg.mentor_feasibility is not None:
            observed = torch.stack(
                [
                    observed[..., k]
                    & feasible_mentor(
                        self.mentor_reached(runs, states, rows, m_rows[..., k]),
                        n_rows,
                        enabled,
                        cfg.mentor_feasibility,
                    )
                    for k in range(mentor.mentors)
                ],
                -1,
            )
        m = self._mentor_at(flat, n_m)
        index, any_observed = best_mentor(m, observed)

        def pick(x):
            return x.gather(-1, index[..., None])[..., 0]

        return pick(m_rows), pick(flat), pick(n_m), pick(m), any_observed

    def _mentor_at(self, flat, n):
        a, v0 = self.config.mentor_concentration, self.config.initial_value
        return (_take(self.mentor_numerator, flat) + a * v0) / (n + a)

    def _row_variance(self, flat, n, q):
        a, v0 = self.config.concentration, self.config.initial_value
        rsum = _take(self.model.row_reward, flat)
        rbar = torch.where(n > 0, rsum / n.clamp(min=1), torch.zeros_like(n))
        cont = _take(self.q_numerator, flat) - rsum
        second = (n * rbar * rbar + 2 * rbar * cont + _take(self.q_second, flat) + a * v0 * v0) / (
            n + a
        )
        var = dirichlet_variance(q, second, n + a)
        # A row with no posterior at all (untried, no prior) valued by ``untried_value``: its
        # value is unbounded above, so no mentor term can be confidently better.
        return torch.where(n + a > 0, var, torch.full_like(var, float("inf")))

    def _mentor_variance(self, flat, n, m):
        a, v0 = self.config.mentor_concentration, self.config.initial_value
        second = (_take(self.mentor_second, flat) + a * v0 * v0) / (n + a)
        return dirichlet_variance(m, second, n + a)

    def own_values(self, runs: torch.Tensor, states: torch.Tensor):
        """Cached ``Q`` of the rows at ``states`` (``runs`` broadcast, ``[..., J]`` out): returns
        ``(rows, q, usable, enabled, flat rows, counts)``; ``usable`` = the run may use the row
        and it has a value (tried, or valued by the prior / ``untried_value``)."""
        cfg = self.config
        rows = self.rows.state_rows.index_select(0, states.reshape(-1)).view(*states.shape, -1)
        flat = self._row_flat(runs[..., None], rows)
        n = _take(self.model.row_count, flat)
        q = self._q_at(flat, n)
        enabled = _take(self.rows.row_enabled, flat)
        if cfg.concentration > 0:
            usable = enabled
        elif cfg.untried_value is None:
            usable = enabled & (n > 0)
        else:
            q = torch.where(n > 0, q, self._untried)
            usable = enabled
        return rows, q, usable, enabled, flat, n

    def state_backup(self, runs: torch.Tensor, states: torch.Tensor):
        """Eq. 2 for ``states [R, n]`` of ``runs [R, 1]`` (or broadcastable): returns
        ``(new V, has_value, mentor_won)``; ``-inf`` where nothing is known. The cache reads the
        inputs (``Q`` per row, the mentor term, counts, variances) from its numerators;
        :func:`~himit_torch.learner.backups.trusted_augmented_backup` evaluates the equation."""
        cfg = self.config
        rows, q, usable, enabled, flat_rows, n_rows = self.own_values(runs, states)
        _, flat_m, n_m, m, observed = self._chosen_mentor(runs, states, rows, n_rows, enabled)
        tries = (
            _take(self.model.state_tries, self._state_flat(runs, states))
            if cfg.mentor_override_after is not None or cfg.mentor_fade is not None
            else None
        )
        confidence = None
        if self.any_confidence and bool(self.rows.use_confidence[runs].any()):
            confidence = MentorConfidence(
                own_var=self._row_variance(flat_rows, n_rows, q),
                mentor_var=self._mentor_variance(flat_m, n_m, m),
                tested=self.rows.use_confidence[runs],
                z=cfg.confidence_z,
            )
        best, mentor_won = trusted_augmented_backup(
            q,
            usable,
            m,
            observed,
            tries,
            override_after=cfg.mentor_override_after,
            confidence=confidence,
            fade=cfg.mentor_fade,
        )
        # Terminal states (and the padding state) keep V = 0.
        has_value = torch.isfinite(best) & ~self.terminal.index_select(
            0, states.reshape(-1)
        ).view_as(states)
        return best, has_value, mentor_won

    def mentor_reached(
        self,
        runs: torch.Tensor,
        states: torch.Tensor,
        rows: torch.Tensor,
        mentor_rows: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """``[..., J]`` how many of each row's outcomes at ``states`` ended in a state the
        mentor was seen moving to from there (``rows``: the states' rows, ``[..., J]``; ``runs``
        broadcast against ``states``; ``mentor_rows``: which mentor's model of the states, by
        default the first's), for :func:`~himit_torch.learner.backups.feasible_mentor`."""
        model, mentor = self.model, self.mentor
        runs = runs.expand_as(states)
        r = runs[..., None].expand_as(rows)
        edges = model.index().forward[r, rows]  # [..., J, K]
        ok = edges >= 0
        flat_e = r[..., None] * model.capacity + edges.clamp(min=0)
        count = torch.where(ok, _take(model.edge_count, flat_e), self._zero)
        succ = torch.where(ok, _take(model.edge_successor, flat_e), torch.full_like(edges, -1))
        m_edges = mentor.index().forward[runs, states if mentor_rows is None else mentor_rows]
        m_ok = m_edges >= 0
        m_flat = runs[..., None] * mentor.capacity + m_edges.clamp(min=0)
        m_succ = torch.where(
            m_ok, _take(mentor.edge_successor, m_flat), torch.full_like(m_edges, -2)
        )
        hit = (succ[..., None] == m_succ[..., None, None, :]).any(-1)  # [..., J, K]
        return (count * hit).sum(-1)

    # ================================================================================ updates
    def backup_and_propagate(
        self, runs: torch.Tensor, states: torch.Tensor, valid: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Back up ``states [R, n]`` of ``runs [R]`` together (where ``valid``), then push each
        change ``δ`` into the caches of the states' predecessors. Returns the predecessors'
        new priorities ``(runs, states, |ΔQ|)`` for the sweeper."""
        best, has_value, _ = self.state_backup(runs[:, None], states)
        flat = self._state_flat(runs[:, None], states)
        old = _take(self.values, flat)
        keep = valid & has_value
        delta = torch.where(keep, best - old, self._zero)
        self.values.view(-1).index_put_((flat[keep],), best[keep])
        changed = delta != 0
        if not bool(changed.any()):
            empty = runs[:0]
            return empty, empty, torch.zeros(0, dtype=torch.float64, device=self.device)
        rr = runs[:, None].expand_as(states)[changed]
        xs, dd, vo = states[changed], delta[changed], old[changed]
        pushes = [self._propagate_options(rr, xs, dd, vo)]
        if self.any_mentor:
            pushes.append(self._propagate_mentor(rr, xs, dd, vo))
        runs_out, states_out, priorities = (torch.cat(parts) for parts in zip(*pushes))
        return runs_out, states_out, priorities

    def _propagate_options(self, runs, states, delta, old):
        """``V(x) += δ``: update the ``Q`` caches of every row with an edge to ``x``."""
        model = self.model
        owner, e = model.index().incoming(runs, states)
        r = runs.index_select(0, owner)
        d = delta.index_select(0, owner)
        flat_e = r * model.capacity + e
        rows = _take(model.edge_row, flat_e)
        g = _take(model.edge_discount, flat_e)
        if self.any_sampling:  # sampled runs: the sampled weight (n + α) w_e Σγ^k / c_e
            assert self.sample is not None
            n_row = _take(model.row_count, self._row_flat(r, rows))
            w = _take(self.sample.option_w, r * model.capacity + e)
            c_e = _take(model.edge_count, flat_e).clamp(min=1e-300)
            g = torch.where(
                self.rows.use_sampling.index_select(0, r),
                ((n_row + self.config.concentration) * w) * (g / c_e),
                g,
            )
        gd = g * d
        flat = self._row_flat(r, rows)
        self.q_numerator.view(-1).index_add_(0, flat, gd)
        if self.any_confidence:  # (second moments only for the confidence-tested runs)
            c = _take(model.edge_count, flat_e).clamp(min=1)
            v_old = old.index_select(0, owner)
            term = g * g / c * ((v_old + d) ** 2 - v_old**2)
            keep = self.rows.use_confidence.index_select(0, r)
            self.q_second.view(-1).index_add_(0, flat[keep], term[keep])
        prio = gd.abs() / (_take(model.row_count, flat) + self.config.concentration).clamp(
            min=1e-300
        )
        push = (prio > self.config.priority_threshold) & _take(self.rows.row_enabled, flat)
        return r[push], self.rows.row_state.index_select(0, rows[push]), prio[push]

    def _propagate_mentor(self, runs, states, delta, old):
        """The same for the mentor term of every state the mentor left towards ``x``."""
        keep = self.rows.use_mentor.index_select(0, runs)
        runs, states, delta, old = runs[keep], states[keep], delta[keep], old[keep]
        mentor = self.mentor
        owner, e = mentor.index().incoming(runs, states)
        r = runs.index_select(0, owner)
        flat_e = r * mentor.capacity + e
        discount = _take(self.mentor_edge_discount, flat_e)  # E[γ^k] (γ: one step)
        gd = discount * delta.index_select(0, owner)
        src = _take(mentor.edge_row, flat_e)
        c = _take(mentor.edge_count, flat_e)
        if self.any_sampling:  # sampled runs: the sampled weight (n + α) w_e
            assert self.sample is not None
            n_src = _take(mentor.row_count, self._mentor_flat(r, src))
            w = _take(self.sample.mentor_w, flat_e)
            c = torch.where(
                self.rows.use_sampling.index_select(0, r),
                (n_src + self.config.mentor_concentration) * w,
                c,
            )
        cd = c * gd
        flat = self._mentor_flat(r, src)
        self.mentor_numerator.view(-1).index_add_(0, flat, cd)
        if self.any_confidence:
            u_old = _take(self.mentor_edge_reward, flat_e) + discount * old.index_select(0, owner)
            term = c * ((u_old + gd) ** 2 - u_old**2)
            keep = self.rows.use_confidence.index_select(0, r)
            self.mentor_second.view(-1).index_add_(0, flat[keep], term[keep])
        prio = cd.abs() / (_take(mentor.row_count, flat) + self.config.mentor_concentration).clamp(
            min=1e-300
        )
        push = prio > self.config.priority_threshold
        return r[push], mentor.row_states(src[push]), prio[push]

    def add_outcome(self, runs, rows, ends, discounts, returns, c_old, g_old) -> None:
        """Fold one newly counted option outcome per run into the ``Q`` cache (after the model's
        :meth:`~himit_torch.DirichletSMDPModel.update` returned the edge's old count ``c_old``
        and summed ``γ^k`` ``g_old``)."""
        v_end = _take(self.values, self._state_flat(runs, ends))
        flat_r = self._row_flat(runs, rows)
        self.q_numerator.view(-1).index_add_(0, flat_r, returns + discounts * v_end)
        if self.any_confidence:
            c_new, g_new = c_old + 1, g_old + discounts
            old_term = torch.where(c_old > 0, g_old * g_old / c_old.clamp(min=1), self._zero)
            term = (g_new * g_new / c_new - old_term) * v_end * v_end
            keep = self.rows.use_confidence.index_select(0, runs)
            self.q_second.view(-1).index_add_(0, flat_r[keep], term[keep])

    def rebuild_options(self) -> None:
        """Recompute the ``Q`` caches from the option model's counts and ``V``, as
        :meth:`add_outcome` and the propagation would have built them: ``Σr + Σ_e Σγ^k V(s')``
        per row and the second moments ``Σ_e (Σγ^k)² / c · V(s')²`` of the confidence test (after
        a model was written wholesale, e.g. preloaded exact models). The sums run in edge order,
        not in the order the increments arrived: equal to the incremental caches up to rounding."""
        model = self.model
        valid = torch.arange(model.capacity, device=self.device) < model.num_edges[:, None]
        runs, slots = valid.nonzero(as_tuple=True)  # run by run, each run's edges in order
        flat_e = runs * model.capacity + slots
        rows, succ = _take(model.edge_row, flat_e), _take(model.edge_successor, flat_e)
        g, v = _take(model.edge_discount, flat_e), _take(self.values, self._state_flat(runs, succ))
        self.q_numerator.copy_(option_backup_edges(model.row_reward, runs, rows, g, v))
        # Σ_e (Σγ^k)² / c · V(s')²: the same edge sum, with weights (Σγ^k)² / c · V(s')
        # (confidence-tested runs only).
        tested = self.rows.use_confidence.index_select(0, runs)
        c = _take(model.edge_count, flat_e)
        self.q_second.copy_(
            option_backup_edges(
                torch.zeros_like(self.q_second),
                runs[tested],
                rows[tested],
                (g * g / c.clamp(min=1e-300) * v)[tested],
                v[tested],
            )
        )

    def set_potential(
        self, runs: torch.Tensor, potential: torch.Tensor, shift: bool = True
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Make ``potential [R, S + 1]`` (0 at terminal states) the shaping potential of
        ``runs [R]`` (potential-based shaping, :func:`~himit_torch.learner.backups.shaped_option_backup`).

        Shaping is implemented as its exact equivalent there (Wiewiora 2003): ``V`` holds
        ``U = V' + Φ``, the shaped value plus the potential, so that every backup, choice and
        priority is the unshaped one's and only the start value moves (``v0 + Φ(s)``). With
        ``shift``, ``V`` moves by the change of ``Φ`` at every state and the change is pushed into
        the ``Q`` caches of the states' predecessors (as a backup's is); without, ``Φ`` is only
        recorded (a ``V`` read back from a checkpoint already holds it). Returns the states
        whose backup now differs from ``V`` — ``(runs, states, |ΔV|)`` — for the sweeper."""
        if potential.shape != (runs.numel(), self.num_states + 1):
            raise ValueError(
                f"set_potential: potential {tuple(potential.shape)} must be "
                f"[{runs.numel()}, {self.num_states + 1}] (one row per run)"
            )
        terminal = self.terminal
        if bool((potential[:, terminal] != 0).any()):
            raise ValueError("set_potential: the potential must be 0 at terminal states")
        potential = potential.to(dtype=torch.float64, device=self.device)
        delta = potential - self.potential.index_select(0, runs)
        self.potential.index_copy_(0, runs, potential)
        if not shift:
            return runs[:0], runs[:0], torch.zeros(0, dtype=torch.float64, device=self.device)
        ri, xs = (delta != 0).nonzero(as_tuple=True)
        if ri.numel():
            rr, dd = runs.index_select(0, ri), delta[ri, xs]
            flat = self._state_flat(rr, xs)
            old = _take(self.values, flat)
            self.values.view(-1).index_add_(0, flat, dd)
            self._propagate_options(rr, xs, dd, old)  # (its priorities: value_changes below)
        return self.value_changes(runs=runs)

    def value_changes(
        self, where: torch.Tensor | None = None, runs: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Where a backup (eq. 2) would change ``V`` by more than the priority threshold:
        ``(runs, states, |new V − V|)``, for the sweeper to queue. ``runs [R]`` (default: every
        run) and ``where [R, S]`` bool limit the search."""
        S = self.num_states
        if runs is None:
            runs = torch.arange(self.batch, device=self.device)
        R = runs.numel()
        states = torch.arange(S, device=self.device)
        best, has_value, _ = self.state_backup(runs[:, None], states[None].expand(R, -1))
        old = self.values.index_select(0, runs)[:, :S]
        change = torch.where(has_value, (best - old).abs(), torch.zeros_like(best))
        queue = change > self.config.priority_threshold
        if where is not None:
            queue &= where
        ri, ss = queue.nonzero(as_tuple=True)
        return runs[ri], ss, change[ri, ss]

    def rebuild_mentor(self, runs: torch.Tensor | None = None) -> None:
        """Recompute the mentor caches of ``runs`` (default: every run) from the mentor model's
        counts, its edge rewards and ``V``, as the propagation would have built them:
        ``Σ_e c_e (r_e + E[γ^k]_e V(s'))`` per mentor row
        (:func:`~himit_torch.learner.backups.mentor_backup_edges`) and the second moments
        ``Σ_e c_e (r_e + E[γ^k]_e V(s'))²`` of the confidence test; other runs' caches are left
        as they are (a sampling run's hold its draw). The sums run in edge order."""
        mentor = self.mentor
        if runs is None:
            runs = torch.arange(self.batch, device=self.device)
        shape = (runs.numel(), self.mentor_numerator.shape[1])
        valid = (
            torch.arange(mentor.capacity, device=self.device)
            < mentor.num_edges.index_select(0, runs)[:, None]
        )
        local, slots = valid.nonzero(as_tuple=True)  # run by run, each run's edges in order
        r = runs.index_select(0, local)
        flat_e = r * mentor.capacity + slots
        src, dst = _take(mentor.edge_row, flat_e), _take(mentor.edge_successor, flat_e)
        c = _take(mentor.edge_count, flat_e)
        v = _take(self.values, self._state_flat(r, dst))
        reward = _take(self.mentor_edge_reward, r * self.mentor_edge_reward.shape[1] + slots)
        discount = _take(self.mentor_edge_discount, r * self.mentor_edge_discount.shape[1] + slots)
        numerator = mentor_backup_edges(shape, local, src, c, reward, discount, v)
        # Σ_e c_e u_e²: the same edge sum with weights c_e u_e (confidence-tested runs only).
        tested = self.rows.use_confidence.index_select(0, r)
        u = (reward + discount * v)[tested]
        second = option_backup_edges(
            torch.zeros(shape, dtype=torch.float64, device=self.device),
            local[tested],
            src[tested],
            c[tested] * u,
            u,
        )
        self.mentor_numerator.index_copy_(0, runs, numerator)
        self.mentor_second.index_copy_(0, runs, second)

    # ======================================================================= posterior samples
    def apply_sample_rows(self, runs: torch.Tensor, rows: torch.Tensor) -> None:
        """Rebuild the ``Q`` numerators of ``(runs[i], rows[i])`` (sampling runs) from their
        posterior sample: ``Q̃ = Σ_e w_e (r̄ + Σγ^k_e / c_e · V(s'_e)) + w_unseen v0`` (summed
        over the row's edges newest first, as the compiled kernel does), stored as
        ``(n + α) Q̃ − α v0``."""
        assert self.sample is not None
        model, sample, cfg = self.model, self.sample, self.config
        alpha, v0 = cfg.concentration, cfg.initial_value
        forward = model.index().forward
        K = forward.shape[2]
        cells = (runs * forward.shape[1] + rows)[:, None] * K + torch.arange(K, device=self.device)
        edges = forward.view(-1).index_select(0, cells.reshape(-1)).view(-1, K)
        valid = edges >= 0
        flat_e = runs[:, None] * model.capacity + edges.clamp(min=0)
        w = _take(sample.option_w, flat_e)
        g = _take(model.edge_discount, flat_e)
        c = torch.where(valid, _take(model.edge_count, flat_e), torch.ones_like(g))
        succ = _take(model.edge_successor, flat_e).clamp(min=0)
        v = _take(self.values, self._state_flat(runs[:, None], succ))
        flat_r = self._row_flat(runs, rows)
        n = _take(model.row_count, flat_r)
        rsum = _take(model.row_reward, flat_r)
        rbar = torch.where(n > 0, rsum / torch.where(n > 0, n, torch.ones_like(n)), self._zero)
        from himit_torch.learner.posterior_sampling import _descending_sum

        acc = _descending_sum(w * (rbar[:, None] + (g / c) * v), valid)
        q = acc + _take(sample.option_unseen, flat_r) * v0
        self.q_numerator.view(-1).index_put_((flat_r,), (n + alpha) * q - alpha * v0)

    def apply_sample_mentor(self, runs: torch.Tensor, states: torch.Tensor) -> None:
        """The same for the mentor numerators of ``(runs[i], states[i])`` (observed mentor rows:
        states, with one mentor):
        ``m̃ = Σ_e w_e (R_m(s, s'_e) + γ V(s'_e)) + w_unseen v0``, stored as
        ``(n + α_m) m̃ − α_m v0``."""
        assert self.sample is not None
        mentor, sample, cfg = self.mentor, self.sample, self.config
        alpha, v0 = cfg.mentor_concentration, cfg.initial_value
        forward = mentor.index().forward
        K = forward.shape[2]
        cells = (runs * forward.shape[1] + states)[:, None] * K + torch.arange(
            K, device=self.device
        )
        edges = forward.view(-1).index_select(0, cells.reshape(-1)).view(-1, K)
        valid = edges >= 0
        flat_e = runs[:, None] * mentor.capacity + edges.clamp(min=0)
        w = _take(sample.mentor_w, flat_e)
        r_e = _take(
            self.mentor_edge_reward,
            runs[:, None] * self.mentor_edge_reward.shape[1] + edges.clamp(min=0),
        )
        discount = _take(
            self.mentor_edge_discount,
            runs[:, None] * self.mentor_edge_discount.shape[1] + edges.clamp(min=0),
        )
        succ = _take(mentor.edge_successor, flat_e).clamp(min=0)
        v = _take(self.values, self._state_flat(runs[:, None], succ))
        from himit_torch.learner.posterior_sampling import _descending_sum

        acc = _descending_sum(w * (r_e + discount * v), valid)
        flat_s = self._mentor_flat(runs, states)
        m = acc + _take(sample.mentor_unseen, flat_s) * v0
        n = _take(mentor.row_count, flat_s)
        self.mentor_numerator.view(-1).index_put_((flat_s,), (n + alpha) * m - alpha * v0)

    def apply_sample(self, runs: torch.Tensor):
        """After a fresh draw for ``runs``: rebuild all their ``Q`` (and, for imitating runs,
        mentor) numerators from the sample, and return the states whose backup now differs
        from ``V`` — ``(runs, states, |ΔV|)`` above the priority threshold — for the sweeper."""
        M = self.num_rows
        R = runs.numel()
        rows = torch.arange(M, device=self.device)
        self.apply_sample_rows(runs.repeat_interleave(M), rows.repeat(R))
        imitating = runs[self.rows.use_mentor.index_select(0, runs)]
        if imitating.numel():
            observed = self.mentor.row_count.index_select(0, imitating)[:, : self.mentor.num_rows]
            observed = observed > 0
            rr, ss = observed.nonzero(as_tuple=True)
            if rr.numel():
                self.apply_sample_mentor(imitating[rr], ss)
        return self.value_changes(runs=runs)
