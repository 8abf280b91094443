#!/bin/bash
# The measurements of docs/method/loop-closing.md: the robust preset with and without loop
# closing (--loop-closing graph | off), filter seed 0, on semi-real logs (the real scans of
# GMapping-corrected logs at their corrected poses, with a drifting odometry of our own; the
# odometries of results/semireal_odometry.sh) and on the held-out Intel and ACES logs.
#   ./run.sh OUT        (CRLAM_DATA: the data folder; every run folder is written under OUT)
# Resumes: a run whose metrics.json exists is not run again.
set -euo pipefail
out=${1:?usage: run.sh OUT}
data=${CRLAM_DATA:-../../../shared/data}
mkdir -p "$out"
. "$(dirname "$0")/../semireal_odometry.sh"  # $good and $mild: the odometries drawn
logs="good:infinite-corridor good:acapulco good:fhw mild:fhw good:freiburg-campus"
for entry in $logs; do
  kind=${entry%%:*}; b=${entry#*:}; log="$out/$kind-$b"
  [ -f "$log/semireal.json" ] || crlam semireal "$data/corrected/$b-corrected.log.gz" -o "$log" --force -q ${!kind} >/dev/null
  for closing in graph off; do
    run="$out/runs-$closing/$kind-$b"
    [ -f "$run/metrics.json" ] || crlam slam "$log/log.clf" --reference "$log/groundtruth.tum" --out "$run" --force --quiet \
      --seed 0 --loop-closing "$closing"
  done
done
for name in intel aces; do
  for closing in graph off; do
    run="$out/runs-$closing/$name-s0"
    [ -f "$run/metrics.json" ] || crlam slam "$name" --relations "$name-relations" --out "$run" --force --quiet --seed 0 \
      --loop-closing "$closing"
  done
done
python "$(dirname "$0")/score.py" "$out"
