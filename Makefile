# Two entry points, each doing its own set-up on a fresh machine:
#   make demo   — the main job (a short experiment-2 run: world, mentor demonstrations, figures)
#   make lint   — ruff (lint + format check), mypy and import-linter (the package's layers)
#   make test   — the fast test suite, on both cores (with Ray, the sweep extra: +250 MB, so the
#                 Ray test runs); make test-all adds the slow tests (long parity runs, 40×40, …)
#   make docs   — the documentation site into docs/_build/html (warnings as errors, references
#                 and links between pages checked), then the code examples of the docs and the
#                 docstrings run as tests; it installs the [docs] extra on first use
#   make docs-check — after make docs: key pages opened offline in headless
#                 Chromium (apt-get installs it if missing), their math typeset by MathJax
#   make wheel-check — python -m build, twine check, and the wheel installed in a fresh venv
#                 runs `himit --version`
# The virtual environment lives in .venv. torch is installed first, on its own, as the build
# named by TORCH_SPEC (default: torch==2.13.0, the CPU wheel on a CPU-only machine), so that the
# package's plain "torch" requirement never pulls a multi-GB CUDA stack by accident. If .venv
# already has a torch (e.g. a CUDA build you installed), it is kept.

PYTHON ?= python3
VENV ?= .venv
TORCH_SPEC ?= torch==2.13.0
BIN := $(VENV)/bin
STAMP := $(VENV)/.himit-installed
DOCS_STAMP := $(VENV)/.himit-docs-installed

.PHONY: demo test test-slow test-all lint bench install clean docs docs-check wheel-check

# Bytecode is cached (in __pycache__, ignored by git) even where the environment sets
# PYTHONDONTWRITEBYTECODE: without the cache each pytest process parses and rewrites the
# asserts of every test module again, ≈ 10 s of the ≈ 23 s a collection takes here.
unexport PYTHONDONTWRITEBYTECODE

# The install ends by compiling the compiled engine's kernels once for this environment, into
# their disk cache (13–14 s on a quiet machine): later processes, tests included, only load them.
$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -c "import torch" 2>/dev/null || $(BIN)/python -m pip install --quiet "$(TORCH_SPEC)"
	$(BIN)/python -m pip install --quiet -e ".[dev,sweep,analysis,minigrid]"
	$(BIN)/python -m himit_torch.runs.kernels
	touch $(STAMP)

install: $(STAMP)

# the [docs] extra on top of the development install (make docs, make wheel-check)
$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[dev,sweep,analysis,minigrid,docs]"
	touch $(DOCS_STAMP)

demo: $(STAMP)
	$(BIN)/himit demo

# pytest-xdist: PYTEST_WORKERS processes (default 2, the cores CI has; "0" runs in this process).
PYTEST_WORKERS ?= 2
PYTEST := $(BIN)/python -m pytest -q -n $(PYTEST_WORKERS)

test: $(STAMP)
	$(PYTEST)

# ruff (lint rules and format check), mypy and import-linter, configured in pyproject.toml.
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/lint-imports

# the slow tests but the multi-seed statistical ones and the extended ones (CI runs make test,
# then this; docs/development.md says what each marker holds)
test-slow: $(STAMP)
	$(PYTEST) -m "slow and not statistical and not extended" --durations=15

test-all: $(STAMP)
	$(PYTEST) -m "slow or not slow"

# -W --keep-going: every warning fails the build, all of them reported. -n (nitpicky): a
# cross-reference to a name that is not documented is a warning too, and MyST warns on a link to
# a page or heading that does not exist, so the internal links are checked here (the linkcheck
# builder would check the external ones, which CI cannot reach). -E: a fresh read of every page,
# so the generated reference pages follow the code. Then the examples: the docs' pages and the
# README (--doctest-glob) and the package's docstrings (--doctest-modules). docs/check_offline.py:
# no page loads a script, stylesheet, font, image or frame from outside the site (MathJax is
# served from _static/mathjax, by sphinx-mathjax-offline). docs/check_tracker_words.py: no page
# cites an issue number (a reader has no tracker). The old site is removed first, so no stale
# page (e.g. a source listing of a module since renamed) is checked or published.
SPHINX_OPTS ?= -W --keep-going -n -E -q
docs: $(DOCS_STAMP)
	rm -rf docs/_build/html
	$(BIN)/python -m sphinx -b html $(SPHINX_OPTS) docs docs/_build/html
	$(BIN)/python docs/check_offline.py docs/_build/html
	$(BIN)/python docs/check_tracker_words.py docs/_build/html
	$(BIN)/python -m pytest -q -p no:cacheprovider -n 0 -m "" --doctest-modules \
		--doctest-glob="*.md" --ignore=docs/_build --ignore=docs/_ext --ignore=docs/conf.py \
		himit_torch docs README.md

# The built site in a real browser, offline: headless Chromium (Debian's, installed with apt-get
# if missing; CI runs as root) opens index.html and concepts.html from their files, with every
# http(s) request sent nowhere, and docs/browser_check.py fails unless MathJax typeset all their
# math, that presets.html shows its table with a column per preset, and that a tutorial, the
# Learner API page and the benchmark's results page render with every figure an image with a
# width. Run after make docs (it does not rebuild the site).
docs-check:
	command -v chromium >/dev/null || (apt-get update -q && apt-get install -y -q chromium)
	$(PYTHON) docs/browser_check.py --site docs/_build/html index.html concepts.html

# The wheel and sdist (python -m build), their metadata (twine check --strict), then the wheel
# installed with its dependencies into a fresh venv (torch first, as TORCH_SPEC: the CPU wheel
# on a CPU-only machine) runs `himit --version` from that venv, not from this checkout.
WHEEL_VENV ?= build/wheel-check-venv
wheel-check: $(DOCS_STAMP)
	rm -rf dist $(WHEEL_VENV)
	$(BIN)/python -m build --outdir dist .
	$(BIN)/python -m twine check --strict dist/*
	$(PYTHON) -m venv $(WHEEL_VENV)
	$(WHEEL_VENV)/bin/python -m pip install --quiet "$(TORCH_SPEC)"
	$(WHEEL_VENV)/bin/python -m pip install --quiet dist/*.whl
	cd $(WHEEL_VENV) && bin/himit --version
	cd $(WHEEL_VENV) && bin/python -c "import himit_torch, sys; \
		assert himit_torch.__file__.startswith(sys.prefix), himit_torch.__file__"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_learner.py

clean:
	rm -rf $(VENV) runs .pytest_cache docs/_build dist build
