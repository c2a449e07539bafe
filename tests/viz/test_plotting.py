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
    short = renderer.values(torch.zeros(world.num_states), title="short")
    wrapped = renderer.values(torch.zeros(world.num_states), title=LONG_TITLE)
    above = lambda image: (image[:70] < 128).any(-1)  # the title's dark pixels, above the map
    assert above(wrapped).any(0)[[0, -1]].tolist() == [False, False]  # not cut at the edges
    # re-broken onto more lines: it reaches further down than a short title
    assert np.flatnonzero(above(wrapped).any(1)).max() > np.flatnonzero(above(short).any(1)).max()
    fig = Figure(figsize=(6, 5), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(LONG_TITLE[:200])
    fig.suptitle(LONG_TITLE[:150])
    FigureCanvasAgg(fig)
    fit_titles(fig)
    fig.canvas.draw()
    assert _inside(fig, ax.title) and _inside(fig, fig._suptitle)


@pytest.mark.slow  # (full draws of five figures, ≈ 4 s: CI's)
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


def _imshow_cells(world, field, log: bool, no_data=None, dpi: int = 100) -> np.ndarray:
    """The slow obvious path: ``plot_state_map`` (matplotlib's ``imshow``) of ``field`` into the
    maps' axes box, drawn; the ``[N, N, 3]`` pixels at the cells' centres."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from himit_torch.viz import plotting

    fig = Figure(figsize=plotting._MAP_FIGSIZE, dpi=dpi)
    ax = fig.add_axes(plotting._MAP_AXES)
    plotting.plot_state_map(ax, world, field, label="", log=log, no_data=no_data, colorbar=False)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return _cell_centres(np.asarray(canvas.buffer_rgba())[..., :3], world, dpi)


def _cell_centres(image: np.ndarray, world, dpi: int = 100) -> np.ndarray:
    from himit_torch.viz import plotting

    N, H, W = world.size, image.shape[0], image.shape[1]
    x0, y0, w, h = plotting._MAP_AXES
    centres = (np.arange(N) + 0.5) / N
    cols = np.floor((x0 + w * centres) * W).astype(int)
    rows = np.floor((1 - (y0 + h) + h * centres) * H).astype(int)
    return image[rows[:, None], cols[None, :]]


def test_map_arrays_colour_each_cell_as_imshow_does():
    """The maps drawn as arrays against matplotlib's ``imshow`` of the same field in the same
    box (``plot_state_map``, the slow obvious path): every cell's centre pixel the same, for
    values with cells still at the initial value, visits on a log scale with never-visited
    cells, walls black throughout."""
    from himit_torch.viz.plotting import MapRenderer

    world = MultiRooms(size=16, rooms=4)
    S = world.num_states
    gen = torch.Generator().manual_seed(0)
    renderer = MapRenderer(world)
    values = -torch.rand(S, generator=gen, dtype=torch.float64)
    values[:40] = -1.0
    image = renderer.values(values, "values")
    expected = _imshow_cells(world, values, log=False, no_data=values == -1.0)
    assert np.array_equal(_cell_centres(image, world), expected)
    visits = torch.randint(0, 3000, (S,), generator=gen)
    visits[100:140] = 0
    image = renderer.visits(visits, None, "visits")
    assert np.array_equal(_cell_centres(image, world), _imshow_cells(world, visits, log=True))
    walls = world.wall_mask.numpy().reshape(16, 16)
    assert (_cell_centres(image, world)[walls] == 0).all() and walls.any()


def test_a_tiny_hand_made_map_has_the_known_pixels():
    """A 4 × 4 world drawn by hand: each cell's centre pixel is the colour worked out here
    from the colormap's table (viridis: its first colour at the lowest value, its last at the
    highest), the walls black, a cell still at the initial value grey, the mentor's dot at
    the centre of its cell only."""
    import matplotlib
    from matplotlib.colors import to_rgb

    from himit_torch.viz.plotting import NO_DATA_COLOR, MapRenderer

    world = MultiRooms(size=4, rooms=1)  # (no walls: 16 free cells)
    assert not world.wall_mask.any()
    inside = np.array([[0, 0], [1, 1], [2, 2], [3, 3]])
    a, b, c, d = (int(r * 4 + k) for r, k in inside)
    values = torch.full((16,), 0.5, dtype=torch.float64)
    values[a], values[b], values[c], values[d] = 0.0, 1.0, 0.25, -1.0  # d: no route known
    image = MapRenderer(world).values(values, "hand-made")
    cells = _cell_centres(image, world)
    viridis = matplotlib.colormaps["viridis"](np.arange(256), bytes=True)[:, :3]
    grey = (np.array(to_rgb(NO_DATA_COLOR)) * 255).round()
    # on the scale 0 … 1 of the cells shown: 0 → colour 0, 1 → colour 255, 0.25 → colour 64
    assert cells[tuple(inside[0])].tolist() == viridis[0].tolist()
    assert cells[tuple(inside[1])].tolist() == viridis[255].tolist()
    assert cells[tuple(inside[2])].tolist() == viridis[64].tolist()
    assert cells[tuple(inside[3])].tolist() == grey.tolist()
    assert cells[0, 1].tolist() == viridis[128].tolist()  # 0.5
    visits = torch.zeros(16, dtype=torch.int64)  # (never visited: grey)
    visits[[a, b, c, d]] = torch.tensor([1, 10, 100, 1000])
    mentor = torch.zeros(16, dtype=torch.int64)
    mentor[b] = 3
    image = MapRenderer(world).visits(visits, mentor, "hand-made")
    cells = _cell_centres(image, world)
    orange = (np.array(to_rgb("#e8590c")) * 255).round().tolist()
    assert cells[tuple(inside[1])].tolist() == orange  # the mentor's dot
    # on the log scale 1 … 1000: 1 → colour 0, 100 → ⌊2/3 · 256⌋ = 170, 1000 → colour 255
    assert cells[tuple(inside[0])].tolist() == viridis[0].tolist()
    assert cells[tuple(inside[2])].tolist() == viridis[170].tolist()
    assert cells[tuple(inside[3])].tolist() == viridis[255].tolist()
    # the dot is half a cell wide: the cell's corner keeps the learner's colour
    H, W = image.shape[:2]
    from himit_torch.viz import plotting

    x0, y0, w, h = plotting._MAP_AXES
    r, k = inside[1]
    corner = image[int((1 - (y0 + h) + h * (r + 0.1) / 4) * H), int((x0 + w * (k + 0.1) / 4) * W)]
    assert corner.tolist() == viridis[85].tolist()  # 10 → ⌊1/3 · 256⌋


def test_policy_map_colours_options_by_kind_and_direction():
    from matplotlib.colors import to_rgb

    from himit_torch.options.builders import learner_options
    from himit_torch.viz.plotting import _POLICY_PALETTE, NO_DATA_COLOR, MapRenderer

    world = MultiRooms(size=16, rooms=4)
    options = learner_options(world, corners=True)
    free = np.flatnonzero(~world.wall_mask.numpy())
    greedy = torch.full((world.num_states,), -1, dtype=torch.int64)
    kinds = {k: i for i, k in enumerate(options.kinds)}  # the last option of each kind
    names = {n: i for i, n in enumerate(options.names)}
    chosen = {
        free[0]: next(i for n, i in names.items() if n.endswith("N")),
        free[1]: kinds["doorway"],
        free[2]: kinds["corner"],
    }
    for s, o in chosen.items():
        greedy[s] = o
    cells = _cell_centres(MapRenderer(world, options).policy(greedy, "p"), world).reshape(-1, 3)
    rgb = lambda c: (np.array(to_rgb(c)) * 255).round().tolist()
    assert cells[free[0]].tolist() == rgb(_POLICY_PALETTE["N"])
    assert cells[free[1]].tolist() == rgb(_POLICY_PALETTE["doorway"])
    assert cells[free[2]].tolist() == rgb(_POLICY_PALETTE["corner"])
    assert cells[free[3]].tolist() == rgb(NO_DATA_COLOR)  # nothing tried


def test_map_colorbar_ticks_follow_the_range():
    """The colorbar's gradient is the frame's; its ticks and labels are the map's: two ranges
    give the same gradient and different labels, and the gradient runs from viridis' first
    colour at the bottom to its last at the top."""
    import matplotlib

    from himit_torch.viz import plotting

    world = MultiRooms(size=16, rooms=4)
    renderer = plotting.MapRenderer(world)
    one = renderer.values(torch.linspace(-1, 0, world.num_states), "t")
    other = renderer.values(torch.linspace(-0.5, 300.0, world.num_states), "t")
    x0, y0, x1, y1 = renderer._frame("values").colorbar
    middle = int((x0 + x1) / 2)
    bar = slice(int(y0) + 2, int(y1) - 2)
    assert np.array_equal(one[bar, middle], other[bar, middle])
    viridis = matplotlib.colormaps["viridis"](np.arange(256), bytes=True)[:, :3]
    assert np.abs(one[int(y1) - 3, middle].astype(int) - viridis[0]).max() <= 8
    assert np.abs(one[int(y0) + 3, middle].astype(int) - viridis[255]).max() <= 8
    labels = (slice(int(y0) - 8, int(y1) + 8), slice(int(x1) + 8, int(x1) + 45))
    assert not np.array_equal(one[labels], other[labels])
    assert (one[labels] < 100).any()  # some text drawn
