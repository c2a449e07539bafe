"""Check that no page of the built site cites the project's issue tracker (``make docs`` runs it).

A reader of the site has no tracker to follow "issue 26" or "Issue 11, item 4" to: a page says
what it is, not where the work came from. Every ``.html`` under the build folder (default
``docs/_build/html``) is read as the text a reader sees (tags dropped, scripts and styles
skipped), and any ``issue N`` / ``issues N`` / ``issue #N`` fails the check, naming the page and
the words around it; the script then exits with status 1. (``tests/test_docs_text.py`` checks
the sources the same way before a build.)

    python docs/check_tracker_words.py [docs/_build/html]

>>> tracker_words("<h1>Issue 11, item 4: the box</h1>")
['Issue 11, item 4: the box']
>>> len(tracker_words("<p>See issues #8 and issue 22.</p>"))
2
>>> tracker_words("<p>an issue with 3 seeds</p><script>var issue = 1</script>")
[]
"""

from __future__ import annotations

import re
import sys
from html.parser import HTMLParser

from site_check import check_site  # (docs/, beside this script)

TRACKER = re.compile(r"\b[Ii]ssues? #?\d+")


class _Text(HTMLParser):
    """The text a reader sees: data outside ``<script>`` and ``<style>``."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.parts: list[str] = []
        self._skip = 0

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag in ("script", "style"):
            self._skip += 1

    def handle_endtag(self, tag: str) -> None:
        if tag in ("script", "style") and self._skip:
            self._skip -= 1

    def handle_data(self, data: str) -> None:
        if not self._skip:
            self.parts.append(data)


def tracker_words(html: str) -> list[str]:
    """The stretches of a page's visible text that cite an issue number (40 characters around
    each)."""
    scanner = _Text()
    scanner.feed(html)
    scanner.close()
    text = " ".join(" ".join(scanner.parts).split())
    return [text[max(m.start() - 40, 0) : m.end() + 40].strip() for m in TRACKER.finditer(text)]


def main(argv: list[str]) -> int:
    return check_site(
        argv,
        "check_tracker_words",
        lambda html: [f"…{words}…" for words in tracker_words(html)],
        "citation(s) of the issue tracker",
        "cite no issue numbers",
        shown=40,
    )


if __name__ == "__main__":
    sys.exit(main(sys.argv))
