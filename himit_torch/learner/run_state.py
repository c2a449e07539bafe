"""What each run is doing and has done: the option it executes, exploration, and its counters.

``RunState`` owns the per-run scalars (``[B]`` tensors) that change every tick; ``RunMetrics``
the per-window records taken from them.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import torch

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

    def state_dict(self) -> dict:
        return {"t": self.t, **{name: getattr(self, name).clone() for name in self._STATE}}

    def load_state_dict(self, state: dict) -> None:
        for name in self._STATE:
            current = getattr(self, name)
            value = state[name]
            if value.shape != current.shape:
                raise ValueError(
                    f"run state {name} has shape {tuple(value.shape)}, this learner's "
                    f"{tuple(current.shape)}"
                )
            setattr(self, name, value.to(current.device).clone())
        self.t = int(state["t"])


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
        """Close a window: record it from ``run`` and reset the run's window counters."""
        self.steps.append(t)
        self.goals_in_window.append(run.window_goals.cpu().clone())
        self.epsilon.append(run.epsilon.cpu().clone())
        self.episodes.append(run.episodes.cpu().clone())
        self.mean_episode_steps.append(
            torch.where(
                run.window_episodes > 0,
                run.window_episode_steps / run.window_episodes.clamp(min=1),
                torch.full(
                    run.window_episodes.shape,
                    float("nan"),
                    dtype=torch.float64,
                    device=run.window_episodes.device,
                ),
            ).cpu()
        )
        self.backups.append(run.backups_done.cpu().clone())
        self.decisions.append(run.decisions.cpu().clone())
        self.mentor_term_wins.append(mentor_wins.cpu())
        run.window_goals.zero_()
        run.window_episode_steps.zero_()
        run.window_episodes.zero_()

    def state_dict(self) -> dict:
        return {f.name: list(getattr(self, f.name)) for f in fields(self)}
