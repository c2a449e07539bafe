"""Posterior sampling (PSRL): runs that plan on a model drawn from their Dirichlet posteriors.

The ``…_psrl`` agent variants (:data:`~himit_torch.learner.agents.AGENTS`) plan on a *sample* of their
option model and of their mentor model instead of on the posterior means (Strens 2000; Osband,
Russo & Van Roy 2013, "(More) efficient reinforcement learning via posterior sampling"). A row's
posterior is the Dirichlet of :class:`~himit_torch.learner.models.SuccessorDirichlet`: its
observed successors' counts ``c_e`` plus the prior mass ``α`` on the lumped unseen outcome. A
sample is ``w ~ Dir(c_1 … c_K, α)``; the sampled option value is

    Q̃(s, o) = Σ_e w_e (r̄ + ḡ_e V(s'_e)) + w_unseen · v0,

with the mean reward ``r̄ = Σr / n`` and the mean discount ``ḡ_e = Σγ^k / c_e`` of the executions
that ended in ``s'_e`` (only the successor probabilities are sampled); the mentor term likewise
``m̃(s) = Σ_e w_e (R_m(s, s'_e) + γ V(s'_e)) + w_unseen · v0``. With ``w`` the posterior mean
(``w_e = c_e / (n + α)``) both are eq. 2's terms exactly.

When the model is drawn:

* **resample** — a fresh draw of every row of the run, at each episode start (after a goal;
  ``LearnerConfig.resample_every = 0``) or every ``resample_every`` decisions, and when the run is
  created or given demonstrations. The value cache then rebuilds the run's ``Q`` numerators from
  the sample and queues every state whose backup changed, so planning proceeds as usual;
* **absorb** — between resamples a row that gets a new outcome keeps a sample of its *updated*
  posterior by the coupling ``w' = s·w + (1 − s)·δ_e`` with ``s = U^{1/(n + α)}`` (``1 − s ~
  Beta(1, n + α)``). If ``w ~ Dir(c)`` then ``w' ~ Dir(c + δ_e)`` (Gamma-sum argument: with
  ``G_i ~ Γ(c_i)`` and ``G' ~ Γ(1)``, ``ΣG / (ΣG + G') ~ Beta(n + α, 1)`` independently of
  ``G / ΣG``), so the sample stays a posterior draw and moves only by the new evidence's share.

**Identical numbers on both engines.** Every draw is a pure function of the run's seed, the
resample number, the kind of draw and a slot (edge id or row), through the counter-based
uniforms of :mod:`himit_torch.rng` — independent of the batch. The Gamma sampler is Marsaglia &
Tsang (2000) with a Marsaglia polar normal, and uses only ``+ − × ÷``, ``sqrt`` (all correctly
rounded IEEE operations; :func:`exact_sqrt`, as torch's own CPU ``sqrt`` is not always) and
the :func:`fixed_log` / :func:`fixed_exp` below, written out in that same arithmetic: libm's
and torch's (SLEEF) ``log``/``exp`` differ in the last bit, which could flip an acceptance test.
:mod:`himit_torch.learner.engines.kernel` repeats each function operation for operation, and sums over a row's edges in the same (descending edge id) order, so a run's sample
is bit for bit the same on either engine.
"""

from __future__ import annotations

import math

import torch

from himit_torch.rng import _shr, splitmix64
from himit_torch.state_checks import all_finite, in_range, private_copy, saved, section, tensor

__all__ = [
    "fixed_log",
    "fixed_exp",
    "exact_sqrt",
    "sample_keys",
    "stream_uniforms",
    "gamma_draws",
    "coupling_share",
    "PosteriorSample",
    "KIND_OPTION_EDGE",
    "KIND_OPTION_UNSEEN",
    "KIND_MENTOR_EDGE",
    "KIND_MENTOR_UNSEEN",
    "KIND_ABSORB",
    "MAX_ATTEMPTS",
]

# ---- constants shared with the compiled kernel (it imports them) ------------------------------
LN2 = 0.6931471805599453
SQRT_HALF = 0.7071067811865476
#: 1 / (2k + 1), k = 0…12: the atanh series of :func:`fixed_log`.
ATANH_COEFFS = tuple(1.0 / (2 * k + 1) for k in range(13))
INV_LN2 = 1.4426950408889634
LN2_HI = 6.93147180369123816490e-01  # fdlibm's split of ln 2 (k·LN2_HI is exact)
LN2_LO = 1.90821492927058770002e-10
#: 1 / j!, j = 0…13: the Taylor series of :func:`fixed_exp`.
EXP_COEFFS = tuple(1.0 / math.factorial(j) for j in range(14))
#: Rejection attempts of one Gamma draw (3 uniforms each: lanes 0…1022); lane 1023 is the
#: shape < 1 boost. After this many rejections (probability ≈ 0.25^341) the draw is its ``d``.
MAX_ATTEMPTS = 341
BOOST_LANE = 1023
#: Salt of the sampler's streams (kept apart from the tick uniforms' keys).
SAMPLE_TAG = 0x2545F4914F6CDD1D
KIND_OPTION_EDGE, KIND_OPTION_UNSEEN, KIND_MENTOR_EDGE, KIND_MENTOR_UNSEEN, KIND_ABSORB = range(5)

_F64 = torch.float64


def fixed_log(x: torch.Tensor) -> torch.Tensor:
    """Natural log of ``x ≥ 0`` (float64) in plain IEEE arithmetic, ``-inf`` at 0.

    ``x = m·2^e`` (``frexp``, exact) with ``m`` in ``[√½, √2)``; ``log m = 2 atanh(z)``,
    ``z = (m − 1)/(m + 1)``, ``|z| ≤ 0.172``, by 13 terms of its series (truncation < 1e-21).
    Accurate to a few ulp; the point is that the compiled kernel computes the same bits."""
    m, e = torch.frexp(x)
    low = m < SQRT_HALF
    m = torch.where(low, m * 2.0, m)
    ef = e.to(_F64) - low.to(_F64)
    z = (m - 1.0) / (m + 1.0)
    z2 = z * z
    p = torch.full_like(z, ATANH_COEFFS[-1])
    for c in reversed(ATANH_COEFFS[:-1]):
        p = p * z2 + c
    out = ef * LN2 + (2.0 * z) * p
    out = torch.where(x == 0, torch.full_like(out, float("-inf")), out)
    return torch.where(x < 0, torch.full_like(out, float("nan")), out)


def fixed_exp(x: torch.Tensor) -> torch.Tensor:
    """``e^x`` (float64) in plain IEEE arithmetic: 0 below −708, ``inf`` above 709.

    ``x = k ln2 + r`` (Cody–Waite, ``|r| ≤ 0.35``), ``e^r`` by 14 Taylor terms (truncation
    < 1e-17), times ``2^k`` built from its bits (exact)."""
    k = torch.floor(x * INV_LN2 + 0.5)
    r = (x - k * LN2_HI) - k * LN2_LO
    p = torch.full_like(r, EXP_COEFFS[-1])
    for c in reversed(EXP_COEFFS[:-1]):
        p = p * r + c
    kk = torch.nan_to_num(k, nan=0.0).clamp(-1022, 1023).to(torch.int64)
    two_k = ((kk + 1023) << 52).view(_F64)
    out = p * two_k
    out = torch.where(x < -708.0, torch.zeros_like(out), out)
    return torch.where(x > 709.0, torch.full_like(out, float("inf")), out)


def exact_sqrt(x: torch.Tensor) -> torch.Tensor:
    """Correctly rounded ``√x`` (IEEE), as the kernel's ``np.sqrt``: torch's CPU ``sqrt`` on
    AVX-512 (SLEEF) is off by one ulp now and then (measured), so on a CPU NumPy's is used; CUDA's
    double ``sqrt`` is correctly rounded."""
    if x.device.type == "cpu":
        import numpy as np

        return torch.from_numpy(np.sqrt(x.detach().contiguous().numpy()))
    return torch.sqrt(x)


def sample_keys(keys: torch.Tensor, events: torch.Tensor, kind: int) -> torch.Tensor:
    """Stream keys of draw kind ``kind`` at resample number ``events`` (``keys``, ``events``
    broadcast; int64): unrelated to the tick uniforms' streams and to each other."""
    salt = splitmix64(events.to(torch.int64) * 8 + (kind + SAMPLE_TAG))
    return splitmix64(keys ^ salt)


def stream_uniforms(keys: torch.Tensor, slots: torch.Tensor, lane: int) -> torch.Tensor:
    """Uniforms in [0, 1): lane ``lane`` of counter ``slots`` of each element's stream ``keys``
    (elementwise :func:`himit_torch.rng.uniforms`)."""
    salt = splitmix64(slots * 1024 + lane)
    return _shr(splitmix64(keys ^ salt), 11).to(_F64) * (1.0 / (1 << 53))


def gamma_draws(keys: torch.Tensor, slots: torch.Tensor, shape: torch.Tensor) -> torch.Tensor:
    """One ``Gamma(shape, 1)`` draw per element from its stream ``(keys, slots)`` (0 where
    ``shape ≤ 0``: an outcome with no mass).

    Marsaglia & Tsang (2000), "A simple method for generating gamma variables": ``d = a − 1/3``,
    ``c = 1/√(9d)``; attempt ``i`` takes lanes ``3i, 3i+1`` for a Marsaglia polar normal ``x``
    and lane ``3i+2`` for the acceptance uniform; ``d·(1 + cx)³`` is accepted by the squeeze or
    the log test. A shape ``a < 1`` draws ``Gamma(a + 1)·U^{1/a}`` (lane 1023)."""
    shape = shape.to(_F64)
    pos = shape > 0
    boost = shape < 1.0
    a = torch.where(boost, shape + 1.0, shape)
    d = a - 1.0 / 3.0
    c = 1.0 / exact_sqrt(9.0 * d.clamp(min=1e-300))
    g = d.clone()
    active = pos.clone()
    for i in range(MAX_ATTEMPTS):
        idx = active.nonzero()[:, 0]
        if idx.numel() == 0:
            break
        k, sl = keys.index_select(0, idx), slots.index_select(0, idx)
        x1 = 2.0 * stream_uniforms(k, sl, 3 * i) - 1.0
        x2 = 2.0 * stream_uniforms(k, sl, 3 * i + 1) - 1.0
        s = x1 * x1 + x2 * x2
        ok = (s < 1.0) & (s > 0.0)
        s_safe = torch.where(ok, s, torch.full_like(s, 0.5))
        x = x1 * exact_sqrt(-2.0 * fixed_log(s_safe) / s_safe)
        di, ci = d.index_select(0, idx), c.index_select(0, idx)
        v = 1.0 + ci * x
        ok = ok & (v > 0.0)
        v = v * v * v
        u = stream_uniforms(k, sl, 3 * i + 2)
        xx = x * x
        squeeze = u < 1.0 - 0.0331 * xx * xx
        v_safe = torch.where(ok, v, torch.ones_like(v))
        log_test = fixed_log(u) < 0.5 * xx + di * (1.0 - v_safe + fixed_log(v_safe))
        accept = ok & (squeeze | log_test)
        done = idx[accept]
        g[done] = (di * v)[accept]
        active[done] = False
    ub = stream_uniforms(keys, slots, BOOST_LANE)
    boosted = g * fixed_exp(fixed_log(ub) / torch.where(boost, shape, torch.ones_like(shape)))
    g = torch.where(boost, boosted, g)
    return torch.where(pos, g, torch.zeros_like(g))


def coupling_share(u: torch.Tensor, total: torch.Tensor) -> torch.Tensor:
    """``s = u^{1/total}`` (0 where ``total ≤ 0``): the share of the old sample kept when one
    outcome is added to a Dirichlet of total mass ``total`` (module docstring)."""
    safe = torch.where(total > 0, total, torch.ones_like(total))
    s = fixed_exp(fixed_log(u) / safe)
    return torch.where(total > 0, s, torch.zeros_like(s))


def _descending_sum(values: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """``Σ_k values[..., k]`` over ``valid`` entries, added from the last column to the first —
    the compiled kernel's order along its newest-first linked lists (padding comes last in a
    row's table and adds exact zeros first), so both engines get the same bits in any batch."""
    acc = torch.zeros(values.shape[:-1], dtype=_F64, device=values.device)
    zero = torch.zeros((), dtype=_F64, device=values.device)
    for k in range(values.shape[-1] - 1, -1, -1):
        acc = acc + torch.where(valid[..., k], values[..., k], zero)
    return acc


class PosteriorSample:
    """The sampled successor probabilities of the batch's sampling runs (the only writer).

    ``option_w [B, E]`` per option-model edge, ``option_unseen [B, M + 1]`` per row (the unseen
    outcome), ``mentor_w [B, E_m]`` per mentor edge, ``mentor_unseen [B, S + 1]`` per state, and
    ``resamples [B]`` (how many full draws each run has made: the next draw's event number).
    Rows of runs that do not sample stay 0 and are never read."""

    def __init__(self, rows, model, mentor, keys: torch.Tensor, config):
        self.rows, self.model, self.mentor, self.keys = rows, model, mentor, keys
        self.option_concentration = float(config.concentration)
        self.mentor_concentration = float(config.mentor_concentration)
        B, dev = model.batch, model.device
        self.batch, self.device = B, dev
        self.enabled = rows.use_sampling
        self.any = bool(self.enabled.any())
        self.option_w = torch.zeros(B, model.capacity, dtype=_F64, device=dev)
        self.option_unseen = torch.zeros(B, model.num_rows + 1, dtype=_F64, device=dev)
        self.mentor_w = torch.zeros(B, mentor.capacity, dtype=_F64, device=dev)
        self.mentor_unseen = torch.zeros(B, mentor.num_rows + 1, dtype=_F64, device=dev)
        self.resamples = torch.zeros(B, dtype=torch.int64, device=dev)
        model.on_grow.append(lambda cap: self._grow("option_w", cap))
        mentor.on_grow.append(lambda cap: self._grow("mentor_w", cap))

    def _grow(self, name: str, capacity: int) -> None:
        old = getattr(self, name)
        if capacity != old.shape[1]:
            grown = torch.zeros(self.batch, capacity, dtype=_F64, device=self.device)
            keep = min(capacity, old.shape[1])
            grown[:, :keep] = old[:, :keep]
            setattr(self, name, grown)

    # ---------------------------------------------------------------------------- drawing
    def _draw_store(self, runs, store, kind_edge, kind_unseen, alpha, w_name, unseen_name):
        """Fresh ``Dir(c, α)`` draws of every row of ``store`` for ``runs`` (event numbers
        ``resamples[runs]``): normalised Gamma draws, the mean where they all underflowed."""
        R, dev = runs.numel(), self.device
        E = int(store.num_edges.index_select(0, runs).max()) if R else 0
        events = self.resamples.index_select(0, runs)
        keys = self.keys.index_select(0, runs)
        ids = torch.arange(max(E, 1), device=dev)
        edge_valid = ids[None] < store.num_edges.index_select(0, runs)[:, None]  # [R, E]
        count = store.edge_count.index_select(0, runs)[:, : ids.numel()]
        g_edge = gamma_draws(
            sample_keys(keys, events, kind_edge)[:, None].expand(-1, ids.numel()).reshape(-1),
            ids[None].expand(R, -1).reshape(-1),
            torch.where(edge_valid, count, torch.zeros_like(count)).reshape(-1),
        ).view(R, -1)
        Rw = store.num_rows  # rows 0…Rw−1 (the padding row is never drawn)
        row_ids = torch.arange(Rw, device=dev)
        if alpha > 0:
            g_unseen = gamma_draws(
                sample_keys(keys, events, kind_unseen)[:, None].expand(-1, Rw).reshape(-1),
                row_ids[None].expand(R, -1).reshape(-1),
                torch.full((R * Rw,), alpha, dtype=_F64, device=dev),
            ).view(R, Rw)
        else:
            g_unseen = torch.zeros(R, Rw, dtype=_F64, device=dev)
        forward = store.index().forward.index_select(0, runs)[:, :Rw]  # [R, Rw, K]
        fvalid = forward >= 0
        fg = g_edge.gather(1, forward.clamp(min=0).reshape(R, -1)).view_as(forward)
        total = _descending_sum(fg, fvalid) + g_unseen  # [R, Rw]
        n = store.row_count.index_select(0, runs)[:, :Rw]
        # Normalise; where every draw underflowed (only with tiny shapes), fall back to the mean.
        edge_rows = store.edge_row.index_select(0, runs)[:, : ids.numel()].clamp(min=0, max=Rw - 1)
        t_e = total.gather(1, edge_rows)
        n_e = n.gather(1, edge_rows)
        mean_e = count / (n_e + alpha).clamp(min=1e-300)
        w = torch.where(t_e > 0, g_edge / t_e.clamp(min=1e-300), mean_e)
        w = torch.where(edge_valid, w, torch.zeros_like(w))
        has_mass = (n + alpha) > 0
        mean_u = torch.where(has_mass, alpha / (n + alpha).clamp(min=1e-300), torch.zeros_like(n))
        wu = torch.where(total > 0, g_unseen / total.clamp(min=1e-300), mean_u)
        w_all, u_all = getattr(self, w_name), getattr(self, unseen_name)
        w_all[runs[:, None], ids[None]] = w
        u_all[runs, :Rw] = wu

    def draw(self, runs: torch.Tensor) -> None:
        """Fresh draws of the option model of ``runs`` and, for imitating runs, of their mentor
        model; advances their ``resamples``."""
        if runs.numel() == 0:
            return
        self._draw_store(
            runs,
            self.model,
            KIND_OPTION_EDGE,
            KIND_OPTION_UNSEEN,
            self.option_concentration,
            "option_w",
            "option_unseen",
        )
        imitating = runs[self.rows.use_mentor.index_select(0, runs)]
        if imitating.numel():
            self._draw_store(
                imitating,
                self.mentor,
                KIND_MENTOR_EDGE,
                KIND_MENTOR_UNSEEN,
                self.mentor_concentration,
                "mentor_w",
                "mentor_unseen",
            )
        self.resamples.index_add_(0, runs, torch.ones_like(runs))

    def absorb(
        self,
        runs: torch.Tensor,
        rows: torch.Tensor,
        edges: torch.Tensor,
        n_old: torch.Tensor,
        decisions: torch.Tensor,
    ) -> None:
        """One new outcome ``(runs[i], rows[i]) → edges[i]`` (the model already counted it;
        ``n_old`` its row's count before): keep a sample of the updated posterior by the
        coupling of the module docstring. ``decisions`` (the runs' decisions before this one)
        numbers the uniform."""
        keys = sample_keys(self.keys.index_select(0, runs), torch.zeros_like(runs), KIND_ABSORB)
        u = stream_uniforms(keys, decisions, 0)
        s = coupling_share(u, n_old + self.option_concentration)
        forward = self.model.index().forward[runs, rows]  # [R, K]
        valid = forward >= 0
        cells = runs[:, None] * self.option_w.shape[1] + forward.clamp(min=0)
        flat = self.option_w.view(-1)
        old = flat.index_select(0, cells.reshape(-1)).view_as(cells)
        flat.index_put_((cells[valid],), (old * s[:, None])[valid])
        self.option_unseen[runs, rows] = self.option_unseen[runs, rows] * s
        self.option_w[runs, edges] = self.option_w[runs, edges] + (1.0 - s)

    # ------------------------------------------------------------------------- checkpoints
    def state_dict(self, copy: bool = True) -> dict:
        """The draws (per edge only in the slots the models use) and the resample counts;
        ``copy=False``: the live tensors and views of them, not copies (see
        :meth:`~himit_torch.Learner.state_dict`)."""
        out = {
            "option_w": self.option_w[:, : self.model.used],
            "option_unseen": self.option_unseen,
            "mentor_w": self.mentor_w[:, : self.mentor.used],
            "mentor_unseen": self.mentor_unseen,
            "resamples": self.resamples,
        }
        return saved(out, copy)

    _STATE = ("option_w", "option_unseen", "mentor_w", "mentor_unseen", "resamples")

    def check_state(
        self, state: dict, option_edges: int, mentor_edges: int, where: str = "sample"
    ) -> None:
        """Check a :meth:`state_dict` read back (``option_edges``, ``mentor_edges``: the lengths
        of the models' saved edge lists, which the per-edge draws follow): the draws float64 of
        this batch's shapes, finite and ≥ 0; ``resamples`` int64 counts.

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, self._STATE)
        B = self.batch
        widths = {
            "option_w": option_edges,
            "option_unseen": self.option_unseen.shape[1],
            "mentor_w": mentor_edges,
            "mentor_unseen": self.mentor_unseen.shape[1],
        }
        for name, width in widths.items():
            value = tensor(state, name, where, _F64, (B, width))
            all_finite(value, f"{where}.{name}", minimum=0.0)
        resamples = tensor(state, "resamples", where, torch.int64, (B,))
        in_range(resamples, f"{where}.resamples", 0, 2**62, "a count")

    def load_state_dict(
        self,
        state: dict,
        option_edges: int,
        mentor_edges: int,
        where: str = "sample",
        *,
        checked: bool = False,
    ) -> None:
        """Restore (after the models, whose capacities the per-edge draws follow), checked
        first (:meth:`check_state`) unless ``checked`` says it was."""
        if not checked:
            self.check_state(state, option_edges, mentor_edges, where)
        for name in ("option_unseen", "mentor_unseen", "resamples"):
            setattr(self, name, private_copy(state[name], self.device))
        for name, store in (("option_w", self.model), ("mentor_w", self.mentor)):
            value = state[name].detach().to(self.device)
            grown = torch.zeros(self.batch, store.capacity, dtype=_F64, device=self.device)
            grown[:, : value.shape[1]] = value
            setattr(self, name, grown)
