"""Pictures of a world with the mentor's and the learner's trajectories (the paper's Fig. 2).

Figures are built on :class:`matplotlib.figure.Figure` directly, never through ``pyplot``, so
importing or using this module changes no global matplotlib state (no backend switch, no open
figures to leak); :func:`save_world_figure` renders with the Agg canvas.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from .demonstrations import Demonstrations
from .world import MultiRooms

__all__ = ["plot_world", "save_world_figure", "value_image", "visitation_image", "policy_image"]

MENTOR_COLOR = "#1f5fbf"
LEARNER_COLOR = "#e8590c"
DOORWAY_COLOR = "#f2c14e"
START_COLOR = "#2b9348"
GOAL_COLOR = "#d62828"


def _trajectories(states) -> list[np.ndarray]:
    """One trajectory (1-D sequence) or several (a sequence of them) as a list of arrays."""
    if isinstance(states, (torch.Tensor, np.ndarray)):
        a = states.detach().cpu().numpy() if isinstance(states, torch.Tensor) else np.asarray(states)
        if a.ndim == 1:
            return [a.astype(np.int64)]
        if a.ndim == 2:
            return [row.astype(np.int64) for row in a]
        raise ValueError(f"learner_states must be 1-D (one trajectory) or 2-D, got shape {a.shape}")
    items = list(states)
    if items and all(np.ndim(x) == 0 for x in items):
        return [np.asarray(items, dtype=np.int64)]
    return [np.asarray(x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else x, dtype=np.int64)
            for x in items]


def _draw_paths(ax: Axes, world: MultiRooms, paths: Sequence[np.ndarray], color: str, alpha: float,
                linewidth: float, zorder: int) -> None:
    for path in paths:
        if path.size == 0:
            continue
        if ((path < 0) | (path >= world.num_states)).any():
            raise ValueError(f"trajectory holds states outside [0, {world.num_states})")
        rows, cols = np.divmod(path, world.size)
        ax.plot(cols, rows, color=color, alpha=alpha, linewidth=linewidth, zorder=zorder,
                solid_capstyle="round", solid_joinstyle="round")


def plot_world(world: MultiRooms, demonstrations: Demonstrations | None = None,
               learner_states=None, ax: Axes | None = None, title: str | None = None) -> Figure:
    """Draw the world like the paper's Fig. 2.

    Walls are black, doorways yellow, the start a green circle and the goal a red star. Each
    mentor episode is a semi-transparent blue line through the cell centres (no jitter: where
    episodes agree the line is darker); the learner's trajectory, if given, is an orange line.

    Args:
        world: the world.
        demonstrations: mentor episodes to draw; must have been recorded in ``world``.
        learner_states: one learner trajectory (1-D states) or several (a list of them).
        ax: draw into these axes; by default a new :class:`~matplotlib.figure.Figure`.
        title: the axes' title; by default the world's size and rooms.

    Returns:
        The figure drawn into.
    """
    if demonstrations is not None:
        demonstrations.check_world(world)
    if ax is None:
        side = 6.0
        fig = Figure(figsize=(side, side + 0.6), layout="constrained")
        ax = fig.add_subplot()
    else:
        fig = ax.get_figure()
    N = world.size
    # 0 free, 1 wall, 2 doorway.
    cells = world.wall_mask.numpy().astype(np.int64)
    cells[world.doorways.numpy()] = 2
    cmap = ListedColormap(["white", "black", DOORWAY_COLOR])
    ax.imshow(cells.reshape(N, N), cmap=cmap, vmin=0, vmax=2, interpolation="nearest",
              extent=(-0.5, N - 0.5, N - 0.5, -0.5), zorder=0)
    handles = [Patch(facecolor="black", label="wall"),
               Patch(facecolor=DOORWAY_COLOR, edgecolor="0.4", label="doorway")]
    if demonstrations is not None:
        paths = [e.numpy() for e in demonstrations.episodes]
        # Fainter lines for more episodes, so overlaps show where the mentor goes reliably.
        alpha = float(np.clip(1.5 / max(1, len(paths)) ** 0.5, 0.12, 0.8))
        _draw_paths(ax, world, paths, MENTOR_COLOR, alpha, 2.0, zorder=2)
        handles.append(Line2D([], [], color=MENTOR_COLOR, linewidth=2.0,
                              label=f"mentor ({len(paths)} episode{'s' * (len(paths) != 1)})"))
    if learner_states is not None:
        paths = _trajectories(learner_states)
        _draw_paths(ax, world, paths, LEARNER_COLOR, 0.85, 1.6, zorder=3)
        handles.append(Line2D([], [], color=LEARNER_COLOR, linewidth=1.6, label="learner"))
    marker = max(7.0, 200.0 / N)
    for state, color, shape, label in ((world.start_state, START_COLOR, "o", "start"),
                                       (world.goal_state, GOAL_COLOR, "*", "goal")):
        r, c = world.coords(state)
        ax.plot([c], [r], marker=shape, color=color, markersize=marker * (1.6 if shape == "*" else 1),
                markeredgecolor="white", markeredgewidth=0.8, linestyle="none", zorder=4)
        handles.append(Line2D([], [], marker=shape, color=color, linestyle="none",
                              markeredgecolor="white", markersize=8, label=label))
    ax.set_xlim(-0.5, N - 0.5)
    ax.set_ylim(N - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title if title is not None else
                 f"{N}×{N} multirooms, {world.rooms}×{world.rooms} rooms")
    ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.01), ncol=len(handles),
              fontsize="small", frameon=False, handlelength=1.5, columnspacing=1.0)
    return fig


def save_world_figure(path: str | os.PathLike, world: MultiRooms,
                      demonstrations: Demonstrations | None = None, learner_states=None,
                      title: str | None = None, dpi: int = 150) -> Path:
    """Draw :func:`plot_world` and write it to ``path`` (PNG by default); returns the path."""
    fig = plot_world(world, demonstrations=demonstrations, learner_states=learner_states,
                     title=title)
    FigureCanvasAgg(fig)
    path = Path(path)
    fig.savefig(path, dpi=dpi, format=path.suffix[1:] or "png")
    return path


# ------------------------------------------------------------------ small images for TensorBoard
def _upscale(rgb: np.ndarray, pixels: int) -> np.ndarray:
    return np.repeat(np.repeat(rgb, pixels, 0), pixels, 1)


def _colormap_image(world: MultiRooms, field: np.ndarray, cmap_name: str, pixels: int) -> np.ndarray:
    import matplotlib
    N = world.size
    wall = world.wall_mask.numpy()
    finite = np.isfinite(field) & ~wall
    lo, hi = (field[finite].min(), field[finite].max()) if finite.any() else (0.0, 1.0)
    scaled = np.clip((field - lo) / max(hi - lo, 1e-12), 0, 1)
    rgb = matplotlib.colormaps[cmap_name](scaled)[:, :3]
    rgb[wall] = 0.0
    return _upscale((rgb.reshape(N, N, 3) * 255).astype(np.uint8), pixels)


def value_image(world: MultiRooms, values: torch.Tensor, pixels: int = 4) -> np.ndarray:
    """``[H, W, 3]`` uint8 heat map of state values (walls black)."""
    return _colormap_image(world, values.detach().double().cpu().numpy(), "viridis", pixels)


def visitation_image(world: MultiRooms, learner_visits: torch.Tensor, mentor_visits: torch.Tensor,
                     pixels: int = 4) -> np.ndarray:
    """``[H, W, 3]`` uint8: learner visits in red, mentor visits in blue (log-scaled), walls grey."""
    N = world.size

    def norm(v):
        v = np.log1p(v.detach().double().cpu().numpy())
        return v / max(v.max(), 1e-12)
    rgb = np.zeros((N * N, 3))
    rgb[:, 0] = norm(learner_visits)
    rgb[:, 2] = norm(mentor_visits)
    rgb[world.wall_mask.numpy()] = 0.35
    return _upscale((rgb.reshape(N, N, 3) * 255).astype(np.uint8), pixels)


def policy_image(world: MultiRooms, options, greedy: torch.Tensor, pixels: int = 4) -> np.ndarray:
    """``[H, W, 3]`` uint8 greedy option per state, coloured by kind and primitive direction:
    N/S/W/E primitives in four colours, doorway options orange, corner options purple, untried
    grey, walls black."""
    palette = {"N": (0.12, 0.47, 0.71), "S": (0.17, 0.63, 0.17), "W": (0.84, 0.15, 0.16),
               "E": (0.58, 0.40, 0.74), "doorway": (1.0, 0.6, 0.0), "corner": (0.55, 0.0, 0.55),
               "custom": (0.0, 0.7, 0.7)}
    N = world.size
    greedy = greedy.cpu().numpy()
    rgb = np.full((N * N, 3), 0.8)
    for s in np.flatnonzero(greedy >= 0):
        o = int(greedy[s])
        kind = options.kinds[o]
        key = options.names[o][-1] if kind == "primitive" else kind
        rgb[s] = palette.get(key, (0.5, 0.5, 0.5))
    rgb[world.wall_mask.numpy()] = 0.0
    return _upscale((rgb.reshape(N, N, 3) * 255).astype(np.uint8), pixels)
