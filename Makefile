# Two commands do everything on a fresh clone: `make run` and `make test`.
# `make test` is the fast tier (<= 5 minutes on 2 cores); `make test-all` adds the slow tier (CI).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
export QT_QPA_PLATFORM ?= offscreen
export MPLBACKEND ?= Agg
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: run test test-all lint typecheck unit unit-all bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip==25.3
	$(BIN)/python -m pip install -q -e ".[dev]"
	touch $(STAMP)

run: $(STAMP)
	@mkdir -p runs
	$(BIN)/rigctl run tlre --config configs/make-run.toml --speed max --out runs/tlre.h5 --force
	$(BIN)/rigctl info runs/tlre.h5
	$(BIN)/rigctl analyse runs/tlre.h5 --out runs/analysis
	$(BIN)/rigctl export runs/tlre.h5 --csv runs/tlre.csv --force
	$(BIN)/rigctl model compare runs/tlre.h5 --report runs/compare
	$(BIN)/rigctl simulate --fn 300 --velocity 1e-5 --duration 60 --out runs/tlre_sim.csv --plot runs/tlre_sim.png --force

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

typecheck: $(STAMP)
	$(BIN)/mypy

# Two pytest workers (this machine's two cores); a test file stays on one worker, so its
# module fixtures are built once. --durations shows creeping costs.
PYTEST := $(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=20

unit: $(STAMP)
	$(PYTEST) -m "not slow"

unit-all: $(STAMP)
	$(PYTEST)

test: lint typecheck unit

test-all: lint typecheck unit-all

bench: $(STAMP)
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf $(VENV) .numba_cache .mypy_cache .pytest_cache .ruff_cache runs
