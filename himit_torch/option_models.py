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
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import torch

from .options import Options

__all__ = ["OptionModels", "option_models", "option_durations", "csr_from_scipy"]


def csr_from_scipy(matrix: sp.csr_matrix) -> torch.Tensor:
    """A torch sparse CSR tensor holding a scipy CSR matrix."""
    with warnings.catch_warnings():  # torch flags sparse CSR as beta on every construction
        warnings.simplefilter("ignore", UserWarning)
        return torch.sparse_csr_tensor(torch.from_numpy(matrix.indptr.astype(np.int64)),
                                       torch.from_numpy(matrix.indices.astype(np.int64)),
                                       torch.from_numpy(matrix.data), size=matrix.shape,
                                       check_invariants=False)


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


def _kernel_rows(P_stack: sp.csr_matrix, policy: np.ndarray, states: np.ndarray, S: int,
                 A: int) -> sp.csr_matrix:
    """One-step kernel rows ``K[states, :]`` under a policy (actions [S] or probabilities [S, A])."""
    if policy.ndim == 1:
        return P_stack[policy[states] * S + states]
    out = None
    for a in range(A):
        rows = sp.diags(policy[states, a]) @ P_stack[a * S + states]
        out = rows if out is None else out + rows
    return out.tocsr()


def option_models(world, options: Options, gamma: float | None = None,
                  step_reward: torch.Tensor | None = None) -> OptionModels:
    """Exact multi-time models of every option from every state of its initiation set.

    Args:
        world: provides ``transition_model() [A, S, S]``, ``reward_model() [S, A]``,
            ``terminal_mask [S]`` and ``gamma``.
        options: the options to model.
        gamma: discount; the world's by default. ``1.0`` gives undiscounted termination
            probabilities (requires every option to terminate with probability 1).
        step_reward: ``[S, A]`` reward per step instead of the world's (ones → expected durations).
    """
    gamma = world.gamma if gamma is None else float(gamma)
    P = world.transition_model(sparse=True).coalesce()
    A, S, _ = P.shape
    if options.num_states != S:
        raise ValueError(f"options are over {options.num_states} states but the world has {S}")
    idx = P.indices().numpy()
    P_stack = sp.csr_matrix((P.values().numpy(), (idx[0] * S + idx[1], idx[2])), shape=(A * S, S))
    R = (world.reward_model() if step_reward is None else torch.as_tensor(step_reward)).double().numpy()
    if R.shape != (S, A):
        raise ValueError(f"step_reward must be [S, A] = [{S}, {A}], got {R.shape}")
    terminal = world.terminal_mask.numpy()
    init_all = options.initiation.numpy()
    beta_all = options.termination.double().numpy()
    policy_all = options.policy.numpy()

    row_state, row_option, rewards, blocks = [], [], [], []
    for o in range(options.num_options):
        policy = policy_all[o]
        stop = np.where(terminal, 1.0, beta_all[o])
        cont = 1.0 - stop
        start = np.flatnonzero(init_all[o])
        # Continuing states reachable from the initiation set.
        in_region = np.zeros(S, dtype=bool)
        frontier = start
        continuing = []
        while frontier.size:
            cols = np.unique(_kernel_rows(P_stack, policy, frontier, S, A).indices)
            new = cols[(cont[cols] > 0) & ~in_region[cols]]
            in_region[new] = True
            continuing.append(new)
            frontier = new
        C = np.concatenate(continuing) if continuing else np.zeros(0, dtype=np.int64)
        r1 = (R * (policy_all[o] if policy.ndim == 2 else np.eye(A)[policy])).sum(1)
        K_I = _kernel_rows(P_stack, policy, start, S, A)
        E_I = K_I @ sp.diags(stop)
        if C.size:
            K_C = _kernel_rows(P_stack, policy, C, S, A)
            T_CC = (K_C[:, C] @ sp.diags(cont[C])).tocsc()
            T_IC = K_I[:, C] @ sp.diags(cont[C])
            E_C = (K_C @ sp.diags(stop)).tocsr()
            exits = np.unique(np.concatenate([E_C.nonzero()[1], E_I.nonzero()[1]]))
            rhs = np.concatenate([gamma * E_C[:, exits].toarray(), r1[C][:, None]], axis=1)
            system = (sp.identity(C.size, format="csc") - gamma * T_CC).tocsc()
            try:
                sol = spla.splu(system).solve(rhs)
            except RuntimeError as err:  # singular: the option can run forever undiscounted
                raise ValueError(f"option {options.names[o]!r} may never terminate from some state "
                                 f"(its absorbing chain is singular at gamma={gamma}); use gamma < 1 "
                                 "or make it terminate") from err
            W, rho = sol[:, :-1], sol[:, -1]
            M = gamma * E_I + sp.csr_matrix(gamma * (T_IC @ W), shape=(start.size, exits.size)) \
                @ sp.csr_matrix((np.ones(exits.size), (np.arange(exits.size), exits)),
                                shape=(exits.size, S))
            r = r1[start] + gamma * (T_IC @ rho)
        else:
            M = gamma * E_I
            r = r1[start]
        M = sp.csr_matrix(M)
        M.eliminate_zeros()
        row_state.append(start)
        row_option.append(np.full(start.size, o))
        rewards.append(np.asarray(r).ravel())
        blocks.append(M)
    T = sp.vstack(blocks).tocsr()
    T.sort_indices()
    transition = csr_from_scipy(T)
    return OptionModels(row_state=torch.from_numpy(np.concatenate(row_state)),
                        row_option=torch.from_numpy(np.concatenate(row_option)),
                        reward=torch.from_numpy(np.concatenate(rewards)),
                        transition=transition, num_options=options.num_options)


def option_durations(world, options: Options) -> OptionModels:
    """Undiscounted models: ``transition`` holds termination probabilities ``Pr(s' | s, o)`` and
    ``reward`` the expected number of primitive steps the option runs."""
    ones = torch.ones(world.num_states, world.num_actions, dtype=torch.float64)
    return option_models(world, options, gamma=1.0, step_reward=ones)
