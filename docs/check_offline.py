"""Check that no page of the built site loads anything from outside it (``make docs`` runs it).

Every ``.html`` under the build folder (default ``docs/_build/html``) is read, and every
resource a browser would *load* — a script, a stylesheet, an icon or preload ``<link>``, an
image, a frame, a media source, an ``<object>``/``<embed>``, a ``url(…)`` in a ``style``
attribute or ``<style>`` block — must not point at ``http://``, ``https://`` or ``//``. Plain
``<a href>`` links to other sites are fine: the reader follows them, the page does not load
them. The site's own ``.css`` files are checked for ``url(…)`` and ``@import`` the same way.
A failure names the page and the URL, and the script exits with status 1.

    python docs/check_offline.py [docs/_build/html]

>>> external_loads('<script src="https://cdn.example/x.js"></script><a href="https://x.org">x</a>')
['<script src> https://cdn.example/x.js']
>>> external_loads('<link rel="stylesheet" href="//fonts.example/a.css"><img src="_static/a.png">')
['<link rel=stylesheet href> //fonts.example/a.css']
>>> external_loads('<link rel="canonical" href="https://example.org/"><div style="x: url(http://a/b.png)">')
['style url() http://a/b.png']
"""

from __future__ import annotations

import re
import sys
from html.parser import HTMLParser
from pathlib import Path

from site_check import check_site  # (docs/, beside this script)

EXTERNAL = re.compile(r"^\s*(https?:)?//", re.IGNORECASE)
CSS_URL = re.compile(r"""(?:url\(\s*|@import\s+)['"]?([^'")\s]+)""", re.IGNORECASE)

# the attributes through which these elements load something
LOADING_ATTRS = {
    "script": ("src",),
    "img": ("src", "srcset"),
    "iframe": ("src",),
    "frame": ("src",),
    "embed": ("src",),
    "object": ("data",),
    "source": ("src", "srcset"),
    "video": ("src", "poster"),
    "audio": ("src",),
    "track": ("src",),
    "input": ("src",),
    "image": ("href", "xlink:href"),  # SVG
    "use": ("href", "xlink:href"),  # SVG
}
# <link rel=…> values that make the browser fetch (or connect to) the href
LOADING_RELS = {
    "stylesheet",
    "icon",
    "shortcut",
    "apple-touch-icon",
    "mask-icon",
    "preload",
    "prefetch",
    "modulepreload",
    "preconnect",
    "dns-prefetch",
    "manifest",
}


def _urls(attr: str, value: str) -> list[str]:
    if attr == "srcset":  # "a.png 1x, b.png 2x"
        return [part.split()[0] for part in value.split(",") if part.strip()]
    return [value]


class _Scanner(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.found: list[str] = []
        self._in_style = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = {name: value or "" for name, value in attrs}
        names = list(LOADING_ATTRS.get(tag, ()))
        label = f"<{tag} {{}}>"
        if tag == "link":
            rels = set(values.get("rel", "").lower().split())
            if rels & LOADING_RELS:
                names = ["href"]
                label = f"<link rel={values['rel']} {{}}>"
        for name in names:
            for url in _urls(name, values.get(name, "")):
                if EXTERNAL.match(url):
                    self.found.append(f"{label.format(name)} {url.strip()}")
        for url in CSS_URL.findall(values.get("style", "")):
            if EXTERNAL.match(url):
                self.found.append(f"style url() {url}")
        self._in_style = tag == "style"

    def handle_endtag(self, tag: str) -> None:
        self._in_style = False

    def handle_data(self, data: str) -> None:
        if self._in_style:
            for url in CSS_URL.findall(data):
                if EXTERNAL.match(url):
                    self.found.append(f"<style> url() {url}")


def external_loads(html: str) -> list[str]:
    """The outside resources an HTML page loads, one ``"<tag attr> URL"`` string each."""
    scanner = _Scanner()
    scanner.feed(html)
    scanner.close()
    return scanner.found


def css_external_loads(css: str) -> list[str]:
    """The outside resources a stylesheet loads (``url(…)``, ``@import``)."""
    return [f"css url() {url}" for url in CSS_URL.findall(css) if EXTERNAL.match(url)]


def css_problems(site: Path) -> list[str]:
    """The outside resources the site's stylesheets load, ``"<file>: <item>"``."""
    return [
        f"{css.relative_to(site)}: {item}"
        for css in sorted(site.rglob("*.css"))
        for item in css_external_loads(css.read_text(encoding="utf-8", errors="replace"))
    ]


def main(argv: list[str]) -> int:
    return check_site(
        argv,
        "check_offline",
        external_loads,
        "resource(s) loaded from outside the site",
        "load nothing from outside the site",
        more=css_problems,
    )


if __name__ == "__main__":
    sys.exit(main(sys.argv))
