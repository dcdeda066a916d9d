# attica: `make run` (demo) and `make test` (everything) work from a fresh clone.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
ATTICA := $(VENV)/bin/attica
STAMP := $(VENV)/.installed
# development tooling (tools/attica_dev: golden, cross, footprint, bench) is not installed by pip
DEV := PYTHONPATH=tools$${PYTHONPATH:+:$$PYTHONPATH} $(PY)

.PHONY: all setup deps build node run test lint pytest bench clean docs-figures coverage

all: build

$(STAMP): pyproject.toml setup.py firmware/include/attica/att_version.h
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev,eval,peers,recordings,dask,view,foxglove]'
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
NODE_SRC := $(sort $(shell find firmware/src -name '*.c'))
NODE_HDR := $(wildcard firmware/include/attica/*.h) $(sort $(shell find firmware/src -name '*.h'))
NODE_PORT := $(wildcard firmware/ports/linux/*.c)

# the small node of docs/firmware-quickstart.md: ARS only, no stages, classic frames, rings of 8
NODE_SMALL_CONFIG := -DATT_WITH_MARS=0 -DATT_WITH_KF=0 -DATT_WITH_EKF=0 -DATT_WITH_GYRO=0 -DATT_WITH_TILT=0 \
  -DATT_WITH_MEKF=0 -DATT_WITH_CALIB=0 -DATT_NODE_WITH_FD=0 -DATT_NODE_RX_RING=8 -DATT_NODE_TX_RING=8

node: build/attica-node build/attica-node-small

build/attica-node: $(NODE_SRC) $(NODE_HDR) $(NODE_PORT) firmware/cflags.txt
	@mkdir -p build/node
	$(CC) $(NODE_CFLAGS) -std=gnu99 -Ifirmware/include -c $(NODE_PORT) -o build/node/port.o
	$(CC) $(NODE_CFLAGS) -Ifirmware/include $(NODE_SRC) build/node/port.o -o $@

build/attica-node-small: $(NODE_SRC) $(NODE_HDR) $(NODE_PORT) firmware/cflags.txt Makefile
	@mkdir -p build/node-small
	$(CC) $(NODE_CFLAGS) $(NODE_SMALL_CONFIG) -std=gnu99 -Ifirmware/include -c $(NODE_PORT) -o build/node-small/port.o
	$(CC) $(NODE_CFLAGS) $(NODE_SMALL_CONFIG) -Ifirmware/include $(NODE_SRC) build/node-small/port.o -o $@

run: build
	$(ATTICA) demo --duration 60
	@echo
	@echo "the same filter as a CAN node (the C node in-process on python-can's virtual bus):"
	$(ATTICA) verify --with-node --duration 10 --show 7 -q

lint: setup
	$(VENV)/bin/ruff check host tools tests docs examples
	$(VENV)/bin/ruff format --check host tools tests docs examples
	$(VENV)/bin/mypy

pytest: build
	$(VENV)/bin/pytest -q -n 2 --dist loadfile

test: deps build fuzz-deps lint pytest

# `make bench BENCH_ARGS="--clock cpu --repeat 15"`: options of python -m attica_dev.bench --help
bench: deps build
	$(DEV) -m attica_dev.bench $(BENCH_ARGS)

# Cortex-M (firmware/ports/cortex_m: M4F, M7, M33, M0+ under QEMU), attica beside Fusion and VQF (built
# from their sdists into build/peers), the figures of docs/performance.md. `make cycles PROFILE=ars,mars`
# adds the per-function instruction profile of those filters; CYCLES_ARGS passes more options
# (python -m attica_dev.cycles --help).
.PHONY: firmware footprint cycles cross
firmware: deps setup
	$(DEV) -m attica_dev.cross firmware

footprint: deps setup
	$(DEV) -m attica_dev.footprint

# The computed tables of docs/firmware-quickstart.md (flash, RAM, instructions, BROAD accuracy per kind;
# the quickstart node's size): python -m attica_dev.kind_table --update; docs/img/view.png, the screenshot of
# docs/view.md, made by the browser test of attica view (tests/test_view_browser.py)
docs-figures: deps build
	$(DEV) -m attica_dev.kind_table --update
	$(DEV) -m attica_dev.settings_doc --update
	ATTICA_DOCS_FIGURES=1 $(VENV)/bin/pytest -q -n 0 tests/test_view_browser.py -k demo_page

# C line and branch coverage of firmware/src from the test suite (an instrumented copy in build/coverage);
# COVERAGE_ARGS: options of python -m attica_dev.coverage --help. 26 minutes measured on this 2-core
# machine while other work ran.
coverage: deps setup
	$(DEV) -m attica_dev.coverage $(COVERAGE_ARGS)

cycles: deps setup
	$(DEV) -m attica_dev.cycles $(if $(PROFILE),--profile $(PROFILE)) $(CYCLES_ARGS)

# The golden comparison on every CPU as one table (the same checks as tests/test_cross.py).
cross: deps setup
	$(DEV) -m attica_dev.cross golden

# attica view under a 1 kHz node for 10 minutes (the test suite runs 20 s of it: tests/test_view_soak.py);
# VIEW_SOAK_SECONDS sets the length. It prints the figures of docs/view.md.
VIEW_SOAK_SECONDS ?= 600
.PHONY: view-soak
view-soak: build
	ATTICA_VIEW_SOAK_SECONDS=$(VIEW_SOAK_SECONDS) $(VENV)/bin/pytest -q -s -n 0 tests/test_view_soak.py

clean:
	rm -rf build dist host/attica/_native*.so host/attica/_live*.so host/attica/_native.stamp host/attica/_firmware host/*.egg-info \
		.pytest_cache .mypy_cache .ruff_cache

# --- robustness: fuzzing, sanitizers, soak (docs/robustness.md) ---------------------------------
# libFuzzer targets (clang): ASan+UBSan builds and a MemorySanitizer build of each C target; atheris
# for the host-side parsers. `make fuzz` runs every target FUZZ_TIME seconds (default 600) from the
# seed corpora (build/fuzz/seeds: made from the test streams, and the kept corpora of the long runs,
# tests/fuzz/corpus) into build/fuzz/corpus; the bounded CI slice is tests/test_fuzz.py.
FUZZ_CC ?= clang
FUZZ_TIME ?= 600
FUZZ_DIR := build/fuzz
FUZZ_TARGETS := fuzz_can fuzz_node fuzz_filter
FUZZ_FW_FLAGS := $(filter-out -fvisibility=hidden -Werror,$(shell cat firmware/cflags.txt)) -Wno-unknown-pragmas
FUZZ_ASAN := -g -O1 -fno-omit-frame-pointer -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all
FUZZ_MSAN := -g -O1 -fno-omit-frame-pointer -fsanitize=fuzzer,memory -fsanitize-memory-track-origins=2
FUZZ_HDR := $(wildcard tests/fuzz/*.h)

.PHONY: fuzz-build fuzz fuzz-deps soak soak-build
# atheris (the host parsers' fuzzer) is a test tool only: installed into the venv here, not a dependency
fuzz-deps: setup
	@$(PY) -c 'import atheris' 2>/dev/null || $(PY) -m pip install -q atheris
fuzz-build: $(FUZZ_TARGETS:%=$(FUZZ_DIR)/%) $(FUZZ_TARGETS:%=$(FUZZ_DIR)/%-msan)

FUZZ_HARNESS_FLAGS := -std=c11 -Wall -Wextra -Werror -Wno-unknown-pragmas -Ifirmware/include

# the firmware sources with the firmware's own flags, the harness with test flags; one link per target
$(FUZZ_DIR)/fw-asan.stamp $(FUZZ_DIR)/fw-msan.stamp: $(NODE_SRC) $(NODE_HDR) firmware/cflags.txt Makefile
	@mkdir -p $(FUZZ_DIR)/$(if $(findstring msan,$@),fw-msan,fw-asan)
	cd $(FUZZ_DIR)/$(if $(findstring msan,$@),fw-msan,fw-asan) && $(FUZZ_CC) $(FUZZ_FW_FLAGS) -Werror \
	  $(if $(findstring msan,$@),$(FUZZ_MSAN),$(FUZZ_ASAN)) -I$(CURDIR)/firmware/include \
	  $(addprefix $(CURDIR)/,$(NODE_SRC)) -c
	@touch $@

$(FUZZ_DIR)/%-msan: tests/fuzz/%.c $(FUZZ_HDR) $(FUZZ_DIR)/fw-msan.stamp
	$(FUZZ_CC) $(FUZZ_HARNESS_FLAGS) $(FUZZ_MSAN) $< $(FUZZ_DIR)/fw-msan/*.o -lm -o $@

$(FUZZ_DIR)/%: tests/fuzz/%.c $(FUZZ_HDR) $(FUZZ_DIR)/fw-asan.stamp
	$(FUZZ_CC) $(FUZZ_HARNESS_FLAGS) $(FUZZ_ASAN) $< $(FUZZ_DIR)/fw-asan/*.o -lm -o $@

fuzz: deps build fuzz-deps fuzz-build
	$(PY) tests/fuzz/campaign.py --time $(FUZZ_TIME)

# Soak (tests/soak/att_soak.c): SOAK_STEPS steps per filter kind (default 1e8; CI runs 1e7 through
# tests/test_soak.py), firmware built with its own flags at -O2.
SOAK_STEPS ?= 100000000
SOAK_DIR := build/soak
$(SOAK_DIR)/att_soak: tests/soak/att_soak.c $(NODE_SRC) $(NODE_HDR) firmware/cflags.txt
	@mkdir -p $(SOAK_DIR)/obj
	cd $(SOAK_DIR)/obj && $(CC) $(shell cat firmware/cflags.txt) -O2 -I$(CURDIR)/firmware/include \
	  $(addprefix $(CURDIR)/,$(NODE_SRC)) -c
	$(CC) -std=c99 -O2 -Wall -Wextra -Werror -Ifirmware/include $< $(SOAK_DIR)/obj/*.o -lm -o $@

soak-build: $(SOAK_DIR)/att_soak

soak: soak-build
	$(SOAK_DIR)/att_soak --steps $(SOAK_STEPS)

# Mutation testing of firmware/src (tools/attica_dev/mutate.py): every mutant (about 7,600: operators,
# comparisons, constants, deleted assignments) judged by the golden, node, config and core test programs
# and by the library under the digests and settings contracts; survivors listed with their reasons, the
# results in build/mutation/report.json. MUTATION_ARGS: --jobs 2, --files 'firmware/src/math/*',
# --sample N --seed S, --covered-only (python -m attica_dev.mutate --help). About 2.5 to 3 hours of one
# core (1.2 to 1.4 s a mutant), half with --jobs 2 on two free cores; the CI slice is tests/test_mutation.py.
.PHONY: mutation
mutation: deps setup
	$(DEV) -m attica_dev.mutate --json build/mutation/report.json $(MUTATION_ARGS)
