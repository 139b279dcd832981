# Setup is idempotent: every target that needs the package depends on .venv/.installed.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
export MPLBACKEND := Agg

.PHONY: demo test test-slow bench bench-quick bench-full bench-flood soak lint clean

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

# Issue 13: the real tool (sim) under 1000 goals/s + 16 MB payloads, rate limit on vs off.
bench-flood: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_link_flood.py --duration 60 --compare-unlimited --out results/link_flood.json

# Issue 13: the tool against a random, hostile client; SOAK_S=600 make soak for a short one.
SOAK_S ?= 3600
soak: $(VENV)/.installed
	$(BIN)/python benchmarks/soak.py --duration $(SOAK_S) --out results/soak.json

lint: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks examples

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
