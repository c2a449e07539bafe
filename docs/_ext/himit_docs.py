"""Directives that generate reference pages from the code at build time, so they never go stale:

* ``.. himit-api::`` — every name of ``himit_torch.__all__``, grouped as the comments in
  ``himit_torch/__init__.py`` group them, each with its docstring (autodoc). An exported name
  without a docstring is a warning, so ``make docs`` (``-W``) fails on it.
* ``.. himit-settings:: module.Class`` — every field of a configuration class declared with
  ``validation.setting`` (:func:`himit_torch.validation.settings_of`): type, default, range or
  choices, whether the compiled engine reads it, the CLI flag and its doc.
* ``.. himit-figures:: experiments/results/exp1/*.png`` — the committed figures of a results
  folder, each captioned in words (:func:`figure_caption`), with its file name.
* ``.. himit-modules::`` — every module of the package, layer by layer (its docstring and the
  members the public API does not already show).
* ``.. himit-layout::`` — the same layers and modules as one table, each module with the first
  sentence of its docstring (:func:`layout_table`; the development page's layout).
* ``.. himit-cli::`` — ``himit --help`` and every subcommand's ``--help``, from the parser the
  command itself uses (:func:`himit_torch.cli.build_parser`).
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import importlib
import inspect
import os
import re
import textwrap
from pathlib import Path
from typing import Any

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.ext.napoleon.docstring import GoogleDocstring
from sphinx.pycode import ModuleAnalyzer
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

logger = logging.getLogger(__name__)

PACKAGE = "himit_torch"


def exported_groups() -> list[tuple[str, list[str]]]:
    """``__all__`` of the package, split into the groups its ``# comment`` lines name."""
    package = importlib.import_module(PACKAGE)
    source = Path(inspect.getfile(package)).read_text(encoding="utf-8")
    tree = ast.parse(source)
    node = next(
        n
        for n in tree.body
        if isinstance(n, ast.Assign) and any(getattr(t, "id", "") == "__all__" for t in n.targets)
    )
    lines = source.splitlines()[node.lineno - 1 : node.end_lineno]
    groups: list[tuple[str, list[str]]] = []
    for line in lines:
        comment = re.match(r"\s*#\s*(.+)", line)
        if comment:
            groups.append((comment.group(1).strip(), []))
            continue
        for name in re.findall(r"\"(\w+)\"", line):
            if not groups:
                groups.append(("other", []))
            groups[-1][1].append(name)
    listed = {n for _, names in groups for n in names}
    unlisted = [n for n in package.__all__ if n not in listed]  # e.g. added by `__all__ += …`
    if unlisted:
        groups.append(("other", unlisted))
    return groups


def _defining_module(name: str, value: Any) -> tuple[str, str] | None:
    """The module whose ``#:`` comment documents the constant ``name``, and that comment."""
    package = importlib.import_module(PACKAGE)
    for modname in sorted(_submodules(package)):
        module = importlib.import_module(modname)
        if getattr(module, name, None) is not value:
            continue
        try:
            docs = ModuleAnalyzer.for_module(modname).find_attr_docs()
        except Exception:  # a module without source
            continue
        doc = docs.get(("", name))
        if doc:
            return modname, "\n".join(doc).strip()
    return None


def _submodules(package: Any) -> list[str]:
    root = Path(inspect.getfile(package)).parent
    out = []
    for path in root.rglob("*.py"):
        parts = path.relative_to(root.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out.append(".".join(parts))
    return out


#: The pages of the public API (``docs/reference/api/<name>.rst``), one per subpackage: an
#: exported name goes to the page of the subpackage that defines it; ``runs`` and
#: ``statistics`` export nothing from ``himit_torch``, so their pages show their modules' own
#: ``__all__``.
API_PAGES = ("worlds", "options", "exact", "mentor", "learner", "runs", "statistics", "viz")


def _defined_in(name: str, value: Any) -> str:
    """The module that defines the exported ``name``."""
    if inspect.ismodule(value):
        return value.__name__
    if inspect.isclass(value) or callable(value):
        return value.__module__
    found = _defining_module(name, value)
    return found[0] if found else PACKAGE


def _page_of(modname: str) -> str:
    return modname.split(".")[1] if modname.count(".") else ""


def _page_modules(page: str) -> list[str]:
    """The modules of a page without exported names (``runs``, ``statistics``), in name order."""
    package = importlib.import_module(PACKAGE)
    if not (Path(inspect.getfile(package)).parent / page).is_dir():
        return [f"{PACKAGE}.{page}"]
    return sorted(n for n in _submodules(package) if _page_of(n) == page)


def _module_names(modname: str, skip: set[str]) -> list[str]:
    """The names of ``modname.__all__`` that the module itself defines (not re-exports)."""
    module = importlib.import_module(modname)
    out = []
    for name in getattr(module, "__all__", []):
        if f"{modname}.{name}" in skip:
            continue
        value = getattr(module, name)
        if (inspect.isclass(value) or inspect.isfunction(value)) and value.__module__ != modname:
            continue
        out.append(name)
    return out


def _data_table(name: str, value: Any) -> list[str]:
    """A table for an exported constant whose repr is too long to read (``AGENTS``)."""
    if name != "AGENTS":
        return []
    from himit_torch.learner.agents import AgentVariant

    fields = AgentVariant._fields
    rst = [".. list-table::", "   :header-rows: 1", ""]
    rst += ["   * - agent"] + [f"     - {f}" for f in fields]
    for agent, variant in value.items():
        rst.append(f"   * - ``{agent}``")
        for f in fields:
            v = getattr(variant, f)
            text = "✓" if v is True else "" if v is False else f"``{v}``"
            rst.append(f"     - {text}")
    return rst + [""]


def _entries(directive: SphinxDirective, names: list[str]) -> list[str]:
    """Autodoc entries of exported names, under the name users write (``himit_torch.Name``)."""
    package = importlib.import_module(PACKAGE)
    rst: list[str] = [f".. py:currentmodule:: {PACKAGE}", ""]
    for name in names:
        value = getattr(package, name)
        if inspect.ismodule(value):
            rst += [f".. automodule:: {value.__name__}", "   :members:", ""]
        elif inspect.isclass(value):
            rst += [f".. autoclass:: {PACKAGE}.{name}", ""]
        elif callable(value):
            rst += [f".. autofunction:: {PACKAGE}.{name}", ""]
        else:
            found = _defining_module(name, value)
            if found is None:
                logger.warning(
                    f"himit-api: {PACKAGE}.{name} is exported but has no `#:` doc "
                    "comment where it is defined",
                    location=directive.get_location(),
                )
                doc = ""
            else:
                doc = found[1]
            table = _data_table(name, value)
            # (an automodule above may have moved the current module)
            rst += [f".. py:currentmodule:: {PACKAGE}", ""]
            rst += [f".. py:data:: {name}"]
            if not table and len(repr(value)) <= 120:  # a long repr is unreadable: left out
                rst += [f"   :value: {value!r}"]
            rst += [""]
            rst += ["   " + line if line else "" for line in doc.splitlines()] + [""]
            rst += ["   " + line if line else "" for line in table]
    return rst


def _summary(names: list[str]) -> list[str]:
    """An autosummary table of ``module.name`` entries (shown by their last component)."""
    if not names:
        return []
    return [".. autosummary::", "   :nosignatures:", ""] + [f"   ~{n}" for n in names] + [""]


class ApiSummaryDirective(SphinxDirective):
    """``.. himit-api-summary:: learner`` — an autosummary table of a page's names: the exported
    names the subpackage defines (``himit_torch.__all__``), else its modules' ``__all__``."""

    required_arguments = 1
    option_spec = {"elsewhere": lambda text: text.split()}

    def run(self) -> list[nodes.Node]:
        page = self.arguments[0]
        package = importlib.import_module(PACKAGE)
        mine = []
        for _, names in exported_groups():
            for name in names:
                value = getattr(package, name)
                home = _defined_in(name, value)
                if _page_of(home) == page:  # a module exported by name: its own path
                    mine.append(home if inspect.ismodule(value) else f"{home}.{name}")
        if not mine:
            skip = set(self.options.get("elsewhere", []))
            mine = [f"{m}.{n}" for m in _page_modules(page) for n in _module_names(m, skip)]
        if not mine:
            logger.warning(f"himit-api-summary: no names for {page}", location=self.get_location())
        # relative to the current module (autosummary refuses it repeated)
        mine = [n.removeprefix(PACKAGE + ".") for n in mine]
        return _parse(self, [f".. py:currentmodule:: {PACKAGE}", "", *_summary(mine)])


class ApiEntriesDirective(SphinxDirective):
    """``.. himit-api-entries:: learner`` — the entries of a page: the exported names the
    subpackage defines, grouped as the comments in ``himit_torch/__init__.py`` group them (a name
    in ``:skip:`` is documented by hand on the page); or, for a subpackage that exports nothing
    (``runs``), each of its modules with a table of its ``__all__`` and its members (but those
    in ``:elsewhere:``, ``module.Name``, documented on another page). An exported name without a
    docstring is a warning, so ``make docs`` (``-W``) fails on it."""

    required_arguments = 1
    option_spec = {
        "skip": lambda text: [t.strip() for t in text.split(",")],
        "elsewhere": lambda text: text.split(),
    }

    def run(self) -> list[nodes.Node]:
        page = self.arguments[0]
        package = importlib.import_module(PACKAGE)
        skip = set(self.options.get("skip", []))
        rst: list[str] = []
        for title, names in exported_groups():
            mine = [
                n
                for n in names
                if _page_of(_defined_in(n, getattr(package, n))) == page and n not in skip
            ]
            if not mine:
                continue
            heading = title[0].upper() + title[1:]
            rst += [heading, "-" * (len(heading) + 2), ""]
            rst += _entries(self, mine)
        if not rst:
            elsewhere = set(self.options.get("elsewhere", []))
            for modname in _page_modules(page):
                heading = f"``{modname}``"
                rst += [heading, "-" * len(heading), ""]
                rst += [f".. py:currentmodule:: {modname}", ""]
                own = _module_names(modname, elsewhere)
                rst += _summary(own)
                rst += [f".. automodule:: {modname}", "   :members:", "   :undoc-members:"]
                excluded = [n.rpartition(".")[2] for n in elsewhere if n.startswith(modname + ".")]
                if excluded:
                    rst += [f"   :exclude-members: {', '.join(excluded)}"]
                rst += [""]
        if not rst:
            logger.warning(f"himit-api-entries: no names for {page}", location=self.get_location())
        return _parse(self, rst)


def contract_layers() -> list[list[str]]:
    """The package's layers, top to bottom, as pyproject.toml's import-linter contract declares
    them: each a list of its sibling subpackages or modules (``"viz | learner"`` is two)."""
    import tomllib

    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    contracts = tomllib.loads(pyproject.read_text())["tool"]["importlinter"]["contracts"]
    layers = next(c["layers"] for c in contracts if c["type"] == "layers")
    return [[name.strip() for name in layer.split("|")] for layer in layers]


def package_layers() -> list[str]:
    """The package's layers, top to bottom, as pyproject.toml's import-linter contract declares
    them (``"viz | learner"`` is two), so this page follows the contract that CI checks."""
    return [name for layer in contract_layers() for name in layer]


#: A sentence's end in a docstring: a full stop before a capital (not ``e.g. x``, ``Fig. 2``).
_SENTENCE_END = re.compile(r"\.\s+(?=[A-Z])")
#: The inline markup of a docstring's summary: ````literal```` or ``:role:`target```.
_INLINE = re.compile(r"``(?P<literal>.+?)``|:[\w:]+:`(?P<role>[^`]+)`")


def module_summary(modname: str) -> str:
    """The first sentence of a module's docstring (its first paragraph, up to a full stop
    before a capital); empty if it has none."""
    doc = inspect.getdoc(importlib.import_module(modname)) or ""
    paragraph = " ".join(doc.strip().split("\n\n")[0].split())
    return _SENTENCE_END.split(paragraph, maxsplit=1)[0].rstrip(".") + ("." if paragraph else "")


def _inline(text: str) -> list[nodes.Node]:
    """``text`` with its reST inline markup as docutils nodes, roles shown as the literal name
    they point to (``:class:`~a.b.C``` → ``C``): the same in a MyST page as in a reST one, and no
    cross-reference to resolve out of its module's context."""
    out: list[nodes.Node] = []
    at = 0
    for found in _INLINE.finditer(text):
        if found.start() > at:
            out.append(nodes.Text(text[at : found.start()]))
        if found.group("literal") is not None:
            code = found.group("literal")
        else:
            role = found.group("role")
            titled = re.fullmatch(r"(.+?)\s*<.+>", role)
            code = titled.group(1) if titled else role
            if code.startswith("~"):
                code = code.rpartition(".")[2]
            code = code.lstrip(".")
        out.append(nodes.literal(code, code))
        at = found.end()
    if at < len(text):
        out.append(nodes.Text(text[at:]))
    return out


def _module_path(modname: str) -> str:
    """``himit_torch.learner.engines`` → ``learner/engines/``; a module → ``runs/bench.py``."""
    module = importlib.import_module(modname)
    parts = modname.split(".")[1:]
    if Path(inspect.getfile(module)).name == "__init__.py":
        return "/".join(parts) + "/"
    return "/".join(parts) + ".py"


def layout_rows() -> list[tuple[str, str, str]]:
    """``(layer, module path, summary)`` for every module of the package, layer by layer top to
    bottom as the import-linter contract declares them (:func:`contract_layers`), each layer's
    package first and its modules in name order; the layer is given on its first row only
    (``"viz | learner"`` for siblings of one layer)."""
    package = importlib.import_module(PACKAGE)
    names = sorted(_submodules(package))
    rows: list[tuple[str, str, str]] = []
    for layer in contract_layers():
        label = " | ".join(layer)
        for name in layer:
            for modname in [n for n in names if n.split(".")[1:2] == [name]]:
                rows.append((label, _module_path(modname), module_summary(modname)))
                label = ""
    return rows


def layout_table() -> nodes.table:
    """The package's layout as a table: layer, module, what it holds (:func:`layout_rows`), built
    as docutils nodes (as :func:`presets_table` is), so that the development page's layout is
    generated from the same sources as the modules page — the layers contract in
    ``pyproject.toml`` and each module's docstring — and cannot go stale."""
    table = nodes.table(classes=["himit-layout"])
    group = nodes.tgroup(cols=3)
    table += group
    for width in (14, 30, 56):
        group += nodes.colspec(colwidth=width)

    def row(cells: list[list[nodes.Node]]) -> nodes.row:
        out = nodes.row()
        for content in cells:
            entry = nodes.entry()
            if content:
                entry += nodes.paragraph("", "", *content)
            out += entry
        return out

    head = nodes.thead()
    head += row([[nodes.Text(h)] for h in ("layer", "module", "what it holds")])
    group += head
    body = nodes.tbody()
    group += body
    for layer, path, summary in layout_rows():
        cells: list[list[nodes.Node]] = [
            [nodes.literal(layer, layer)] if layer else [],
            [nodes.literal(path, path)],
            _inline(summary),
        ]
        body += row(cells)
    return table


class LayoutDirective(SphinxDirective):
    """``.. himit-layout::`` — :func:`layout_table`. A module without a docstring, or in no layer
    of the contract, is a warning (so ``make docs``, ``-W``, fails on it)."""

    def run(self) -> list[nodes.Node]:
        package = importlib.import_module(PACKAGE)
        layers = package_layers()
        for modname in sorted(_submodules(package)):
            if modname == PACKAGE:
                continue
            if modname.split(".")[1] not in layers:
                logger.warning(
                    f"himit-layout: {modname} is in no layer of pyproject.toml's import-linter "
                    "contract",
                    location=self.get_location(),
                )
            elif not module_summary(modname):
                logger.warning(
                    f"himit-layout: {modname} has no docstring to say what it holds",
                    location=self.get_location(),
                )
        return [layout_table()]


class ModulesDirective(SphinxDirective):
    """Every module of the package, layer by layer: its docstring and its public members but
    those exported by ``himit_torch`` (documented once, in the public API) and those named in
    ``:elsewhere:`` (``module.Name``, documented on another page)."""

    option_spec = {
        "elsewhere": lambda text: text.split(),
        # layers whose modules have a page of their own in the API (``api/<layer>``)
        "paged": lambda text: text.split(),
    }

    def run(self) -> list[nodes.Node]:
        elsewhere = self.options.get("elsewhere", [])
        paged = self.options.get("paged", [])
        package = importlib.import_module(PACKAGE)
        exported = set(package.__all__)
        exported_modules = {
            getattr(package, n).__name__ for n in exported if inspect.ismodule(getattr(package, n))
        }
        names = sorted(_submodules(package))
        rst: list[str] = []
        layers = package_layers()
        placed = {n for n in names if n.split(".")[1:2] and n.split(".")[1] in layers}
        for modname in sorted(set(names) - placed - {PACKAGE}):
            logger.warning(
                f"himit-modules: {modname} is in no layer of pyproject.toml's import-linter "
                "contract",
                location=self.get_location(),
            )
        for layer in layers:
            members = [n for n in names if n.split(".")[1:2] == [layer]]
            heading = f"``{PACKAGE}.{layer}``"
            rst += [heading, "-" * len(heading), ""]
            if layer in paged:
                rst += [f"Every module of ``{PACKAGE}.{layer}``: :doc:`api/{layer}`.", ""]
                continue
            for modname in members:
                if modname in exported_modules:
                    rst += [f"``{modname}``: exported, see :mod:`{modname}` in :doc:`api`.", ""]
                    continue
                module = importlib.import_module(modname)
                own = [
                    n
                    for n in getattr(module, "__all__", [])
                    if (n in exported and getattr(package, n, None) is getattr(module, n))
                    or f"{modname}.{n}" in elsewhere
                ]
                rst += [f".. automodule:: {modname}", "   :members:", "   :undoc-members:"]
                if own:
                    rst += [f"   :exclude-members: {', '.join(own)}"]
                rst += [""]
        return _parse(self, rst)


def _type_text(s: Any) -> str:
    kind = s.kind.__name__ if isinstance(s.kind, type) else str(s.kind)
    if s.kind is tuple:
        kind = f"tuple[{s.item.__name__}, ...]"
    return f"{kind} | None" if s.optional else kind


def _range_text(s: Any) -> str:
    info = s.info
    parts = []
    for op, bound in (("≥", info.ge), (">", info.gt), ("≤", info.le), ("<", info.lt)):
        if bound is not None:
            parts.append(f"{op} {bound:g}")
    if info.choices:
        parts.append("one of " + ", ".join(f"``{c!r}``" for c in info.choices))
    return "; ".join(parts)


class SettingsDirective(SphinxDirective):
    """Each declared field of a configuration class: ``py:attribute`` entries (so that
    ``:attr:`LearnerConfig.mentor_fade``` links here) with type, default, range and doc."""

    required_arguments = 1  # module.Class
    option_spec = {
        "documented-as": lambda text: text.strip(),  # the class's documented name
        "cli": lambda text: text.strip(),  # the command whose flags set the fields
        "cli-skip": lambda text: [t.strip() for t in text.split(",")],  # fields without a flag
    }

    def run(self) -> list[nodes.Node]:
        from himit_torch.validation import settings_of

        modname, _, clsname = self.arguments[0].rpartition(".")
        cls = getattr(importlib.import_module(modname), clsname)
        module, _, name = self.options.get("documented-as", self.arguments[0]).rpartition(".")
        command = self.options.get("cli")
        skip = self.options.get("cli-skip", [])
        declared = settings_of(cls)
        if not declared:
            logger.warning(
                f"himit-settings: {cls} declares no settings", location=self.get_location()
            )
        rst = [f".. py:currentmodule:: {module}", ""]
        for s in declared:
            rst += [f".. py:attribute:: {name}.{s.name}", f"   :type: {_type_text(s)}"]
            rst += [f"   :value: {s.default!r}", ""]
            facts = [_range_text(s)] if _range_text(s) else []
            # the CLI makes a flag of every field but a nested configuration (cli.py)
            if command and s.name not in skip and not dataclasses.is_dataclass(s.kind):
                facts.append(f"``{command} --{s.name.replace('_', '-')}``")
            if s.info.kernel:
                facts.append("read by the compiled engine")
            if facts:
                rst += ["   " + "; ".join(facts), ""]
            rst += ["   " + line if line else "" for line in s.info.doc.splitlines()] + [""]
        return _parse(self, rst)


def _literal_paragraph(text: str) -> nodes.paragraph:
    return nodes.paragraph("", "", nodes.literal(text, text))


def presets_table(presets: Any) -> nodes.table:
    """A table of every field any of ``presets`` (name → ``Preset``) sets: a row per field, a
    column per preset with its value (a value that differs from the first preset's in bold), and
    the reasons — the first preset's, then each other value's, named by the presets that take it.
    Built as docutils nodes, so it renders the same in a MyST page as in a reST one."""
    names = list(presets)
    fields = list(dict.fromkeys(f for p in presets.values() for f in p.settings))
    table = nodes.table(classes=["himit-presets"])
    group = nodes.tgroup(cols=len(names) + 2)
    table += group
    for width in [16] + [10] * len(names) + [44]:
        group += nodes.colspec(colwidth=width)

    def row(cells: list[list[nodes.Node]]) -> nodes.row:
        out = nodes.row()
        for content in cells:
            entry = nodes.entry()
            entry.extend(content)
            out += entry
        return out

    head = nodes.thead()
    head += row(
        [[nodes.paragraph(text="setting")]]
        + [[_literal_paragraph(n)] for n in names]
        + [[nodes.paragraph(text="reason")]]
    )
    group += head
    body = nodes.tbody()
    group += body
    first = presets[names[0]]
    for field in fields:
        base = first.settings.get(field, (None, "not set"))
        cells: list[list[nodes.Node]] = [[_literal_paragraph(field)]]
        reasons: dict[tuple[str, str], list[str]] = {}
        for name in names:
            value, why = presets[name].settings.get(field, (None, "not set"))
            text = repr(value)
            literal: nodes.Node = nodes.literal(text, text)
            if (value, why) != base:
                literal = nodes.strong("", "", literal)
            cells.append([nodes.paragraph("", "", literal)])
            reasons.setdefault((text, why), []).append(name)
        reason_nodes: list[nodes.Node] = []
        for (text, why), takers in reasons.items():
            label = ", ".join(takers) if len(reasons) > 1 else ""
            para = nodes.paragraph()
            if label:
                para += nodes.strong(text=f"{label} ({text}): ")
            para += nodes.Text(why)
            reason_nodes.append(para)
        cells.append(reason_nodes)
        body += row(cells)
    return table


class PresetsDirective(SphinxDirective):
    """The presets (``himit_torch.learner.presets``): each one's summary, then a table of every
    field any preset sets (:func:`presets_table`): its value under each preset and the reasons."""

    def run(self) -> list[nodes.Node]:
        from himit_torch.learner.presets import PRESETS

        summaries = nodes.definition_list()
        for preset in PRESETS.values():
            item = nodes.definition_list_item()
            item += nodes.term("", "", nodes.literal(preset.name, preset.name))
            item += nodes.definition("", nodes.paragraph(text=preset.summary))
            summaries += item
        return [summaries, presets_table(PRESETS)]


class CliDirective(SphinxDirective):
    """``himit --help`` and each subcommand's ``--help`` (each study of ``himit run`` too), each
    in a section of its own."""

    def run(self) -> list[nodes.Node]:
        from himit_torch.cli import build_parser

        old = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: a fixed width here
        try:
            helps: list[tuple[str, str]] = []
            todo = [("himit", build_parser())]
            while todo:  # each command, then its subcommands (himit run exp1, …) in order
                title, parser = todo.pop(0)
                helps.append((title, parser.format_help()))
                for action in parser._actions:
                    if isinstance(action, argparse._SubParsersAction):
                        todo += [(f"{title} {n}", sub) for n, sub in action.choices.items()]
        finally:
            if old is None:
                del os.environ["COLUMNS"]
            else:
                os.environ["COLUMNS"] = old
        rst: list[str] = []
        for title, text in helps:
            label = "cli-" + title.replace(" ", "-")  # :ref:`cli-himit-sweep`
            underline = "-" * (len(title) + 6)
            rst += [f".. _{label}:", "", f"``{title}``", underline, "", ".. code-block:: text", ""]
            rst += [textwrap.indent(line, "   ") if line else "" for line in text.splitlines()]
            rst += [""]
        return _parse(self, rst)


#: Captions in words for the committed figures, by file name (``{n}``: the world's size, from
#: a name ending in ``world<n>``). A name not matched here is captioned with its words.
FIGURE_CAPTIONS: tuple[tuple[str, str], ...] = (
    (r"fig2_world(\d+)", "The {n}×{n} world: the mentor's path and the imitator's greedy path"),
    (r"fig3_curves_world(\d+)", "Goals per window over learning on the {n}×{n} world, each agent"),
    (r"fig4_curves_world(\d+)", "Goals per window over learning on the {n}×{n} world, each agent"),
    (r"fig_curves_world(\d+)", "Goals per window over learning on the {n}×{n} world, each agent"),
    (r"fig5_scaling", "Total goals as a % of optimal by world size, each agent"),
    (r"first_goal_world(\d+)", "Steps to the first goal on the {n}×{n} world, each agent"),
    (r"first_goal_km_(\w+)", "Steps to the first goal (Kaplan–Meier), the {0} preset"),
    (r"curves_taxi", "Goals over learning on Gymnasium's Taxi, each agent"),
    (r"curves_cliffwalking", "Goals over learning on Gymnasium's CliffWalking, each agent"),
    (r"curves_frozenlake8x8", "Goals over learning on Gymnasium's FrozenLake 8×8, each agent"),
    (r"curves_exp(\d)", "Goals over learning, experiment {0}'s world, each agent"),
    (r"fig_exp(\d)_curves", "Goals over learning in experiment {0}, 20 seeds per cell"),
    (
        r"fig_exp3_scaling",
        "Experiment 3: the benefit of imitation by world size, 20 seeds per cell",
    ),
    (r"options_discovered_(\w+)_exp(\d)", "Options discovered, {0} agent, experiment {1}'s world"),
    (r"subgoals_exp(\d)", "The subgoals found from the mentor's states, experiment {0}'s world"),
    (r"hierarchy", "Does the hierarchy help? Eq. 2 against eq. 1 under the same settings"),
    (
        r"stress_(\w+)",
        "Experiment 2's world under the {0} stress: each method's greedy policy and first goal",
    ),
    (r"speed", "Puzzle box: openings over learning and the greedy policy's value, per agent"),
    (r"organisation", "Puzzle box: the organisation of the final plans, and over learning"),
    (
        r"transfer",
        "Puzzle box: 4-skewer demonstrations, a 5-skewer box: openings and value per agent",
    ),
)


def figure_caption(name: str) -> str:
    """A caption in words for the figure file ``name`` (``fig2_world40.png``): from
    :data:`FIGURE_CAPTIONS`, else the file name's words."""
    stem = Path(name).stem
    for pattern, text in FIGURE_CAPTIONS:
        found = re.fullmatch(pattern, stem)
        if found:
            words = [g.replace("_", " ") for g in found.groups()]
            return text.format(*words, n=words[0] if words else "")
    words = stem.replace("_", " ").replace("-", " ")
    return words[:1].upper() + words[1:]


class FiguresDirective(SphinxDirective):
    """The committed figures matching a glob (relative to the repository root), in name order,
    each captioned in words (:func:`figure_caption`) with its file name: a results page shows
    what its folder holds, and a figure added or removed there shows up here without an edit.
    ``:exclude:`` names files (comma-separated) the page already shows beside its text. A glob
    matching nothing is a warning."""

    required_arguments = 1
    option_spec = {
        "width": str,
        "exclude": lambda text: [t.strip() for t in text.split(",") if t.strip()],
    }

    def run(self) -> list[nodes.Node]:
        root = Path(self.env.srcdir).parent
        exclude = set(self.options.get("exclude", []))
        files = [p for p in sorted(root.glob(self.arguments[0])) if p.name not in exclude]
        if not files:
            logger.warning(
                f"himit-figures: no file matches {self.arguments[0]}", location=self.get_location()
            )
        docdir = (Path(self.env.srcdir) / self.env.docname).parent
        out: list[nodes.Node] = []
        for path in files:
            figure = nodes.figure()
            caption = figure_caption(path.name)
            image = nodes.image(uri=os.path.relpath(path, docdir), alt=caption)
            image["width"] = self.options.get("width", "85%")
            figure += image
            figure += nodes.caption(
                "", "", nodes.Text(caption + " "), nodes.literal(path.name, path.name)
            )
            out.append(figure)
        return out


def _parse(directive: SphinxDirective, rst: list[str]) -> list[nodes.Node]:
    node = nodes.section()
    node.document = directive.state.document
    source = directive.get_source_info()[0]
    content = StringList(rst, source=f"{source} (generated)")
    nested_parse_with_titles(directive.state, content, node)
    return node.children


def warn_undocumented(app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list[str]):
    """An exported name (or its module's documented member) without a docstring fails the
    build: autodoc would silently show only its signature."""
    package = importlib.import_module(PACKAGE)
    short = name.removeprefix(PACKAGE + ".")
    if short in package.__all__ and not any(line.strip() for line in lines):
        logger.warning(f"{name} is exported by {PACKAGE} but has no docstring")


def document_settings(
    app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list[str]
) -> None:
    """A configuration class declared with ``validation.setting`` (:class:`LearnerConfig`) gets
    each field's doc as a ``:param:`` (autodoc adds its type) and a link to the Settings page,
    which lists each field with its range and CLI flag. Not on the Settings page itself, which
    lists the fields as entries of their own."""
    from himit_torch.validation import Setting, settings_of

    if what != "class" or not dataclasses.is_dataclass(obj) or app.env.docname.endswith("settings"):
        return
    fields = dataclasses.fields(obj)  # type: ignore[arg-type]
    if not any(isinstance(v, Setting) for f in fields for v in f.metadata.values()):
        return
    declared = settings_of(obj)
    if not declared:
        return
    lines += [
        "",
        "Each field's range, default and ``himit run`` flag: :doc:`/reference/settings`.",
        "",
    ]
    for s in declared:
        doc = s.info.doc.splitlines() or [""]
        lines.append(f":param {s.name}: {doc[0]}")
        lines += ["   " + line if line.strip() else "" for line in doc[1:]]
    lines.append("")


def resolve_exported(app: Sphinx, env: Any, node: Any, contnode: Any) -> Any:
    """Resolve a reference to an exported object by the path where it is defined
    (``himit_torch.worlds.table_world.world_model``), or by its bare name from inside its module
    (``STIMULUS_FEATURES``, ``Demonstrations.save``), to its entry in the public API
    (``himit_torch.world_model``): each object is documented once, under the name users write.
    A name that matches no documented object, or several, stays a warning."""
    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    context = node.get("py:module") or ""
    if not (target.startswith(PACKAGE + ".") or context.startswith(PACKAGE)):
        return None
    domain = env.get_domain("py")
    parts = target.split(".")
    for start in range(len(parts) - 1, -1, -1):
        candidate = f"{PACKAGE}." + ".".join(parts[start:])
        if candidate in domain.objects:
            break
    else:
        # a bare name used inside its own module, whose docstring is shown under the exported
        # name (``ACTION_NAMES`` in ``MultiRooms``): the one documented object of that name
        found = [name for name in domain.objects if name.endswith("." + target)]
        if len(found) != 1:
            return None
        candidate = found[0]
    return domain.resolve_xref(
        env, node["refdoc"], app.builder, node["reftype"], candidate, node, contnode
    )


def _attribute_docstring_as_text(self: GoogleDocstring) -> list[str]:
    """Napoleon reads an attribute's docstring ``"text: more text"`` as ``"type: description"``
    (numpydoc's habit). The package's attribute docs are plain text (types are annotations), so
    here the whole docstring is the description."""
    lines = [self._lines.next(), *self._dedent(self._consume_to_end())]
    return self._format_field("", "", self.__class__(lines, self._config).lines())


def _navigation_of_source_pages_drawn_once() -> None:
    """Furo draws the whole navigation tree for every page, ≈ 0.5 s a page here; the ≈ 90
    source pages of ``sphinx.ext.viewcode`` (``_modules/…``) are in no toctree, so theirs
    differ only by the depth of the page's relative links: each depth's is drawn once per build
    (the same bytes; each build's set-up starts an empty store). Furo is pinned
    (pyproject.toml); without its private ``_compute_navigation_tree`` every page draws its
    own, as before."""
    import furo

    draw = getattr(furo, "_himit_draw_navigation", getattr(furo, "_compute_navigation_tree", None))
    if draw is None:
        return
    drawn: dict[int, str] = {}

    def navigation_tree(context: dict[str, Any]) -> str:
        page = context.get("pagename", "")
        if not page.startswith("_modules/"):
            return draw(context)
        depth = page.count("/")
        if depth not in drawn:
            drawn[depth] = draw(context)
        return drawn[depth]

    furo._himit_draw_navigation = draw  # (a second build in this process wraps the original)
    furo._compute_navigation_tree = navigation_tree


def setup(app: Sphinx) -> dict[str, Any]:
    GoogleDocstring._parse_attribute_docstring = _attribute_docstring_as_text  # type: ignore[method-assign]
    app.setup_extension("sphinx.ext.autosummary")  # the API pages' tables
    app.add_directive("himit-api-summary", ApiSummaryDirective)
    app.add_directive("himit-api-entries", ApiEntriesDirective)
    app.add_directive("himit-settings", SettingsDirective)
    app.add_directive("himit-cli", CliDirective)
    app.add_directive("himit-presets", PresetsDirective)
    app.add_directive("himit-modules", ModulesDirective)
    app.add_directive("himit-layout", LayoutDirective)
    app.add_directive("himit-figures", FiguresDirective)
    app.connect("autodoc-process-docstring", warn_undocumented)
    app.connect("autodoc-process-docstring", document_settings)
    app.connect("missing-reference", resolve_exported)
    _navigation_of_source_pages_drawn_once()
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
