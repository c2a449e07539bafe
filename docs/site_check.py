"""What the built site's checks share: read every page of the site and report what a check
finds in each (``check_offline.py``, ``check_tracker_words.py``)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path


def check_site(
    argv: list[str],
    name: str,
    find: Callable[[str], list[str]],
    found: str,
    clean: str,
    more: Callable[[Path], list[str]] | None = None,
    shown: int | None = None,
) -> int:
    """Run ``find`` over the text of every page of the site (``argv[1]``, default
    ``docs/_build/html``) and print what it found, ``"<page>: <item>"`` (``more(site)``: further
    problems of the site's other files). Returns the process status: 1 if anything was found or
    there is no page, else 0. ``found``/``clean``: the report's words after the count of problems
    or of pages; ``shown``: at most that many problems listed."""
    site = Path(argv[1]) if len(argv) > 1 else Path(__file__).resolve().parent / "_build" / "html"
    pages = sorted(site.rglob("*.html"))
    if not pages:
        print(f"{name}: no .html under {site} (build the docs first: make docs)")
        return 1
    problems = [
        f"{page.relative_to(site)}: {item}"
        for page in pages
        for item in find(page.read_text(encoding="utf-8", errors="replace"))
    ]
    problems += more(site) if more else []
    if problems:
        print(f"{name}: {len(problems)} {found}:")
        print("\n".join(f"  {p}" for p in problems[:shown]))
        return 1
    print(f"{name}: {len(pages)} pages {clean}")
    return 0
