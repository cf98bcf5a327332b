#!/usr/bin/env bash
# Session 26's longer one-leg run on a lent 16-core machine (set up by bench/device_setup.sh):
# 2 arms x 8 seeds, 16 runs side by side, each trained for MINUTES of wall clock from the
# shipped runner on run-2d-clock-one-leg (arm one-leg) or the same with the run played 1.05
# times faster (arm tempo-105), its end network judged on 200 deterministic episodes of its own
# scene (seeds 100-299); every checkpoint comes back (tarred) to judge here.
# Usage (on the machine, from the repository root):
#   bash bench/results/learn-to-run-2d/one-leg/long/device.sh OUT
# (MINUTES, SEEDS, EPISODES and INSTALL=0 shrink it for a try here.)
set -euo pipefail
out=${1:?OUT}
minutes=${MINUTES:-7}
seeds=${SEEDS:-0 1 2 3 4 5 6 7}
episodes=${EPISODES:-200}
source bench/device_setup.sh  # the carried wheels, the project, PATH, one thread
here=bench/results/learn-to-run-2d/one-leg/long
runs=/tmp/one-leg-long
python3 bench/job_arms.py $here/job.yaml --out $runs --seeds $seeds --scene stage \
  --episodes $episodes --judge-seed 100 --side-by-side 16 --train-minutes $minutes \
  --arm one-leg \
  --arm tempo-105 stages.0.scene=one-leg-tempo-105.yaml \
  > $runs.log 2>&1 || { tail -40 $runs.log; tail -20 $runs/*/seed-*.log; exit 1; }
tail -8 $runs.log
tar czf "$out/one-leg-long.tgz" --exclude=tb --exclude=checkpoints -C /tmp one-leg-long one-leg-long.log
set -- $seeds  # the checkpoints, in files under the 16 MiB a returned file may hold
half=$(( ($# + 1) / 2 ))
for arm in one-leg tempo-105; do
  first=() rest=()
  for s in $seeds; do
    if [ ${#first[@]} -lt $half ]; then first+=("$arm/seed-$s"); else rest+=("$arm/seed-$s"); fi
  done
  tar czf "$out/$arm-a.tgz" --exclude=tb -C $runs "${first[@]}"
  [ ${#rest[@]} -eq 0 ] || tar czf "$out/$arm-b.tgz" --exclude=tb -C $runs "${rest[@]}"
done
ls -la "$out"
