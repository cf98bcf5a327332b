# Every target does its own set-up from nothing: a .venv with torch (CPU build) first, then the project.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench clean

$(STAMP): pyproject.toml
	command -v apt-get >/dev/null && (dpkg -s libosmesa6 >/dev/null 2>&1 || apt-get install -y -q libosmesa6) || true
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/gaitforge scenes check --all --seconds 2
	$(BIN)/gaitforge scenes check --all --seconds 2 --backend opensim

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

bench: $(STAMP)
	$(BIN)/python bench/env_speed.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build *.egg-info
