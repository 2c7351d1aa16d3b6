#!/usr/bin/env bash
# Multi-chart geometry-image table (BENCHMARKS.md, "Multi-chart geometry images"): converts every shared mesh
# at the memory cost of a 257x257 geometry image (--samples 66049), with the default --charts auto, without
# and with --optimize, plus the project's own 257x257 geometry image with --optimize for the meshes gim
# converts; reports PSNR (1M samples per direction), stretch and packing efficiency, charts, the whole
# command's time and peak memory (/usr/bin/time), and whether the reconstruction is closed and manifold.
#   scripts/bench_mcgim.sh [MESH...]      (default: every shared mesh; THREADS=1 by default: one core)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh >/dev/null
SHARED=${SHARED:-../shared/data/meshes}
OUT=${OUT:-out/bench_mcgim}
THREADS=${THREADS:-1}
mkdir -p "$OUT"
MESHES=("$@")
[ ${#MESHES[@]} -gt 0 ] || MESHES=(bunny_closed camel cow hand buddha fist foot kitten eight cathead bunny teapot teapot_patches dragon)
printf '| mesh | faces | method | PSNR (dB) | stretch eff. | packing eff. | charts | W×H | boundary / non-manifold edges | command s | peak MB |\n'
printf '|---|---|---|---|---|---|---|---|---|---|---|\n'
for m in "${MESHES[@]}"; do
  faces=$(build/gimforge -q info "$SHARED/$m.ply" --json 2>/dev/null | python3 -c "import json,sys; print(json.load(sys.stdin)['faces'])")
  for variant in mcgim mcgim_opt gim_opt; do
    case $variant in
      mcgim) args=(--method mcgim --samples 66049) ;;
      mcgim_opt) args=(--method mcgim --samples 66049 --optimize) ;;
      gim_opt) args=(--method gim --size 257 --optimize) ;;
    esac
    rm -f "$OUT/$m.$variant.h5"
    if ! /usr/bin/time -f '%e %M' -o "$OUT/$m.$variant.time" build/gimforge -q -j "$THREADS" convert "$SHARED/$m.ply" \
        "${args[@]}" -o "$OUT/$m.$variant.h5" --json > "$OUT/$m.$variant.json" 2> "$OUT/$m.$variant.err"; then
      printf '| %s | %s | %s | refused: %s |\n' "$m" "$faces" "$variant" "$(tail -1 "$OUT/$m.$variant.err")"
      continue
    fi
    build/gimforge -q reconstruct "$OUT/$m.$variant.h5" -o "$OUT/$m.$variant.ply" > /dev/null
    build/gimforge -q info "$OUT/$m.$variant.ply" --json > "$OUT/$m.$variant.info.json" 2> /dev/null || true
    python3 - "$OUT/$m.$variant" "$m" "$variant" "$faces" <<'PY'
import json, sys
base, mesh, variant, faces = sys.argv[1:]
j = json.load(open(base + ".json")); i = json.load(open(base + ".info.json"))
seconds, kb = open(base + ".time").read().split()
charts = f"{j['charts']:.0f}" if "charts" in j else "1"
size = f"{j['width']}×{j['height']}" if "width" in j else "257×257"
packing = f"{j['packing_efficiency']:.3f}" if "packing_efficiency" in j else "1"
print(f"| {mesh} | {faces} | {variant} | {j['psnr']:.2f} | {j['stretch_efficiency']:.3f} | {packing} | "
      f"{charts} | {size} | {i['boundary_edges']} / {i['nonmanifold_edges']} | {float(seconds):.1f} | {int(kb) / 1024:.0f} |")
PY
  done
done
