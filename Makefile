# attica: `make run` (demo) and `make test` (everything) work from a fresh clone.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
ATTICA := $(VENV)/bin/attica
STAMP := $(VENV)/.installed

.PHONY: all setup deps build run test lint pytest bench clean

all: build

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	@touch $(STAMP)

setup: $(STAMP)

deps:
	@bash host/tools/install-system-deps.sh

build: setup
	$(PY) -m attica._build

run: build
	$(ATTICA) demo --duration 60

lint: setup
	$(VENV)/bin/ruff check host tests docs
	$(VENV)/bin/ruff format --check host tests docs
	$(VENV)/bin/mypy

pytest: build
	$(VENV)/bin/pytest -q

test: deps build lint pytest

bench: deps build
	$(PY) -m attica.bench

clean:
	rm -rf build host/attica/_native*.so host/attica/_native.stamp .pytest_cache .mypy_cache .ruff_cache
