#!/bin/bash
# Regenerates every run behind results/localization/README.md into RUNS (default: runs/localization),
# one after another, then the tables and figures of this folder. Usage, from the repository root:
#   bash results/localization/run_all.sh [RUNS]
# The data folder is $CRLAM_DATA (default: ../shared/data). Each step is skipped when its folder is
# complete (holds COMPLETE), so an interrupted script can simply be run again.
set -euo pipefail
DATA=${CRLAM_DATA:-../shared/data}
RUNS=${1:-runs/localization}
HERE=results/localization
mkdir -p "$RUNS"
done_() { [ -f "$1/COMPLETE" ]; }

# (a) Intel: a map from GMapping's corrected log, then the raw log localized on it from its known start.
done_ "$RUNS/intel-map" || crlam map "$DATA/corrected/intel-corrected.log.gz" --out "$RUNS/intel-map" \
    --resolution 0.05 --max-range 20 --quiet --force
done_ "$RUNS/intel-loc" || crlam localize "$DATA/intel/intel.clf.bz2" --map "$RUNS/intel-map" --out "$RUNS/intel-loc" \
    --initial-pose 0 0 -0.002458 --relations "$DATA/intel/intel.relations" --quiet --force

# (b) Intel: 20 global localizations from random scans, judged against the run from the known start.
if [ -d "$RUNS/intel-trials" ]; then resume=--resume; else resume=; fi
done_ "$RUNS/intel-trials" || crlam localize "$DATA/intel/intel.clf.bz2" --map "$RUNS/intel-map" \
    --out "$RUNS/intel-trials" --trials 20 --reference "$RUNS/intel-loc/trajectory.tum" --quiet $resume

# (c) TurtleBot 4 bag on its owners' floor map, no initial pose.
BAG="$DATA/bags/turtlebot4-mac-floor"
done_ "$RUNS/tb4-global" || crlam localize "$BAG" --map "$BAG/mac_1st_floor_final.yaml" --out "$RUNS/tb4-global" \
    --global --nav2-free-thresh 0.196 --skip-no-returns --quiet --force

# (d) ACES: the first half mapped, continued with the second half, against one run over the whole log.
[ -f "$RUNS/aces-first.clf.gz" ] || python "$HERE/split_log.py" "$DATA/aces/aces.clf.bz2" \
    "$RUNS/aces-first.clf.gz" "$RUNS/aces-second.clf.gz"
for s in 0 1 2 3 4 5 6 7 8 9 10 11; do
    done_ "$RUNS/aces-whole-s$s" || crlam slam "$DATA/aces/aces.clf.bz2" --out "$RUNS/aces-whole-s$s" --seed $s \
        --relations "$DATA/aces/aces.relations" --no-hits-first --quiet --force
    done_ "$RUNS/aces-first-s$s" || crlam slam "$RUNS/aces-first.clf.gz" --out "$RUNS/aces-first-s$s" --seed $s --no-hits-first --quiet --force
    (cd "$RUNS/aces-first-s$s" && find . -type f -print0 | sort -z | xargs -0 sha256sum) > "$RUNS/aces-first-s$s.sha256"
    done_ "$RUNS/aces-cont-s$s" || crlam slam "$RUNS/aces-second.clf.gz" --out "$RUNS/aces-cont-s$s" \
        --continue "$RUNS/aces-first-s$s" --seed $s --no-hits-first --quiet --force
    (cd "$RUNS/aces-first-s$s" && sha256sum --quiet -c "../aces-first-s$s.sha256") && echo "aces-first-s$s untouched"
done

# The simulated floors of look-alike rooms the competing-place settings were chosen on.
python "$HERE/lookalike.py" "$RUNS/lookalike" "$HERE"
python "$HERE/lookalike.py" "$RUNS/lookalike-intel-scale" "$HERE" --floor intel-scale

# Tables and figures of this folder.
python "$HERE/collect.py" "$RUNS" "$HERE" --data "$DATA"
