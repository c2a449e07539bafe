"""Pictures of a MiniGrid world (:class:`~himit_torch.MiniGridWorld`): the grid as MiniGrid
itself draws it, with paths over it (:func:`plot_minigrid_paths`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from himit_torch.viz.plotting import CURVE_COLORS
from himit_torch.worlds.minigrid import MiniGridWorld

__all__ = ["plot_minigrid_paths", "path_offsets"]


def path_offsets(count: int, tile_size: int = 32, spread: float = 0.5) -> np.ndarray:
    """``[count]`` pixel shifts that set ``count`` paths side by side in a cell: evenly from
    ``−spread/2`` to ``+spread/2`` of a tile (one path: no shift), added to both coordinates of
    each path's cell centres, so that paths through the same cells stay apart."""
    if count <= 1:
        return np.zeros(max(count, 0))
    return tile_size * spread * (np.arange(count) / (count - 1) - 0.5)


def plot_minigrid_paths(
    world: MiniGridWorld,
    paths: Sequence[tuple[str, Sequence[int] | torch.Tensor]],
    state: int | None = None,
    *,
    colors: Sequence[str] | None = None,
    ax: Axes | None = None,
    title: str | None = None,
    tile_size: int = 32,
    spread: float = 0.5,
) -> Figure:
    """Draw ``world`` in ``state`` as MiniGrid renders it (:meth:`MiniGridWorld.render
    <himit_torch.MiniGridWorld.render>`), with labelled paths over it.

    Each path is a line with a dot per step through the centre of the agent's cell in each of
    its states (:meth:`MiniGridWorld.cell_center <himit_torch.MiniGridWorld.cell_center>`),
    shifted by :func:`path_offsets` so that paths sharing cells run side by side; the legend,
    below the grid, names them.

    Args:
        world: the MiniGrid world.
        paths: ``(label, states)`` pairs, e.g. the mentor's demonstration episode and each
            agent's greedy trajectory (``learner.views.greedy_trajectory``).
        state: the state drawn underneath (default: the world's start state).
        colors: one colour per path (default: :data:`~himit_torch.viz.plotting.CURVE_COLORS`
            in order).
        ax: draw into these axes; by default a new :class:`~matplotlib.figure.Figure`.
        title: the axes' title (default: none).
        tile_size: pixels per cell of MiniGrid's drawing.
        spread: how far apart the paths run, as a share of a cell.

    Returns:
        The figure drawn into.

    Raises:
        TypeError: ``world`` is not a :class:`~himit_torch.MiniGridWorld`.
        ValueError: a path holds a state outside the world, ``colors`` is not one per path, or
            ``spread`` is outside [0, 1].
    """
    if not isinstance(world, MiniGridWorld):
        raise TypeError(
            f"plot_minigrid_paths draws a MiniGridWorld (ht.from_minigrid), got "
            f"{type(world).__name__}"
        )
    if not 0.0 <= spread <= 1.0:
        raise ValueError(f"spread is a share of a cell, in [0, 1]; got {spread}")
    colors = list(CURVE_COLORS if colors is None else colors)
    if len(colors) < len(paths):
        raise ValueError(f"colors must give one colour per path ({len(paths)}), got {len(colors)}")
    states = []
    for label, path in paths:
        p = torch.as_tensor(path, dtype=torch.int64).reshape(-1)
        if ((p < 0) | (p >= world.num_states)).any():
            raise ValueError(
                f"path {label!r} holds states outside the world's [0, {world.num_states})"
            )
        states.append(p)
    if ax is None:
        fig = Figure(figsize=(5, 5.6), layout="constrained")
        ax = fig.add_subplot()
    else:
        parent = ax.get_figure()
        assert isinstance(parent, Figure), "plot_minigrid_paths draws into the axes of a Figure"
        fig = parent
    image = world.render(world.start_state if state is None else state, tile_size=tile_size)
    height, width = image.shape[:2]
    # Pixel edges on whole numbers, so that a cell's centre is (x + ½)·tile exactly.
    ax.imshow(image, extent=(0, width, height, 0), interpolation="nearest", zorder=0)
    for (label, _), p, shift, color in zip(
        paths, states, path_offsets(len(paths), tile_size, spread), colors
    ):
        xy = world.cell_center(p, tile_size=tile_size) + shift
        ax.plot(xy[:, 0], xy[:, 1], "o-", color=color, ms=3, lw=1.5, label=label, zorder=2)
    ax.set_xlim(0, width)
    ax.set_ylim(height, 0)
    ax.set_axis_off()
    if title is not None:
        ax.set_title(title, fontsize="medium")
    if paths:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.01), fontsize="small", frameon=False)
    return fig
