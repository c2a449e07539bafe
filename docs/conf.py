"""Sphinx configuration of the himit_torch documentation (``make docs`` builds it).

Sphinx + furo + myst-nb: the API reference comes from the docstrings (which are reStructuredText,
so autodoc reads them as they are), the pages are Markdown, and the notebooks render with the
outputs they are committed with. ``make docs`` builds with ``-W --keep-going`` and
``nitpicky``: a broken link between pages, an unknown page, a cross-reference to a name that is
not documented, or an exported name without a docstring fails the build.
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))  # the package of this checkout, not an installed copy
sys.path.insert(0, str(DOCS / "_ext"))

import himit_torch  # noqa: E402

project = "himit_torch"
author = "the himit_torch authors"
copyright = "2026, the himit_torch authors"
release = himit_torch.__version__
version = release

extensions = [
    "myst_nb",  # Markdown pages (myst-parser) and notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",  # the docstrings' "Args:" / "Returns:" sections
    "sphinx.ext.mathjax",
    # MathJax 3 from the site's own _static/mathjax (the PyPI package bundles it; it sets
    # mathjax_path), not from a CDN: the math renders offline (make docs-check checks it).
    "sphinx-mathjax-offline",
    "sphinx.ext.viewcode",
    "himit_docs",  # docs/_ext: the public API, the settings tables and the CLI's --help
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "_screenshots", "Thumbs.db", ".DS_Store", "**.ipynb_checkpoints"]
root_doc = "index"

# ----------------------------------------------------------------------------------- MyST
myst_enable_extensions = ["dollarmath", "amsmath", "deflist", "colon_fence", "attrs_inline"]
myst_heading_anchors = 3  # [text](page.md#a-heading) links are checked like any other
# Notebooks are shown with the outputs they are committed with (notebooks/build_notebooks.py
# --execute writes them); the build never runs them.
nb_execution_mode = "off"

# -------------------------------------------------------------------------- cross-references
# Every reference to a Python object must resolve to a documented one. Objects of other
# libraries are not linked (no intersphinx: CI has no network to fetch their inventories), so
# they are named here rather than flagged.
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(torch|np|numpy|numba|scipy|gymnasium|gym|nx|networkx|matplotlib|plt|ray)(\..*)?"),
    (r"py:.*", r"(Tensor|Generator|ndarray|NDArray|Axes|Figure|Path|PathLike|Env|Callable)"),
    (r"py:.*", r"(collections\.abc|typing|pathlib|os|dataclasses|argparse|enum|types)\..*"),
    (r"py:.*", r"(Any|Sequence|Mapping|Iterable|Iterator|Literal|NamedTuple|Self|NoReturn)"),
    (r"py:.*", r"(optional|default|callable|array_like|array-like)"),
    # the type variable of a study's own configuration class (runs.study), not a class
    (r"py:class", r"himit_torch\.runs\.study\.Config"),
]

# --------------------------------------------------------------------------------- autodoc
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_preserve_defaults = True
autodoc_class_signature = "mixed"
# sphinx.ext.autosummary (himit_docs sets it up) makes the API pages' tables of names, from the
# entries the pages already have: no stub pages generated.
autosummary_generate = False
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False

# ---------------------------------------------------------------------------------- output
html_theme = "furo"
html_title = f"himit_torch {release}"
html_static_path: list[str] = []
