"""The row table: every available ``(s, o)`` pair ("row") of a batch, grouped by state, and which
runs may use which rows (their agent variant). Built once from the options; never changes.

Shapes: ``M`` rows (plus one padding row ``M``), ``J`` rows per state at most, ``A`` actions.
"""

from __future__ import annotations

from collections.abc import Sequence

import torch

from himit_torch.learner.agents import AGENTS
from himit_torch.options.bundle import Options

__all__ = ["RowTable"]


class RowTable:
    """Rows of the batch and the per-run variant masks.

    Attributes:
        state_rows: ``[S + 1, J]`` the rows of each state, ascending, padded with ``M``.
        row_state, row_option: ``[M + 1]`` state and option of each row (padding: ``S``, 0).
        row_first_action: ``[M + 1]`` the first primitive action of each row's option at its
            state (the most probable one for stochastic policies), for ``mentor_choice="match"``.
        primitive_rows: ``[S + 1, A]`` the row of each primitive action at each state (``M``
            where that primitive is not available).
        row_enabled: ``[B, M + 1]`` whether run ``b``'s agent variant may use the row.
        use_mentor, use_confidence: ``[B]`` the variant's mentor term and confidence test.
        use_sampling: ``[B]`` whether the variant plans on a posterior sample (``…_psrl``).
        use_shaping: ``[B]`` whether the variant shapes with the demonstrations' potential
            (``pbrs…``).
        use_cloning: ``[B]`` whether the variant acts on a policy cloned from the demonstrations
            (``bco``).
    """

    def __init__(self, options: Options, num_actions: int, agents: Sequence[str], device):
        dev = torch.device(device)
        S, O = options.num_states, options.num_options
        init = options.initiation.to(dev)
        opt_idx, state_idx = init.nonzero(as_tuple=True)
        order = torch.argsort(state_idx * O + opt_idx)
        row_state, row_option = state_idx[order], opt_idx[order]
        M = row_state.numel()
        self.num_rows, self.num_states, self.num_options = M, S, O
        first = torch.ones(M, dtype=torch.bool, device=dev)
        first[1:] = row_state[1:] != row_state[:-1]
        starts = torch.cummax(
            torch.where(first, torch.arange(M, device=dev), torch.zeros_like(row_state)), 0
        ).values
        rank = torch.arange(M, device=dev) - starts
        J = int(rank.max()) + 1 if M else 1
        self.state_rows = torch.full((S + 1, J), M, dtype=torch.int64, device=dev)
        self.state_rows[row_state, rank] = torch.arange(M, device=dev)
        self.row_state = torch.cat([row_state, torch.tensor([S], device=dev)])
        self.row_option = torch.cat([row_option, torch.zeros(1, dtype=torch.int64, device=dev)])

        def first_action(opts: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
            # (never the dense [O, S, A] table: on 120×120 with corner options it is ~600 MB)
            policy = options.policy.to(dev)[opts, states]
            return policy.argmax(-1) if options.stochastic else policy.long()

        self.row_first_action = torch.cat(
            [first_action(row_option, row_state), torch.zeros(1, dtype=torch.int64, device=dev)]
        )
        prim_option = torch.full((num_actions,), -1, dtype=torch.int64)
        primitives = [o for o, kind in enumerate(options.kinds) if kind == "primitive"]
        if primitives:
            index = torch.tensor(primitives, device=dev)
            # (the primitives' rows only: a float copy of the whole [O, S] table is 150 MB on 120×120)
            first_state = options.initiation[index.cpu()].to(dev).to(torch.uint8).argmax(1)
            for o, a in zip(primitives, first_action(index, first_state).tolist()):
                prim_option[a] = o
        self.primitive_rows = torch.full((S + 1, num_actions), M, dtype=torch.int64, device=dev)
        for a, o in enumerate(prim_option.tolist()):
            if o >= 0:
                is_o = row_option == o
                self.primitive_rows[row_state[is_o], a] = torch.arange(M, device=dev)[is_o]

        B = len(agents)
        primitive = options.is_primitive.to(dev)
        # "extended" variants: the extended options, and the primitives only at states where no
        # extended option starts (a doorway, where a doorway option ends)
        extended_at = torch.zeros(S + 1, dtype=torch.bool, device=dev)
        extended_at[row_state[~primitive[row_option]]] = True
        extended_rows = ~primitive[row_option] | ~extended_at[row_state]
        enabled = torch.zeros(B, M, dtype=torch.bool, device=dev)
        self.use_mentor = torch.zeros(B, dtype=torch.bool, device=dev)
        self.use_confidence = torch.zeros(B, dtype=torch.bool, device=dev)
        self.use_sampling = torch.zeros(B, dtype=torch.bool, device=dev)
        self.use_shaping = torch.zeros(B, dtype=torch.bool, device=dev)
        self.use_cloning = torch.zeros(B, dtype=torch.bool, device=dev)
        for b, agent in enumerate(agents):
            which, mentor, confident, sampling, shaping, cloning = AGENTS[agent]
            self.use_sampling[b] = sampling
            self.use_shaping[b] = shaping
            self.use_cloning[b] = cloning
            if which == "all":
                enabled[b] = True
            elif which == "primitive":
                enabled[b] = primitive[row_option]
            else:
                enabled[b] = extended_rows
            self.use_mentor[b] = mentor
            self.use_confidence[b] = confident
        if not bool(enabled.any(1).all()):
            raise ValueError(
                "an agent variant has no usable option (e.g. 'primitives' with no "
                "primitive options in the set)"
            )
        self.row_enabled = torch.cat([enabled, torch.zeros(B, 1, dtype=torch.bool, device=dev)], 1)
