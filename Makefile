# Two entry points: `make run` (every case, report under reports/latest) and `make test`.
# Both create .venv and install what they need, so a fresh machine with Python 3.11 and make
# is enough.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= reports/latest
WORKERS ?= 2

.PHONY: run test install bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	$(BIN)/crosscheck run cases --out $(OUT) --workers $(WORKERS) --baseline reports/baseline.json

test: $(STAMP)
	$(BIN)/python -m pytest -n $(WORKERS) -q

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_rigid.py
	$(BIN)/python benchmarks/bench_cost.py
	$(BIN)/python benchmarks/bench_fluid.py

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

clean:
	rm -rf $(VENV) reports/latest
