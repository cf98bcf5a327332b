#!/bin/bash
# The run stage continued for 0.9 M env steps from recipe runs' end networks, one after the
# other: bash bench/results/learn-to-run-2d/longer-finetune/run.sh OUT_DIR SEED:CHECKPOINT[:STD]...
# (STD: the start's action noise reset to it; without, as trained).
# Writes OUT_DIR/seed-S.yaml, OUT_DIR/seed-S.log and the run under OUT_DIR/seed-S/.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=$(mkdir -p "${1:?OUT_DIR}" && cd "$1" && pwd)
shift
for arm in "$@"; do
  IFS=: read -r seed checkpoint std <<< "$arm"
  init=$(cd "$(dirname "$checkpoint")" && pwd)/$(basename "$checkpoint")
  sed -e "s/SEED/$seed/" -e "s|INIT|$init|" -e "s/ACTION_STD/${std:-null}/" \
    "$here/continue.yaml.in" > "$out/seed-$seed.yaml"
  gaitforge train "$out/seed-$seed.yaml" --run-dir "$out/seed-$seed" --log-every 30 \
    > "$out/seed-$seed.log" 2>&1
done
