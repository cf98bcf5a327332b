#!/bin/bash
# Arms of the fine-tune A/Bs on seeds 0-2, seed by seed (one rollout actor + the learner
# each, one run at a time): bash bench/results/learn-to-run-2d/critic-lr/run.sh OUT_DIR ARM...
# where an ARM is CRITIC_LR:MIRROR[:ACTION_STD[:GAMMA]], e.g. null:true (the recipe),
# 3.0e-4:true, null:false, 3.0e-4:true:0.035 (the start's action noise reset to 0.035),
# 3.0e-4:false:0.035:0.99 (and the discount at 0.99, not 0.95). SEEDS="3 4" runs other
# seeds. (The critic warm-up arm, 3.0e-4:true:50000 then, ran at commit ddc3bc9.)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:?OUT_DIR}
shift
mkdir -p "$out"
for seed in ${SEEDS:-0 1 2}; do
  for arm in "$@"; do
    IFS=: read -r critic_lr mirror std gamma <<< "$arm"
    std=${std:-null}
    gamma=${gamma:-0.95}
    name="seed-$seed-critic-lr-$critic_lr"
    [ "$mirror" = true ] || name="$name-no-mirror"
    [ "$std" = null ] || name="$name-std-$std"
    [ "$gamma" = 0.95 ] || name="$name-gamma-$gamma"
    sed -e "s/SEED/$seed/" -e "s/CRITIC_LR/$critic_lr/" -e "s/MIRROR/$mirror/" \
      -e "s/ACTION_STD/$std/" -e "s/GAMMA/$gamma/" "$here/finetune.yaml.in" > "$here/$name.yaml"
    gaitforge train "$here/$name.yaml" --run-dir "$out/$name" --log-every 30 > "$out/$name.log" 2>&1
  done
done
