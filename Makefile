# attica: `make run` (demo) and `make test` (everything) work from a fresh clone.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
ATTICA := $(VENV)/bin/attica
STAMP := $(VENV)/.installed
# development tooling (tools/attica_dev: golden, cross, footprint, bench) is not installed by pip
DEV := PYTHONPATH=tools$${PYTHONPATH:+:$$PYTHONPATH} $(PY)

.PHONY: all setup deps build node run test lint pytest bench clean

all: build

$(STAMP): pyproject.toml setup.py firmware/include/attica/att_version.h
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev,eval,peers]'
	@touch $(STAMP)

setup: $(STAMP)

deps:
	@bash host/tools/install-system-deps.sh

# the cffi extension in place for this editable checkout (a wheel builds it through setup.py's hook)
build: setup node
	$(PY) -m attica._build

# attica-node: the CAN node on Linux SocketCAN (firmware core + firmware/ports/linux). The core is
# compiled with the strict firmware flags; the port needs -std=gnu99 for the socket headers.
NODE_CFLAGS := $(shell cat firmware/cflags.txt) -O2
NODE_SRC := $(wildcard firmware/src/*.c)
NODE_HDR := $(wildcard firmware/include/attica/*.h) $(wildcard firmware/src/*.h) $(wildcard firmware/can/gen/*)
NODE_PORT := $(wildcard firmware/ports/linux/*.c)

node: build/attica-node

build/attica-node: $(NODE_SRC) $(NODE_HDR) $(NODE_PORT) firmware/cflags.txt
	@mkdir -p build/node
	$(CC) $(NODE_CFLAGS) -std=gnu99 -Ifirmware/include -c $(NODE_PORT) -o build/node/port.o
	$(CC) $(NODE_CFLAGS) -Ifirmware/include $(NODE_SRC) build/node/port.o -o $@

run: build
	$(ATTICA) demo --duration 60
	@echo
	@echo "the same filter as a CAN node (the C node in-process on python-can's virtual bus):"
	$(ATTICA) verify --with-node --duration 10 --show 7 -q

lint: setup
	$(VENV)/bin/ruff check host tools tests docs
	$(VENV)/bin/ruff format --check host tools tests docs
	$(VENV)/bin/mypy

pytest: build
	$(VENV)/bin/pytest -q -n 2 --dist loadfile

test: deps build lint pytest

bench: deps build
	$(DEV) -m attica_dev.bench

# Cortex-M (firmware/ports/cortex_m: M4F, M7, M33, M0+ under QEMU), attica beside Fusion and VQF (built
# from their sdists into build/peers), the figures of docs/performance.md. `make cycles PROFILE=ars,mars`
# adds the per-function instruction profile of those filters; CYCLES_ARGS passes more options
# (python -m attica_dev.cycles --help).
.PHONY: firmware footprint cycles cross
firmware: deps setup
	$(DEV) -m attica_dev.cross firmware

footprint: deps setup
	$(DEV) -m attica_dev.footprint

cycles: deps setup
	$(DEV) -m attica_dev.cycles $(if $(PROFILE),--profile $(PROFILE)) $(CYCLES_ARGS)

# The golden comparison on every CPU as one table (the same checks as tests/test_cross.py).
cross: deps setup
	$(DEV) -m attica_dev.cross golden

clean:
	rm -rf build dist host/attica/_native*.so host/attica/_native.stamp host/attica/_firmware host/*.egg-info \
		.pytest_cache .mypy_cache .ruff_cache
