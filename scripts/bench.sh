#!/usr/bin/env bash
# Runs the benchmarks whose figures are recorded in BENCHMARKS.md. Needs ../shared/data/meshes/dragon.ply.
# Run on an otherwise idle machine: timings of a loaded machine are meaningless.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh >/dev/null
DRAGON=${DRAGON:-../shared/data/meshes/dragon.ply}
[ -f "$DRAGON" ] || { echo "bench: $DRAGON not found" >&2; exit 1; }
echo "== binary PLY read throughput"
build/bench/bench_ply_read "$DRAGON" --repeat 10
for offset in 1e-4 1e-3; do
  echo "== exact point queries, 1 thread, samples ${offset} x diag from the dragon's surface"
  build/bench/bench_point_query "$DRAGON" --samples 2000000 --offset "$offset" --threads 1
done
echo "== gimforge metrics dragon vs itself (2 x 1M samples + vertices, all cores)"
/usr/bin/time -f "wall %e s, max RSS %M KiB" build/gimforge --quiet metrics "$DRAGON" "$DRAGON" --json
