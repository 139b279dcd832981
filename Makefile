# Setup is idempotent: every target that needs the package depends on .venv/.installed.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
export MPLBACKEND := Agg

.PHONY: demo test test-slow bench lint clean

$(BIN)/python:
	$(PY) -m venv $(VENV)

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install -q -e '.[pc,dev]'
	touch $@

demo: $(VENV)/.installed
	$(BIN)/articutool demo

test: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/python -m pytest -m "not slow" -q

test-slow: $(VENV)/.installed
	$(BIN)/python -m pytest -m slow -q

bench: $(VENV)/.installed
	$(BIN)/python -m pytest benchmarks -q --benchmark-only --benchmark-json=benchmarks/results.json

lint: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
