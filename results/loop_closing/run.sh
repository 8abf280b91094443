#!/bin/bash
# The measurements of docs/method/loop-closing.md: the robust preset with and without loop
# closing (--loop-closing graph, its default | off), filter seed 0 unless said, on semi-real logs (the real scans of
# GMapping-corrected logs at their corrected poses, with a drifting odometry of our own; the
# odometries of results/semireal_odometry.sh) and on the held-out Intel and ACES logs.
#   ./run.sh OUT        (CRLAM_DATA: the data folder; every run folder is written under OUT)
# Resumes: a run whose metrics.json exists is not run again.
set -euo pipefail
out=${1:?usage: run.sh OUT}
data=${CRLAM_DATA:-../../../shared/data}
mkdir -p "$out"
. "$(dirname "$0")/../semireal_odometry.sh"  # $good and $mild: the odometries drawn
# kind:building:seeds. Acapulco in three filter seeds: there a closure is right in kind but costs
# centimetres in two of them.
logs="good:infinite-corridor:0 good:acapulco:0,1,2 good:fhw:0 mild:fhw:0 good:freiburg-campus:0
      mild:infinite-corridor:0 mild:belgioioso:0 mild:orebro:0 mild:seattle:0"
for entry in $logs; do
  kind=${entry%%:*}; rest=${entry#*:}; b=${rest%%:*}; seeds=${rest#*:}; log="$out/$kind-$b"
  [ -f "$log/semireal.json" ] || crlam semireal "$data/corrected/$b-corrected.log.gz" -o "$log" --force -q ${!kind} >/dev/null
  for seed in ${seeds//,/ }; do
    name="$kind-$b"; [ "$seed" = 0 ] || name="$name-s$seed"
    for closing in graph off; do
      run="$out/runs-$closing/$name"
      [ -f "$run/metrics.json" ] || crlam slam "$log/log.clf" --reference "$log/groundtruth.tum" --out "$run" --force --quiet \
        --seed "$seed" --loop-closing "$closing"
    done
  done
done
for name in intel aces; do
  for seed in 0 1 2; do
    for closing in graph off; do
      run="$out/runs-$closing/$name-s$seed"
      [ -f "$run/metrics.json" ] || crlam slam "$name" --relations "$name-relations" --out "$run" --force --quiet --seed "$seed" \
        --loop-closing "$closing"
    done
  done
done
python "$(dirname "$0")/score.py" "$out"
