#!/usr/bin/env bash
# Speed-for-accuracy benchmark: the fidelity sweeps and stress runs behind the README's
# "Speed for accuracy" section. Run from the repository root; writes bench/results/fidelity/
# (CSV, JSON, PNG, logs) and saves recommended profiles there (not in ~/.gaitforge).
set -u
OUT=bench/results/fidelity
mkdir -p "$OUT"
export GAITFORGE_PROFILES_DIR="$OUT/profiles" COLUMNS=200 OMP_NUM_THREADS=1
G=.venv/bin/gaitforge
run() { local log="$OUT/$1.log"; shift; { echo "\$ gaitforge $*"; /usr/bin/time -f "wall %e s" $G "$@"; } >"$log" 2>&1; }
run sweep-walk-2d-mujoco fidelity sweep walk-2d --backend mujoco --out "$OUT"
run sweep-walk-3d-mujoco fidelity sweep walk-3d --backend mujoco --out "$OUT"
run sweep-walk-2d-opensim fidelity sweep walk-2d --backend opensim --out "$OUT"
run stress-walk-3d-mujoco fidelity stress walk-3d --backend mujoco
run stress-walk-2d-mujoco fidelity stress walk-2d --backend mujoco
run stress-walk-2d-opensim fidelity stress walk-2d --backend opensim --seconds 0.5
