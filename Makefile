# mavnav: the two set-up commands of README.md live here.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test install bench clean

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -e '.[test]'
	touch $(STAMP)

install: $(STAMP)

# The main job on a bundled log.
demo: $(STAMP)
	$(BIN)/mavnav covariance config/paper_2015_covariance.yaml --duration 5

# The whole test suite.
test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	$(BIN)/python bench/estimator.py

clean:
	rm -rf $(VENV) build *.egg-info
