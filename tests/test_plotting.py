"""The Fig. 2 style world picture: what is drawn, where, and that it saves without pyplot."""

import numpy as np
import pytest
from matplotlib.figure import Figure

from himit_torch.demonstrations import Demonstrations
from himit_torch.plotting import LEARNER_COLOR, MENTOR_COLOR, plot_world, save_world_figure
from himit_torch.world import MultiRooms

N = 8
EPISODES = [[0, 1, 9, 17, 25, 26], [0, 8, 16, 17]]     # cells r·8 + c, top-left room only


@pytest.fixture
def world() -> MultiRooms:
    return MultiRooms(size=N, rooms=2)


def lines_of(fig: Figure, color: str):
    from matplotlib.colors import same_color
    return [ln for ln in fig.axes[0].get_lines() if same_color(ln.get_color(), color)]


def test_mentor_episodes_and_learner_are_drawn_through_cell_centres(world):
    demos = Demonstrations(EPISODES, world)
    learner = [0, 1, 2, 3]
    fig = plot_world(world, demos, learner_states=learner)
    mentor = lines_of(fig, MENTOR_COLOR)
    assert len(mentor) == 2
    rows, cols = np.divmod(np.array(EPISODES[0]), N)
    assert np.array_equal(mentor[0].get_xdata(), cols) and np.array_equal(mentor[0].get_ydata(), rows)
    assert 0 < mentor[0].get_alpha() < 1  # semi-transparent, so overlaps read darker
    (learner_line,) = lines_of(fig, LEARNER_COLOR)
    assert np.array_equal(learner_line.get_xdata(), [0, 1, 2, 3])
    assert np.array_equal(learner_line.get_ydata(), [0, 0, 0, 0])
    image = fig.axes[0].get_images()[0].get_array()
    assert image.shape == (N, N)
    assert image[4, 0] == 1 and image[4, 2] == 2 and image[0, 0] == 0  # wall, doorway, free


def test_several_learner_trajectories_and_given_axes(world):
    fig = Figure()
    ax = fig.add_subplot()
    assert plot_world(world, learner_states=[[0, 1], [0, 8, 16]], ax=ax, title="mine") is fig
    assert len(lines_of(fig, LEARNER_COLOR)) == 2
    assert ax.get_title() == "mine"


def test_demonstrations_from_another_world_are_refused(world):
    demos = Demonstrations(EPISODES, MultiRooms(size=N, rooms=2, slip=0.3))
    with pytest.raises(ValueError, match="slip"):
        plot_world(world, demos)


def test_learner_states_outside_the_world_are_refused(world):
    with pytest.raises(ValueError, match=r"outside \[0, 64\)"):
        plot_world(world, learner_states=[0, 64])


def test_save_world_figure_writes_a_png(world, tmp_path):
    path = save_world_figure(tmp_path / "world.png", world, Demonstrations(EPISODES, world))
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 2000
