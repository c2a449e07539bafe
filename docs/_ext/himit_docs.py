"""Directives that generate reference pages from the code at build time, so they never go stale:

* ``.. himit-api::`` — every name of ``himit_torch.__all__``, grouped as the comments in
  ``himit_torch/__init__.py`` group them, each with its docstring (autodoc). An exported name
  without a docstring is a warning, so ``make docs`` (``-W``) fails on it.
* ``.. himit-settings:: module.Class`` — every field of a configuration class declared with
  ``validation.setting`` (:func:`himit_torch.validation.settings_of`): type, default, range or
  choices, whether the compiled engine reads it, the CLI flag and its doc.
* ``.. himit-figures:: experiments/results/exp1/*.png`` — the committed figures of a results
  folder, each captioned with its path.
* ``.. himit-modules::`` — every module of the package, layer by layer (its docstring and the
  members the public API does not already show).
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


class ApiDirective(SphinxDirective):
    """Autodoc entries for every name of ``himit_torch.__all__``, in its groups."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        package = importlib.import_module(PACKAGE)
        rst: list[str] = [f".. py:currentmodule:: {PACKAGE}", ""]
        for title, names in exported_groups():
            heading = title[0].upper() + title[1:]
            rst += [heading, "-" * (len(heading) + 2), ""]
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
                            location=self.get_location(),
                        )
                        doc = ""
                    else:
                        doc = found[1]
                    # (an automodule above may have moved the current module)
                    rst += [f".. py:currentmodule:: {PACKAGE}", ""]
                    rst += [f".. py:data:: {name}", f"   :value: {value!r}", ""]
                    rst += ["   " + line if line else "" for line in doc.splitlines()] + [""]
        return _parse(self, rst)


def package_layers() -> list[str]:
    """The package's layers, top to bottom, as pyproject.toml's import-linter contract declares
    them (``"viz | learner"`` is two), so this page follows the contract that CI checks."""
    import tomllib

    pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
    contracts = tomllib.loads(pyproject.read_text())["tool"]["importlinter"]["contracts"]
    layers = next(c["layers"] for c in contracts if c["type"] == "layers")
    return [name.strip() for layer in layers for name in layer.split("|")]


class ModulesDirective(SphinxDirective):
    """Every module of the package, layer by layer: its docstring and its public members but
    those exported by ``himit_torch`` (documented once, in the public API) and those named in
    ``:elsewhere:`` (``module.Name``, documented on another page)."""

    option_spec = {"elsewhere": lambda text: text.split()}

    def run(self) -> list[nodes.Node]:
        elsewhere = self.options.get("elsewhere", [])
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


class PresetsDirective(SphinxDirective):
    """The presets (``himit_torch.learner.presets``): each one's summary, then a table of every
    field any preset sets, with each preset's value and its reason."""

    def run(self) -> list[nodes.Node]:
        from himit_torch.learner.presets import PRESETS

        rst: list[str] = []
        for preset in PRESETS.values():
            rst += [f"``{preset.name}``", f"   {preset.summary}", ""]
        fields = list(dict.fromkeys(f for p in PRESETS.values() for f in p.settings))
        rst += [".. list-table::", "   :header-rows: 1", "   :widths: 16 42 42", ""]
        rst += ["   * - field"] + [f"     - ``{name}``" for name in PRESETS]
        for field in fields:
            rst.append(f"   * - ``{field}``")
            for preset in PRESETS.values():
                value, why = preset.settings.get(field, (None, "not set"))
                rst.append(f"     - ``{value!r}``: {why}")
        rst.append("")
        return _parse(self, rst)


class CliDirective(SphinxDirective):
    """``himit --help`` and each subcommand's ``--help``, each in a section of its own."""

    def run(self) -> list[nodes.Node]:
        from himit_torch.cli import build_parser

        old = os.environ.get("COLUMNS")
        os.environ["COLUMNS"] = "100"  # argparse wraps to the terminal: a fixed width here
        try:
            parser = build_parser()
            helps = [("himit", parser.format_help())]
            subparsers = next(
                a for a in parser._actions if isinstance(a, argparse._SubParsersAction)
            )
            for name, sub in subparsers.choices.items():
                helps.append((f"himit {name}", sub.format_help()))
        finally:
            if old is None:
                del os.environ["COLUMNS"]
            else:
                os.environ["COLUMNS"] = old
        rst: list[str] = []
        for title, text in helps:
            label = "cli-" + title.replace(" ", "-")  # :ref:`cli-himit-sweep`
            rst += [f".. _{label}:", "", f"``{title}``", "-" * (len(title) + 6), "", "::", ""]
            rst += [textwrap.indent(line, "   ") if line else "" for line in text.splitlines()]
            rst += [""]
        return _parse(self, rst)


class FiguresDirective(SphinxDirective):
    """The committed figures matching a glob (relative to the repository root), in name order,
    each captioned with its file name: a results page shows what its folder holds, and a figure
    added or removed there shows up here without an edit. A glob matching nothing is a
    warning."""

    required_arguments = 1
    option_spec = {"width": str}

    def run(self) -> list[nodes.Node]:
        root = Path(self.env.srcdir).parent
        files = sorted(root.glob(self.arguments[0]))
        if not files:
            logger.warning(
                f"himit-figures: no file matches {self.arguments[0]}", location=self.get_location()
            )
        docdir = (Path(self.env.srcdir) / self.env.docname).parent
        out: list[nodes.Node] = []
        for path in files:
            figure = nodes.figure()
            image = nodes.image(uri=os.path.relpath(path, docdir), alt=path.name)
            image["width"] = self.options.get("width", "85%")
            figure += image
            figure += nodes.caption(text=str(path.relative_to(root)))
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


def setup(app: Sphinx) -> dict[str, Any]:
    GoogleDocstring._parse_attribute_docstring = _attribute_docstring_as_text  # type: ignore[method-assign]
    app.add_directive("himit-api", ApiDirective)
    app.add_directive("himit-settings", SettingsDirective)
    app.add_directive("himit-cli", CliDirective)
    app.add_directive("himit-presets", PresetsDirective)
    app.add_directive("himit-modules", ModulesDirective)
    app.add_directive("himit-figures", FiguresDirective)
    app.connect("autodoc-process-docstring", warn_undocumented)
    app.connect("missing-reference", resolve_exported)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
