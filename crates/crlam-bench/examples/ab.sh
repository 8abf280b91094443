#!/usr/bin/env bash
# Interleaved A/B timing of two builds of the `info_timing` example (this VM's speed drifts by up
# to 30 % within minutes, so only alternating runs of both binaries give a stable ratio).
#
#   cargo build --release -p crlam-bench --example info_timing && cp target/release/examples/info_timing /tmp/it_a
#   (change the code, rebuild, copy to /tmp/it_b)
#   crates/crlam-bench/examples/ab.sh /tmp/it_a /tmp/it_b crmi 7
#
# Prints the median of each side and the median of the per-pair ratios B/A (< 1: B is faster).
# Works with any binary whose output starts with one decimal figure, e.g. the `filter_timing`
# example (`ab.sh /tmp/ft_a /tmp/ft_b clam 5`; a rate, so there B/A > 1 means B is faster).
set -euo pipefail
a=$1 b=$2 workload=$3 n=${4:-6}
for _ in $(seq "$n"); do
  ta=$("$a" "$workload" | grep -oE "[0-9]+\.[0-9]+" | head -1)
  tb=$("$b" "$workload" | grep -oE "[0-9]+\.[0-9]+" | head -1)
  echo "$ta $tb"
done | python3 -c "
import statistics as st, sys
r = [tuple(map(float, line.split())) for line in sys.stdin]
print('A median %.1f  B median %.1f  B/A ratio median %.3f' % (
    st.median(a for a, _ in r), st.median(b for _, b in r), st.median(b / a for a, b in r)))
"
