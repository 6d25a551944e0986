# Quick start: `make demo` then `make test`. Both create .venv when it is missing.
PYTHON ?= python3.11
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test lint docs clean bytecode renderer browser

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.demo-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[demo]'
	touch $@

$(VENV)/.test-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

$(VENV)/.docs-installed: pyproject.toml | $(BIN)/python
	$(BIN)/pip install --quiet -e '.[docs]'
	touch $@

# Bytecode as a wheel install would have it (this checkout is installed editable): a run does not compile the package
# each time, which matters where PYTHONDONTWRITEBYTECODE is set (CI images) — 0.1-0.2 s of every command.
bytecode:
	$(BIN)/python -m compileall -q urdf_pipeline > /dev/null

# The last line says how to open the recording, as it can be typed here with no venv activated (.venv/bin/rerun is
# the viewer of the installed rerun-sdk; it needs a screen).
demo: $(VENV)/.demo-installed bytecode
	$(BIN)/python -m urdf_pipeline.examples configs
	$(BIN)/urdf-pipeline run configs/demo.yaml
	@echo "open it: $(BIN)/rerun configs/out/episode_000.rrd"

# Pictures (snapshot, plan/diff --render) are drawn by the Rerun viewer, which needs a Vulkan driver: without a GPU's,
# Mesa's software one. Installed here when no driver is there and we are root with apt; otherwise the renderer tests
# skip, saying what to install.
renderer:
	@if ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json 2>/dev/null | grep -q .; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing mesa-vulkan-drivers (a software Vulkan driver) for the pictures"; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  apt-get install -y -qq mesa-vulkan-drivers >/dev/null 2>&1 || \
	  { apt-get update -qq >/dev/null && apt-get install -y -qq mesa-vulkan-drivers >/dev/null; } || \
	  echo "note: could not install mesa-vulkan-drivers: the renderer tests will skip"; \
	else echo "note: no Vulkan driver: the renderer tests will skip; install one: sudo apt-get install mesa-vulkan-drivers"; fi

# The web pages (plan --html, diff --html, browse) are tested in a real browser: Debian's chromium, driven headless over
# its DevTools protocol (nothing downloads a browser build). Installed here when missing and we are root with apt;
# otherwise the browser tests skip, saying what to install.
browser:
	@if command -v chromium >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "installing chromium (Debian's) for the browser tests"; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  apt-get install -y -qq chromium >/dev/null 2>&1 || \
	  { apt-get update -qq >/dev/null && apt-get install -y -qq chromium >/dev/null; } || \
	  echo "note: could not install chromium: the browser tests will skip"; \
	else echo "note: no chromium: the browser tests will skip; install it: sudo apt-get install chromium"; fi

# The checks CI runs before the tests (and .pre-commit-config.yaml before a commit): lint, format, types
# (configured in pyproject.toml; mccabe complexity at most 12).
lint: $(VENV)/.test-installed
	$(BIN)/ruff check urdf_pipeline tests benchmarks
	$(BIN)/ruff format --check urdf_pipeline tests benchmarks
	$(BIN)/mypy

# -rs: each skipped test's reason at the end (a missing Vulkan driver, chromium, ../shared).
test: lint bytecode renderer browser
	$(BIN)/python -m pytest -rs

# The site of docs/, into docs/_build/html (git-ignored). Strict, as tests/docs builds it: any warning (a broken link
# or anchor, a missing page, a page in no table of contents) fails the build, after all of them are reported.
docs: $(VENV)/.docs-installed
	$(BIN)/python -m sphinx -W --keep-going -n -q -b html docs docs/_build/html
	@echo "open it: docs/_build/html/index.html"

clean:
	rm -rf configs/out configs/data configs/robots
