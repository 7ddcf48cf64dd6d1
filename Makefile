# daskrad — `make help` lists the targets.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
SCENE ?= scenes/cornell_box.obj
OUT ?= out/cornell_box.exr
WORKERS ?=

.DEFAULT_GOAL := help
.PHONY: help install test lint bench stress run clean

help: ## list the targets
	@grep -E '^[a-z]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-9s %s\n", $$1, $$2}'

# The venv is rebuilt when pyproject.toml changes (the stamp is older than it).
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

# numba's on-disk cache does not notice an edit to a kernel that another file's kernel calls
# (docs/stack.md), so every cached kernel is dropped whenever a kernel file is newer than this stamp.
KERNELS := $(wildcard daskrad/kernels/*.py)
NUMBA_STAMP := $(VENV)/.kernels
$(NUMBA_STAMP): $(KERNELS) $(STAMP)
	find daskrad -name '*.nbi' -delete -o -name '*.nbc' -delete
	touch $@

# Compile every numba kernel into its on-disk cache once (daskrad warmup: 100-120 s on a
# 2-core machine), so the first run after an install or a kernel edit is not a silent
# compile; it runs again after $(NUMBA_STAMP) dropped the cache.
WARM_STAMP := $(VENV)/.warm
$(WARM_STAMP): $(NUMBA_STAMP)
	$(BIN)/daskrad warmup
	touch $@

install: $(STAMP) $(WARM_STAMP) ## create .venv, install daskrad (editable) with test tools, compile

test: $(NUMBA_STAMP) ## run the test suite (fast cases; the long stress cases are `make stress`)
	$(BIN)/python -m pytest -q -m "not slow"

lint: $(STAMP) ## ruff and the import-linter layering contracts
	$(BIN)/ruff check daskrad tests benchmarks
	$(BIN)/lint-imports

bench: $(WARM_STAMP) ## run the benchmarks; tables on stdout, JSON in benchmarks/results/
	$(BIN)/python -m benchmarks

stress: $(NUMBA_STAMP) ## the numerical stress suite (long cases included) and its report table
	$(BIN)/python -m pytest -q tests/test_stress.py
	$(BIN)/python -m benchmarks.bench_stress

run: $(WARM_STAMP) ## render the bundled Cornell box (SCENE=, OUT=, WORKERS=N to change)
	mkdir -p $(dir $(OUT))
	$(BIN)/daskrad run $(SCENE) -o $(OUT) $(if $(WORKERS),--workers $(WORKERS))

clean: ## remove the venv, caches and outputs
	rm -rf $(VENV) out .pytest_cache .hypothesis
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
