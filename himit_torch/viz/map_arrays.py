"""Maps drawn as arrays: the pieces :class:`~himit_torch.viz.plotting.MapRenderer` composes a
TensorBoard map from, without drawing a figure per map.

A map's frame (legend, axes outline, colorbar gradient and its label) does not depend on the
data: matplotlib draws it once per kind (:class:`MapFrame`). Each map then copies the frame and
draws into it what changes, in NumPy:

* the field, coloured as matplotlib colours it (:func:`colour_lut`, :func:`colour_cells`: the
  colormap's 256 colours indexed as :class:`matplotlib.colors.Colormap` indexes them, on a
  linear or logarithmic scale), walls and no-data cells in their colours, each cell repeated
  over the pixels the axes give it (:func:`cell_of_pixels`, nearest neighbour as ``imshow``);
* dots (the mentor's states) as discs in their cells (:func:`disc_mask`);
* the colorbar's ticks (matplotlib's locators and formatters, no axis drawn) and the title,
  as text rendered by FreeType (:func:`text_alpha`, matplotlib's own font and size) and blended
  into the pixels (:func:`blend_text`).

An 80 × 80 map takes a few milliseconds (``benchmarks/bench_maps.py``), against ≈ 0.1–0.2 s
for a matplotlib figure redrawn per map.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "MapFrame",
    "colour_lut",
    "colour_cells",
    "cell_of_pixels",
    "disc_mask",
    "text_alpha",
    "blend_text",
    "draw_text",
    "rgb_bytes",
]


def rgb_bytes(colour) -> np.ndarray:
    """``[3]`` uint8 of a matplotlib colour (a name, ``"#rrggbb"``, a grey level string)."""
    from matplotlib.colors import to_rgb

    return (np.array(to_rgb(colour)) * 255).round().astype(np.uint8)


@functools.lru_cache(maxsize=8)
def colour_lut(cmap: str) -> np.ndarray:
    """``[N, 3]`` uint8: the colours of matplotlib colormap ``cmap`` (its ``N``, 256 for
    viridis), as ``Colormap.__call__(..., bytes=True)`` gives them."""
    import matplotlib

    colormap = matplotlib.colormaps[cmap]
    lut = colormap(np.arange(colormap.N), bytes=True)[:, :3]
    lut.flags.writeable = False
    return lut


def colour_cells(
    values: np.ndarray, lo: float, hi: float, log: bool, lut: np.ndarray
) -> np.ndarray:
    """``[S, 3]`` uint8 colours of ``values`` on the scale ``lo … hi`` (``log``: logarithmic;
    every value must then be > 0), indexed into ``lut`` as matplotlib's ``Normalize`` or
    ``LogNorm`` and ``Colormap`` do: ``x = (v − lo) / (hi − lo)`` (of the logarithms), index
    ``⌊x · N⌋``, ``x = 1`` the last colour, below 0 the first and above 1 the last (viridis has
    no colours of its own for out-of-range values)."""
    v = np.asarray(values, dtype=np.float64)
    if log:
        x = (np.log10(v) - math.log10(lo)) / (math.log10(hi) - math.log10(lo))
    else:
        x = (v - lo) / (hi - lo)
    n = lut.shape[0]
    with np.errstate(invalid="ignore"):
        index = np.clip(np.floor(x * n), 0, n - 1)
    return lut[np.nan_to_num(index).astype(np.intp)]


def cell_of_pixels(n: int, start: float, length: float, first: int, stop: int) -> np.ndarray:
    """For pixels ``first … stop − 1`` along one side of a box that starts at pixel coordinate
    ``start`` and spans ``length`` pixels holding ``n`` cells: the cell each pixel's centre falls
    in (``imshow``'s nearest-neighbour sampling), clipped to ``0 … n − 1``."""
    centres = np.arange(first, stop) + 0.5
    return np.clip(np.floor((centres - start) / length * n), 0, n - 1).astype(np.intp)


def disc_mask(
    n: int, start: float, length: float, first: int, stop: int, diameter: float
) -> np.ndarray:
    """``[stop − first]`` float: for pixels along one side, their distance from the centre of
    their cell in pixels (squared distances of rows and columns add to a disc's test:
    ``dy² + dx² ≤ (diameter / 2)²``)."""
    centres = np.arange(first, stop) + 0.5
    cell = np.clip(np.floor((centres - start) / length * n), 0, n - 1)
    return centres - (start + (cell + 0.5) * length / n)


@functools.lru_cache(maxsize=1024)
def text_alpha(text: str, points: float, dpi: float) -> tuple[np.ndarray, int]:
    """``(alpha [h, w] float32 in 0 … 1, baseline)`` of one line of ``text`` in matplotlib's
    default font at ``points`` and ``dpi``, rendered by FreeType as matplotlib's Agg backend
    renders text (its font file, size, hinting); ``baseline``: the bitmap's row of the text's
    baseline. Remembered: tick labels and titles repeat."""
    from matplotlib.backends.backend_agg import get_hinting_flag
    from matplotlib.font_manager import FontProperties, fontManager, get_font

    font = get_font(fontManager._find_fonts_by_props(FontProperties()))
    font.clear()
    font.set_size(points, dpi)
    font.set_text(text, 0.0, flags=get_hinting_flag())
    font.draw_glyphs_to_bitmap(antialiased=True)
    image = np.asarray(font.get_image(), dtype=np.float32) / 255.0
    descent = font.get_descent() / 64.0
    baseline = image.shape[0] - int(round(descent)) - 1
    image.flags.writeable = False
    return image, baseline


def blend_text(image: np.ndarray, alpha: np.ndarray, top: int, left: int, colour) -> None:
    """Blend ``colour`` into ``image [H, W, 3]`` uint8 with coverage ``alpha`` placed at row
    ``top``, column ``left`` (the part inside the image)."""
    h, w = alpha.shape
    r0, c0 = max(top, 0), max(left, 0)
    r1, c1 = min(top + h, image.shape[0]), min(left + w, image.shape[1])
    if r1 <= r0 or c1 <= c0:
        return
    a = alpha[r0 - top : r1 - top, c0 - left : c1 - left, None]
    region = image[r0:r1, c0:c1].astype(np.float32)
    colour = np.asarray(colour, dtype=np.float32)
    image[r0:r1, c0:c1] = (region * (1 - a) + colour * a + 0.5).astype(np.uint8)


def draw_text(
    image: np.ndarray,
    text: str,
    x: float,
    y: float,
    points: float,
    dpi: float,
    ha: str = "left",
    va: str = "center",
    colour=(0, 0, 0),
) -> int:
    """Draw one line of ``text`` into ``image`` at pixel ``(x, y)`` (column, row from the top),
    aligned ``ha`` (``left``, ``center``, ``right``) and ``va`` (``top``: the bitmap's top;
    ``center``; ``baseline``). Returns its width in pixels."""
    alpha, baseline = text_alpha(text, points, dpi)
    h, w = alpha.shape
    left = {"left": x, "center": x - w / 2, "right": x - w}[ha]
    top = {"top": y, "center": y - h / 2, "baseline": y - baseline}[va]
    blend_text(image, alpha, int(round(top)), int(round(left)), colour)
    return w


@dataclass(frozen=True)
class MapFrame:
    """The pixels of one kind of map that never change, and where the rest goes: ``pixels``
    ``[H, W, 3]`` uint8, the frame (legend, colorbar gradient and label); ``box`` ``(x0, y0, x1,
    y1)``, the map axes' box in pixels (columns; rows from the top); ``inner`` ``(row0, row1,
    col0, col1)``, the map's pixels; ``colorbar``, the colorbar axes' box as ``box``, or
    ``None`` (the greedy-option map); ``title`` ``(x, y)``, where the title's lines are centred
    and its top; ``dpi``, pixels per inch (text sizes are in points); ``font``, the text's
    size in points (matplotlib's ``"medium"``)."""

    pixels: np.ndarray
    box: tuple[float, float, float, float]
    inner: tuple[int, int, int, int]
    colorbar: tuple[float, float, float, float] | None
    title: tuple[float, float]
    dpi: float
    font: float
