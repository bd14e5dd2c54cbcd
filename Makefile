# mavnav: the two set-up commands of README.md live here.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
BASE := $(VENV)/.installed-base
FULL := $(VENV)/.installed-test

.PHONY: demo test test-fast golden install bench clean

$(VENV)/bin/python:
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip

$(BASE): pyproject.toml | $(VENV)/bin/python
	$(BIN)/pip install -q -e .
	touch $(BASE)

# Test extras: pytest, hypothesis, filterpy (the independent reference filter),
# the fleet engine (dask), playwright for the browser test, and MAVProxy
# (headless, without its GUI dependencies) for the ground-station routing test.
$(FULL): pyproject.toml | $(VENV)/bin/python
	$(BIN)/pip install -q -e '.[test,fleet,web]'
	$(BIN)/pip install -q --no-deps MAVProxy==1.8.75 pynmeagps defusedxml pyserial
	touch $(BASE) $(FULL)

install: $(BASE)

# The main job on the bundled logs: audit every simulated flight in sitl_logs/.
demo: $(BASE)
	@mkdir -p out
	$(BIN)/mavnav audit sitl_logs/ --json out/demo_audit.json
	@echo "per-file audit JSON: out/demo_audit.json"

# The whole test suite.
test: $(FULL)
	$(BIN)/python -m pytest -q

# The fast lane (about 30 s on two cores, against some 9 minutes for the whole
# suite): everything but the tests marked slow (Monte Carlo and statistics,
# subprocesses and live links, the shared real logs beyond one per format, whole
# flights beyond one per area, the larger fuzzers, the viewer, the browser).
test-fast: $(FULL)
	$(BIN)/python -m pytest -q -m "not slow"

# Rewrite the golden outputs (tests/golden/: mavnav audit of sitl_logs/, JSON, CSV
# and table) with the current code, when a change of behaviour is meant; review
# the diff of tests/golden/ before committing it. tests/test_golden.py compares.
golden: $(BASE)
	$(BIN)/python -m tests.support.golden

bench: $(FULL)
	$(BIN)/python bench/estimator.py
	$(BIN)/python bench/ingest.py
	$(BIN)/python bench/audit.py
	$(BIN)/python bench/integrity.py
	$(BIN)/python bench/fleet.py

clean:
	rm -rf $(VENV) build *.egg-info out
