# Setup is idempotent: every target that needs the package depends on .venv/.installed.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
export MPLBACKEND := Agg

.PHONY: demo test test-slow test-no-avx512 bench bench-quick bench-full bench-sim bench-flood bench-stops bench-ros2-flood bench-loop soak lint clean syspkgs experiments

$(BIN)/python:
	$(PY) -m venv $(VENV)

# articutool_interfaces (the ROS 2 package for `articutool ros2`) is built with cmake into the
# venv; where the ROS 2 wheels do not exist (not CPython 3.11 on x86-64) the step says so and
# exits 0, and everything else installs and tests.
IDL := $(wildcard src/articutool/link/articutool_interfaces/*.* src/articutool/link/articutool_interfaces/*/* \
  src/articutool/ros2/peer_interfaces/*/*.* src/articutool/ros2/peer_interfaces/*/*/*)
$(VENV)/.installed: pyproject.toml $(IDL) | $(BIN)/python syspkgs
	$(BIN)/python -m pip install -q -e '.[pc,dev,ros]'
	$(BIN)/python -m articutool.ros2.build_interfaces
	touch $@

# System packages the README promises, installed with apt when missing (Debian/Ubuntu):
# EGL + Mesa for headless MuJoCo rendering (`articutool sim --video/--snapshot`, `meal
# --video`, `view --export`); Graphviz's `dot` for the rendered tree (`articutool meal
# --show-tree F.png`); Chromium for the viewer's real-browser test (`articutool view`).
EGL_PKGS := libegl1 libgl1-mesa-dri
BROWSER_PKGS := chromium
syspkgs:
	@missing=""; \
	ldconfig -p | grep -q 'libEGL.so.1' || missing="$(EGL_PKGS)"; \
	command -v dot >/dev/null 2>&1 || missing="$$missing graphviz"; \
	command -v chromium >/dev/null 2>&1 || missing="$$missing $(BROWSER_PKGS)"; \
	if [ -n "$$missing" ]; then \
	  echo "installing$$missing (offscreen rendering, tree pictures, the viewer's browser test)"; \
	  SUDO=$$( [ "$$(id -u)" = 0 ] || echo sudo ); \
	  $$SUDO apt-get update -q && $$SUDO apt-get install -y -q $$missing; \
	fi

# The main job: the transport figures (plan, verify, kinematic wrist simulation), then one
# whole bite by the Articutool in the physics world, its video under results/demo/. Pecans:
# a noodle bite runs at 0.1-0.3x real time (several minutes); DEMO_FOOD=noodles make demo.
DEMO_FOOD ?= pecans
demo: $(VENV)/.installed
	$(BIN)/articutool demo
	mkdir -p results/demo
	$(BIN)/articutool meal --food $(DEMO_FOOD) --bites 1 --video results/demo/bite-$(DEMO_FOOD)-$$(date +%Y%m%d-%H%M%S).mp4

# The tests run on every core (pytest-xdist; TEST_WORKERS=0 for one process): each module's
# tests together on one worker, the tests marked `floods` one after another on one worker
# (tests/conftest.py); the 25 longest tests and the 25 costliest in CPU are listed at the
# end with the suite's CPU total (on 2 cores it is CPU-bound: 3 workers were no faster).
# Exit 5 (no test selected, e.g. PYTEST_ARGS=-k that matches none) passes.
TEST_WORKERS ?= auto
PYTEST = $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadgroup $(PYTEST_ARGS)
test: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks studies examples
	$(PYTEST) -m "not slow" --durations=25 || [ $$? -eq 5 ]

test-slow: $(VENV)/.installed
	$(PYTEST) -m slow || [ $$? -eq 5 ]

# The physics tests as a CPU without AVX-512 computes them: NumPy's AVX-512 loops off (NumPy
# 2.4's names) and OpenBLAS on its AVX2 (Haswell) kernels; tests/avx2_paths.py first checks
# that both took effect (NumPy ignores a name it does not dispatch on).
AVX2_ONLY := NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" OPENBLAS_CORETYPE=Haswell
# The default tests of the food in MuJoCo: spills, sleeping loads, irregular pieces.
PHYSICS_TESTS := tests/test_viewer.py tests/test_sim_physics.py tests/test_load_sleep.py \
  tests/test_shedding_physics.py
test-no-avx512: $(VENV)/.installed
	$(AVX2_ONLY) $(BIN)/python tests/avx2_paths.py
	$(AVX2_ONLY) $(PYTEST) -m "not slow" $(PHYSICS_TESTS) || [ $$? -eq 5 ]

bench: $(VENV)/.installed
	$(BIN)/python -m pytest benchmarks -q --benchmark-only --benchmark-json=results/benchmarks.json

# Exp. 2a: 20 tasks x 3 systems, 30 s timeout (a few minutes on 2 cores); resumable.
bench-quick: $(VENV)/.installed
	$(BIN)/articutool bench transport --limit 20 --timeout 30 --out results/bench-quick

# The committed full run (results/exp2a) and the tolerance sweep (results/sweep).
bench-full: $(VENV)/.installed
	$(BIN)/articutool bench transport --timeout 60 --workers 1 --out results/exp2a
	$(BIN)/articutool bench transport --tolerance-sweep --limit 30 --timeout 30 --workers 1 --out results/sweep

# The physics world's real-time factor per food and whether speed settings change outcomes.
bench-sim: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_sim.py --seeds 5 --out results/sim_benchmark.json

# The real tool (sim) under 1000 goals/s + 16 MB payloads, rate limit on vs off.
bench-flood: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_link_flood.py --duration 60 --compare-unlimited --out results/link_flood.json

# A PC's stops under floods (unsigned, forged, replayed, another paired PC, all).
bench-stops: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_link_stops.py --out results/link_stops.json

# articutool ros2 under 1000 bad calls/s for 5 s and a burst of 600 cancels: every call answered?
bench-ros2-flood: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_ros2_flood.py --out results/ros2_flood.json

# The wrist's 50 Hz loop under 0/1/2/4 flooders of 2000 unsigned requests/s and a CPU hog, 10 min
# each (about 42 min); the same without CAP_SYS_NICE, 2 min each.
bench-loop: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_loop_period.py --out results/loop_period.json
	$(BIN)/python benchmarks/bench_loop_period.py --seconds 120 --without-cap-sys-nice --out results/loop_period_without_cap_sys_nice.json

# The tool against a random, hostile client; SOAK_S=600 make soak for a short one.
SOAK_S ?= 3600
soak: $(VENV)/.installed
	$(BIN)/python benchmarks/soak.py --duration $(SOAK_S) --out results/soak.json

# The thesis' physical experiments in the physics world (results/experiments),
# resumable: rerun to finish an interrupted run. EXP_TRIALS=5 make experiments for a short one.
# Order: capacity gives Exp. 2c its load; Exp. 1 gives Exp. 2c its thresholds (at report time).
EXP_TRIALS ?= 20
EXP_OUT ?= results/experiments
EXP_FLAGS ?=
experiments: $(VENV)/.installed
	$(BIN)/articutool experiment capacity --trials $(EXP_TRIALS) --out $(EXP_OUT) $(EXP_FLAGS)
	$(BIN)/articutool experiment exp2b --trials $(EXP_TRIALS) --out $(EXP_OUT) $(EXP_FLAGS)
	$(BIN)/articutool experiment exp1 --trials $(EXP_TRIALS) --out $(EXP_OUT) $(EXP_FLAGS)
	$(BIN)/articutool experiment exp2c --trials $(EXP_TRIALS) --out $(EXP_OUT) $(EXP_FLAGS)
	$(BIN)/articutool experiment exp3 --trials $(EXP_TRIALS) --out $(EXP_OUT) $(EXP_FLAGS)
	$(BIN)/articutool sim-calibrate --food water --json > $(EXP_OUT)/static_tilt_water.json
	$(BIN)/articutool sim-calibrate --food noodles --json > $(EXP_OUT)/strand_laws_noodles.json
	$(BIN)/python studies/transport_spill.py --out $(EXP_OUT)/slosh_crosscheck.json
	$(BIN)/articutool experiment report --out $(EXP_OUT)

lint: $(VENV)/.installed
	$(BIN)/ruff check src tests benchmarks studies examples

clean:
	rm -rf $(VENV) .pytest_cache .benchmarks
