# Two commands on a fresh machine: `make run` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
HOST ?= 127.0.0.1
PORT ?= 8000
# Test processes: most tests wait on processes, browsers and the network, so three share a pair
# of cores well (measured from a fresh clone: 11:33 of pytest with three, 12:47 with two);
# `make test TEST_PROCESSES=0` runs them all in one.
TEST_PROCESSES ?= 3
export HOST PORT
# Python keeps the bytecode of what it imports here even where the environment says not to:
# pip compiles what it installs, but not this project's own sources or pytest's rewritten
# tests, which each of the tests' few hundred processes compiled anew (0.3 s a process, 6 s
# a test process's collection).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: run test test-fast hooks format compile-ahead lint typecheck pytest docs docs-check bench clean clean-compiled

PIP := $(BIN)/python -m pip install --quiet

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# What running needs, and on top of it what testing needs (pytest, ruff, mypy, psycopg).
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(PIP) -e .
	touch $@

# The `rl` extra's learners need torch: this exact version is a CPU build on these machines'
# disk, where a looser spec would download a CUDA one of several GB, so it goes in first.
$(VENV)/.installed-torch: | $(BIN)/python
	$(PIP) torch==2.13.0
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed $(VENV)/.installed-torch
	$(PIP) -e '.[test,rl]'
	touch $@

# A PostgreSQL DATABASE_URL needs the driver of the `postgres` extra; `make run TRAIN=1` the
# `rl` extra, for a worker that also trains networks (jobs of robots.policy ppo, recurrent_ppo).
RUN_DATABASE_URL := $(or $(NANONAV_DATABASE_URL),$(DATABASE_URL))
RUN_NEEDS := $(VENV)/.installed $(if $(filter postgres%,$(RUN_DATABASE_URL)),$(VENV)/.installed-postgres) $(if $(TRAIN),$(VENV)/.installed-rl)

$(VENV)/.installed-rl: $(VENV)/.installed $(VENV)/.installed-torch
	$(PIP) -e '.[rl]'
	touch $@

$(VENV)/.installed-postgres: $(VENV)/.installed
	$(PIP) -e '.[postgres]'
	touch $@

run: $(RUN_NEEDS)
	$(if $(TRAIN),NANONAV_WORKER_TRAINS=true) $(BIN)/python -m nanonav.run_local

# The checks side by side (each uses one core), then the tests (which use them all). The
# engine's kernels compile meanwhile, from as soon as NanoNav itself is installed: pip, which
# installs the test tools after it, and the checks leave a core idle most of that time.
test: $(VENV)/.installed
	$(MAKE) --no-print-directory -j4 --output-sync=target compile-ahead lint typecheck docs-check
	$(MAKE) --no-print-directory pytest

# numba's cache of the kernels the tests use (tests/compile_ahead.py); quick once it is full.
compile-ahead: $(VENV)/.installed
	$(BIN)/python -m tests.compile_ahead

lint: $(VENV)/.installed-test
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: $(VENV)/.installed-test
	$(BIN)/mypy

pytest: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n $(TEST_PROCESSES)

# The tests without real processes end to end, a browser or a benchmark's run: a few minutes
# while working (make test, and CI, run them all).
test-fast: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n $(TEST_PROCESSES) -m "not e2e and not browser and not benchmark"

# ruff and mypy before each commit (.pre-commit-config.yaml), with the tools `make test` runs.
hooks: $(VENV)/.installed-test
	$(BIN)/pre-commit install

# Formats the code and applies ruff's safe fixes, as `make test`'s lint then expects.
format: $(VENV)/.installed-test
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

# The documentation site: the reference pages are written from the code, then built into site/.
$(VENV)/.installed-docs: $(VENV)/.installed
	$(PIP) -e '.[docs]'
	touch $@

docs: $(VENV)/.installed-docs
	$(BIN)/python docs/_scripts/reference.py
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict

# In `make test`: a stale reference page or a broken link or anchor fails.
docs-check: $(VENV)/.installed-test
	$(BIN)/python docs/_scripts/reference.py --check
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet --site-dir $$(mktemp -d)

bench: $(VENV)/.installed
	$(BIN)/python benchmarks/engine.py
	$(BIN)/python benchmarks/cost.py
	$(BIN)/python benchmarks/service.py

clean: clean-compiled
	rm -rf $(VENV) var site .mypy_cache .ruff_cache .pytest_cache

# numba's cache of the compiled engine, kept by a digest of the engine's sources
# (nanonav/engine/compiled.py), and any left from before there was one.
clean-compiled:
	rm -rf nanonav/engine/__pycache__/compiled-*
	find nanonav -name '*.nbi' -delete -o -name '*.nbc' -delete
