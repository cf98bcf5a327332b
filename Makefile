# Every target does its own set-up from nothing: a .venv with torch (CPU build) first, then the project.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench clean

$(STAMP): pyproject.toml
	command -v apt-get >/dev/null && (dpkg -s libosmesa6 >/dev/null 2>&1 || apt-get install -y -q libosmesa6 || (apt-get update -q && apt-get install -y -q libosmesa6)) || true
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

# The main job, short: the gait2d curriculum (stand, walk with a blended bigger network, run,
# obstacles) at 1/1000 of its budget, then an evaluation with an MCAP recording and a video.
RUN_DIR := runs/make-run
run: $(STAMP)
	$(BIN)/gaitforge scenes check --all --seconds 1
	$(BIN)/gaitforge train examples/gait2d-curriculum.yaml --budget-scale 0.001 --run-dir $(RUN_DIR)
	$(BIN)/gaitforge evaluate $(RUN_DIR) --episodes 5 --sweep \
		--record $(RUN_DIR)/evaluate.mcap --video $(RUN_DIR)/evaluate.mp4 --json-out $(RUN_DIR)/evaluate.json

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
