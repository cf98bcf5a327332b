#!/usr/bin/env bash
# Session 24's speed-term A/B on a lent 16-core machine (no Ray there: its wheel is too big to
# carry, so each run rolls out in-process, workers.num_workers 0): 3 arms x 5 seeds, 15 runs
# side by side, each trained for the same 5.5 minutes of wall clock from the shipped runner with
# no in-training evaluation, its last network judged on 100 deterministic run-2d-clock
# episodes (seeds 0-99), then each arm's speed profile (30 episodes). The wheels the image
# lacks (mujoco, gymnasium, pydantic, ...; for Python 3.12) are carried in .devwheels/
# (bench/device_setup.sh says how they were fetched).
# Usage (on the machine, from the repository root): bash bench/results/learn-to-run-2d/speed-term/device.sh OUT
# (MINUTES, SEEDS, PROFILE_EPISODES and INSTALL=0 shrink it for a try on a small machine.)
set -euo pipefail
out=${1:?OUT}
minutes=${MINUTES:-5.5}
seeds=${SEEDS:-0 1 2 3 4}
profile_episodes=${PROFILE_EPISODES:-30}
source bench/device_setup.sh  # the carried wheels, the project, PATH, one thread
python3 -c "import gaitforge.service.cli, mujoco, torch; print('torch', torch.__version__, 'mujoco', mujoco.__version__)"
here=bench/results/learn-to-run-2d/speed-term
runs=/tmp/speed-term
python3 bench/job_arms.py $here/runner-speed-term.yaml --out $runs --seeds $seeds \
  --scene run-2d-clock --episodes 100 --side-by-side 15 --train-minutes $minutes \
  --arm control workers.num_workers=0 stages.0.evaluate=null \
  --arm term-0.2 workers.num_workers=0 stages.0.evaluate=null stages.0.scene=run-2d-clock-speed-term-02.yaml \
  --arm term-0 workers.num_workers=0 stages.0.evaluate=null stages.0.scene=run-2d-clock-speed-term-0.yaml \
  > $runs.log 2>&1 || { tail -40 $runs.log; tail -20 $runs/*/seed-*.log; exit 1; }
tail -12 $runs.log
for arm in control term-0.2 term-0; do
  python3 bench/speed_profile.py $(for s in $seeds; do echo $runs/$arm/seed-$s; done) \
    --labels $(for s in $seeds; do echo seed-$s; done) --scene run-2d-clock --episodes $profile_episodes --out $runs/$arm/profile.png > $runs/$arm/profile.txt 2>&1 &
done
python3 bench/speed_profile.py examples/policies/run-2d --labels runner --scene run-2d-clock \
  --episodes $profile_episodes --out $runs/runner-profile.png > $runs/runner-profile.txt 2>&1 &
wait
tar czf "$out/speed-term.tgz" --exclude=tb -C /tmp speed-term speed-term.log
ls -la "$out"
