#!/bin/bash
# The default filter and its variants on simulated worlds rotated 17 deg against the map grid.
# usage: results/rotated_worlds/run_all.sh RUNS   (then: python results/rotated_worlds/collect.py RUNS results/rotated_worlds)
set -euo pipefail
RUNS=${1:?usage: run_all.sh RUNS}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$RUNS"
for world in museum office; do
    crlam simulate --world $world --sensor sick --scans 1 -o "$RUNS/$world-upright" --force --quiet
done
python "$HERE/make_world.py" "$RUNS/office-upright" "$RUNS/office-rotated" 4 17
python "$HERE/make_world.py" "$RUNS/museum-upright" "$RUNS/museum-rotated" 2 17
for world in museum office; do
    for s in 0 1; do
        crlam simulate --world "$RUNS/$world-rotated/world.yaml" --sensor sick --scans 3000 --seed $s \
            -o "$RUNS/log-$world-$s" --force --quiet --max-map-cells 1e8 --max-image-pixels 1e8
    done
done
run() {  # run NAME SEEDS flags...
    name=$1; seeds=$2; shift 2
    for log in museum-0 museum-1 office-0 office-1; do
        for seed in $seeds; do
            out="$RUNS/$name-$log-seed$seed"
            # --degeneracy off: the rows were measured with the scan read in every direction.
            [ -f "$out/COMPLETE" ] || RAYON_NUM_THREADS=1 crlam slam "$RUNS/log-$log/log.clf" --out "$out" \
                --reference "$RUNS/log-$log/groundtruth.tum" --seed $seed --quiet --force --degeneracy off "$@"
        done
    done
}
run default "0 1"
# The variants below keep the first pose's frame: what the default is without its turn.
run no-alignment "0 1" --grid-alignment none
run sub-cell-unaligned "0 1" --grid-alignment none --sub-cell unaligned
run hit-means "0 1" --grid-alignment none --hit-means
run chord "0 1" --grid-alignment none --cause-kernel chord
run sub-cell-on "0 1" --sub-cell on
run match "0 1" --grid-alignment none --proposal-pose match
run gmapping-lattice "0 1" --grid-alignment none --lattice-step 0.01 0.005
run range20 "0" --grid-alignment none --max-range 20
run cell005 "0" --grid-alignment none --resolution 0.05
run ogm-gmapping "0" --preset paper --method ogm --ogm-map gmapping --motion gmapping --ogm-motion-draws per_scan \
    --particles 30 --resolution 0.05 --max-range 80 --linear-update 1.0 --angular-update 0.5 --max-map-cells 1e8
run remap-no-alignment "0 1" --grid-alignment none --degeneracy remap
