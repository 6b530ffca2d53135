# Two entry points: `make run` (every case, report under reports/latest) and `make test`.
# Both create .venv and install what they need, so a fresh machine with Python 3.11 and make
# is enough.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= reports/latest
WORKERS ?= 2

.PHONY: run test install bench lint clean browser

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

# RUN_FLAGS: more options of `crosscheck run` (.ci/run passes --no-cost)
RUN_FLAGS ?=

run: $(STAMP)
	$(BIN)/crosscheck run cases --out $(OUT) --workers $(WORKERS) --baseline reports/baseline.json $(RUN_FLAGS)

# Headless Chromium for the report's browser test (tests/report/test_browser.py): Debian's
# package, installed where missing (as root, else through sudo). Where it cannot be installed the
# test says so: skipped on a developer's machine, failed under CI=true.
browser:
	@command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || { \
	  echo "make: installing Debian's chromium for the report's browser test"; \
	  SUDO=$$([ "$$(id -u)" = 0 ] || echo sudo); \
	  $$SUDO apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium >/dev/null; } || \
	  echo "make: could not install chromium: the browser test will say so"

# --durations: CI's log lists the slowest tests (the run is held to 15 minutes on 2 cores).
# The Python packages and Debian's chromium install side by side (-j2): both mostly wait on
# downloads, and on a fresh machine that is what the tests wait for.
test:
	@$(MAKE) --no-print-directory -j2 install browser
	$(BIN)/python -m pytest -n $(WORKERS) -q --durations=30

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_rigid.py
	$(BIN)/python benchmarks/bench_cost.py
	$(BIN)/python benchmarks/bench_fluid.py
	$(BIN)/python benchmarks/bench_piles.py

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

clean:
	rm -rf $(VENV) reports/latest
