# Quick start: `make demo` then `make test`. Both create .venv when it is missing.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test clean bytecode

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.demo-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[demo]'
	touch $@

$(VENV)/.test-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

# Bytecode as a wheel install would have it (this checkout is installed editable): a run does not compile the package
# each time, which matters where PYTHONDONTWRITEBYTECODE is set (CI images) — 0.1-0.2 s of every command.
bytecode:
	$(BIN)/python -m compileall -q urdf_pipeline > /dev/null

demo: $(VENV)/.demo-installed bytecode
	$(BIN)/python -m urdf_pipeline.examples configs
	$(BIN)/urdf-pipeline run configs/demo.yaml

test: $(VENV)/.test-installed bytecode
	$(BIN)/python -m pytest

clean:
	rm -rf configs/out configs/data configs/robots
