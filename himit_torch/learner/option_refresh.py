"""A learner's runs continued with a new option set, keeping what they learned.

A :class:`~himit_torch.Learner`'s option set is fixed for its life (the row table is built from
it). Options discovered from a growing model (:mod:`himit_torch.options.discovery`) change as evidence
grows, so :func:`with_options` builds a new learner over a new option set and carries the runs'
state into it:

* **Option models** — the rows ``(s, o)`` of every option that is *kept* keep their counts, edges
  and cached ``Q`` numerators; rows of new or changed options start empty. A new option is kept
  when the old set has an option of the same name (the ``k``-th of that name matches the
  ``k``-th) that behaves the same from ``s``: equal termination ``β`` everywhere and equal policy
  where either may act (the states of both initiation sets and where ``β < 1``). Then an
  execution from ``s`` has the same outcome distribution, so its counts remain evidence about
  it. The primitive options must be the first options of both sets, unchanged.
* **Everything else, unchanged** — ``V``, the mentor model and its rewards and caches, a
  ``bco`` run's cloned actions (actions, kept as they are: its primitives are too), the sweep queue and pending budgets, each run's counters (``t``, goals, episodes, ε and its
  schedule state, first goal, decisions, backups, visits, ``state_tries``), its position, its
  seed and thereby its random stream (a counter-based stream whose position is ``t``), and the
  per-window metrics.
* **The option in flight** — a run that is executing a kept option goes on executing it. A run
  whose option was dropped or changed (or that its new agent variant may not use) ends it at the
  swap *without learning from it* — the outcome of an interrupted option is not an outcome of the
  option — and chooses its next option at its current state, ε-greedily over the new set, with
  the uniforms of draw ``−(t + 2)`` of its stream (draws ``≥ 0`` are the ticks', ``−1`` the first
  choice): deterministic per seed. ε, the decision counter and the model do not change then.
* **Planning** — where the swap changed a run's usable rows at ``s`` (a row dropped, or a new one
  usable), ``s`` is queued if a backup would change ``V(s)`` (:meth:`ValueCache.value_changes`);
  the sweeps of the following decisions propagate it. Values themselves are not recomputed.

The exact statement this gives (tested on both engines): swapping to the *same* option set —
or to any set in which a run's usable options are the same, e.g. a ``primitives`` run when
options are added — continues that run bit for bit as if nothing had happened. The carried
``Q`` numerators of kept rows are the incremental caches themselves, not a recomputation
(:meth:`ValueCache.rebuild_options` sums in another order: equal up to rounding, which ties
decided at 1e-12 would turn into a different run).

Not carried: learners with ``LearnerConfig.option_models = "exact"`` (their models come from the
world, not from evidence: build a new learner).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import torch

from himit_torch.learner.agents import AGENTS
from himit_torch.learner.choice import choose_rows
from himit_torch.options.bundle import Options
from himit_torch.rng import uniforms
from himit_torch.validation import as_int_array

if TYPE_CHECKING:
    from himit_torch.learner.learner import Learner

__all__ = ["with_options", "option_correspondence", "row_correspondence"]


def _leading_primitives(options: Options) -> int:
    """How many of the first options are primitive (all primitives must come first)."""
    kinds = options.kinds
    P = 0
    while P < len(kinds) and kinds[P] == "primitive":
        P += 1
    return P


def _same_behaviour(old: Options, o_old: int, new: Options, o_new: int, num_actions: int) -> bool:
    """Whether option ``o_old`` of ``old`` and ``o_new`` of ``new`` have equal ``β`` everywhere
    and equal policies wherever either may act (both initiation sets and where ``β < 1``)."""
    beta_old, beta_new = old.termination[o_old], new.termination[o_new]
    if not torch.equal(beta_old.double(), beta_new.double()):
        return False
    acts = old.initiation[o_old] | new.initiation[o_new] | (beta_new < 1)
    if old.stochastic or new.stochastic:
        p_old = old.select([o_old]).action_probabilities(num_actions)[0]
        p_new = new.select([o_new]).action_probabilities(num_actions)[0]
        return torch.equal(p_old[acts], p_new[acts])
    return torch.equal(old.policy[o_old][acts].long(), new.policy[o_new][acts].long())


def option_correspondence(old: Options, new: Options, num_actions: int) -> torch.Tensor:
    """``[O_new]`` int64: the option of ``old`` that each option of ``new`` continues, −1 where it
    is new or behaves differently (see the module docstring: same name — the ``k``-th of a name
    matches the ``k``-th — and same ``β`` and policy where either may act)."""
    seen: dict[str, int] = {}
    old_by_name: dict[tuple[str, int], int] = {}
    for o, name in enumerate(old.names):
        old_by_name[(name, seen.get(name, 0))] = o
        seen[name] = seen.get(name, 0) + 1
    seen.clear()
    out = torch.full((new.num_options,), -1, dtype=torch.int64)
    for o, name in enumerate(new.names):
        k = seen.get(name, 0)
        seen[name] = k + 1
        o_old = old_by_name.get((name, k))
        if o_old is not None and _same_behaviour(old, o_old, new, o, num_actions):
            out[o] = o_old
    return out


def row_correspondence(old_learner: Learner, new_learner: Learner, options: torch.Tensor):
    """``[M_old + 1]`` int64: the row of ``new_learner`` that continues each row of
    ``old_learner`` (−1: dropped; the padding row maps to the padding row), given the option
    correspondence ``options [O_new]`` of :func:`option_correspondence`. A row continues when its
    option is kept and its state lies in the new option's initiation set."""
    old_rows, new_rows = old_learner.rows, new_learner.rows
    dev = old_learner.device
    O_old, O_new = old_learner.num_options, new_learner.num_options
    to_new = torch.full((O_old,), -1, dtype=torch.int64, device=dev)
    kept = (options >= 0).nonzero()[:, 0].to(dev)
    to_new[options.to(dev)[kept]] = kept
    s_old, o_old = old_rows.row_state[:-1], old_rows.row_option[:-1]
    o_new = to_new[o_old]
    # The new row table enumerates rows by ascending state · O + option: a sorted key.
    new_keys = new_rows.row_state[:-1] * O_new + new_rows.row_option[:-1]
    key = s_old * O_new + o_new.clamp(min=0)
    at = torch.searchsorted(new_keys, key).clamp(max=max(new_keys.numel() - 1, 0))
    found = (o_new >= 0) & (new_keys.numel() > 0) & (new_keys[at] == key)
    mapping = torch.where(found, at, torch.full_like(at, -1))
    return torch.cat([mapping, torch.tensor([new_learner.num_rows], device=dev)])


def _check(learner: Learner, options: Options, runs: list[int], agents: list[str]) -> None:
    if not isinstance(options, Options):
        raise ValueError(f"options must be an Options bundle, got {type(options).__name__}")
    if options.num_states != learner.num_states:
        raise ValueError(
            f"the new options are over {options.num_states} states but the learner's world has "
            f"{learner.num_states}: they were built for another world; build them for "
            "learner.world"
        )
    if learner.config.option_models != "learned":
        raise ValueError(
            "with_options carries learned option models; a learner with "
            f"LearnerConfig.option_models={learner.config.option_models!r} takes its models "
            "from the world: build a new Learner with the new options instead"
        )
    old = learner.options
    P = _leading_primitives(old)
    if P != int(old.is_primitive.sum()):
        raise ValueError(
            "the learner's primitive options are not its first options; with_options needs "
            "them first (Options.concat(primitive_options(world), …))"
        )
    if _leading_primitives(options) != P or int(options.is_primitive.sum()) != P:
        raise ValueError(
            f"the new options must start with the learner's {P} primitive options and hold no "
            f"others; they start with {_leading_primitives(options)} and hold "
            f"{int(options.is_primitive.sum())}: use Options.concat(primitive_options(world), "
            "…) with the learner's world"
        )
    A = int(learner.world.num_actions)
    for o in range(P):
        same = (
            old.names[o] == options.names[o]
            and torch.equal(old.initiation[o], options.initiation[o])
            and _same_behaviour(old, o, options, o, A)
        )
        if not same:
            raise ValueError(
                f"primitive option {o} ({old.names[o]!r}) differs in the new options "
                f"({options.names[o]!r}: name, initiation set or action): the new options must "
                "start with the same primitives, built for the same world "
                "(primitive_options(learner.world))"
            )
    if not runs:
        raise ValueError("runs is empty: carry at least one run")
    bad = [b for b in runs if not 0 <= b < learner.batch]
    if bad or len(set(runs)) != len(runs):
        raise ValueError(f"runs={runs}: give distinct run indices in 0…{learner.batch - 1}")
    if len(agents) != len(runs):
        raise ValueError(f"{len(agents)} agents for {len(runs)} runs: give one per carried run")
    unknown = sorted({repr(a) for a in agents if not isinstance(a, str) or a not in AGENTS})
    if unknown:
        raise ValueError(f"unknown agent variant(s) {unknown}; use one of {sorted(AGENTS)}")
    for b, agent in zip(runs, agents):
        _, mentor, confident, sampling, shaping, cloning = AGENTS[agent]
        _, old_mentor, old_confident, old_sampling, old_shaping, old_cloning = AGENTS[
            learner.agents[b]
        ]
        if sampling or old_sampling:
            # The posterior draw (PosteriorSample) is per edge of the old option set; carrying
            # it across a change of options is not implemented, and redrawing would silently
            # change the run.
            raise ValueError(
                f"run {b} ({learner.agents[b]} → {agent}): posterior-sampling (…_psrl) runs "
                "cannot be carried to a new option set; use the mean-model variant"
            )
        if (mentor, confident, shaping, cloning) != (
            old_mentor,
            old_confident,
            old_shaping,
            old_cloning,
        ):
            raise ValueError(
                f"run {b} ({learner.agents[b]}) cannot become {agent!r}: a new variant may change "
                "which options a run uses, not whether it has a mentor term, its confidence "
                "test, shaping or cloning (e.g. primitives → options, imitation_primitives → "
                "imitation, pbrs_primitives → pbrs)"
            )


def with_options(
    learner: Learner,
    options: Options,
    *,
    runs: Sequence[int] | None = None,
    agents: Sequence[str] | None = None,
    engine: str | None = None,
) -> Learner:
    """A new learner over ``options`` that continues ``learner``'s runs (the module docstring says
    what is carried and what happens to an option in flight). ``learner`` is left unchanged.

    Args:
        learner: the learner to continue (``LearnerConfig.option_models = "learned"``).
        options: the new option set, starting with ``learner``'s primitive options (unchanged),
            over the same world.
        runs: which runs to carry, in this order (default: all), whole numbers in
            ``0…B−1`` (``99`` or ``0.7`` refused); each keeps its seed.
        agents: the carried runs' new agent variants (default: the same), e.g. ``"options"`` for
            a ``"primitives"`` run; the mentor term and the confidence test must stay.
        engine: the new learner's engine (default: ``learner``'s).

    Raises:
        TypeError: ``learner`` is no :class:`~himit_torch.Learner`.
        ValueError: options over another world, without the same leading primitives, bad runs
            or agents, or a learner with exact option models.
    """
    from himit_torch.learner.learner import Learner

    if not isinstance(learner, Learner):
        raise TypeError(
            f"with_options: learner must be the Learner to continue (a Learner over the old "
            f"options), got {type(learner).__name__}"
        )
    runs = (
        list(range(learner.batch))
        if runs is None
        else as_int_array("with_options: runs", runs, 0, learner.batch - 1).tolist()
    )
    if agents is not None and (
        isinstance(agents, (str, bytes)) or not isinstance(agents, (list, tuple))
    ):
        raise ValueError(
            f"with_options: agents must be a list (one per carried run), got {agents!r}"
        )
    agents = [learner.agents[b] for b in runs] if agents is None else list(agents)
    _check(learner, options, runs, agents)
    dev = learner.device
    idx = torch.tensor(runs, dtype=torch.int64, device=dev)
    new = Learner(
        learner.world,
        options,
        agents,
        [learner.seeds[b] for b in runs],
        config=learner.config,
        reward=[learner.rewards[b] for b in runs],
        device=dev,
        engine=engine or learner.engine.name,
    )
    correspondence = option_correspondence(learner.options, options, learner.world.num_actions)
    row_map = row_correspondence(learner, new, correspondence)
    M_new = new.num_rows

    # ---- the option model: kept rows' edges (in their order) and row sums
    old_model = learner.model
    E = old_model.capacity
    edge_row = old_model.edge_row[idx]
    valid = torch.arange(E, device=dev) < old_model.num_edges[idx, None]
    mapped = torch.where(valid, row_map[edge_row.clamp(min=0)], torch.full_like(edge_row, -1))
    keep = valid & (mapped >= 0)
    slot = keep.long().cumsum(1) - 1
    count = keep.sum(1)
    width = max(1, int(count.max()))
    rr, ee = keep.nonzero(as_tuple=True)
    model_state: dict[str, torch.Tensor] = {"num_edges": count}
    for name, fill, value in (
        ("edge_row", -1, mapped),
        ("edge_successor", -1, old_model.edge_successor[idx]),
        ("edge_count", 0, old_model.edge_count[idx]),
        ("edge_discount", 0, old_model.edge_discount[idx]),
    ):
        out = torch.full((len(runs), width), fill, dtype=value.dtype, device=dev)
        out[rr, slot[rr, ee]] = value[rr, ee]
        model_state[name] = out
    kept_old = (row_map[:-1] >= 0).nonzero()[:, 0]
    kept_new = row_map[kept_old]

    def rows_carried(table: torch.Tensor) -> torch.Tensor:
        """``[R, M_new + 1]`` from ``[B, M_old + 1]``: kept rows' entries, zeros elsewhere."""
        out = torch.zeros(len(runs), M_new + 1, dtype=table.dtype, device=dev)
        out[:, kept_new] = table[idx][:, kept_old]
        return out

    model_state["row_count"] = rows_carried(old_model.row_count)
    model_state["row_reward"] = rows_carried(old_model.row_reward)
    model_state["state_tries"] = old_model.state_tries[idx]
    new.model.load_state_dict(model_state)

    # ---- mentor model, value caches (kept rows' Q numerators as they are), queue, metrics
    new.mentor.load_state_dict({k: v[idx] for k, v in learner.mentor.state_dict().items()})
    cache = learner.cache.state_dict()
    cache = {k: v[idx] for k, v in cache.items()}
    cache["q_numerator"] = rows_carried(learner.cache.q_numerator)
    cache["q_second"] = rows_carried(learner.cache.q_second)
    new.cache.load_state_dict(cache, mentor_edges=learner.mentor.used)
    new.sweeper.load_state_dict({k: v[idx] for k, v in learner.sweeper.state_dict().items()})
    new.sync_potential()  # (the shaping runs' V, carried, already holds their potential)
    new.cloning.load_state_dict({"action": learner.cloning.action[idx]})  # (actions, not rows)
    new.metrics = type(learner.metrics)(
        **{
            k: [x if k == "steps" else x[idx.cpu()].clone() for x in v]
            for k, v in learner.metrics.state_dict().items()
        }
    )

    # ---- run state; options in flight that were dropped (or are not usable any more) end here
    run = {
        k: (v[idx] if isinstance(v, torch.Tensor) else v)
        for k, v in learner.run_state.state_dict().items()
    }
    row = row_map[run["row"]]
    arange = torch.arange(len(runs), device=dev)
    cut = (row < 0) | ~new.rows.row_enabled[arange, row.clamp(min=0)]
    row = torch.where(cut, torch.full_like(row, M_new), row)
    run["row"] = row
    run["duration"] = torch.where(cut, torch.zeros_like(run["duration"]), run["duration"])
    run["discounted_return"] = torch.where(
        cut, torch.zeros_like(run["discounted_return"]), run["discounted_return"]
    )
    run["discount"] = torch.where(cut, torch.ones_like(run["discount"]), run["discount"])
    run["option_start"] = torch.where(cut, run["position"], run["option_start"])
    new.run_state.load_state_dict(run)
    if bool(cut.any()):
        cr = cut.nonzero()[:, 0]
        u = uniforms(new.keys, -(learner.views.t + 2), new.LANES)[cr]
        new.run_state.row[cr] = choose_rows(
            new.cache,
            cr,
            new.run_state.position[cr],
            u[:, 3:5],
            new.run_state.epsilon[cr],
            new.config.mentor_choice,
            new.config.tie_break,
            new.cloning.at(cr, new.run_state.position[cr]) if new.cloning.any else None,
        )

    # ---- queue the states where a run's usable rows changed and a backup would change V
    changed = _usable_rows_changed(learner, new, idx, row_map)
    new.sweeper.push(*new.cache.value_changes(changed))
    new.engine.invalidate()
    return new


def _usable_rows_changed(
    old: Learner, new: Learner, idx: torch.Tensor, row_map: torch.Tensor
) -> torch.Tensor:
    """``[R, S]`` bool: states where a carried run may use a row now that it could not before,
    or could before and cannot now."""
    dev, S = new.device, new.num_states
    R = idx.numel()
    changed = torch.zeros(R, S + 1, dtype=torch.int64, device=dev)
    old_enabled = old.rows.row_enabled[idx][:, :-1]  # [R, M_old]
    new_enabled = new.rows.row_enabled[:, :-1]  # [R, M_new]
    has_new = row_map[:-1] >= 0
    still = torch.zeros_like(old_enabled)
    still[:, has_new] = new_enabled[:, row_map[:-1][has_new]]
    lost = old_enabled & ~still
    changed.index_add_(1, old.rows.row_state[:-1], lost.long())
    inverse = torch.full((new.num_rows,), -1, dtype=torch.int64, device=dev)
    inverse[row_map[:-1][has_new]] = has_new.nonzero()[:, 0]
    had = torch.zeros_like(new_enabled)
    known = inverse >= 0
    had[:, known] = old_enabled[:, inverse[known]]
    gained = new_enabled & ~had
    changed.index_add_(1, new.rows.row_state[:-1], gained.long())
    return changed[:, :S] > 0
