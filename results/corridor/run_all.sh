#!/bin/bash
# The default filter (solution remapping on degenerate scans) and the alternatives in a featureless
# simulated corridor.
# usage: results/corridor/run_all.sh RUNS   (then: python results/corridor/collect.py RUNS results/corridor)
set -euo pipefail
RUNS=${1:?usage: run_all.sh RUNS}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$RUNS"
python "$HERE/make_world.py" "$RUNS/world"
for s in 0 1; do
    [ -f "$RUNS/log-$s/COMPLETE" ] || crlam simulate --world "$RUNS/world/corridor.yaml" --sensor paper --scans 1500 \
        --seed $s -o "$RUNS/log-$s" --force --quiet > /dev/null
done
run() {  # run NAME SEEDS flags...
    name=$1; seeds=$2; shift 2
    for log in 0 1; do
        for seed in $seeds; do
            out="$RUNS/$name-log$log-seed$seed"
            [ -f "$out/COMPLETE" ] || RAYON_NUM_THREADS=1 crlam slam "$RUNS/log-$log/log.clf" --out "$out" \
                --reference "$RUNS/log-$log/groundtruth.tum" --seed $seed --quiet --force "$@"
        done
    done
}
run default "0 1"
run off "0 1" --degeneracy off
run posterior "0 1" --degeneracy off --match-climb posterior
run endpoint-weight "0" --degeneracy off --scan-match-weight endpoint
run posterior-endpoint-weight "0" --degeneracy off --match-climb posterior --scan-match-weight endpoint
run ogm-gmapping "0" --preset paper --method ogm --ogm-map gmapping --motion gmapping --ogm-motion-draws per_scan \
    --particles 30 --resolution 0.05 --max-range 80 --linear-update 1.0 --angular-update 0.5 --max-map-cells 1e8
