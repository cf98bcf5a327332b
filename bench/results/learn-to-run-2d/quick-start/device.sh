#!/usr/bin/env bash
# Session 25's quick-start A/B on a lent 16-core machine (set up by bench/device_setup.sh: no
# Ray there, rollouts in-process, the wheels carried in .devwheels/): 4 arms x 4 seeds, 16 runs
# side by side, each trained for the same MINUTES of wall clock from the
# shipped runner, its last network judged on 200 deterministic episodes of its own scene
# (seeds 100-299), then each arm's speed profile (30 episodes a seed).
# Usage (on the machine, from the repository root):
#   bash bench/results/learn-to-run-2d/quick-start/device.sh OUT
# (MINUTES, SEEDS, EPISODES, PROFILE_EPISODES and INSTALL=0 shrink it for a try here.)
set -euo pipefail
out=${1:?OUT}
minutes=${MINUTES:-5}
seeds=${SEEDS:-0 1 2 3}
episodes=${EPISODES:-200}
profile_episodes=${PROFILE_EPISODES:-30}
source bench/device_setup.sh  # the carried wheels, the project, PATH, one thread
here=bench/results/learn-to-run-2d/quick-start
runs=/tmp/quick-start
in_process="workers.num_workers=0"
python3 bench/job_arms.py $here/job.yaml --out $runs --seeds $seeds --scene stage \
  --episodes $episodes --judge-seed 100 --side-by-side 16 --train-minutes $minutes \
  --arm control $in_process \
  --arm lead-06-08 $in_process stages.0.scene=lead-06-08.yaml \
  --arm lead-04-08 $in_process stages.0.scene=lead-04-08.yaml \
  --arm lead-06-08-tempo-105 $in_process stages.0.scene=lead-06-08-tempo-105.yaml \
  > $runs.log 2>&1 || { tail -40 $runs.log; tail -20 $runs/*/seed-*.log; exit 1; }
tail -12 $runs.log
scene_of() { case $1 in control) echo run-2d-clock-forward ;; *) echo $here/$1.yaml ;; esac; }
for arm in control lead-06-08 lead-04-08 lead-06-08-tempo-105; do
  python3 bench/speed_profile.py $(for s in $seeds; do echo $runs/$arm/seed-$s; done) \
    --labels $(for s in $seeds; do echo seed-$s; done) --scene "$(scene_of $arm)" \
    --episodes $profile_episodes --out $runs/$arm/profile.png > $runs/$arm/profile.txt 2>&1 &
done
wait
tar czf "$out/quick-start.tgz" --exclude=tb --exclude=checkpoints -C /tmp quick-start quick-start.log
for arm in control lead-06-08 lead-04-08 lead-06-08-tempo-105; do
  for s in $seeds; do  # the end networks only
    last=$(ls -d $runs/$arm/seed-$s/checkpoints/ckpt-* | tail -1)
    mkdir -p "$out/end/$arm/seed-$s" && cp -r "$last" "$out/end/$arm/seed-$s/"
  done
done
ls -la "$out"
