"""Open built pages in headless Chromium and check that MathJax typeset their math, and that
the presets page shows its table.

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
    if failures:
        print("browser_check: the built site does not show what a reader needs offline:")
        print("\n".join(f"  {f}" for f in failures))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
