#!/usr/bin/env bash
# Instructions per call of the solver bench workloads (examples/profile_solvers.rs), counted by
# callgrind: (Ir of 1 + N calls - Ir of 1 call) / N, so loading the fixtures cancels out.
# Deterministic; a proxy for cost, not a timing.
#
#   host-tests/scripts/count_solvers.sh [CASE...]      (from the repository root)
set -euo pipefail
cargo build --quiet --release -p camgeom --example profile_solvers
exe=target/release/examples/profile_solvers
cases=("$@")
if [ ${#cases[@]} -eq 0 ]; then
  cases=(epnp_50 eight_64 seven five f_ransac_200 e_ransac_200)
fi
ir() {
  valgrind --tool=callgrind --callgrind-out-file=/dev/null "$exe" "$@" 2>&1 |
    sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
for case in "${cases[@]}"; do
  n=20
  case "$case" in *ransac*) n=4 ;; esac
  for ty in f32 f64; do
    one=$(ir "$case" "$ty" 1)
    many=$(ir "$case" "$ty" $((n + 1)))
    echo "$case $ty $(( (many - one) / n ))"
  done
done
