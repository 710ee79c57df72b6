# refexmc developer entry points. Each target creates and uses the local virtual environment.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo smoke baseline test test-fast test-cuda test-cpus device-wheels mutate bench bench-campaign lint format clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev,dask,cuda]"
	touch $(STAMP)

## demo: the ReFEx Monte-Carlo study (000 sec. 6.2), 100 dispersed flights, and its summary
demo: $(STAMP)
	$(BIN)/refexmc run campaigns/refex-mc100.yaml -o runs/refex-mc100 --overwrite

## smoke: the CI smoke campaign (20 dispersed flights), its report and its comparison with baselines/smoke;
## exit 1 if a requirement fails or a gated statistic is significantly worse than the baseline (docs/compare.md):
## the requirement's fuel_remaining by 1 % of the tank, and, gated on purpose here, the attitude error at the
## end (ReFEx: at hand-over) by 0.1 deg and the valve openings by 50 per flight
SMOKE_TOLERANCES := --tolerance fuel_remaining=0.01 --tolerance attitude_error_end_deg=0.1 --tolerance pulses_total=50
smoke: $(STAMP)
	$(BIN)/refexmc run campaigns/smoke.yaml -o runs/smoke --overwrite --no-progress
	$(BIN)/refexmc report runs/smoke
	$(BIN)/refexmc compare baselines/smoke runs/smoke $(SMOKE_TOLERANCES)

## baseline: regenerate baselines/smoke (runs table in one part, manifest, resolved campaign; no histories). Run it on
## purpose when a change legitimately changes the flight results, and commit the new baseline with the change
baseline: $(STAMP)
	rm -rf runs/smoke-baseline
	REFEXMC_CHUNK_SIZE=1000 $(BIN)/refexmc run campaigns/smoke.yaml -o runs/smoke-baseline --no-progress
	rm -rf baselines/smoke
	mkdir -p baselines/smoke
	cp -R runs/smoke-baseline/runs runs/smoke-baseline/manifest.json runs/smoke-baseline/campaign.resolved.yaml \
		baselines/smoke/

## test: the test suite (what CI runs, with test-cuda and test-cpus), on TEST_WORKERS pytest-xdist workers (2: CI's
## cores). A file's tests stay on one worker (--dist loadfile: module fixtures fly once), files in tests/conftest.py's
## order (longest first, not xdist's by test count) so that the workers finish together. TEST_WORKERS=0 runs them in
## this process
TEST_WORKERS ?= 2
XDIST := -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder
test: $(STAMP)
	$(BIN)/python -m pytest -q $(XDIST) -m "not cuda and not emulated_cpu"

## test-fast: skip tests marked slow
test-fast: $(STAMP)
	$(BIN)/python -m pytest -q $(XDIST) -m "not slow and not cuda and not emulated_cpu"

## test-cuda: the GPU backend's simulator flights and every family's PTX compile (no GPU needed; minutes of
## numba-cuda compiles, so apart from make test's 15 minutes; .ci/run runs both)
test-cuda: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist load -m cuda

## test-cpus: every vehicle family flown on emulated CPUs (other OpenBLAS kernels, glibc's libm without its FMA
## variants, numpy at SSE4.2 with numba compiling every kernel for a generic x86-64 in a cold cache of its own) to
## the same runs-table bits, and that cold compile's family pruning (docs/campaigns.md "On any CPU",
## docs/families.md). Its cold compile is ~200 s of one core, so apart from make test's 15 minutes; .ci/run runs it.
## The test flies its CPUs in subprocesses side by side: one pytest process
test-cpus: $(STAMP)
	$(BIN)/python -m pytest -q -m emulated_cpu tests/test_cpu_independence.py

## mutate: mutation testing (mutmut) of refexmc/core/ and report/requirements.py against their unit tests, in a
## copy (build/mutate) whose kernels lose their @jit decorators (mutmut skips decorated functions; REFEXMC_DISABLE_JIT=1
## makes them plain Python anyway). Hours on 2 cores, not in CI; MUTANTS='refexmc.core.navigation*' narrows it and
## a second run only tries what changed (docs/mutation.md)
MUTATE_DIR := build/mutate
# the wheels benchmarks/gpu_device.sh installs on a lent GPU machine (Python 3.12, no network there)
DEVICE_WHEELS = numpy==2.4.6 numba-cuda==0.30.4 gmpy2 SALib multiprocess dill jsonschema jsonschema-specifications referencing rpds-py
device-wheels: $(STAMP)
	rm -rf .whl && $(VENV)/bin/pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
	  --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux_2_17_x86_64 \
	  --platform manylinux2014_x86_64 --platform manylinux_2_24_x86_64 -d .whl $(DEVICE_WHEELS)

mutate: $(STAMP)
	mkdir -p $(MUTATE_DIR)
	rm -rf $(MUTATE_DIR)/refexmc $(MUTATE_DIR)/tests
	cp -R refexmc tests configs campaigns pyproject.toml $(MUTATE_DIR)/
	sed -i -E '/^@jit(_noalloc|_inline)?(\(.*\))?$$/d' $(MUTATE_DIR)/refexmc/core/*.py
	cd $(MUTATE_DIR) && REFEXMC_DISABLE_JIT=1 $(CURDIR)/$(BIN)/mutmut run $(MUTANTS)
	cd $(MUTATE_DIR) && $(CURDIR)/$(BIN)/mutmut results

## bench: flight-kernel benchmarks (results go to benchmarks/RESULTS.md by hand)
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_flight.py

## bench-campaign: campaign throughput, speed-up, memory, bytes per run (a few minutes)
bench-campaign: $(STAMP)
	$(BIN)/python benchmarks/bench_campaign.py

## lint: ruff lint and format check
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: $(STAMP)
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

clean:
	rm -rf $(VENV) runs .pytest_cache .ruff_cache
	find . -name __pycache__ -prune -exec rm -rf {} +
