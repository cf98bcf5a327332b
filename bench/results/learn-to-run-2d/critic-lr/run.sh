#!/bin/bash
# Both arms of the critic-lr A/B, interleaved, one after the other (one rollout actor + the
# learner each): bash bench/results/learn-to-run-2d/critic-lr/run.sh OUT_DIR
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:?OUT_DIR}
mkdir -p "$out"
for seed in 0 1 2; do
  for arm in null 3.0e-4; do
    name="seed-$seed-critic-lr-$arm"
    sed -e "s/SEED/$seed/" -e "s/CRITIC_LR/$arm/" "$here/finetune.yaml.in" > "$here/$name.yaml"
    gaitforge train "$here/$name.yaml" --run-dir "$out/$name" --log-every 30 > "$out/$name.log" 2>&1
  done
done
