"""Pictures of a world, its maps and learning curves: the paper's Fig. 2 (:func:`plot_world`),
per-state maps (:func:`plot_state_map`), learning curves with the seeds' spread
(:func:`plot_goal_curves`), first goals per seed (:func:`plot_first_goals`) and the maps logged
to TensorBoard (:class:`MapRenderer`).

One look everywhere: walls are black (:data:`WALL_COLOR`) in every picture; cells with nothing
to show (never visited, zero salience, a value still at its initial −1) are grey
(:data:`NO_DATA_COLOR`) and named in a legend, so they never read as "low"; colour scales are
viridis, which has neither black nor grey, and every colorbar says what it measures.

Figures are built on :class:`matplotlib.figure.Figure` directly, never through ``pyplot``, so
importing or using this module changes no global matplotlib state (no backend switch, no open
figures to leak); :func:`save_world_figure` renders with the Agg canvas.
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.text import Text
from matplotlib.ticker import FuncFormatter

from himit_torch.mentor.demonstrations import Demonstrations
from himit_torch.statistics import t_interval
from himit_torch.worlds.multirooms import MultiRooms

__all__ = [
    "fit_titles",
    "save_figure",
    "plot_world",
    "save_world_figure",
    "plot_state_map",
    "map_legend",
    "plot_goal_curves",
    "plot_first_goals",
    "plot_mean_band",
    "runs_split",
    "MapRenderer",
    "value_image",
    "visitation_image",
    "policy_image",
    "CURVE_COLORS",
    "WALL_COLOR",
    "NO_DATA_COLOR",
    "MAP_CMAP",
]

MENTOR_COLOR = "#1f5fbf"
LEARNER_COLOR = "#e8590c"
DOORWAY_COLOR = "#f2c14e"
START_COLOR = "#2b9348"
GOAL_COLOR = "#d62828"
#: Walls, in every picture.
WALL_COLOR = "black"
#: Cells with nothing to show (never visited, no value yet), named in a legend.
NO_DATA_COLOR = "#c8c8c8"
MAP_CMAP = "viridis"
OPTIMUM_COLOR = "0.2"
PAPER_OPTIMUM_COLOR = "0.55"
#: Distinct curve colours (Okabe & Ito's colour-blind-safe set, yellow swapped for a dark gold
#: that shows on white); one per variant, in order.
CURVE_COLORS = (
    "#0072B2",
    "#D55E00",
    "#009E73",
    "#CC79A7",
    "#E69F00",
    "#56B4E9",
    "#000000",
    "#8F7A00",
)


def _trajectories(states) -> list[np.ndarray]:
    """One trajectory (1-D sequence) or several (a sequence of them) as a list of arrays."""
    if isinstance(states, (torch.Tensor, np.ndarray)):
        a = (
            states.detach().cpu().numpy()
            if isinstance(states, torch.Tensor)
            else np.asarray(states)
        )
        if a.ndim == 1:
            return [a.astype(np.int64)]
        if a.ndim == 2:
            return [row.astype(np.int64) for row in a]
        raise ValueError(f"learner_states must be 1-D (one trajectory) or 2-D, got shape {a.shape}")
    items = list(states)
    if items and all(np.ndim(x) == 0 for x in items):
        return [np.asarray(items, dtype=np.int64)]
    return [
        np.asarray(x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else x, dtype=np.int64)
        for x in items
    ]


def _draw_paths(
    ax: Axes,
    world: MultiRooms,
    paths: Sequence[np.ndarray],
    color: str,
    alpha: float,
    linewidth: float,
    zorder: int,
) -> None:
    for path in paths:
        if path.size == 0:
            continue
        if ((path < 0) | (path >= world.num_states)).any():
            raise ValueError(f"trajectory holds states outside [0, {world.num_states})")
        rows, cols = np.divmod(path, world.size)
        ax.plot(
            cols,
            rows,
            color=color,
            alpha=alpha,
            linewidth=linewidth,
            zorder=zorder,
            solid_capstyle="round",
            solid_joinstyle="round",
        )


def plot_world(
    world: MultiRooms,
    demonstrations: Demonstrations | None = None,
    learner_states=None,
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
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
        parent = ax.get_figure()
        assert isinstance(parent, Figure), "plot_world draws into the axes of a Figure"
        fig = parent
    N = world.size
    # 0 free, 1 wall, 2 doorway.
    cells = world.wall_mask.numpy().astype(np.int64)
    cells[world.doorways.numpy()] = 2
    cmap = ListedColormap(["white", WALL_COLOR, DOORWAY_COLOR])
    ax.imshow(
        cells.reshape(N, N),
        cmap=cmap,
        vmin=0,
        vmax=2,
        interpolation="nearest",
        extent=(-0.5, N - 0.5, N - 0.5, -0.5),
        zorder=0,
    )
    handles: list[Artist] = [
        Patch(facecolor=WALL_COLOR, label="wall"),
        Patch(facecolor=DOORWAY_COLOR, edgecolor="0.4", label="doorway"),
    ]
    if demonstrations is not None:
        paths = [e.numpy() for e in demonstrations.episodes]
        # Fainter lines for more episodes, so overlaps show where the mentor goes reliably.
        alpha = float(np.clip(1.5 / max(1, len(paths)) ** 0.5, 0.12, 0.8))
        _draw_paths(ax, world, paths, MENTOR_COLOR, alpha, 2.0, zorder=2)
        handles.append(
            Line2D(
                [],
                [],
                color=MENTOR_COLOR,
                linewidth=2.0,
                label=f"mentor ({len(paths)} episode{'s' * (len(paths) != 1)})",
            )
        )
    if learner_states is not None:
        paths = _trajectories(learner_states)
        _draw_paths(ax, world, paths, LEARNER_COLOR, 0.85, 1.6, zorder=3)
        handles.append(Line2D([], [], color=LEARNER_COLOR, linewidth=1.6, label="learner"))
    marker = max(7.0, 200.0 / N)
    for state, color, shape, label in (
        (world.start_state, START_COLOR, "o", "start"),
        (world.goal_state, GOAL_COLOR, "*", "goal"),
    ):
        r, c = world.coords(state)
        ax.plot(
            [c],
            [r],
            marker=shape,
            color=color,
            markersize=marker * (1.6 if shape == "*" else 1),
            markeredgecolor="white",
            markeredgewidth=0.8,
            linestyle="none",
            zorder=4,
        )
        handles.append(
            Line2D(
                [],
                [],
                marker=shape,
                color=color,
                linestyle="none",
                markeredgecolor="white",
                markersize=8,
                label=label,
            )
        )
    ax.set_xlim(-0.5, N - 0.5)
    ax.set_ylim(N - 0.5, -0.5)
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(
        title
        if title is not None
        else f"{N}×{N} multirooms: a {world.rooms}×{world.rooms} grid of rooms of "
        f"{world.room_size}×{world.room_size} cells",
        fontsize="medium",
    )
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.01),
        ncol=len(handles),
        fontsize="small",
        frameon=False,
        handlelength=1.5,
        columnspacing=1.0,
    )
    return fig


def _wrap_to_width(text: Text, width_px: float, renderer) -> None:
    """Re-break ``text`` at spaces so that no line is wider than ``width_px``; a single word
    still too wide makes the font smaller (down to 6 pt)."""
    words = text.get_text().split()
    if not words:
        return
    while True:
        lines: list[str] = []
        current = ""
        for word in words:
            trial = f"{current} {word}".strip()
            text.set_text(trial)
            if current and text.get_window_extent(renderer).width > width_px:
                lines.append(current)
                current = word
            else:
                current = trial
        lines.append(current)
        text.set_text("\n".join(lines))
        size = float(text.get_fontsize())
        if text.get_window_extent(renderer).width <= width_px or size <= 6:
            return
        text.set_fontsize(max(6.0, size * 0.85))


def _place_boxes(fig: Figure, renderer) -> None:
    """Put the axes of ``fig`` where a draw would, without drawing: the layout engine's pass
    (as :meth:`Figure.draw` runs it) and each axes' aspect (as :meth:`Axes.draw` applies it).

    That is all of a draw that a title's horizontal extent depends on (an axes title is centred
    on its axes' box, the suptitle on the figure); the rest of a draw (ticks, legends, the
    titles' heights) each later draw does again from these boxes, so the saved pixels are a
    full draw's. Drawing every artist for nothing was a third of :func:`fit_titles`'s time."""
    engine = fig.get_layout_engine()
    if fig.axes and engine is not None:
        try:
            engine.execute(fig)
        except ValueError:
            pass  # (Figure.draw ignores it too: a figure too small for its decorations)
    for ax in fig.axes:
        locator = ax.get_axes_locator()
        ax.apply_aspect(None if locator is None else locator(ax, renderer))


def fit_titles(fig: Figure, margin: float = 0.01) -> None:
    """Make every title of ``fig`` (axes titles, the suptitle, and texts registered with
    ``fig._himit_titles``) fit inside the figure: lines are re-broken at spaces to the width
    available around the title's anchor, then the figure is laid out again (a constrained
    layout makes room above the axes for the extra lines). Call before saving: the boxes are
    placed, the rest (ticks, the titles' heights) is left to the figure's next draw."""
    renderer = (
        fig.canvas.get_renderer()
        if hasattr(fig.canvas, "get_renderer")
        else FigureCanvasAgg(fig).get_renderer()
    )
    # The axes are placed (a layout engine, an aspect) before their titles are measured; a
    # figure of fixed boxes whose only titles are figure texts (the maps) needs no placing: its
    # texts stay where they were put, and its caller's draw shows them. The second placing
    # stays even where no title was re-broken: a constrained layout does not settle in one
    # pass, so the number of passes shows in the saved pixels (one pass fewer changes a dozen
    # pixels of exp1's curves).
    laid_out = fig.get_layout_engine() is not None
    texts = [ax.title for ax in fig.axes if ax.title.get_text()]
    if laid_out or texts:
        with warnings.catch_warnings():  # the unwrapped titles may not leave the axes room yet
            warnings.filterwarnings("ignore", "constrained_layout not applied", UserWarning)
            _place_boxes(fig, renderer)
    texts += [t for t in (getattr(fig, "_suptitle", None),) if t is not None and t.get_text()]
    texts += [t for t in getattr(fig, "_himit_titles", []) if t.get_text()]
    width = fig.bbox.width
    for text in texts:
        box = text.get_window_extent(renderer)
        ha = text.get_horizontalalignment()
        anchor = {"left": box.x0, "right": box.x1}.get(ha, (box.x0 + box.x1) / 2)
        left, right = anchor - margin * width, (1 - margin) * width - anchor
        room = {"left": right, "right": left}.get(ha, 2 * min(left, right))
        if box.width > room or box.x0 < 0 or box.x1 > width:
            _wrap_to_width(text, max(room, 20.0), renderer)
    if laid_out:
        _place_boxes(fig, renderer)


def save_figure(fig: Figure, path: str | os.PathLike, dpi: int, fit: bool = False) -> None:
    """Write ``fig`` to ``path`` (its folder made) at ``dpi`` through the Agg canvas, the way
    every study's figures are written; ``fit``: :func:`fit_titles` first."""
    FigureCanvasAgg(fig)
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    if fit:
        fit_titles(fig)
    fig.savefig(path, dpi=dpi)


def save_world_figure(
    path: str | os.PathLike,
    world: MultiRooms,
    demonstrations: Demonstrations | None = None,
    learner_states=None,
    title: str | None = None,
    dpi: int = 150,
) -> Path:
    """Draw :func:`plot_world` and write it to ``path`` (PNG by default); returns the path."""
    fig = plot_world(
        world, demonstrations=demonstrations, learner_states=learner_states, title=title
    )
    FigureCanvasAgg(fig)
    path = Path(path)
    fit_titles(fig)
    fig.savefig(path, dpi=dpi, format=path.suffix[1:] or "png")
    return path


# ============================================================================ per-state maps
def _numpy(x) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        return x.detach().cpu().double().numpy()
    return np.asarray(x, dtype=np.float64)


def _wall_layer(world: MultiRooms) -> np.ma.MaskedArray:
    """``[N, N]``: 1 on the walls, masked elsewhere: the layer a map draws over its field in
    ``WALL_COLOR``."""
    N = world.size
    return np.ma.masked_array(np.ones(world.num_states), ~world.wall_mask.numpy()).reshape(N, N)


def plot_state_map(
    ax: Axes,
    world: MultiRooms,
    field,
    *,
    label: str,
    title: str | None = None,
    log: bool = False,
    vmin: float | None = None,
    vmax: float | None = None,
    no_data=None,
    colorbar: bool = True,
    cmap: str = MAP_CMAP,
):
    """Draw a per-state quantity ``field [S]`` on the world's grid.

    Walls are :data:`WALL_COLOR`; the cells of ``no_data [S]`` (bool: e.g. never visited) are
    :data:`NO_DATA_COLOR`, outside the colour scale, so that "nothing here" never looks like a
    low value (with ``log=True``, cells ≤ 0 are no-data too). Add :func:`map_legend` to name both.

    Args:
        ax: the axes to draw into.
        world: the world (its size and walls).
        field: ``[S]`` values.
        label: what the colour measures, written on the colorbar (required: a colour scale
            without a label is not readable).
        title: the axes' title.
        log: logarithmic colour scale.
        vmin, vmax: the colour range (default: the data's); give the same to panels that are
            compared, and draw one colorbar for them (``colorbar=False`` and ``fig.colorbar``).
        no_data: ``[S]`` bool, cells to show as "no data".
        colorbar: draw a colorbar beside ``ax``, labelled ``label``.
        cmap: a matplotlib colormap name.

    Returns:
        The :class:`~matplotlib.image.AxesImage` (for a shared colorbar).
    """
    import matplotlib
    from matplotlib.colors import LogNorm, Normalize

    N = world.size
    values = _numpy(field).reshape(-1)
    if values.shape != (world.num_states,):
        raise ValueError(
            f"field has {values.size} entries; the world has {world.num_states} states"
        )
    wall = world.wall_mask.numpy()
    hide = wall | ~np.isfinite(values)
    if no_data is not None:
        hide |= _numpy(no_data).reshape(-1).astype(bool)
    if log:
        hide |= values <= 0
    shown = values[~hide]
    lo = vmin if vmin is not None else (shown.min() if shown.size else (1.0 if log else 0.0))
    hi = vmax if vmax is not None else (shown.max() if shown.size else 10.0 if log else 1.0)
    if hi <= lo:
        hi = lo * 10 if log else lo + 1.0
    norm = LogNorm(lo, hi) if log else Normalize(lo, hi)
    colours = matplotlib.colormaps[cmap].with_extremes(bad=NO_DATA_COLOR)
    image = ax.imshow(
        np.ma.masked_array(values, hide).reshape(N, N),
        cmap=colours,
        norm=norm,
        interpolation="nearest",
    )
    ax.imshow(_wall_layer(world), cmap=ListedColormap([WALL_COLOR]), interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    if title is not None:
        ax.set_title(title, fontsize="medium")
    if colorbar:
        figure = ax.get_figure()
        assert figure is not None, "plot_state_map draws into axes that belong to a figure"
        figure.colorbar(image, ax=ax, label=label, shrink=0.85)
    return image


def map_legend(target, no_data_label: str | None = None, extra: Sequence = (), **kwargs):
    """A legend naming the walls, the no-data grey (``no_data_label``, e.g. "never visited") and
    any ``extra`` handles; ``target`` is an Axes or a Figure."""
    handles = [Patch(facecolor=WALL_COLOR, label="wall")]
    if no_data_label:
        handles.append(Patch(facecolor=NO_DATA_COLOR, edgecolor="0.5", label=no_data_label))
    handles.extend(extra)
    options = dict(loc="lower center", ncol=len(handles), fontsize="small", frameon=False)
    if isinstance(target, Figure):
        options["bbox_to_anchor"] = (0.5, -0.01)
    else:
        options.update(loc="upper center", bbox_to_anchor=(0.5, -0.01))
    options.update(kwargs)
    return target.legend(handles=handles, **options)


# ========================================================================== learning curves
def _steps_label(x, _pos=None) -> str:
    """Tick labels of step axes: 25k, 1.5M."""
    if abs(x) >= 1e6:
        return f"{x / 1e6:g}M"
    return f"{x / 1e3:g}k" if abs(x) >= 1e3 else f"{x:g}"


_STEPS_FORMAT = FuncFormatter(_steps_label)


def runs_split(goals) -> bool:
    """Whether the seeds ended in different outcomes, so that their mean describes no run:
    some seed's last value is below half of the best seed's (e.g. three runs near 52 goals per
    window and two near 0)."""
    last = np.asarray(goals, dtype=np.float64)[:, -1]
    return bool(last.size > 1 and last.max() > 0 and (last < 0.5 * last.max()).any())


def plot_goal_curves(
    ax: Axes,
    steps,
    goals,
    *,
    colors=None,
    optimum: float | None = None,
    paper_optimum: float | None = None,
    window: int | None = None,
    seed_lines: bool = False,
    legend: bool = True,
) -> None:
    """Goals per window against steps, one entry per variant: the mean over seeds (solid), the
    seeds' range as a band, and — where the runs split (:func:`runs_split`) — the median
    (dashed); the legend states ``n`` and how many runs reached the goal at all.

    Args:
        ax: the axes.
        steps: ``[W]`` step at the end of each window.
        goals: ``{name: [n, W]}`` goals per window of each seed.
        colors: ``{name: colour}`` (default: :data:`CURVE_COLORS` in order).
        optimum: our exact optimal rate per window (drawn and labelled).
        paper_optimum: the paper's reported optimum (drawn fainter, labelled as the paper's).
        window: steps per window, for the y label.
        seed_lines: also draw each seed thinly.
        legend: add the legend (outside the axes, on the right).
    """
    steps = np.asarray(steps)
    for i, (name, runs) in enumerate(goals.items()):
        runs = np.atleast_2d(np.asarray(runs, dtype=np.float64))
        color = (colors or {}).get(name, CURVE_COLORS[i % len(CURVE_COLORS)])
        n = runs.shape[0]
        found = int((runs.sum(1) > 0).sum())
        text = f"{name}: mean of n={n}, {found}/{n} found the goal"
        if n > 1:
            ax.fill_between(steps, runs.min(0), runs.max(0), color=color, alpha=0.18, lw=0)
        if seed_lines:
            for run in runs:
                ax.plot(steps, run, color=color, lw=0.6, alpha=0.5)
        split = runs_split(runs)
        if split:
            text += "; median dashed"
        ax.plot(steps, runs.mean(0), color=color, lw=2, label=text)
        if split:
            ax.plot(steps, np.median(runs, 0), color=color, lw=1.5, ls="--")
    if optimum is not None:
        ax.axhline(
            optimum,
            color=OPTIMUM_COLOR,
            ls=":",
            lw=1.2,
            label=f"optimal policy, exact: {optimum:.1f}",
        )
    if paper_optimum is not None:
        ax.axhline(
            paper_optimum,
            color=PAPER_OPTIMUM_COLOR,
            ls="-.",
            lw=0.9,
            label=f"the paper's optimum: ≈ {paper_optimum:.1f}",
        )
    ax.set_xlabel("primitive steps")
    ax.xaxis.set_major_formatter(_STEPS_FORMAT)
    ax.set_ylabel(f"goals per {window:,} steps" if window else "goals per window")
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    if legend:
        ax.legend(
            fontsize="small",
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            title="band: seeds' range",
            title_fontsize="small",
        )


def plot_mean_band(ax: Axes, x, values, *, color, label: str, alpha: float = 0.18) -> None:
    """The mean of ``values`` (``[runs, len(x)]``) at each ``x`` as a line, and its 95 %
    Student-t interval (:func:`~himit_torch.statistics.t_interval`) as a band. A run without a
    value at a point (NaN, ±inf) is left out there; a point with one value has no band, one with
    none no line."""
    values = np.asarray(values, dtype=np.float64)
    mean, half = np.full(values.shape[1], np.nan), np.zeros(values.shape[1])
    for i, column in enumerate(values.T):
        measured = column[np.isfinite(column)]
        if measured.size:
            ci = t_interval(measured)
            mean[i], half[i] = ci.estimate, np.nan_to_num(ci.half_width)
    ax.plot(x, mean, color=color, lw=2, label=label)
    ax.fill_between(x, mean - half, mean + half, color=color, alpha=alpha, lw=0)


def plot_first_goals(
    ax: Axes, first_goals, steps: int, *, colors=None, title: str | None = None
) -> None:
    """Each run's first-goal step, one row per variant: a dot per seed (log-scaled steps; runs
    that never found it at "never" on the right), the median as a bar, ``n`` on the label.

    Args:
        ax: the axes.
        first_goals: ``{name: [n]}`` first-goal steps, −1 for never.
        steps: the runs' length (where "never" is drawn, beyond it).
        colors: ``{name: colour}`` (default: :data:`CURVE_COLORS` in order).
        title: the axes' title.
    """
    names = list(first_goals)
    never_x = steps * 2.0
    for i, name in enumerate(names):
        y = len(names) - 1 - i
        color = (colors or {}).get(name, CURVE_COLORS[i % len(CURVE_COLORS)])
        firsts = np.asarray(first_goals[name], dtype=np.float64)
        x = np.where(firsts >= 0, np.maximum(firsts, 1), never_x)
        # Spread equal values vertically so that every seed stays visible.
        offsets = np.linspace(-0.22, 0.22, len(x)) if len(x) > 1 else np.zeros(1)
        ax.scatter(x, y + offsets, color=color, s=28, zorder=3, edgecolor="white", linewidth=0.5)
        found = firsts[firsts >= 0]
        if found.size == firsts.size:
            med = float(np.median(found))
            ax.plot([med, med], [y - 0.35, y + 0.35], color=color, lw=2.5, zorder=2)
            what = f"median {med:,.0f}"
        else:
            what = f"{found.size}/{firsts.size} found it"
        ax.text(never_x * 1.6, y, f"n={firsts.size}, {what}", va="center", fontsize="small")
    ax.set_xscale("log")
    ax.set_yticks(range(len(names)), names[::-1])
    ax.set_ylim(-0.6, len(names) - 0.4)
    ticks = [t for t in (100, 1_000, 10_000, 100_000, 1_000_000) if t <= steps]
    ax.set_xticks([*ticks, never_x], [_steps_label(t) for t in ticks] + ["never"])
    ax.minorticks_off()
    found_steps = [float(v) for f in first_goals.values() for v in f if v > 0]
    ax.set_xlim((min(found_steps) if found_steps else steps / 10) / 2, never_x * 1.4)
    ax.axvline(steps, color="0.6", lw=0.8, ls=":")
    ax.annotate(
        "end of the runs",
        (steps, 1.0),
        xycoords=("data", "axes fraction"),
        xytext=(-3, -3),
        textcoords="offset points",
        ha="right",
        va="top",
        fontsize="x-small",
        color="0.4",
    )
    ax.set_xlabel("step of the first goal (log scale; dots: seeds, bar: median where all found it)")
    ax.grid(axis="x", alpha=0.3)
    if title is not None:
        ax.set_title(title, fontsize="medium")


# ============================================================ maps for TensorBoard, as RGB arrays
_POLICY_PALETTE = {
    "N": "#1f77b4",
    "S": "#2ca02c",
    "W": "#d62728",
    "E": "#9467bd",
    "doorway": "#ff7f0e",
    "corner": "#8c564b",
    "custom": "#17becf",
}
_POLICY_NAMES = {
    "N": "primitive N",
    "S": "primitive S",
    "W": "primitive W",
    "E": "primitive E",
    "doorway": "doorway option",
    "corner": "corner option",
    "custom": "other option",
}
#: The mentor's states on the visits map.
_MENTOR_DOT_COLOR = "#e8590c"
#: A map figure's size (inches), its axes' and colorbar's boxes (figure fractions) and where
#: its title is anchored (the top centre of the axes' column).
_MAP_FIGSIZE = (5.6, 4.8)
_MAP_AXES = (0.03, 0.13, 0.60, 0.70)
_MAP_COLORBAR = (0.68, 0.18, 0.035, 0.60)
_MAP_TITLE = (0.33, 0.975)
#: Tick lengths on the colorbar (points: matplotlib's defaults, major and minor) and the gap
#: between a major tick and its label.
_TICK, _MINOR_TICK, _TICK_PAD = 3.5, 2.0, 3.5

#: This process's map frames (:class:`~himit_torch.viz.map_arrays.MapFrame`), by kind, dpi and
#: legend: they do not depend on the world, so every renderer of the process shares them.
_MAP_FRAMES: dict[tuple, Any] = {}


def _map_frame(kind: str, dpi: int, initial_value: float):
    """The frame of a map of ``kind`` (``values``, ``visits``, ``policy``), drawn by matplotlib
    once per process: the legend, the colorbar's gradient, outline and label; no data, no
    ticks, no title (each map draws those into its copy of the frame)."""
    from matplotlib.colors import LogNorm, Normalize

    from himit_torch.viz.map_arrays import MapFrame

    key = (kind, dpi, initial_value if kind == "values" else None)
    frame = _MAP_FRAMES.get(key)
    if frame is not None:
        return frame
    fig = Figure(figsize=_MAP_FIGSIZE, dpi=dpi)
    ax = fig.add_axes(_MAP_AXES)
    ax.set_axis_off()  # (the map and its outline are drawn into the array)
    colorbar = None
    if kind == "policy":
        keys = list(_POLICY_PALETTE)
        handles = [Patch(facecolor=_POLICY_PALETTE[k], label=_POLICY_NAMES[k]) for k in keys]
        handles += [
            Patch(facecolor=NO_DATA_COLOR, edgecolor="0.5", label="nothing tried"),
            Patch(facecolor=WALL_COLOR, label="wall"),
        ]
        fig.legend(
            handles=handles,
            loc="center left",
            bbox_to_anchor=(0.64, 0.48),
            fontsize="small",
            frameon=False,
        )
    else:
        log = kind == "visits"
        import matplotlib

        image = ax.imshow(
            np.ones((1, 1)),
            cmap=matplotlib.colormaps[MAP_CMAP],
            norm=LogNorm(1, 10) if log else Normalize(0, 1),
        )
        cax = fig.add_axes(_MAP_COLORBAR)
        label = "visits of the learner (log scale)" if log else "V(s), the learner's value"
        bar = fig.colorbar(image, cax=cax, label=label)
        bar.set_ticks([])
        bar.minorticks_off()
        # (where the label sits beside tick labels about 4 characters wide)
        cax.yaxis.set_label_coords(3.3 if log else 3.6, 0.5)
        colorbar = cax
        extra = []
        if log:
            extra = [
                Line2D(
                    [],
                    [],
                    marker="o",
                    color=_MENTOR_DOT_COLOR,
                    linestyle="none",
                    markersize=4,
                    label="mentor's states",
                )
            ]
            no_data = "never visited"
        else:
            initial = f"{initial_value:g}".replace("-", "−")
            no_data = f"V = {initial}: no route to the goal known yet"
        fig.legend(
            handles=[
                Patch(facecolor=WALL_COLOR, label="wall"),
                Patch(facecolor=NO_DATA_COLOR, edgecolor="0.5", label=no_data),
                *extra,
            ],
            loc="lower center",
            bbox_to_anchor=(0.45, 0.0),
            ncol=3 if extra else 2,
            fontsize="small",
            frameon=False,
        )
        image.remove()  # (the colorbar keeps its gradient; the map is the array's)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    pixels = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    H = pixels.shape[0]

    def box(axes) -> tuple[float, float, float, float]:
        b = axes.bbox  # (display coordinates: y up)
        return (b.x0, H - b.y1, b.x1, H - b.y0)

    x0, y0, x1, y1 = box(ax)
    inner = (
        int(math.ceil(y0 - 0.5)),
        int(math.floor(y1 - 0.5)) + 1,
        int(math.ceil(x0 - 0.5)),
        int(math.floor(x1 - 0.5)) + 1,
    )
    pixels.flags.writeable = False
    frame = MapFrame(
        pixels=pixels,
        box=(x0, y0, x1, y1),
        inner=inner,
        colorbar=None if colorbar is None else box(colorbar),
        title=(_MAP_TITLE[0] * pixels.shape[1], (1 - _MAP_TITLE[1]) * H),
        dpi=float(dpi),
        font=float(matplotlib_font_size("medium")),
    )
    _MAP_FRAMES[key] = frame
    return frame


def matplotlib_font_size(size: str) -> float:
    """A named font size (``"medium"``, ``"small"``) in points, as matplotlib resolves it."""
    from matplotlib.font_manager import FontProperties

    return float(FontProperties(size=size).get_size_in_points())


def _rgb(colour) -> np.ndarray:
    """``[3]`` uint8 of a matplotlib colour, looked up once."""
    from himit_torch.viz.map_arrays import rgb_bytes

    rgb = _RGB.get(colour)
    if rgb is None:
        rgb = _RGB[colour] = rgb_bytes(colour)
    return rgb


_RGB: dict[str, np.ndarray] = {}


def _mentor_dot_diameter(cell_px: float) -> float:
    """The mentor's dots on a visits map, in pixels: half a cell wide, so that the learner's
    colour stays visible around them."""
    return cell_px / 2


class MapRenderer:
    """The maps of one world logged to TensorBoard — state values, greedy option, visits — as
    ``[H, W, 3]`` uint8 images with their colorbar or legend, 560 × 480 pixels at 100 dpi.

    Drawn as arrays (:mod:`himit_torch.viz.map_arrays`): the frame of each kind of map
    (legend, colorbar and its label) is drawn by matplotlib once per process and shared by
    every renderer; each map copies it and draws its cells (the colormap applied in NumPy,
    walls and no-data cells in their colours, the mentor's states as dots), the colorbar's
    ticks and labels and its title into the copy: a few milliseconds a map on 80×80, against
    ≈ 0.1–0.2 s for a figure redrawn per map (``benchmarks/bench_maps.py``). Renderers in
    several threads share nothing they write.

    Args:
        world: the world.
        options: the learner's options (names and kinds, for the greedy-option legend).
        initial_value: the learner's initial value (cells still at it are shown as no-data).
        dpi: pixels per inch of the images.
    """

    def __init__(
        self, world: MultiRooms, options=None, initial_value: float = -1.0, dpi: int = 100
    ):
        self.world, self.options, self.initial_value, self.dpi = world, options, initial_value, dpi
        self._option_codes: np.ndarray | None = None  # (the policy map's colour of each option)
        self._walls = world.wall_mask.numpy().copy()
        self._grid: tuple | None = None  # (each pixel's cell, the mentor's dots' pixels)

    def _frame(self, kind: str):
        return _map_frame(kind, self.dpi, self.initial_value)

    def _pixels_of_cells(self, frame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(rows, cols, dot)``: the cell row of each pixel row of the map and the cell column
        of each pixel column (``imshow``'s nearest-neighbour sampling), and ``[h, w]`` bool,
        the pixels of a dot centred in their cell (the mentor's, half a cell wide, so that the learner's colour stays visible around
        them). The same for every kind of map (one axes box)."""
        if self._grid is None:
            from himit_torch.viz.map_arrays import cell_of_pixels, disc_mask

            N = self.world.size
            x0, y0, x1, y1 = frame.box
            r0, r1, c0, c1 = frame.inner
            rows = cell_of_pixels(N, y0, y1 - y0, r0, r1)
            cols = cell_of_pixels(N, x0, x1 - x0, c0, c1)
            dy = disc_mask(N, y0, y1 - y0, r0, r1, 0.0)
            dx = disc_mask(N, x0, x1 - x0, c0, c1, 0.0)
            radius = _mentor_dot_diameter((x1 - x0) / N) / 2
            self._grid = (rows, cols, (dy[:, None] ** 2 + dx[None, :] ** 2) <= radius**2)
        return self._grid

    def _compose(self, kind: str, colours: np.ndarray, title: str, dots=None, scale=None):
        """The map of ``kind``: the frame with ``colours [S, 3]`` (walls drawn over them) in the
        axes, ``dots [S]`` (bool) as the mentor's dots, the colorbar's ``scale`` ``(lo, hi,
        log)`` and ``title``."""
        frame = self._frame(kind)
        image = frame.pixels.copy()
        N = self.world.size
        colours = colours.copy()
        colours[self._walls] = _rgb(WALL_COLOR)
        rows, cols, dot = self._pixels_of_cells(frame)
        # the cells' columns repeated, then whole pixel rows (gathering [S, 3] per pixel at
        # once is ≈ 10× slower: 3-byte items)
        pixels = np.take(np.take(colours.reshape(N, N, 3), cols, axis=1), rows, axis=0)
        if dots is not None and dots.any():
            marked = np.take(np.take(dots.reshape(N, N), cols, axis=1), rows, axis=0) & dot
            pixels[marked] = _rgb(_MENTOR_DOT_COLOR)
        r0, r1, c0, c1 = frame.inner
        image[r0:r1, c0:c1] = pixels
        # the axes' outline: one pixel around the map
        image[r0, c0:c1] = image[r1 - 1, c0:c1] = 0
        image[r0:r1, c0] = image[r0:r1, c1 - 1] = 0
        if scale is not None:
            self._colorbar_ticks(image, frame, *scale)
        self._title(image, frame, title)
        return image

    @staticmethod
    def _colorbar_ticks(image: np.ndarray, frame, lo: float, hi: float, log: bool) -> None:
        """The colorbar's ticks and their labels for the scale ``lo … hi``, where matplotlib's
        locators put them (a colorbar's: ``MaxNLocator`` with 9 bins on a linear scale,
        ``LogLocator`` on a log one, its minor ticks unlabelled)."""
        from matplotlib.ticker import LogLocator, MaxNLocator, ScalarFormatter

        from himit_torch.viz.map_arrays import draw_text

        assert frame.colorbar is not None
        x0, y0, x1, y1 = frame.colorbar
        points = frame.dpi / 72

        def row(v: float) -> float:
            if log:
                share = (math.log10(v) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
            else:
                share = (v - lo) / (hi - lo)
            return y1 - share * (y1 - y0)

        def mark(v: float, length: float) -> None:
            r = int(math.floor(row(v)))
            r = min(max(r, int(y0)), int(math.ceil(y1)) - 1)
            image[r, int(round(x1)) : int(round(x1 + length * points))] = 0

        inside = lambda ticks: [t for t in ticks if lo - 1e-12 <= t <= hi + 1e-12]
        left = x1 + (_TICK + _TICK_PAD) * points
        if log:
            for t in inside(
                LogLocator(base=10, subs=[2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]).tick_values(
                    lo, hi
                )
            ):
                mark(t, _MINOR_TICK)
            for t in inside(LogLocator(base=10).tick_values(lo, hi)):
                mark(t, _TICK)
                exponent = str(int(round(math.log10(t)))).replace("-", "−")
                width = draw_text(image, "10", left, row(t) + 1, frame.font, frame.dpi, va="center")
                draw_text(
                    image,
                    exponent,
                    left + width + 1,
                    row(t) - 0.35 * frame.font * points,
                    0.7 * frame.font,
                    frame.dpi,
                    va="center",
                )
            return
        ticks = inside(MaxNLocator(nbins=9, steps=[1, 2, 2.5, 5, 10]).tick_values(lo, hi))
        formatter = ScalarFormatter()
        formatter.create_dummy_axis()
        assert formatter.axis is not None
        formatter.axis.set_view_interval(lo, hi)
        formatter.axis.set_data_interval(lo, hi)
        for t, text in zip(ticks, formatter.format_ticks(ticks)):
            mark(t, _TICK)
            draw_text(image, text, left, row(t), frame.font, frame.dpi, va="center")
        offset = formatter.get_offset()
        if offset:
            draw_text(image, offset, x0, y0 - 4, frame.font, frame.dpi, va="baseline")

    @staticmethod
    def _title(image: np.ndarray, frame, title: str) -> None:
        """``title`` centred above the map, its lines re-broken at spaces where wider than the
        room around the anchor (as :func:`fit_titles` does)."""
        from himit_torch.viz.map_arrays import draw_text, text_alpha

        x, top = frame.title
        W = image.shape[1]
        room = 2 * min(x - 0.01 * W, 0.99 * W - x)
        lines: list[str] = []
        for line in title.split("\n"):
            current = ""
            for word in line.split():
                trial = f"{current} {word}".strip()
                if current and text_alpha(trial, frame.font, frame.dpi)[0].shape[1] > room:
                    lines.append(current)
                    current = word
                else:
                    current = trial
            lines.append(current)
        px = frame.font * frame.dpi / 72
        for i, line in enumerate(lines):
            if line:
                baseline = top + 0.95 * px + 1.2 * px * i
                draw_text(image, line, x, baseline, frame.font, frame.dpi, "center", "baseline")

    def _field(self, values: np.ndarray, hide: np.ndarray, log: bool):
        """``(colours [S, 3], (lo, hi, log))``: ``values`` coloured on the range of those shown
        (walls, ``hide``, non-finite and, on a log scale, values ≤ 0 are grey)."""
        from himit_torch.viz.map_arrays import colour_cells, colour_lut

        hide = hide | self._walls | ~np.isfinite(values)
        if log:
            hide |= values <= 0
        shown = values[~hide]
        lo, hi = (shown.min(), shown.max()) if shown.size else ((1.0, 10.0) if log else (0.0, 1.0))
        if hi <= lo:
            hi = lo * 10 if log else lo + 1e-3
        colours = np.empty((values.size, 3), dtype=np.uint8)
        colours[~hide] = colour_cells(shown, float(lo), float(hi), log, colour_lut(MAP_CMAP))
        colours[hide] = _rgb(NO_DATA_COLOR)
        return colours, (float(lo), float(hi), log)

    def values(self, values, title: str = "") -> np.ndarray:
        """``values [S]``: colour = ``V(s)``; cells still at the initial value (−1: the value of
        never reaching the goal, kept until the learned model links the cell to the goal) grey."""
        v = _numpy(values).reshape(-1)
        hide = np.isclose(v, self.initial_value, rtol=0, atol=1e-9)
        colours, scale = self._field(v, hide, log=False)
        return self._compose("values", colours, title, scale=scale)

    def visits(self, visits, mentor_visits=None, title: str = "") -> np.ndarray:
        """``visits [S]`` of the learner (log colour scale, never visited grey) with the mentor's
        states (``mentor_visits [S] > 0``) marked."""
        v = _numpy(visits).reshape(-1)
        colours, scale = self._field(v, np.zeros_like(v, dtype=bool), log=True)
        dots = None if mentor_visits is None else _numpy(mentor_visits).reshape(-1) > 0
        return self._compose("visits", colours, title, dots=dots, scale=scale)

    def policy(self, greedy, title: str = "") -> np.ndarray:
        """``greedy [S]`` option per state (−1: nothing tried), coloured by kind and, for
        primitives, direction."""
        if self.options is None:
            raise ValueError("MapRenderer.policy needs the options (MapRenderer(world, options))")
        keys = list(_POLICY_PALETTE)
        if self._option_codes is None:  # the colour of each option, looked up once
            option_codes = []
            for kind, name in zip(self.options.kinds, self.options.names):
                key = name[-1] if kind == "primitive" else kind
                option_codes.append(keys.index(key) if key in keys else keys.index("custom"))
            self._option_codes = np.array(option_codes, dtype=np.int64)
        g = _numpy(greedy).reshape(-1).astype(np.int64)
        palette = np.stack([_rgb(_POLICY_PALETTE[k]) for k in keys])
        colours = np.empty((g.size, 3), dtype=np.uint8)
        colours[:] = _rgb(NO_DATA_COLOR)
        tried = g >= 0
        colours[tried] = palette[self._option_codes[g[tried]]]
        return self._compose("policy", colours, title)


def value_image(
    world: MultiRooms, values: torch.Tensor, title: str = "", initial_value: float = -1.0
) -> np.ndarray:
    """``[H, W, 3]`` uint8 map of state values with its colorbar (see :class:`MapRenderer`)."""
    return MapRenderer(world, initial_value=initial_value).values(values, title)


def visitation_image(
    world: MultiRooms,
    learner_visits: torch.Tensor,
    mentor_visits: torch.Tensor | None = None,
    title: str = "",
) -> np.ndarray:
    """``[H, W, 3]`` uint8 map of the learner's visits (log scale) with the mentor's states."""
    return MapRenderer(world).visits(learner_visits, mentor_visits, title)


def policy_image(world: MultiRooms, options, greedy: torch.Tensor, title: str = "") -> np.ndarray:
    """``[H, W, 3]`` uint8 map of the greedy option per state, with its legend."""
    return MapRenderer(world, options).policy(greedy, title)


# ============================================================================ discovered subgoals
SUBGOAL_COLOR = "#c2185b"


def plot_subgoals(
    world: MultiRooms,
    subgoals,
    demonstrations: Demonstrations | None = None,
    options=None,
    ax: Axes | None = None,
    title: str | None = None,
) -> Figure:
    """The world (:func:`plot_world`) with discovered subgoals and, if given, options to them.

    Subgoals that are true doorways are drawn as filled magenta squares, the others as hollow
    ones; ``options`` (an :class:`~himit_torch.Options`, e.g. from
    :func:`himit_torch.options.discovery.learned_subgoal_options`) shade each cell by how many of them
    may start there and draw each option's action there as a short arrow.

    Args:
        world: the world.
        subgoals: a :class:`~himit_torch.options.discovery.Subgoals` or a sequence of states.
        demonstrations: mentor episodes to draw beneath.
        options: options whose initiation sets and policies to draw (subgoal options only).
        ax, title: as for :func:`plot_world`.
    """
    from himit_torch.worlds.multirooms import ACTION_DELTAS

    states = list(getattr(subgoals, "states", subgoals))
    fig = plot_world(world, demonstrations=demonstrations, ax=ax, title=title)
    ax = fig.axes[0] if ax is None else ax
    N = world.size
    if options is not None:
        init = options.initiation.numpy()
        cover = init.sum(0).astype(np.float64)
        shade = np.ma.masked_where(cover == 0, cover).reshape(N, N)
        ax.imshow(
            shade,
            cmap="Purples",
            alpha=0.45,
            vmin=0,
            vmax=max(1.0, cover.max()) * 1.5,
            interpolation="nearest",
            extent=(-0.5, N - 0.5, N - 0.5, -0.5),
            zorder=1,
        )
        if not options.stochastic:
            policy = options.policy.numpy()
            for o in range(options.num_options):
                cells = np.flatnonzero(init[o])
                if not cells.size:
                    continue
                dr, dc = np.asarray(ACTION_DELTAS)[policy[o, cells]].T
                r, c = np.divmod(cells, N)
                ax.quiver(
                    c,
                    r,
                    dc,
                    -dr,
                    color="#5e3c99",
                    alpha=0.5,
                    scale=2.6 * N / 10,
                    width=0.002,
                    zorder=1.5,
                )
    doors = set(world.doorways.tolist())
    marker = max(6.0, 160.0 / N)
    for hit in (True, False):
        pick = [s for s in states if (s in doors) == hit]
        if not pick:
            continue
        r, c = np.divmod(np.asarray(pick), N)
        ax.plot(
            c,
            r,
            "s",
            markersize=marker,
            markeredgewidth=1.6,
            linestyle="none",
            markeredgecolor=SUBGOAL_COLOR,
            markerfacecolor=SUBGOAL_COLOR if hit else "none",
            zorder=5,
        )
    legend = ax.get_legend()
    handles = list(legend.legend_handles) if legend is not None else []
    handles += [
        Line2D(
            [], [], marker="s", color=SUBGOAL_COLOR, linestyle="none", label="subgoal: a doorway"
        ),
        Line2D(
            [],
            [],
            marker="s",
            markerfacecolor="none",
            color=SUBGOAL_COLOR,
            linestyle="none",
            label="subgoal: not a doorway",
        ),
    ]
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.01),
        ncol=min(4, len(handles)),
        fontsize="small",
        frameon=False,
        handlelength=1.5,
    )
    return fig
