"""The documentation reads as a reference, not as a work log: no page says where its work came
from on the project's tracker ("issue 11, item 4"), which a reader does not have; and the
presets page's table is a real table (built as docutils nodes, which a MyST page renders).

Checked: every Markdown page under docs/ (the built site excluded), every file those pages
include (the committed results pages, the protocols, the changelog: found from the ``{include}``
directives, so a page added there is checked too) and the package's sources, whose docstrings
the API reference renders. No allow-list: the changelog is history, but it names releases and
changes, not tracker numbers, and it is a page of the site like any other."""

import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
TRACKER = re.compile(r"\b[Ii]ssues? #?\d+")
INCLUDE = re.compile(r"^(?:```|:::)\{include\}\s+(\S+)", re.M)


def _pages() -> list[Path]:
    return sorted(p for p in DOCS.rglob("*.md") if "_build" not in p.relative_to(DOCS).parts)


def _checked_files() -> list[Path]:
    files = set(_pages())
    for page in _pages():
        for target in INCLUDE.findall(page.read_text(encoding="utf-8")):
            files.add((page.parent / target).resolve())
    files |= set((ROOT / "himit_torch").rglob("*.py"))
    return sorted(files)


def test_includes_are_found():
    """The walk reaches the included results pages (else the check below checks too little)."""
    checked = {p.relative_to(ROOT).as_posix() for p in _checked_files()}
    assert "experiments/results/mechanism/results.md" in checked
    assert "benchmarks/results.md" in checked
    assert "CHANGELOG.md" in checked


def test_no_tracker_numbers_on_public_pages():
    hits = []
    for path in _checked_files():
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if TRACKER.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not hits, "tracker numbers a reader cannot look up:\n" + "\n".join(hits)


def test_presets_table_is_a_table():
    pytest.importorskip("sphinx")
    from docutils import nodes

    from himit_torch.learner.presets import PRESETS

    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        from himit_docs import presets_table
    finally:
        sys.path.remove(str(DOCS / "_ext"))

    table = presets_table(PRESETS)
    assert isinstance(table, nodes.table)
    head, body = table.next_node(nodes.thead), table.next_node(nodes.tbody)
    header = [entry.astext() for entry in head.next_node(nodes.row).children]
    assert header == ["setting", *PRESETS, "reason"]
    assert {"paper", "explore-goals", "mentor-fade", "recommended"} <= set(header)
    fields = {f for p in PRESETS.values() for f in p.settings}
    rows = {row.children[0].astext(): row for row in body.children}
    assert set(rows) == fields
    # a value that differs from the paper's is told apart (bold), with the reason for it
    fade = rows["mentor_fade"]
    cells = [entry.astext() for entry in fade.children]
    assert cells[1:6] == ["None", "None", "20.0", "20.0", "20.0"]
    assert fade.children[3].next_node(nodes.strong) is not None
    assert fade.children[1].next_node(nodes.strong) is None
    # the reasons, by the presets that take each value: subgoal-mentor's fading has its own
    assert "mentor-fade, recommended (20.0)" in cells[-1]
    assert "subgoal-mentor (20.0)" in cells[-1]


def test_layout_table_is_generated_from_the_layers_and_docstrings():
    """The development page's layout table is generated (``{himit-layout}``), not written by
    hand: every module of the package has a row, in the order of the layers contract, with the
    first sentence of its docstring."""
    pytest.importorskip("sphinx")
    import importlib

    from docutils import nodes

    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        from himit_docs import contract_layers, layout_rows, layout_table, module_summary
    finally:
        sys.path.remove(str(DOCS / "_ext"))

    page = (DOCS / "development.md").read_text(encoding="utf-8")
    assert "```{himit-layout}" in page
    assert not re.search(r"^\| `learner/`", page, re.M)  # the hand-written table is gone
    rows = layout_rows()
    package = ROOT / "himit_torch"
    modules = set()
    for path in package.rglob("*.py"):
        parts = path.relative_to(package).with_suffix("").parts
        modules.add(
            "/".join(parts[:-1]) + "/" if parts[-1] == "__init__" else "/".join(parts) + ".py"
        )
    modules.discard("/")  # the package itself
    assert sorted(path for _, path, _ in rows) == sorted(modules)  # each once
    assert all(summary.endswith(".") for _, _, summary in rows)
    # the layers in the contract's order, each named on its first row
    labels = [label for label, _, _ in rows if label]
    assert labels == [" | ".join(layer) for layer in contract_layers()]
    assert module_summary("himit_torch.learner.inspect").startswith("The read-only views")
    learner = next(i for i, (_, path, _) in enumerate(rows) if path == "learner/learner.py")
    assert rows[learner][2] == module_summary("himit_torch.learner.learner")
    assert importlib.import_module("himit_torch.learner.learner").__doc__.startswith(
        rows[learner][2].rstrip(".")
    )
    table = layout_table()
    assert isinstance(table, nodes.table)
    body = table.next_node(nodes.tbody)
    assert len(body.children) == len(rows)
    # roles become the name they point to, as code: no cross-reference out of its module
    assert not any(":class:" in row.astext() or "``" in row.astext() for row in body.children)


def test_built_presets_page_has_the_table():
    """After ``make docs``: the page holds a real table naming the presets."""
    page = DOCS / "_build" / "html" / "presets.html"
    if not page.exists():
        pytest.skip("the docs are not built (make docs)")
    html = page.read_text(encoding="utf-8")
    assert "<table" in html
    assert "list-table" not in html
    table = html[html.index("<table") : html.index("</table>")]
    for name in ("paper", "explore-goals", "mentor-fade", "recommended", "subgoal-mentor"):
        assert name in table


def test_source_pages_draw_furos_navigation_tree_once_per_depth(monkeypatch):
    """The ≈ 90 ``_modules/…`` source pages share their navigation tree (one per depth of the
    page, its links being relative) within a build; every other page draws its own."""
    pytest.importorskip("sphinx")
    import types

    calls: list[str] = []

    def draw(context):
        calls.append(context["pagename"])
        return f"tree seen from {context['pagename'].count('/')} folders down"

    furo = types.ModuleType("furo")
    furo._compute_navigation_tree = draw  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "furo", furo)
    sys.path.insert(0, str(DOCS / "_ext"))
    try:
        from himit_docs import _navigation_of_source_pages_drawn_once
    finally:
        sys.path.remove(str(DOCS / "_ext"))
    _navigation_of_source_pages_drawn_once()
    tree = furo._compute_navigation_tree  # type: ignore[attr-defined]
    pages = ["concepts", "concepts", "_modules/himit_torch/cli", "_modules/himit_torch/rng"]
    pages += ["_modules/himit_torch/runs/pool", "_modules/himit_torch/runs/sweep"]
    trees = [tree({"pagename": p}) for p in pages]
    # one draw per depth of the source pages
    assert calls == ["concepts", "concepts", "_modules/himit_torch/cli", pages[4]]
    assert trees == [f"tree seen from {p.count('/')} folders down" for p in pages]
    # a second set-up (a new build in this process) wraps furo's own function, with its own
    # store: it draws the source pages' trees again
    _navigation_of_source_pages_drawn_once()
    assert furo._himit_draw_navigation is draw  # type: ignore[attr-defined]
    calls.clear()
    furo._compute_navigation_tree({"pagename": "_modules/himit_torch/rng"})  # type: ignore[attr-defined]
    assert calls == ["_modules/himit_torch/rng"]
