# refexmc developer entry points. Each target creates and uses the local virtual environment.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast bench lint format clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

## demo: fly the nominal ReFEx case and print its summary
demo: $(STAMP)
	$(BIN)/refexmc run campaigns/nominal.yaml -o runs/nominal --overwrite

## test: the whole test suite (what CI runs)
test: $(STAMP)
	$(BIN)/python -m pytest -q

## test-fast: skip tests marked slow
test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

## bench: performance benchmarks (results go to benchmarks/RESULTS.md by hand)
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_flight.py

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
