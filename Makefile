# Setup is idempotent: every target that needs the package depends on .venv/.installed.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
export MPLBACKEND := Agg

.PHONY: demo test test-slow bench bench-quick bench-full lint clean

$(BIN)/python:
	$(PY) -m venv $(VENV)

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[pc,dev,ros]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/articutool demo

test: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/python -m pytest -m "not slow" -q

test-slow: $(VENV)/.installed
	$(BIN)/python -m pytest -m slow -q

bench: $(VENV)/.installed
	$(BIN)/python -m pytest benchmarks -q --benchmark-only --benchmark-json=results/benchmarks.json

# Exp. 2a: 20 tasks x 3 systems, 30 s timeout (a few minutes on 2 cores); resumable.
bench-quick: $(VENV)/.installed
	$(BIN)/articutool bench transport --limit 20 --timeout 30 --out results/bench-quick

# The committed full run (results/exp2a) and the tolerance sweep (results/sweep).
bench-full: $(VENV)/.installed
	$(BIN)/articutool bench transport --timeout 60 --workers 2 --out results/exp2a
	$(BIN)/articutool bench transport --tolerance-sweep --limit 30 --timeout 30 --workers 2 --out results/sweep

lint: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks examples

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
