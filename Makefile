# Every target does its own set-up from nothing: Debian's OSMesa (videos) and Chromium (the
# pages' browser tests) where apt-get exists, a .venv with torch (CPU build) first, then the project.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint bench clean

$(STAMP): pyproject.toml
	command -v apt-get >/dev/null && (dpkg -s libosmesa6 chromium >/dev/null 2>&1 || apt-get install -y -q libosmesa6 chromium || (apt-get update -q && apt-get install -y -q libosmesa6 chromium)) || true
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet torch==2.13.0
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

# The service's round trip on embedded defaults (local Ray, SQLite, files under
# runs/make-run/service): start `gaitforge serve`, submit the gait2d curriculum (stand, walk
# with a blended bigger network, run, obstacles) at 1/1000 of its budget, follow it live,
# download its final checkpoint and recordings, evaluate the checkpoint with an MCAP recording
# and a video, stop the service and its Ray head (also on failure), print where everything is.
# Then the shipped walker (examples/policies/walk-2d, trained by examples/learn-to-walk.yaml)
# walks walk-2d's 10 s from standing: 5 episodes, the first as a video and an MCAP recording.
RUN_DIR := runs/make-run
run: $(STAMP)
	$(BIN)/gaitforge scenes check --all --seconds 1
	$(BIN)/python -m gaitforge.service.client.round_trip --job examples/gait2d-curriculum.yaml \
		--budget-scale 0.001 --out $(RUN_DIR) --episodes 5
	$(BIN)/gaitforge evaluate examples/policies/walk-2d --episodes 5 \
		--video $(RUN_DIR)/walker.mp4 --record $(RUN_DIR)/walker.mcap

# The suite runs on every core (pytest-xdist): each worker has its own Ray head, service and
# browser, and every port a test opens is chosen free, so workers never collide. Tests that
# read one converted model share a worker (xdist_group), so each model is converted once.
test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python -m pytest -q -n auto --dist loadgroup

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

bench: $(STAMP)
	$(BIN)/python bench/env_speed.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache build *.egg-info
