# Quick start: `make demo` then `make test`. Both create .venv when it is missing.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.demo-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[demo]'
	touch $@

$(VENV)/.test-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

demo: $(VENV)/.demo-installed
	$(BIN)/python -m urdf_pipeline.examples configs
	$(BIN)/urdf-pipeline run configs/demo.yaml

test: $(VENV)/.test-installed
	$(BIN)/python -m pytest

clean:
	rm -rf configs/out configs/data configs/robots
