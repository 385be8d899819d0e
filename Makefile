# Two commands do everything on a fresh clone: `make run` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
export QT_QPA_PLATFORM ?= offscreen
export MPLBACKEND ?= Agg
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: run test lint typecheck unit bench clean

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

unit: $(STAMP)
	$(BIN)/python -m pytest -q

test: lint typecheck unit

bench: $(STAMP)
	$(BIN)/python -m benchmarks.run_all

clean:
	rm -rf $(VENV) .numba_cache .mypy_cache .pytest_cache .ruff_cache runs
