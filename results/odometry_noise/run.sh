#!/bin/bash
# The measurements of docs/method/odometry-noise.md: semi-real logs (the real scans of
# GMapping-corrected logs at their corrected poses, with a drifting odometry of our own) run with
# the robust preset's odometry-noise rule and with GMapping's fixed default noise.
#   ./run.sh OUT        (CRLAM_DATA: the data folder; every run folder is written under OUT)
# Resumes: a run whose metrics.json exists is not run again.
set -euo pipefail
out=${1:?usage: run.sh OUT}
data=${CRLAM_DATA:-../../../shared/data}
mkdir -p "$out"
. "$(dirname "$0")/../semireal_odometry.sh"  # $good and $mild: the odometries drawn
logs="good:infinite-corridor good:freiburg-campus good:acapulco good:fhw mild:infinite-corridor mild:acapulco mild:fhw mild:belgioioso mild:seattle mild:orebro"
for entry in $logs; do
  kind=${entry%%:*}; b=${entry#*:}; log="$out/$kind-$b"
  [ -f "$log/semireal.json" ] || crlam semireal "$data/corrected/$b-corrected.log.gz" -o "$log" --force -q ${!kind} >/dev/null
  for noise in estimate model; do
    run="$out/runs-$noise/$kind-$b"
    [ -f "$run/metrics.json" ] || crlam slam "$log/log.clf" --reference "$log/groundtruth.tum" --out "$run" --force --quiet \
      --seed 0 --motion-noise "$noise"
  done
done
python "$(dirname "$0")/score.py" "$out"
