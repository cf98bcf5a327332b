#!/bin/bash
# The fine-tune A/Bs' end networks (and their start) judged again, on 200 deterministic
# run-2d-clock episodes with seeds 0..199 (not the 1,000,000 + i the runs were watched on):
# bash bench/results/learn-to-run-2d/critic-lr/evaluate.sh OUT_DIR RUN_DIR...
# Writes OUT_DIR/<run>.json (every episode) and <run>.txt (the table) per run and prints one
# line per run (reevaluated/ holds the tables and the lines).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:?OUT_DIR}
shift
mkdir -p "$out"
for run in "$here/start-imitation-seed1-2.05M" "$@"; do
  name=$(basename "$run")
  gaitforge evaluate "$run" --scene run-2d-clock --episodes 200 --seed 0 \
    --json-out "$out/$name.json" > "$out/$name.txt" 2>&1
  echo "$name: $(grep -E 'fall rate|speed m/s' "$out/$name.txt" | tr -s ' ' | tr '\n' ' ')"
done
