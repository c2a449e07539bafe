"""Exact option models from a world's true dynamics (for planning checks and the mentor).

For an option ``o`` started in ``s`` (Sutton, Precup & Singh 1999, eqs. for multi-time models;
the paper's Section II):

* ``P^o[s, s'] = Σ_k γ^k Pr(o terminates in s' after exactly k steps)``
* ``r(s, o)   = E[ Σ_{k=1}^{K} γ^{k-1} r_k ]``, the discounted reward collected while it runs.

Both come from one absorbing-chain solve per option. With ``K[s, s']`` the one-step kernel of the
option's policy, ``c = 1 − β`` (β forced to 1 at terminal states) and ``C`` the states where it
may continue:

    W_C = γ (I − γ K_CC diag(c_C))⁻¹ K_C diag(β)              (from a continuing state)
    P^o[s, :] = γ K[s,:] diag(β) + γ K[s, C] diag(c_C) W_C
    ρ_C = (I − γ K_CC diag(c_C))⁻¹ r1_C,  r(s, o) = r1[s] + γ K[s, C] diag(c_C) ρ_C

where ``r1[s] = Σ_a π(a|s) R[s, a]``. With ``γ = 1`` and per-step reward 1 the same solve gives
termination probabilities and expected durations (see :func:`option_durations`).
"""

from __future__ import annotations

import warnings
import weakref
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch

from himit_torch.exact import reference_cache
from himit_torch.options.bundle import Options
from himit_torch.worlds.table_world import world_model

__all__ = [
    "OptionModels",
    "option_models",
    "option_durations",
    "option_models_and_durations",
    "csr_from_scipy",
]


def csr_from_scipy(matrix: sp.csr_matrix) -> torch.Tensor:
    """A torch sparse CSR tensor holding a scipy CSR matrix."""
    with warnings.catch_warnings():  # torch flags sparse CSR as beta on every construction
        warnings.simplefilter("ignore", UserWarning)
        return torch.sparse_csr_tensor(
            torch.from_numpy(matrix.indptr.astype(np.int64)),
            torch.from_numpy(matrix.indices.astype(np.int64)),
            torch.from_numpy(matrix.data),
            size=matrix.shape,
            check_invariants=False,
        )


@dataclass(frozen=True)
class OptionModels:
    """Exact models of every available ``(s, o)``, flattened into ``M`` rows.

    Attributes:
        row_state: ``[M]`` int64 start state of each row.
        row_option: ``[M]`` int64 option of each row.
        reward: ``[M]`` float64 ``r(s, o)``.
        transition: ``[M, S]`` float64 sparse CSR, ``P^o[s, s']`` (multi-time weights; rows sum
            to ``E[γ^k] ≤ 1``).
        num_options: ``O``.
    """

    row_state: torch.Tensor
    row_option: torch.Tensor
    reward: torch.Tensor
    transition: torch.Tensor
    num_options: int

    @property
    def num_states(self) -> int:
        return self.transition.shape[1]

    @property
    def num_rows(self) -> int:
        return self.row_state.shape[0]

    def q_values(self, values: torch.Tensor) -> torch.Tensor:
        """``[M]`` option values ``r(s, o) + Σ_{s'} P^o[s, s'] V(s')`` for ``values [S]``."""
        return self.reward + (self.transition @ values.double()[:, None])[:, 0]

    def dense(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``(P [O, S, S], r [O, S])`` dense, zero where an option is unavailable (small worlds)."""
        O, S = self.num_options, self.num_states
        P = torch.zeros(O, S, S, dtype=torch.float64)
        r = torch.zeros(O, S, dtype=torch.float64)
        P[self.row_option, self.row_state] = self.transition.to_dense()
        r[self.row_option, self.row_state] = self.reward
        return P, r


#: Absorbing chains with up to this many continuing states are solved densely (room-sized
#: options, microseconds each); larger ones with a sparse LU.
_DENSE_LIMIT = 1024
#: Many small chains of one option are solved in dense groups of up to this many states.
_CHAIN_BATCH = 128


def _chains(c_from: np.ndarray, c_to: np.ndarray, n: int) -> list[np.ndarray]:
    """The continuing states ``0 … n−1`` of an option in groups to solve one at a time: all of
    them at once when they fit a dense solve (``n ≤ _DENSE_LIMIT``), else their weakly connected
    components under the edges ``c_from → c_to`` (chains that never meet, e.g. the puzzle box's
    "do step j on the skewer at hand", one small chain per skewer and level) packed in order into
    groups of at most ``_CHAIN_BATCH`` states (a dense solve costs the cube of its size); a
    component larger than that is a group of its own (dense up to ``_DENSE_LIMIT``, else a sparse
    LU). Each group's system and exits are its own, so no solve carries the
    other chains' exits as right-hand sides."""
    if n <= _DENSE_LIMIT:
        return [np.arange(n)]
    from scipy.sparse.csgraph import connected_components

    graph = sp.csr_matrix((np.ones(c_from.size), (c_from, c_to)), shape=(n, n))
    count, label = connected_components(graph, directed=True, connection="weak")
    if count == 1:
        return [np.arange(n)]
    order = np.argsort(label, kind="stable")
    sizes = np.bincount(label, minlength=count)
    groups: list[np.ndarray] = []
    current: list[np.ndarray] = []
    filled = 0
    for members in np.split(order, np.cumsum(sizes)[:-1]):
        if current and filled + members.size > _CHAIN_BATCH:
            groups.append(np.sort(np.concatenate(current)))
            current, filled = [], 0
        current.append(members)
        filled += members.size
    groups.append(np.sort(np.concatenate(current)))
    return groups


def _dense(
    rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, shape: tuple[int, int]
) -> np.ndarray:
    """A dense matrix from triplets, summing duplicates."""
    flat = np.bincount(rows * shape[1] + cols, weights=vals, minlength=shape[0] * shape[1])
    return flat.reshape(shape)


def _sparse(
    rows: np.ndarray, cols: np.ndarray, vals: np.ndarray, shape: tuple[int, int]
) -> sp.csr_matrix:
    """A sparse CSR matrix from triplets, summing duplicates."""
    return sp.csr_matrix((vals, (rows, cols)), shape=shape)


def option_models(
    world, options: Options, gamma: float | None = None, step_reward: torch.Tensor | None = None
) -> OptionModels:
    """Exact multi-time models of every option from every state of its initiation set.

    Args:
        world: provides ``terminal_mask [S]``, ``gamma`` and its true model: ``transition_model()
            [A, S, S]`` and ``reward_model() [S, A]``, or a ``dynamics_table()`` to derive them
            from (:func:`himit_torch.worlds.table_world.world_model`).
        options: the options to model.
        gamma: discount; the world's by default. ``1.0`` gives undiscounted termination
            probabilities (requires every option to terminate with probability 1).
        step_reward: ``[S, A]`` reward per step instead of the world's (ones → expected durations).
    """
    return _remembered(world, options, [(gamma, step_reward)])[0]


def option_models_and_durations(world, options: Options) -> tuple[OptionModels, OptionModels]:
    """``(option_models(world, options), option_durations(world, options))`` in one pass over
    the options: the continuing sets and one-step kernels are built once for both (≈ 35 % less
    time than the two calls); the results are the two calls' to the bit."""
    ones = torch.ones(world.num_states, world.num_actions, dtype=torch.float64)
    discounted, durations = _remembered(world, options, [(None, None), (1.0, ones)])
    return discounted, durations


# The models of the bundles still alive, by (world, options): a study builds them for the same
# bundle several times (the mentor's policy and the evaluation of it, the greedy tracker, the
# optimum), ≈ 1 s each on the paper's largest worlds. An entry is used only while the world and
# the options are the objects it was made for and the options' tensors were not written in place
# since (their version counters), and dropped when the options are.
_MEMO: dict[tuple[int, int], tuple[weakref.ref, weakref.ref, tuple[int, ...], dict]] = {}


def _variant_key(world, gamma: float | None, step_reward) -> tuple[float, str] | None:
    """The memo's name for a ``(gamma, step_reward)`` variant: the world's reward or unit costs
    (the durations); ``None`` for any other reward (not remembered)."""
    g = world.gamma if gamma is None else float(gamma)
    if step_reward is None:
        return (g, "world")
    reward = torch.as_tensor(step_reward)
    if reward.shape == (world.num_states, world.num_actions) and bool((reward == 1).all()):
        return (g, "ones")
    return None


def _remembered(
    world, options: Options, variants: list[tuple[float | None, torch.Tensor | None]]
) -> list[OptionModels]:
    """:func:`_option_models`, computing only the variants not already computed for this world
    and these options (the results are shared: treat them as read-only)."""
    keys = [_variant_key(world, g, r) for g, r in variants]
    if any(k is None for k in keys) or not isinstance(options, Options):
        return _option_models(world, options, variants)
    versions = tuple(t._version for t in (options.initiation, options.termination, options.policy))
    memo_key = (id(world), id(options))
    entry = _MEMO.get(memo_key)
    if (
        entry is None
        or entry[0]() is not world
        or entry[1]() is not options
        or entry[2] != versions
    ):
        try:
            entry = (weakref.ref(world), weakref.ref(options), versions, {})
        except TypeError:  # (a world that takes no weak reference: not remembered)
            return _option_models(world, options, variants)
        _MEMO[memo_key] = entry
        weakref.finalize(options, _MEMO.pop, memo_key, None)
    known = entry[3]
    # (every key is a variant's name here: the None ones returned above)
    missing = [(k, v) for k, v in zip(keys, variants) if k is not None and k not in known]
    # the models of the same content computed before, by this process or another run
    # (exact.reference_cache: on disk, checked when read)
    stored = {k: reference_cache.models_key(world, options, *k) for k, _ in missing}
    for k, _ in missing:
        cached = reference_cache.load_models(stored[k], options, _from_arrays)
        if cached is not None:
            known[k] = cached
    missing = [(k, v) for k, v in missing if k not in known]
    if missing:
        for (k, _), models in zip(missing, _option_models(world, options, [v for _, v in missing])):
            known[k] = models
            reference_cache.store_models(stored[k], models)
    for k in stored:  # (what is computed from these models alone is kept by their key too)
        reference_cache.remember_key(known[k], stored[k])
    return [known[k] for k in keys]


def _from_arrays(arrays: dict[str, np.ndarray], num_options: int, num_states: int) -> OptionModels:
    """The :class:`OptionModels` of a cache entry's arrays (exact.reference_cache)."""
    matrix = sp.csr_matrix(
        (arrays["data"], arrays["indices"], arrays["indptr"]),
        shape=(arrays["row_state"].shape[0], num_states),
    )
    return OptionModels(
        row_state=torch.from_numpy(arrays["row_state"]),
        row_option=torch.from_numpy(arrays["row_option"]),
        reward=torch.from_numpy(arrays["reward"]),
        transition=csr_from_scipy(matrix),
        num_options=num_options,
    )


def _option_models(
    world, options: Options, variants: list[tuple[float | None, torch.Tensor | None]]
) -> list[OptionModels]:
    """:func:`option_models` for each ``(gamma, step_reward)`` of ``variants``, sharing the
    per-option work that does not depend on them (each option's chain,
    :func:`~himit_torch.exact.option_chains.option_chain`)."""
    # (imported here: Numba's import, ≈ 0.5 s, stays out of ``import himit_torch``)
    from himit_torch.exact.option_chains import option_chain

    P, R_world = world_model(world)
    A, S, _ = P.shape
    if options.num_states != S:
        raise ValueError(f"options are over {options.num_states} states but the world has {S}")
    gammas = [world.gamma if g is None else float(g) for g, _ in variants]
    rewards = []
    for _, step_reward in variants:
        R = (R_world if step_reward is None else torch.as_tensor(step_reward)).double().numpy()
        if R.shape != (S, A):
            raise ValueError(f"step_reward must be [S, A] = [{S}, {A}], got {R.shape}")
        rewards.append(R)
    idx = P.indices().numpy()
    P_stack = sp.csr_matrix((P.values().numpy(), (idx[0] * S + idx[1], idx[2])), shape=(A * S, S))
    P_stack.eliminate_zeros()
    P_csr = (P_stack.indptr.astype(np.int64), P_stack.indices.astype(np.int64), P_stack.data)
    terminal = world.terminal_mask.numpy()
    init_all = options.initiation.numpy()
    beta_all = options.termination.numpy()  # (each option's row as float64 when it is used)
    policy_all = options.policy.numpy()
    if options.stochastic:  # float32 rows (checked to 1e-5) would let Σ_s' P^o exceed E[γ^k]
        policy_all = options.policy.double().numpy()
        sums = policy_all.sum(-1, keepdims=True)
        policy_all = np.divide(policy_all, sums, out=np.zeros_like(policy_all), where=sums > 0)
    # option_chain's policy: [S, k] actions and their weights (a deterministic one: k = 1, 1.0)
    if options.stochastic:
        actions = np.tile(np.arange(A, dtype=np.int64), (S, 1))
    else:
        always = np.ones((S, 1))
    scratch = np.full(S, -1, dtype=np.int64)  # option_chain's state -> index in C

    row_state: list[np.ndarray] = []
    row_option: list[np.ndarray] = []
    # per variant: rewards and the triplets of the stacked [M, S] transition
    out: list[tuple[list[np.ndarray], ...]] = [([], [], [], []) for _ in variants]
    offset = 0
    for o in range(options.num_options):
        policy = policy_all[o]
        start = np.flatnonzero(init_all[o])
        chain = option_chain(
            *P_csr,
            terminal,
            beta_all[o].astype(np.float64),
            actions if options.stochastic else policy.astype(np.int64)[:, None],
            policy if options.stochastic else always,
            start,
            scratch,
        )
        C = chain.continuing
        nI, nC = start.size, C.size
        both = np.concatenate([start, C])
        if nC:
            E_C = _dense(chain.exit_row, chain.exit_col, chain.exit_value, (nC, chain.exits.size))
            dense = nC <= _DENSE_LIMIT
            T_CC = (_dense if dense else _sparse)(
                chain.cc_row, chain.cc_col, chain.cc_value, (nC, nC)
            )
            # chains of C that never meet are solved apart (T_CC is block-diagonal over them)
            groups = [] if dense else _chains(chain.cc_row, chain.cc_col, nC)
            J = chain.j_state
            T_JC = (_dense if dense else _sparse)(
                chain.jc_row, chain.jc_col, chain.jc_value, (J.size, nC)
            )
        for (rewards_v, rows_v, cols_v, vals_v), gamma, R in zip(out, gammas, rewards):
            # r1 at the starts, then at C
            r1 = (R[both] * policy[both]).sum(1) if policy.ndim == 2 else R[both, policy[both]]
            # Stopping at once: gamma K[s, s'] beta(s').
            rows_o, cols_o, vals_o = [chain.hit_row], [chain.hit_state], [gamma * chain.hit_value]
            r = r1[:nI].copy()
            if nC:
                rhs = np.concatenate([gamma * E_C, r1[nI:][:, None]], axis=1)
                try:
                    if dense:
                        sol = np.linalg.solve(np.eye(nC) - gamma * T_CC, rhs)
                    elif len(groups) == 1:
                        system = (sp.identity(nC, format="csc") - gamma * T_CC).tocsc()
                        sol = spla.splu(system).solve(rhs)
                    else:
                        sol = _solve_groups(T_CC, rhs, gamma, groups)
                except (np.linalg.LinAlgError, RuntimeError) as err:
                    raise _never_terminates(options.names[o], gamma) from err
                if not np.isfinite(sol).all():
                    raise _never_terminates(options.names[o], gamma)
                W, rho = sol[:, :-1], sol[:, -1]
                # Continuing first: gamma K[s, C] (1 - beta_C) W_C, only for starts that can
                # continue.
                via = np.asarray(gamma * (T_JC @ W))
                jr, jc = np.nonzero(via)
                rows_o.append(J[jr])
                cols_o.append(chain.exits[jc])
                vals_o.append(via[jr, jc])
                r[J] += gamma * (T_JC @ rho)
            rows_v.append(np.concatenate(rows_o) + offset)
            cols_v.append(np.concatenate(cols_o))
            vals_v.append(np.concatenate(vals_o))
            rewards_v.append(r)
        row_state.append(start)
        row_option.append(np.full(nI, o))
        offset += nI
    states = torch.from_numpy(np.concatenate(row_state))
    option_index = torch.from_numpy(np.concatenate(row_option))
    result = []
    for rewards_v, rows_v, cols_v, vals_v in out:
        T = sp.csr_matrix(
            (np.concatenate(vals_v), (np.concatenate(rows_v), np.concatenate(cols_v))),
            shape=(offset, S),
        )
        T.sum_duplicates()
        T.eliminate_zeros()
        T.sort_indices()
        result.append(
            OptionModels(
                row_state=states,
                row_option=option_index,
                reward=torch.from_numpy(np.concatenate(rewards_v)),
                transition=csr_from_scipy(T),
                num_options=options.num_options,
            )
        )
    return result


def _solve_groups(
    T_CC: sp.csr_matrix, rhs: np.ndarray, gamma: float, groups: list[np.ndarray]
) -> np.ndarray:
    """``(I − γ T_CC)⁻¹ rhs`` where ``T_CC`` is block-diagonal over ``groups`` (:func:`_chains`):
    one solve per group, over the right-hand sides that group touches (the others are 0 there)."""
    sol = np.zeros_like(rhs)
    T = T_CC.tocsr()
    for members in groups:
        block = T[members][:, members]
        touched = np.flatnonzero(np.any(rhs[members] != 0, axis=0))
        if touched.size == 0:
            continue
        b = rhs[np.ix_(members, touched)]
        n = members.size
        if n <= _DENSE_LIMIT:
            part = np.linalg.solve(np.eye(n) - gamma * block.toarray(), b)
        else:
            part = spla.splu((sp.identity(n, format="csc") - gamma * block).tocsc()).solve(b)
        sol[np.ix_(members, touched)] = part
    return sol


def _never_terminates(name: str, gamma: float) -> ValueError:
    return ValueError(
        f"option {name!r} may never terminate from some state (its absorbing chain "
        f"is singular at gamma={gamma}); use gamma < 1 or make it terminate"
    )


def option_durations(world, options: Options) -> OptionModels:
    """Undiscounted models: ``transition`` holds termination probabilities ``Pr(s' | s, o)`` and
    ``reward`` the expected number of primitive steps the option runs."""
    ones = torch.ones(world.num_states, world.num_actions, dtype=torch.float64)
    return option_models(world, options, gamma=1.0, step_reward=ones)
