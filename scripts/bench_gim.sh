#!/usr/bin/env bash
# Geometry-image acceptance table (BENCHMARKS.md): converts every shared mesh at 257x257 on ONE thread,
# reports PSNR (1M samples per direction), stretch efficiency, cut and per-stage times, and checks that the
# reconstruction of every LOD level (257, 129, 65) is closed and manifold for closed inputs.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh >/dev/null
SHARED=${SHARED:-../shared/data/meshes}
OUT=${OUT:-out/bench_gim}
mkdir -p "$OUT"
rm -f "$OUT/gim.h5"
printf '| mesh | faces | genus / loops | PSNR (dB) | stretch eff. | Floater eff. | cut-paths | augment. | cut s | param. s | sample s | total s | LOD 257/129/65: boundary edges, non-manifold edges |\n'
printf '|---|---|---|---|---|---|---|---|---|---|---|---|---|\n'
for m in bunny_closed cow camel fist foot kitten hand eight buddha cathead bunny; do
  build/gimforge -q -j 1 convert "$SHARED/$m.ply" --method gim --size 257 -o "$OUT/gim.h5" --json > "$OUT/$m.json"
  lods=""
  for level in 0 1 2; do
    build/gimforge -q reconstruct "$OUT/gim.h5" --name "$m" --level "$level" -o "$OUT/${m}_L$level.ply" > /dev/null
    build/gimforge -q info "$OUT/${m}_L$level.ply" --json > "$OUT/${m}_L$level.json"
    lods+=$(python3 -c "import json; j=json.load(open('$OUT/${m}_L$level.json')); print(f\"{j['boundary_edges']},{j['nonmanifold_edges']}\", end='')")
    [ "$level" -lt 2 ] && lods+=" / "
  done
  build/gimforge -q info "$SHARED/$m.ply" --json > "$OUT/${m}_in.json"
  python3 - "$OUT/$m.json" "$OUT/${m}_in.json" "$m" "$lods" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); i = json.load(open(sys.argv[2]))
topo = f"{i['genus'][0]} / {i['boundary_loops']}"
print(f"| {sys.argv[3]} | {i['faces']} | {topo} | {j['psnr']:.2f} | {j['stretch_efficiency']:.3f} | {j['floater_efficiency']:.4f} | "
      f"{j['cut_paths']:.0f} | {j['augmentations']:.0f} | {j['seconds_cut']:.2f} | {j['seconds_parametrize']:.1f} | "
      f"{j['seconds_sample']:.2f} | {j['seconds_total']:.1f} | {sys.argv[4]} |")
PY
done
