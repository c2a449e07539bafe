"""The cloned policy of the BCO runs (behavioural cloning from observation; the ``bco`` agent).

:class:`ClonedPolicy` owns ``action [B, S + 1]``: each run's cloned action ``π_bc(s)`` (``−1``:
none, and always for runs that do not clone). :meth:`ClonedPolicy.refit` recomputes it for some
runs from their own option model and their mentor model with the pure functions of
:mod:`himit_torch.mentor.cloning` (inverse model, relabelling, cloning; on the CPU compiled into
one pass, :mod:`himit_torch.learner.cloned_refit`, the same actions to the bit); the learner calls it
every ``LearnerConfig.bco_every`` ticks and when demonstrations are added, outside the engines'
tick loop. Both engines read it when a run chooses (:func:`~himit_torch.learner.choice.greedy_rows`
and the compiled ``choose``): a cloning run's greedy choice at ``s`` is the primitive
``π_bc(s)`` where it is defined.

The inverse model's counts ``n(s, a, s')`` are not a new piece of state: a cloning run uses its
primitive options only, so every primitive step it takes is one execution of a primitive option,
and the option model's edge ``(row of (s, a), s')`` holds exactly ``n(s, a, s')``.
"""

from __future__ import annotations

import torch

from himit_torch.learner.models import DirichletMentorModel, DirichletSMDPModel
from himit_torch.learner.rows import RowTable
from himit_torch.mentor.cloning import clone_policy, inverse_model, relabel
from himit_torch.state_checks import DamagedState, in_range, private_copy, saved, section, tensor

__all__ = ["ClonedPolicy"]


class ClonedPolicy:
    """Each run's cloned action per state (the module docstring).

    Attributes:
        action: ``[B, S + 1]`` int64, ``π_bc(s)`` or ``−1`` (none; the padding state ``S``
            always ``−1``).
        row_action: ``[M + 1]`` the primitive action of each row (``−1``: not a primitive
            option's row), derived from the row table.
    """

    def __init__(self, rows: RowTable, num_actions: int, inverse: str, device):
        self.rows, self.num_actions, self.inverse = rows, num_actions, inverse
        #: Whether some run of the batch clones (the row table is fixed).
        self.any = bool(rows.use_cloning.any())
        dev = torch.device(device)
        B, S, M = rows.row_enabled.shape[0], rows.num_states, rows.num_rows
        self.action = torch.full((B, S + 1), -1, dtype=torch.int64, device=dev)
        prim = rows.primitive_rows  # [S + 1, A]
        available = prim < M
        self.row_action = torch.full((M + 1,), -1, dtype=torch.int64, device=dev)
        actions = torch.arange(num_actions, device=dev).expand_as(prim)
        self.row_action[prim[available]] = actions[available]

    def runs(self) -> torch.Tensor:
        """``[R]`` the runs that clone (the ``bco`` agent)."""
        return self.rows.use_cloning.nonzero()[:, 0]

    def at(self, runs: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        """``[R]`` the cloned action of ``runs`` at ``states`` (``−1``: none)."""
        return self.action[runs, states]

    def refit(
        self, runs: torch.Tensor, model: DirichletSMDPModel, mentor: DirichletMentorModel
    ) -> None:
        """Relabel the mentor's transitions with each run's inverse model and clone its policy
        anew (the cloning runs among ``runs``; others keep ``−1``). On the CPU compiled
        (:func:`~himit_torch.learner.cloned_refit.refit_actions`), elsewhere
        :meth:`actions_in_torch`: the same actions to the bit."""
        runs = torch.as_tensor(runs, dtype=torch.int64, device=self.action.device).reshape(-1)
        runs = runs[self.rows.use_cloning.index_select(0, runs)]
        if runs.numel() == 0:
            return
        S = self.rows.num_states
        if self.action.device.type == "cpu":
            # (imported here: Numba loads at the first compiled call, not with the package)
            from himit_torch.learner.cloned_refit import refit_actions

            self.action[runs, :S] = refit_actions(
                runs,
                (model.edge_row, model.edge_successor, model.edge_count, model.num_edges),
                (mentor.edge_row, mentor.edge_successor, mentor.edge_count, mentor.num_edges),
                self.rows.row_state,
                self.row_action,
                S,
                self.num_actions,
                self.inverse == "likelihood",
            )
        else:
            self.action[runs, :S] = self.actions_in_torch(runs, model, mentor)

    def actions_in_torch(
        self, runs: torch.Tensor, model: DirichletSMDPModel, mentor: DirichletMentorModel
    ) -> torch.Tensor:
        """``[R, S]`` the cloned actions of the cloning ``runs`` by the pure functions of
        :mod:`himit_torch.mentor.cloning` (inverse model, relabelling, cloning), in torch on the
        learner's device: :meth:`refit`'s way off the CPU, and the reference its compiled way is
        tested against."""
        # All runs in one call of each function: run i's states become i·(S + 1) + s (S + 1
        # leaves room for a padding state), so no (s, s') or (s, a) of two runs ever meet, and
        # every group sums the same entries in the same order as run by run.
        S, R = self.rows.num_states, runs.numel()
        stride = S + 1
        own_edges, own_run = _edges(model.num_edges, model.edge_row, runs)
        edge_row = model.edge_row[runs][own_edges]
        act = self.row_action.index_select(0, edge_row)
        own = act >= 0
        offset = (own_run * stride)[own]
        inverse = inverse_model(
            self.rows.row_state.index_select(0, edge_row)[own] + offset,
            act[own],
            model.edge_successor[runs][own_edges][own] + offset,
            model.edge_count[runs][own_edges][own],
            self.inverse,
        )
        seen, seen_run = _edges(mentor.num_edges, mentor.edge_row, runs)
        offset = seen_run * stride
        sources = mentor.row_states(mentor.edge_row[runs][seen]) + offset  # (mentors pooled)
        labels = relabel(inverse, sources, mentor.edge_successor[runs][seen] + offset)
        cloned = clone_policy(
            sources, labels, mentor.edge_count[runs][seen], R * stride, self.num_actions
        )
        return cloned.view(R, stride)[:, :S]

    def state_dict(self, copy: bool = True) -> dict:
        """The cloned actions; ``copy=False``: the live tensor, not a copy (see
        :meth:`~himit_torch.Learner.state_dict`)."""
        return saved({"action": self.action}, copy)

    def check_state(self, state: dict, where: str = "cloning") -> None:
        """Check a :meth:`state_dict` read back: ``action`` int64 ``[B, S + 1]``, ``−1`` or an
        action in ``0 … A − 1`` whose primitive option is available at that state, ``−1`` at the
        padding state and for every run that does not clone.

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, ("action",))
        field = f"{where}.action"
        action = tensor(state, "action", where, torch.int64, tuple(self.action.shape))
        in_range(action, field, -1, self.num_actions - 1, "an action, or −1: none")
        action = action.to(self.action.device)
        if bool((action[:, -1] != -1).any()):
            raise DamagedState(field, "holds an action at the padding state (must be −1)")
        wrong = (~self.rows.use_cloning) & (action >= 0).any(1)
        if bool(wrong.any()):
            b = int(wrong.nonzero()[0, 0])
            raise DamagedState(field, f"run {b} does not clone but holds cloned actions")
        S, M = self.rows.num_states, self.rows.num_rows
        states = torch.arange(S, device=action.device).expand(action.shape[0], -1)
        row = self.rows.primitive_rows[states, action[:, :S].clamp(min=0)]
        if bool(((action[:, :S] >= 0) & (row >= M)).any()):
            raise DamagedState(field, "holds a primitive that is not available at its state")

    def load_state_dict(self, state: dict, where: str = "cloning", *, checked: bool = False):
        """Restore a :meth:`state_dict`, checked first (:meth:`check_state`) unless ``checked``
        says it was."""
        if not checked:
            self.check_state(state, where)
        self.action = private_copy(state["action"], self.action.device)


def _edges(num_edges: torch.Tensor, edge_row: torch.Tensor, runs: torch.Tensor):
    """The used slots of ``runs``' edge lists, as a mask ``[R, capacity]`` over
    ``edge_row[runs]``, and the run (``0 … R − 1``) of each used slot in row-major order."""
    capacity = edge_row.shape[1]
    used = torch.arange(capacity, device=edge_row.device) < num_edges[runs].unsqueeze(1)
    which = torch.arange(runs.numel(), device=edge_row.device).unsqueeze(1).expand_as(used)
    return used, which[used]
