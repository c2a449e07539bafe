# Two entry points, each doing its own set-up on a fresh machine:
#   make demo   — the main job (a short experiment-2 run: world, mentor demonstrations, figures)
#   make lint   — ruff (lint + format check), mypy and import-linter (the package's layers)
#   make test   — the fast test suite, on both cores (with Ray, the sweep extra: +250 MB, so the
#                 Ray test runs); make test-all adds the slow tests (long parity runs, 40×40, …)
# The virtual environment lives in .venv. torch is installed first, on its own, as the build
# named by TORCH_SPEC (default: torch==2.13.0, the CPU wheel on a CPU-only machine), so that the
# package's plain "torch" requirement never pulls a multi-GB CUDA stack by accident. If .venv
# already has a torch (e.g. a CUDA build you installed), it is kept.

PYTHON ?= python3
VENV ?= .venv
TORCH_SPEC ?= torch==2.13.0
BIN := $(VENV)/bin
STAMP := $(VENV)/.himit-installed

.PHONY: demo test test-slow test-all lint bench install clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -c "import torch" 2>/dev/null || $(BIN)/python -m pip install --quiet "$(TORCH_SPEC)"
	$(BIN)/python -m pip install --quiet -e ".[dev,sweep]"
	touch $(STAMP)

install: $(STAMP)

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

# the slow tests but the multi-seed statistical ones (CI runs make test, then this)
test-slow: $(STAMP)
	$(PYTEST) -m "slow and not statistical" --durations=15

test-all: $(STAMP)
	$(PYTEST) -m "slow or not slow"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_learner.py

clean:
	rm -rf $(VENV) runs .pytest_cache
