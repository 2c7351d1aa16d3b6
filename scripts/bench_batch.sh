#!/usr/bin/env bash
# Batch scaling benchmark (BENCHMARKS.md): a collection of ITEMS meshes (copies of the committed test meshes,
# four classes) converted with `gimforge batch --method gim --size 129` by 1 worker rank (mpirun -n 2:
# master + worker) and by 2 worker ranks (mpirun -n 3). Prints wall times of the whole command (scheduling,
# conversion, shard commits, journal, merge) and the parallel efficiency T1 / (2 T2). Run on an idle machine.
set -euo pipefail
cd "$(dirname "$0")/.."
ITEMS=${ITEMS:-200}
OUT=${OUT:-out/bench_batch}
if [ -z "${GF:-}" ]; then  # GF=path/to/gimforge skips the build
  scripts/build.sh >/dev/null
  GF=build/gimforge
fi
rm -rf "$OUT" && mkdir -p "$OUT/collection"
meshes=(fist kitten cathead sphere_r1)
for ((i = 0; i < ITEMS; ++i)); do
  m=${meshes[$((i % 4))]}
  mkdir -p "$OUT/collection/$m"
  cp "tests/data/$m.ply" "$OUT/collection/$m/$(printf '%04d' "$i").ply"
done
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
run() {  # run NP ARCHIVE -> seconds
  local start end
  start=$(date +%s.%N)
  mpirun -n "$1" --oversubscribe --bind-to none "$GF" -q batch --input "$OUT/collection" --method gim --size 129 \
    --metric-samples 50000 -o "$2" > /dev/null
  end=$(date +%s.%N)
  /usr/bin/python3 -c "print(f'{$end - $start:.2f}')"
}
t1=$(run 2 "$OUT/one_worker.h5")
t2=$(run 3 "$OUT/two_workers.h5")
/usr/bin/python3 - "$t1" "$t2" "$ITEMS" "$OUT" <<'PY'
import sys, h5py, numpy as np
t1, t2, n, out = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
a = h5py.File(f"{out}/one_worker.h5", "r")["batch/gim_129/data"][...]
b = h5py.File(f"{out}/two_workers.h5", "r")["batch/gim_129/data"][...]
print(f"items {n}: 1 worker {t1:.2f} s ({t1 / n * 1000:.0f} ms/item), 2 workers {t2:.2f} s; "
      f"parallel efficiency {t1 / (2 * t2) * 100:.1f}%; data bit-identical: {np.array_equal(a, b)}; shape {a.shape}")
PY
