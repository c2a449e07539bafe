"""MiniGrid pictures: the grid as MiniGrid draws it, with labelled paths side by side over it."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

pytest.importorskip("minigrid")

from himit_torch.viz.minigrid import path_offsets, plot_minigrid_paths  # noqa: E402
from himit_torch.worlds.minigrid import from_minigrid  # noqa: E402
from himit_torch.worlds.multirooms import MultiRooms  # noqa: E402

TILE = 32


@pytest.fixture(scope="module")
def world():
    return from_minigrid("MiniGrid-DoorKey-5x5-v0")


def _walk(world, actions: list[str]) -> list[int]:
    """The states of the actions, named, stepped from the start on the world's table."""
    succ = world.dynamics_table().successors[:, :, -1]
    states = [world.start_state]
    for name in actions:
        states.append(int(succ[states[-1], world.action_names.index(name)]))
    return states


def _canvas(world, paths, state=None) -> np.ndarray:
    """The figure's pixels, one per pixel of MiniGrid's drawing (the axes fill the figure;
    the legend below them falls outside it)."""
    h, w = world.render(world.start_state, tile_size=TILE).shape[:2]
    fig = Figure(figsize=(w / 100, h / 100), dpi=100)
    ax = fig.add_axes((0, 0, 1, 1))
    plot_minigrid_paths(world, paths, state, ax=ax, tile_size=TILE)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3]


def test_the_paths_run_through_the_cell_centres_side_by_side(world):
    mentor = _walk(world, ["forward", "right", "forward"])
    learner = _walk(world, ["right", "forward", "left"])
    fig = plot_minigrid_paths(world, [("mentor", mentor), ("learner", learner)])
    ax = fig.axes[0]
    shifts = path_offsets(2, TILE)
    assert shifts[0] < 0 < shifts[1]  # apart, where the paths share cells
    assert [line.get_label() for line in ax.lines] == ["mentor", "learner"]
    for line, path, shift in zip(ax.lines, (mentor, learner), shifts):
        np.testing.assert_array_equal(line.get_xydata(), world.cell_center(path, TILE) + shift)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["mentor", "learner"]
    # The background is MiniGrid's own drawing of the start.
    np.testing.assert_array_equal(ax.images[0].get_array(), world.render(world.start_state))


def test_the_figure_shows_minigrids_pixels_where_no_path_is_drawn(world):
    later = _walk(world, ["right", "forward"])[-1]
    assert later != world.start_state
    bare = _canvas(world, [], later)
    np.testing.assert_array_equal(bare, world.render(later, tile_size=TILE))
    path = _walk(world, ["right", "forward", "forward"])
    drawn = _canvas(world, [("learner", path)], later)
    changed = (drawn != bare).any(-1)
    x, y = world.cell_center(path, TILE)[0].astype(int)  # (one path: no shift)
    assert changed[y, x]  # the path's dot on its first cell
    # Away from the path's cells (the top row of walls), MiniGrid's pixels are untouched.
    assert changed.any() and not changed[: TILE // 2].any()


def test_refusals(world):
    with pytest.raises(TypeError, match="MiniGridWorld"):
        plot_minigrid_paths(MultiRooms(size=8, rooms=2), [])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="'mentor' holds states outside"):
        plot_minigrid_paths(world, [("mentor", [0, world.num_states])])
    with pytest.raises(ValueError, match="one colour per path"):
        plot_minigrid_paths(world, [("a", [0]), ("b", [0])], colors=["red"])
