"""Open built pages in headless Chromium and check that MathJax typeset their math, that the
presets page shows its table, and that a tutorial, the ``Learner`` API page and a results page
render with their figures.

``make docs-check`` runs it after ``make docs``. Each page (default: ``index.html`` and
``concepts.html`` of ``docs/_build/html``) is opened from its file with ``chromium --headless
--dump-dom``, with a proxy that goes nowhere, so nothing outside the site can load even on a
machine with a network: the math must be typeset by the site's own ``_static/mathjax``. The
page passes when every math element Sphinx wrote (``class="math"``) holds a ``<mjx-container>``
and no raw TeX delimiter (``\\(``, ``\\[``) is left in the text of the math. A failure names the
page and what is wrong, and the script exits with status 1.

    python docs/browser_check.py [--site docs/_build/html] [--chromium chromium] [page.html ...]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path

PAGES = ("index.html", "concepts.html")
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    # every http(s) request goes to a closed local port: only file:// loads
    "--proxy-server=http://127.0.0.1:9",
    "--virtual-time-budget=10000",
)
RAW_TEX = ("\\(", "\\[")
VOID = {"area", "base", "br", "col", "embed", "hr", "img", "input", "link", "meta", "source"}


class _MathScanner(HTMLParser):
    """The math elements of a page: for each, whether it holds an <mjx-container>, and the
    text it shows outside of MathJax's output."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.maths: list[dict[str, object]] = []
        self._stack: list[tuple[str, bool]] = []  # (tag, opens a math element)
        self._math_depth = 0  # > 0: inside a math element
        self._mjx_depth = 0  # > 0: inside MathJax's output

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag in VOID:
            return
        classes = (dict(attrs).get("class") or "").split()
        opens_math = "math" in classes and self._math_depth == 0
        if opens_math:
            self.maths.append({"typeset": False, "raw": ""})
        self._stack.append((tag, opens_math))
        if opens_math or self._math_depth:
            self._math_depth += 1
        if tag == "mjx-container" or self._mjx_depth:
            self._mjx_depth += 1
            if self._math_depth:
                self.maths[-1]["typeset"] = True

    def handle_endtag(self, tag: str) -> None:
        if tag in VOID or not any(open_tag == tag for open_tag, _ in self._stack):
            return
        while self._stack:
            open_tag, _ = self._stack.pop()
            self._math_depth = max(self._math_depth - 1, 0) if self._math_depth else 0
            self._mjx_depth = max(self._mjx_depth - 1, 0) if self._mjx_depth else 0
            if open_tag == tag:
                break

    def handle_data(self, data: str) -> None:
        if self._math_depth and not self._mjx_depth:
            self.maths[-1]["raw"] = str(self.maths[-1]["raw"]) + data


def problems_of(dom: str) -> list[str]:
    """What is wrong with the math of a page's rendered DOM (empty: all typeset).

    >>> problems_of('<p><span class="math">\\\\(x\\\\)</span></p>')
    ['math 1 of 1 not typeset: \\\\(x\\\\)', 'math 1 of 1 shows raw TeX: \\\\(x\\\\)']
    >>> problems_of('<div class="math"><mjx-container><mjx-math>x</mjx-math></mjx-container></div>')
    []
    """
    scanner = _MathScanner()
    scanner.feed(dom)
    scanner.close()
    out = []
    total = len(scanner.maths)
    for i, math in enumerate(scanner.maths, 1):
        raw = " ".join(str(math["raw"]).split())
        if not math["typeset"]:
            out.append(f"math {i} of {total} not typeset: {raw[:80]}")
        if any(delim in raw for delim in RAW_TEX):
            out.append(f"math {i} of {total} shows raw TeX: {raw[:80]}")
    return out


#: The presets page's table must show a column per preset (the page a reader is sent to for
#: "why each setting").
PRESET_PAGE = "presets.html"
PRESET_COLUMNS = ("paper", "explore-goals", "mentor-fade", "recommended")


class _TableHeaders(HTMLParser):
    """The header cells (``<th>``) of each ``<table>`` of a page, as text."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tables: list[list[str]] = []
        self._in_th = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "table":
            self.tables.append([])
        elif tag == "th" and self.tables:
            self._in_th = True
            self.tables[-1].append("")

    def handle_endtag(self, tag: str) -> None:
        if tag == "th":
            self._in_th = False

    def handle_data(self, data: str) -> None:
        if self._in_th:
            self.tables[-1][-1] += data.strip()


def preset_table_problems(dom: str) -> list[str]:
    """What is wrong with the presets page's rendered table (empty: a table has a column per
    preset, and no reStructuredText shows as text).

    >>> preset_table_problems('<table><tr><th>setting</th><th>paper</th><th>explore-goals</th>'
    ...     '<th>mentor-fade</th><th>recommended</th></tr></table>')
    []
    >>> preset_table_problems('<p>.. list-table::</p>')
    ['no table with the columns paper, explore-goals, mentor-fade, recommended', 'raw reST shown: .. list-table::']
    """
    scanner = _TableHeaders()
    scanner.feed(dom)
    scanner.close()
    out = []
    if not any(all(c in headers for c in PRESET_COLUMNS) for headers in scanner.tables):
        out.append(f"no table with the columns {', '.join(PRESET_COLUMNS)}")
    if ".. list-table::" in dom:
        out.append("raw reST shown: .. list-table::")
    return out


#: Pages a reader opens first, beyond the math pages: each must render with its title, and
#: every figure it shows must be an image with a width (the file a browser would load).
FIGURE_PAGES = ("tutorials/quickstart.html", "reference/api/learner.html",
                "results/benchmark/results.html")  # fmt: skip


class _Images(HTMLParser):
    """The ``src`` of every ``<img>`` of a page, and whether it has an ``<h1>``."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.sources: list[str] = []
        self.titled = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "img":
            self.sources.append(dict(attrs).get("src") or "")
        self.titled |= tag == "h1"


def image_width(data: bytes) -> int:
    """The width in pixels of a PNG, JPEG or GIF image, or of an SVG's ``width``/``viewBox``
    (0: not an image a browser could draw).

    >>> image_width(bytes.fromhex("89504e470d0a1a0a0000000d4948445200000280000001e0"))
    640
    >>> image_width(b"not an image")
    0
    """
    import re
    import struct

    if data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) >= 24:
        return int(struct.unpack(">I", data[16:20])[0])
    if data[:6] in (b"GIF87a", b"GIF89a"):
        return int(struct.unpack("<H", data[6:8])[0])
    if data[:2] == b"\xff\xd8":
        i = 2
        while i + 9 < len(data):
            marker, size = data[i + 1], struct.unpack(">H", data[i + 2 : i + 4])[0]
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                return int(struct.unpack(">H", data[i + 7 : i + 9])[0])
            i += 2 + size
        return 0
    text = data[:4096].decode("utf-8", "replace")
    if "<svg" in text:
        m = re.search(r'width="([0-9.]+)|viewBox="[-0-9. ]*? [-0-9.]+ ([0-9.]+)', text)
        return int(float(m.group(1) or m.group(2))) if m else 0
    return 0


def figure_problems(dom: str, page: Path) -> list[str]:
    """What keeps a rendered page's figures from showing: a page without a title, an image
    whose file is missing or is no image."""
    import base64
    from urllib.parse import unquote

    scanner = _Images()
    scanner.feed(dom)
    scanner.close()
    out = [] if scanner.titled else ["no <h1>: the page did not render"]
    for src in scanner.sources:
        if src.startswith("data:"):
            data = base64.b64decode(src.split(",", 1)[1]) if ";base64," in src else b""
        else:
            path = (page.parent / unquote(src.split("#")[0].split("?")[0])).resolve()
            data = path.read_bytes() if path.is_file() else b""
        if image_width(data) <= 0:
            out.append(f"figure not shown: {src[:80]}")
    return out


def render(chromium: str, page: Path) -> str:
    """The page's DOM after its scripts ran, as headless Chromium dumps it."""
    result = subprocess.run(
        [chromium, *CHROMIUM_FLAGS, "--dump-dom", page.resolve().as_uri()],
        capture_output=True,
        text=True,
        timeout=60,
    )
    if result.returncode != 0 or "<html" not in result.stdout:
        sys.exit(
            f"browser_check: {chromium} failed on {page} (status {result.returncode}):\n"
            + result.stderr[-2000:]
        )
    return result.stdout


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    here = Path(__file__).resolve().parent
    parser.add_argument("--site", type=Path, default=here / "_build" / "html")
    parser.add_argument("--chromium", default=None, help="the browser (default: chromium)")
    parser.add_argument("pages", nargs="*", default=list(PAGES))
    args = parser.parse_args(argv)
    chromium = args.chromium or shutil.which("chromium") or shutil.which("chromium-headless-shell")
    if not chromium:
        print("browser_check: no chromium on PATH (apt-get install chromium)")
        return 1
    failures = []
    for name in args.pages:
        page = args.site / name
        if not page.is_file():
            failures.append(f"{name}: no such page under {args.site} (run make docs first)")
            continue
        built = _MathScanner()
        built.feed(page.read_text(encoding="utf-8"))
        if not built.maths:
            failures.append(f"{name}: no math in the built page, nothing to check")
            continue
        dom = render(chromium, page)
        problems = problems_of(dom)
        typeset = dom.count("<mjx-container")
        failures += [f"{name}: {p}" for p in problems[:6]]
        if len(problems) > 6:
            failures.append(f"{name}: … and {len(problems) - 6} more")
        if not problems:
            print(f"browser_check: {name}: {len(built.maths)} math elements, {typeset} typeset")
    presets = args.site / PRESET_PAGE
    if not presets.is_file():
        failures.append(f"{PRESET_PAGE}: no such page under {args.site}")
    else:
        problems = preset_table_problems(render(chromium, presets))
        failures += [f"{PRESET_PAGE}: {p}" for p in problems]
        if not problems:
            print(f"browser_check: {PRESET_PAGE}: the presets table shows a column per preset")
    for name in FIGURE_PAGES:
        page = args.site / name
        if not page.is_file():
            failures.append(f"{name}: no such page under {args.site}")
            continue
        dom = render(chromium, page)
        problems = figure_problems(dom, page)
        failures += [f"{name}: {p}" for p in problems]
        if not problems:
            shown = dom.count("<img")
            print(f"browser_check: {name}: renders, {shown} figure(s) shown")
    if failures:
        print("browser_check: the built site does not show what a reader needs offline:")
        print("\n".join(f"  {f}" for f in failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
