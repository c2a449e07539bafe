"""What each run is doing and has done: the option it executes, exploration, and its counters.

``RunState`` owns the per-run scalars (``[B]`` tensors) that change every tick; ``RunMetrics``
the per-window records taken from them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import torch

from himit_torch.state_checks import (
    DamagedState,
    all_finite,
    in_range,
    private_copy,
    saved,
    section,
    tensor,
    tensor_of,
    whole,
)

__all__ = ["RunState", "RunMetrics"]


class RunState:
    """Per-run state of a batch of ``B`` runs over ``S`` states.

    The executing option: ``position`` (current state), ``option_start`` (where it started),
    ``row`` (its ``(s, o)`` row), ``duration`` (steps so far), ``discounted_return`` (``Σ γ^k r``
    so far) and ``discount`` (``γ^duration``). Exploration: ``epsilon``, ``found_goal``.
    Counters (cumulative unless named ``window_…``): ``goals``, ``window_goals``, ``episodes``,
    ``episode_start`` (tick the episode began), ``window_episode_steps``, ``window_episodes``,
    ``backups_done``, ``decisions``, ``first_goal_step`` (−1 until the first goal) and
    ``visits [B, S + 1]`` (states occupied after each primitive step).
    """

    _INT = (
        "position",
        "option_start",
        "row",
        "duration",
        "goals",
        "window_goals",
        "episodes",
        "episode_start",
        "window_episode_steps",
        "window_episodes",
        "backups_done",
        "decisions",
        "first_goal_step",
    )
    _FLOAT = ("discounted_return", "discount", "epsilon")
    _STATE = _INT + _FLOAT + ("found_goal", "visits")
    # The per-run tensors set by name in __init__ ([B] each; visits [B, S + 1]).
    position: torch.Tensor
    option_start: torch.Tensor
    row: torch.Tensor
    duration: torch.Tensor
    goals: torch.Tensor
    window_goals: torch.Tensor
    episodes: torch.Tensor
    episode_start: torch.Tensor
    window_episode_steps: torch.Tensor
    window_episodes: torch.Tensor
    backups_done: torch.Tensor
    decisions: torch.Tensor
    first_goal_step: torch.Tensor
    discounted_return: torch.Tensor
    discount: torch.Tensor
    epsilon: torch.Tensor

    def __init__(
        self,
        batch: int,
        num_states: int,
        start: torch.Tensor,
        pad_row: int,
        eps_start: float,
        device,
    ):
        dev = torch.device(device)
        for name in self._INT:
            setattr(self, name, torch.zeros(batch, dtype=torch.int64, device=dev))
        for name in self._FLOAT:
            setattr(self, name, torch.zeros(batch, dtype=torch.float64, device=dev))
        self.position.copy_(start)
        self.option_start.copy_(start)
        self.row.fill_(pad_row)
        self.discount.fill_(1.0)
        self.epsilon.fill_(eps_start)
        self.first_goal_step.fill_(-1)
        self.found_goal = torch.zeros(batch, dtype=torch.bool, device=dev)
        self.visits = torch.zeros(batch, num_states + 1, dtype=torch.int64, device=dev)
        self.t = 0
        self.num_states, self.pad_row = num_states, pad_row

    def state_dict(self, copy: bool = True) -> dict:
        """The run state; ``copy=False``: its live tensors, not copies (see
        :meth:`~himit_torch.Learner.state_dict`)."""
        return {"t": self.t, **saved({name: getattr(self, name) for name in self._STATE}, copy)}

    #: The most ticks a checkpoint may say were run (far beyond any run; the counters of the
    #: random streams and the tick counts stay well inside int64).
    MAX_TICKS = 2**53

    def check_state(self, state: dict, where: str = "run") -> int:
        """Check a :meth:`state_dict` read back against this batch: every tensor int64 / float64 /
        bool as created, ``[B]`` (``visits [B, S + 1]``); ``position`` and ``option_start``
        states; ``row`` a row of the table (or its padding row, no row); counters ≥ 0, the ticks
        they name within ``0 … t``; ``discount`` and ``epsilon`` in ``[0, 1]``; the return
        finite. Returns ``t``.

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, ("t", *self._STATE))
        t = whole(state, "t", where, 0, self.MAX_TICKS)
        S = self.num_states
        for name in self._STATE:
            current = getattr(self, name)
            value = tensor(state, name, where, current.dtype, tuple(current.shape))
            field = f"{where}.{name}"
            if name in ("position", "option_start"):
                in_range(value, field, 0, S - 1, "a state")
            elif name == "row":
                in_range(value, field, 0, self.pad_row, "a row, or the padding row: none")
            elif name == "episode_start":
                in_range(value, field, 0, t, "a tick so far")
            elif name == "first_goal_step":
                in_range(value, field, -1, t, "a tick so far, or −1: no goal yet")
            elif name in ("discount", "epsilon"):
                in_range(value, field, 0.0, 1.0, "a probability" if name == "epsilon" else "γ^k")
            elif name == "discounted_return":
                all_finite(value, field)
            elif name != "found_goal":
                in_range(value, field, 0, 2**62, "a count")
        if not torch.equal(state["found_goal"], state["first_goal_step"] >= 0):
            raise DamagedState(
                f"{where}.found_goal", "disagrees with first_goal_step (−1: no goal yet)"
            )
        return t

    def load_state_dict(self, state: dict, where: str = "run", *, checked: bool = False) -> None:
        """Restore a :meth:`state_dict`, checked first (:meth:`check_state`) unless ``checked``
        says it was."""
        self.t = state["t"] if checked else self.check_state(state, where)
        for name in self._STATE:
            setattr(self, name, private_copy(state[name], getattr(self, name).device))


def mean_episode_steps(steps: torch.Tensor, episodes: torch.Tensor) -> torch.Tensor:
    """The mean length of the episodes that ended in a window, from the window's total steps and
    count of those episodes (NaN where none ended), as float64 (any shape)."""
    return torch.where(
        episodes > 0,
        steps / episodes.clamp(min=1),
        torch.full(episodes.shape, float("nan"), dtype=torch.float64, device=episodes.device),
    )


@dataclass
class RunMetrics:
    """Per-window metrics of every run (lists over windows of ``[B]`` tensors)."""

    steps: list[int] = field(default_factory=list)
    goals_in_window: list[torch.Tensor] = field(default_factory=list)
    epsilon: list[torch.Tensor] = field(default_factory=list)
    episodes: list[torch.Tensor] = field(default_factory=list)
    mean_episode_steps: list[torch.Tensor] = field(default_factory=list)
    backups: list[torch.Tensor] = field(default_factory=list)
    decisions: list[torch.Tensor] = field(default_factory=list)
    mentor_term_wins: list[torch.Tensor] = field(default_factory=list)

    def curve(self) -> torch.Tensor:
        """``[windows, B]`` goals per window."""
        if not self.goals_in_window:
            return torch.zeros(0, 0)
        return torch.stack(self.goals_in_window)

    def record(self, t: int, run: RunState, mentor_wins: torch.Tensor) -> None:
        """Close a window: record it from ``run`` (:meth:`record_closed` of one window) and
        reset the run's window counters."""
        counts = {name: getattr(run, name).cpu()[None] for name in self._WINDOW_FIELDS}
        self.record_closed([t], counts, mentor_wins.cpu()[None])
        run.window_goals.zero_()
        run.window_episode_steps.zero_()
        run.window_episodes.zero_()

    #: The run state's fields a window's record is read from.
    _WINDOW_FIELDS = (
        "window_goals",
        "epsilon",
        "episodes",
        "window_episode_steps",
        "window_episodes",
        "backups_done",
        "decisions",
    )

    def record_closed(
        self, ends: list[int], counts: dict[str, torch.Tensor], mentor_wins: torch.Tensor
    ) -> None:
        """Record windows an engine closed itself: ``ends`` their last ticks, ``counts`` the
        run state's window counters at each end (``[W, B]`` each, named as the run state's:
        ``window_goals``, ``epsilon``, ``episodes``, ``window_episode_steps``,
        ``window_episodes``, ``backups_done``, ``decisions``), ``mentor_wins`` ``[W, B]`` the
        mentor term's win share — what :meth:`record` would have recorded at each end."""
        means = mean_episode_steps(counts["window_episode_steps"], counts["window_episodes"])
        self.steps.extend(ends)
        for i in range(len(ends)):
            self.goals_in_window.append(counts["window_goals"][i].clone())
            self.epsilon.append(counts["epsilon"][i].clone())
            self.episodes.append(counts["episodes"][i].clone())
            self.mean_episode_steps.append(means[i].clone())
            self.backups.append(counts["backups_done"][i].clone())
            self.decisions.append(counts["decisions"][i].clone())
            self.mentor_term_wins.append(mentor_wins[i].clone())

    #: The dtype of each field's ``[B]`` records (``steps``: Python ints).
    _DTYPES = {
        "goals_in_window": torch.int64,
        "epsilon": torch.float64,
        "episodes": torch.int64,
        "mean_episode_steps": torch.float64,
        "backups": torch.int64,
        "decisions": torch.int64,
        "mentor_term_wins": torch.float64,
    }

    def state_dict(self) -> dict:
        return {f.name: list(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_state_dict(
        cls, state: dict, batch: int, window: int, t: int, where: str = "metrics"
    ) -> RunMetrics:
        """The metrics of a :meth:`state_dict` read back, checked first: one record per window
        of the ``t`` ticks run (``steps`` the windows' ends ``window, 2·window, …``), every
        record a ``[batch]`` tensor of its field's dtype (kept on the CPU), counts ≥ 0 and ε in
        ``[0, 1]``.

        Raises:
            DamagedState: naming the field and what is wrong with it.
        """
        section(state, where, [f.name for f in fields(cls)])
        windows = t // window
        for name, records in state.items():
            if type(records) not in (list, tuple):
                raise DamagedState(
                    f"{where}.{name}", f"is a {type(records).__name__}, not a list of windows"
                )
            if len(records) != windows:
                raise DamagedState(
                    f"{where}.{name}",
                    f"holds {len(records)} windows, but {t} ticks make {windows} windows of "
                    f"{window}",
                )
        ends = [window * (i + 1) for i in range(windows)]
        if [type(x) for x in state["steps"]] != [int] * windows or list(state["steps"]) != ends:
            raise DamagedState(
                f"{where}.steps", f"is not the windows' ends {window}, {2 * window}, …"
            )
        out = cls(steps=list(state["steps"]))
        cpu = torch.device("cpu")
        for name, dtype in cls._DTYPES.items():
            records = [
                tensor_of(x, f"{where}.{name}[{i}]", dtype, (batch,))
                for i, x in enumerate(state[name])
            ]
            if records:
                stacked = torch.stack(records)
                if name == "epsilon":
                    in_range(stacked, f"{where}.{name}", 0.0, 1.0, "a probability")
                elif dtype == torch.int64:
                    in_range(stacked, f"{where}.{name}", 0, 2**62, "a count")
            setattr(out, name, [private_copy(x, cpu) for x in records])
        return out
