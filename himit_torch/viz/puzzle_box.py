"""Pictures of the puzzle box (:class:`~himit_torch.PuzzleBox`): a state, the order in which a
policy does the steps (which shows its organisation at a glance), and the skewers' levels along
an episode."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from matplotlib.axes import Axes
from matplotlib.patches import FancyBboxPatch, Rectangle

from himit_torch.worlds.puzzle_box import PuzzleBox

__all__ = ["plot_box", "plot_step_order", "plot_levels", "GRIP_COLORS"]

#: Colours of the hand's grasps (and of the steps done with them).
GRIP_COLORS = {"open": "#7f7f7f", "power": "#1f77b4", "pinch": "#ff7f0e"}
_DONE, _TODO, _OUT = "#2ca02c", "#e6e6e6", "#98df8a"


def plot_box(ax: Axes, box: PuzzleBox, state: int, title: str | None = None) -> None:
    """The box in ``state``: one row per skewer, its ``n`` steps as cells (green: done), the
    skewer drawn pulled out by its level, and the hand — a circle at its skewer, coloured by its
    grasp (:data:`GRIP_COLORS`), or at the rest position on the left."""
    progress, at, grasp = box.decode(state)
    k, n = box.skewers, box.steps
    ax.add_patch(
        FancyBboxPatch(
            (0.6, -0.6), n + 0.8, k + 0.2, boxstyle="round,pad=0.05", fc="#fdf6e3", ec="0.3"
        )
    )
    for i, p in enumerate(progress):
        y = k - 1 - i
        for j in range(n):
            ax.add_patch(
                Rectangle((1 + j, y - 0.3), 0.9, 0.6, fc=_DONE if j < p else _TODO, ec="0.4")
            )
            ax.text(1.45 + j, y, f"{j + 1}", ha="center", va="center", fontsize="x-small")
        # the skewer sticks out to the right by how far it has come
        ax.add_patch(Rectangle((n + 1.5, y - 0.08), 0.4 + 0.6 * p, 0.16, fc="#8c564b", ec="none"))
        label = f"skewer {i + 1}" + (" (out)" if p == n else "")
        ax.text(0.5, y, label, ha="right", va="center", fontsize="small")
        if at == i and grasp is not None:
            ax.add_patch(
                FancyBboxPatch(
                    (1 + min(p, n - 1) - 0.05, y - 0.42), 1.0, 0.84,
                    boxstyle="round,pad=0.02", fc="none", ec=GRIP_COLORS[grasp], lw=2.5,
                )
            )  # fmt: skip
            ax.text(n + 4.6, y, f"hand: {grasp}", color=GRIP_COLORS[grasp], va="center")
    if at is None:
        ax.text(n + 4.6, (k - 1) / 2, "hand home", color="0.3", va="center")
    ax.set_xlim(-1.8, n + 7.5)
    ax.set_ylim(-0.9, k - 0.1)
    ax.set_aspect("equal")
    ax.axis("off")
    if title:
        ax.set_title(title, fontsize="medium")


def plot_step_order(
    ax: Axes,
    subgoals: Sequence[str] | Sequence[tuple[int, int]],
    skewers: int,
    steps: int = 4,
    grips: Sequence[str] | None = None,
    title: str | None = None,
) -> None:
    """The order in which the steps were done: a skewer × step grid with each cell's rank (1 =
    first). Skewer by skewer reads along the rows, step by step down the columns. Cells never
    done stay blank; ``grips`` (one per step, in order) colours each rank by the grip used.

    Args:
        subgoals: ``"i.j"`` strings (1-based, as :func:`~himit_torch.runs.puzzle_box.greedy_plan`
            gives them) or ``(skewer, step)`` pairs (0-based skewer, 1-based step).
    """
    pairs = [
        (int(g.split(".")[0]) - 1, int(g.split(".")[1])) if isinstance(g, str) else g
        for g in subgoals
    ]
    rank = np.full((skewers, steps), np.nan)
    for r, (i, j) in enumerate(pairs, start=1):
        rank[i, j - 1] = r
    # light greys (earlier lighter), so that the grips' colours stay readable on every cell
    ax.imshow(rank, cmap="Greys", vmin=0, vmax=2.2 * max(skewers * steps, 2), aspect="auto")
    for r, (i, j) in enumerate(pairs, start=1):
        color = GRIP_COLORS.get(grips[r - 1], "black") if grips and r <= len(grips) else "black"
        ax.text(j - 1, i, str(r), ha="center", va="center", color=color, fontweight="bold")
    ax.set_xticks(range(steps), [f"step {j + 1}" for j in range(steps)])
    ax.set_yticks(range(skewers), [f"skewer {i + 1}" for i in range(skewers)])
    ax.tick_params(length=0, labelsize="small")
    if title:
        ax.set_title(title, fontsize="medium")


def plot_levels(ax: Axes, box: PuzzleBox, states: Sequence[int], title: str | None = None) -> None:
    """Each skewer's level along an episode (one step line per skewer, offset a little so they
    do not hide each other), with the moments the hand gripped a skewer marked by grip."""
    seq = torch.as_tensor(np.asarray(states, dtype=np.int64))
    progress = box.progress(seq).numpy()
    t = np.arange(len(seq))
    for i in range(box.skewers):
        ax.step(t, progress[:, i] + 0.06 * i, where="post", lw=1.8, label=f"skewer {i + 1}")
    for grasp in ("power", "pinch"):
        held = box.grasp_mask(grasp).numpy()[seq.numpy()]
        if held.any():
            ax.scatter(
                t[held], np.full(held.sum(), -0.4), s=8, color=GRIP_COLORS[grasp],
                label=f"hand in a {grasp} grip",
            )  # fmt: skip
    ax.set_yticks(range(box.steps + 1))
    ax.set_ylim(-0.7, box.steps + 0.5)
    ax.set_xlabel("primitive step of the episode")
    ax.set_ylabel("steps done")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="x-small", loc="upper left", ncol=2)
    if title:
        ax.set_title(title, fontsize="medium")
