#!/bin/bash
# usage: run.sh LOG OUT [flags...]
log=$1; out=$2; shift 2
crlam slam "$log" --out "$out" --relations "${CRLAM_DATA:-../../../shared/data}/intel/intel.relations" -q --force "$@" > $out.log 2>&1
python - "$out" <<'PY'
import json,sys
m=json.load(open(sys.argv[1]+'/metrics.json'))
print(sys.argv[1], round(m['relations']['trans_mean_m'],4), round(m['relations']['rot_mean_deg'],3), m.get('correlative_front_end'), round(m['wall_time_s'],1))
PY
