"""Pictures: the Fig. 2 world (what is drawn, where, saved without pyplot), state maps that keep
"no data" apart from low values, curves with n, bands and medians, first goals, TensorBoard maps."""

import numpy as np
import pytest
import torch
from matplotlib.figure import Figure

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.viz.plotting import (
    LEARNER_COLOR,
    MENTOR_COLOR,
    plot_goal_curves,
    plot_world,
    save_world_figure,
)
from himit_torch.worlds.multirooms import MultiRooms

N = 8
EPISODES = [[0, 1, 9, 17, 25, 26], [0, 8, 16, 17]]  # cells r·8 + c, top-left room only


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
    assert np.array_equal(mentor[0].get_xdata(), cols) and np.array_equal(
        mentor[0].get_ydata(), rows
    )
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


# ------------------------------------------------------------------------------- state maps
def test_state_map_keeps_never_visited_apart_from_low_values(world):
    from matplotlib.colors import to_rgba

    from himit_torch.viz.plotting import NO_DATA_COLOR, WALL_COLOR, plot_state_map

    field = np.zeros(world.num_states)
    field[[0, 1, 2]] = [0.0, 0.5, 1.0]  # visited, salience 0 / 0.5 / 1
    never = np.ones(world.num_states, dtype=bool)
    never[[0, 1, 2]] = False
    fig = Figure()
    ax = fig.add_subplot()
    image = plot_state_map(ax, world, field, label="salience", no_data=never)
    data = image.get_array()
    # A visited cell with salience 0 is coloured (the low end); never-visited cells are masked
    # and drawn in the no-data grey, which is not a colour of the scale.
    assert not data.mask[0, 0] and data.mask[0, 3] and data.mask[4, 0]
    assert image.cmap.get_bad() == pytest.approx(to_rgba(NO_DATA_COLOR))
    assert all(
        image.cmap(x) != pytest.approx(to_rgba(NO_DATA_COLOR)) for x in np.linspace(0, 1, 11)
    )
    walls = ax.get_images()[1]
    assert walls.cmap(0.0) == pytest.approx(to_rgba(WALL_COLOR))
    assert fig.axes[-1].get_ylabel() == "salience"  # the colorbar says what it measures


def test_log_map_shows_zero_counts_as_no_data(world):
    from himit_torch.viz.plotting import plot_state_map

    visits = np.zeros(world.num_states)
    visits[[0, 1]] = [1, 100]
    fig = Figure()
    image = plot_state_map(fig.add_subplot(), world, visits, label="visits", log=True)
    assert image.get_array().mask.reshape(-1)[2] and image.norm.vmin == 1 and image.norm.vmax == 100


# --------------------------------------------------------------------------- learning curves
def test_runs_split_when_some_seeds_end_far_below_the_others():
    from himit_torch.viz.plotting import runs_split

    assert runs_split(np.array([[0, 50], [0, 52], [0, 1]]))
    assert not runs_split(np.array([[0, 50], [0, 52], [0, 40]]))
    assert not runs_split(np.array([[0, 0], [0, 0]]))  # all failed alike: no split


def test_goal_curves_state_n_outcomes_median_and_our_optimum():
    from matplotlib.collections import PolyCollection

    from himit_torch.viz.plotting import plot_goal_curves

    fig = Figure()
    ax = fig.add_subplot()
    steps = np.array([5000, 10000])
    plot_goal_curves(
        ax,
        steps,
        {
            "known": np.array([[30, 50], [35, 52], [20, 48]]),
            "none": np.array([[0, 52], [10, 51], [0, 0]]),
        },
        optimum=54.72,
        paper_optimum=53.2,
        window=5000,
    )
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "known: mean of n=3, 3/3 found the goal" in labels
    assert "none: mean of n=3, 2/3 found the goal; median dashed" in labels
    assert "optimal policy, exact: 54.7" in labels and "the paper's optimum: ≈ 53.2" in labels
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert len(dashed) == 1 and list(dashed[0].get_ydata()) == [0, 51]  # only "none" split
    assert len([c for c in ax.collections if isinstance(c, PolyCollection)]) == 2  # two bands


def test_first_goals_show_never_and_the_median():
    from himit_torch.viz.plotting import plot_first_goals

    fig = Figure()
    ax = fig.add_subplot()
    plot_first_goals(ax, {"known": [876, 2953, 4451], "none": [-1, 97145, 31118]}, 100_000)
    texts = [t.get_text() for t in ax.texts]
    assert "n=3, median 2,953" in texts and "n=3, 2/3 found it" in texts
    assert "never" in [t.get_text() for t in ax.get_xticklabels()]


# ------------------------------------------------------------------------ TensorBoard maps
def test_value_map_greys_out_cells_still_at_the_initial_value():
    from matplotlib.colors import to_rgb

    from himit_torch.viz.plotting import NO_DATA_COLOR, MapRenderer

    world = MultiRooms(size=16, rooms=4)
    renderer = MapRenderer(world)
    grey = (np.array(to_rgb(NO_DATA_COLOR)) * 255).round()
    values = torch.full((world.num_states,), -0.5, dtype=torch.float64)
    values[:128] = -1.0  # the top half: no route known yet
    with_unknown = renderer.values(values, "half unknown")
    all_known = renderer.values(torch.full_like(values, -0.5), "all known")
    count = lambda rgb: int((np.abs(rgb.astype(float) - grey).sum(-1) < 8).sum())
    assert with_unknown.shape[1] >= 400 and with_unknown.dtype == np.uint8
    # Only the legend's patch is grey when no cell is at −1.
    assert count(with_unknown) > 10 * max(count(all_known), 1)


# ------------------------------------------------------------------------- titles fit
LONG_TITLE = (
    "a very long title that names the world, the mentor's episodes, the learner's "
    "greedy path and every setting of the run, far wider than any figure "
) * 2


def _inside(fig: Figure, text) -> bool:
    renderer = fig.canvas.get_renderer()
    box, frame = text.get_window_extent(renderer), fig.bbox
    return (
        box.x0 >= frame.x0 - 0.5
        and box.x1 <= frame.x1 + 0.5
        and box.y0 >= frame.y0 - 0.5
        and box.y1 <= frame.y1 + 0.5
    )


def test_long_titles_are_wrapped_inside_the_figure(world, tmp_path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from himit_torch.viz.plotting import MapRenderer, fit_titles

    fig = plot_world(world, title=LONG_TITLE)
    FigureCanvasAgg(fig)
    fig.canvas.draw()
    assert not _inside(fig, fig.axes[0].title), "the check must be able to fail"
    fit_titles(fig)
    fig.canvas.draw()
    assert _inside(fig, fig.axes[0].title)
    assert fig.axes[0].title.get_text().split() == LONG_TITLE.split()  # nothing dropped
    # the saved figure, the TensorBoard maps and the report's curves do it themselves
    save_world_figure(tmp_path / "w.png", world, title=LONG_TITLE)
    renderer = MapRenderer(world)
    renderer.values(torch.zeros(world.num_states), title=LONG_TITLE)
    parts = renderer._figure("values")
    assert _inside(parts["fig"], parts["title"])
    fig = Figure(figsize=(6, 5), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(LONG_TITLE[:200])
    fig.suptitle(LONG_TITLE[:150])
    FigureCanvasAgg(fig)
    fit_titles(fig)
    fig.canvas.draw()
    assert _inside(fig, ax.title) and _inside(fig, fig._suptitle)


def test_fit_titles_places_boxes_as_a_full_draw_would(world, monkeypatch):
    """fit_titles places the axes without drawing the figure (a layout pass and the axes'
    aspects): the titles it wraps, their font sizes and the saved PNG's bytes are those of the
    full draws it placed them with before — on a world (equal-aspect axes in a constrained
    layout), one anchored on the left (its title is centred on the square the aspect leaves,
    not on the axes' slot: measured before the aspect, it looks as if it fitted), curves
    with the legend beside the axes and a suptitle, and a figure without a layout engine; a
    title that fits is left as it is."""
    import io

    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from himit_torch.viz import plotting

    steps = np.arange(1, 21) * 5000
    goals = {
        "a": np.random.default_rng(0).integers(0, 40, (3, 20)),
        "b": np.random.default_rng(1).integers(0, 40, (3, 20)),
    }

    def curves(layout, title, suptitle=None):
        fig = Figure(figsize=(6, 4), layout=layout)
        ax = fig.add_subplot()
        plot_goal_curves(ax, steps, goals, optimum=45.0, window=5000)
        ax.set_title(title, fontsize="medium")
        if suptitle:
            fig.suptitle(suptitle)
        return fig

    def world_on_the_left():  # its title centred on the square, not on the axes' slot
        fig = Figure(figsize=(9, 4), layout="constrained")
        ax = fig.add_subplot()
        plot_world(world, ax=ax, title=LONG_TITLE[:110])
        ax.set_anchor("W")
        return fig

    makers = {
        "world on the left": world_on_the_left,
        "world": lambda: plot_world(
            world, Demonstrations(EPISODES, world), [0, 1, 2], title=LONG_TITLE
        ),
        "curves": lambda: curves("constrained", LONG_TITLE, suptitle=LONG_TITLE[:130]),
        "no layout engine": lambda: curves(None, LONG_TITLE[:150]),
        "short": lambda: curves("constrained", "fits"),
    }

    def fitted_and_saved(make):
        fig = make()
        FigureCanvasAgg(fig)
        plotting.fit_titles(fig)
        titles = [fig.axes[0].title, *([fig._suptitle] if fig._suptitle else [])]
        png = io.BytesIO()
        fig.savefig(png, dpi=110, format="png")
        return [(t.get_text(), t.get_fontsize()) for t in titles], png.getvalue()

    placed = {name: fitted_and_saved(make) for name, make in makers.items()}
    monkeypatch.setattr(
        plotting, "_place_boxes", lambda fig, renderer: fig.draw_without_rendering()
    )
    for name, make in makers.items():
        titles, png = placed[name]
        assert (titles, png) == fitted_and_saved(make), name
        assert all(("\n" in text) == (name != "short") for text, _ in titles), (name, titles)


def test_tensorboard_hint_runs_as_typed(monkeypatch, tmp_path):
    """The printed command names an executable that exists as typed from the current folder (on
    PATH, or a path to the script beside this Python, or this Python with ``-m``)."""
    import os
    import shlex
    import shutil
    import sys

    from himit_torch.viz.tensorboard import tensorboard_command

    def runnable(program: str) -> bool:
        if "/" in program:
            return os.path.isfile(program) and os.access(program, os.X_OK)
        return shutil.which(program) is not None

    command = shlex.split(tensorboard_command(tmp_path / "tb"))
    assert command[-2:] == ["--logdir", str(tmp_path / "tb")] and runnable(command[0])
    monkeypatch.setenv("PATH", "")  # not on PATH: the script beside this Python, or -m
    command = shlex.split(tensorboard_command("runs/x/tb"))
    assert "/" in command[0] and runnable(command[0]), command
    if "-m" in command:
        assert command[1:3] == ["-m", "tensorboard.main"]
        assert os.path.samefile(command[0], sys.executable)


def test_each_map_image_is_the_figures_full_draw():
    """The maps redraw only what changes over a background drawn once; every image must be
    pixel for pixel what a full draw of the same figure gives (the obvious, slow path) —
    across colour ranges, titles, mentor dots and greedy options that change between images."""
    from himit_torch.options.builders import learner_options
    from himit_torch.viz.plotting import MapRenderer

    world = MultiRooms(size=16, rooms=4)
    options = learner_options(world, corners=True)
    renderer = MapRenderer(world, options)
    gen = torch.Generator().manual_seed(0)
    S = world.num_states

    def full_draw(kind: str) -> np.ndarray:
        parts = renderer._figure(kind)
        for artist in parts["fig"].findobj():
            artist.set_animated(False)
        parts["canvas"].draw()
        return np.asarray(parts["canvas"].buffer_rgba())[..., :3].copy()

    images = 0
    for k in range(3):
        values = -torch.rand(S, generator=gen, dtype=torch.float64) * (k + 1)
        values[: 5 * k] = -1.0  # some cells still at the initial value
        visits = torch.randint(0, 10 ** (k + 1), (S,), generator=gen)
        mentor = (torch.rand(S, generator=gen) < 0.1 * k).long()
        greedy = torch.randint(-1, len(options.names), (S,), generator=gen)
        title = "a title " * (1 + 6 * k)  # the longest wraps onto two lines
        for kind, image in (
            ("values", renderer.values(values, title)),
            ("visits", renderer.visits(visits, mentor if k else None, title)),
            ("policy", renderer.policy(greedy, title)),
        ):
            assert np.array_equal(image, full_draw(kind)), (kind, k)
            images += 1
    assert images == 9


def test_maps_on_the_process_figures_are_those_of_figures_built_for_the_world(monkeypatch):
    """Renderers share the process's map figures, each setting them to its world's grid: every
    image must be pixel for pixel what a figure built for that world gives (the obvious path,
    a renderer with no figures to share) — worlds of other sizes and walls, back and forth, two
    renderers taking turns, a world the figures were built for coming back."""
    from himit_torch.options.builders import learner_options
    from himit_torch.viz import plotting

    monkeypatch.setattr(plotting, "_MAP_FIGURES", {})
    worlds = [
        MultiRooms(size=16, rooms=4),
        MultiRooms(size=24, rooms=3),
        MultiRooms(size=12, rooms=3),
    ]
    renderers = [plotting.MapRenderer(w, learner_options(w, corners=True)) for w in worlds]
    gen = torch.Generator().manual_seed(1)
    figures = set()
    for turn, r in enumerate([0, 1, 0, 2, 1, 2, 0]):
        renderer, S = renderers[r], worlds[r].num_states
        values = -torch.rand(S, generator=gen, dtype=torch.float64)
        values[:7] = -1.0
        visits = torch.randint(0, 1000, (S,), generator=gen)
        mentor = (torch.rand(S, generator=gen) < 0.1).long()
        greedy = torch.randint(-1, len(renderer.options.names), (S,), generator=gen)
        title = f"turn {turn}: world {worlds[r].size}"
        for kind, data in (
            ("values", (values,)),
            ("visits", (visits, mentor)),
            ("policy", (greedy,)),
        ):
            shared = getattr(renderer, kind)(*data, title)
            figures.add(id(renderer._figure(kind)["fig"]))
            with monkeypatch.context() as m:
                m.setattr(plotting, "_MAP_FIGURES", {})
                built = getattr(plotting.MapRenderer(worlds[r], renderer.options), kind)(
                    *data, title
                )
            assert shared.shape == built.shape and np.array_equal(shared, built), (kind, turn)
    assert len(figures) == 3  # (one figure of each kind served every world)
