#!/bin/bash
b=$1; out=$2; shift 2
crlam slam $b.clf --out $out --reference $b.truth.tum -q --force "$@" > $out.log 2>&1
python - $b $out <<'PY'
import sys, numpy as np, json
from crlam.io.tum import read_tum
b, out = sys.argv[1:3]
t = read_tum(b + '.truth.tum').poses; e = read_tum(out + '/trajectory.tum').poses
m = json.load(open(out + '/metrics.json'))
d = np.hypot(*(e[:, :2] - t[:, :2]).T)
print(out, 'end err %.2f  rmse %.2f  max %.2f' % (d[-1], np.sqrt(np.mean(d**2)), d.max()), m.get('correlative_front_end'), 'wall %.0f' % m['wall_time_s'], 'rss %.0f' % m['peak_rss_mb'])
PY
