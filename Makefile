# boom_hydraulics: two commands for a newcomer (see README).
#   make run    set up if needed, then run the node with the default scenario
#   make test   set up if needed, check the import floors, then run the whole test suite
#   make mutants MODULE=model/friction.py [TESTS="test/..."]   mutation testing of one module
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
WITH_ENV := tools/with-env

DEPS_STAMP := $(VENV)/.boom-deps-stamp
BUILD_STAMP := install/.boom-build-stamp
BUILD_INPUTS := $(shell find src -path '*/__pycache__' -prune -o \( -name package.xml -o \
	-name CMakeLists.txt -o -name '*.msg' -o -name '*.srv' -o -name '*.action' -o -name setup.py -o \
	-name setup.cfg -o -name '*.launch.py' -o -name '*.urdf' -o -name '*.rviz' -o -name '*.json' \) -print) \
	$(wildcard config/*.yaml) \
	tools/build tools/cmake/drop_missing_include_dirs.cmake

# the package's modules byte-compiled (see the rule)
PY_SOURCES := $(shell find src -path '*/__pycache__' -prune -o -name '*.py' -print)
BYTECODE_STAMP := install/.boom-bytecode-stamp

# the compiled model in numba's on-disk cache (tools/warm-up): again when a source the kernels
# compile or the default configuration changed, or when the cache folder the stamp names is
# gone (a cleared ~/.cache)
WARM_STAMP := install/.boom-warm-stamp
PACKAGE := src/boom_hydraulics/boom_hydraulics
KERNEL_SOURCES := $(wildcard $(PACKAGE)/model/*.py $(PACKAGE)/solve/*.py) $(PACKAGE)/jit.py config/default.yaml
CACHE_THERE := $(shell read -r folder 2>/dev/null < $(WARM_STAMP) && { [ "$$folder" = none ] || [ -d "$$folder" ]; } && echo yes)

.PHONY: setup run node test lint imports bench mutants clean FORCE

setup: $(BUILD_STAMP) $(BYTECODE_STAMP) $(WARM_STAMP)

$(DEPS_STAMP): requirements.txt requirements-nodeps.txt constraints.txt
	@test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --disable-pip-version-check -q \
		-r requirements.txt -c constraints.txt
	$(VENV)/bin/python -m pip install --disable-pip-version-check -q --no-deps \
		-r requirements-nodeps.txt
	@touch $@

$(BUILD_STAMP): $(DEPS_STAMP) $(BUILD_INPUTS)
	tools/build
	@touch $@

# the package's modules byte-compiled beside their sources (src/**/__pycache__, which the
# symlinked install imports): where Python may not write them itself (PYTHONDONTWRITEBYTECODE,
# set in many containers and CI images), each program would compile every module it imports
# again at its start, 0.16 s of a boom-sweep's 0.84 s (bench/results/history.md). Only what changed
# is compiled again; a module edited since is compiled afresh at import, as always.
$(BYTECODE_STAMP): $(BUILD_STAMP) $(PY_SOURCES)
	$(VENV)/bin/python -m compileall -q src
	@touch $@

# compiles before the first run, so that the node starts at once (it writes the stamp itself)
$(WARM_STAMP): $(BUILD_STAMP) $(KERNEL_SOURCES) $(if $(CACHE_THERE),,FORCE)
	$(WITH_ENV) python tools/warm-up --stamp $@

FORCE:

run: setup
	$(WITH_ENV) boom-demo --params-file config/default.yaml

node: setup
	$(WITH_ENV) boom_sim --ros-args --params-file config/default.yaml

# The floors' import contract first, then the suite on every core: a worker per core and one
# more (many node tests wait on a node's clock, and the extra worker runs a test meanwhile),
# each test file on one worker (its module fixtures made once), the compiled kernels built once before
# the workers start (test/conftest.py).
TEST_WORKERS := $(shell echo $$(( $$(nproc) + 1 )))
test: setup imports
	$(WITH_ENV) python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=25 test

lint: setup imports
	$(WITH_ENV) ruff check src test bench
	$(WITH_ENV) ruff format --check src test bench

# the floors of the package never loop back (.importlinter); before the tests, so CI checks it
imports: setup
	$(WITH_ENV) lint-imports --no-cache

bench: setup
	$(WITH_ENV) python bench/bench_model.py

# Mutation testing of one module (tools/mutants; docs/architecture.md, "Mutation testing"): not
# part of test or CI. The tester, cosmic-ray, in a venv of its own (its pins are not the project's);
# nice, one mutant at a time.
MUTANTS_VENV := .venv-mutants
MUTANTS_STAMP := $(MUTANTS_VENV)/.boom-mutants-stamp
$(MUTANTS_STAMP): requirements-mutants.txt
	@test -x $(MUTANTS_VENV)/bin/python || $(PYTHON) -m venv $(MUTANTS_VENV)
	$(MUTANTS_VENV)/bin/python -m pip install --disable-pip-version-check -q --no-deps -r requirements-mutants.txt
	@touch $@

mutants: $(BUILD_STAMP) $(BYTECODE_STAMP) $(MUTANTS_STAMP)
	nice -n 15 $(WITH_ENV) python tools/mutants --tester $(MUTANTS_VENV)/bin \
		$(if $(TIMEOUT),--timeout $(TIMEOUT)) -- "$(MODULE)" $(TESTS)

clean:
	rm -rf build install log $(VENV) $(MUTANTS_VENV)
	find src -name __pycache__ -type d -prune -exec rm -rf {} +
