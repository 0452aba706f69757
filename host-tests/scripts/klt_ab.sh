#!/usr/bin/env bash
# Alternating timing of two builds of the `klt_count` example on the peer table's KLT case
# (basketball1 -> its warp by the known homography, 278 corners, `Gradients::Auto`): each
# round runs A then B, `reps` calls each; prints each build's µs per call, the minimum first.
# Alternating cancels most of this machine's drift, which moves a single criterion run by
# 5-10 % within minutes. Build the two binaries first, e.g.:
#
#   cargo build --release -p camgeom-host --example klt_count
#   cp target/release/examples/klt_count /tmp/klt_new   # and likewise /tmp/klt_old at the base commit
#   host-tests/scripts/klt_ab.sh /tmp/klt_old /tmp/klt_new 2000 6
set -euo pipefail
a=$1 b=$2 reps=${3:-2000} rounds=${4:-5}
for _ in $(seq "$rounds"); do
  for bin in "$a" "$b"; do
    s=$(date +%s%N)
    "$bin" "$reps" auto 278 known > /dev/null
    e=$(date +%s%N)
    echo "$bin $(( (e - s) / reps / 1000 ))"
  done
done | sort -k1,1 -k2,2n | awk '{all[$1] = all[$1] " " $2; if (!($1 in lo)) lo[$1] = $2}
  END {for (k in lo) print k ": min " lo[k] " µs, all" all[k]}'
