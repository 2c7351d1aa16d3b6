#!/usr/bin/env bash
# Spherical geometry-image acceptance table (BENCHMARKS.md): converts every closed genus-0 shared mesh with
# all four domains on ONE thread (octa and flat-octa n = 128, tetra n = 181, cube n = 104: the paper's
# Table 3 sizes, about 66K samples each), then the bunny with holes (octa). Reports PSNR (1M samples per
# direction), L2 stretch efficiencies (S->M, D->S, D->M), time per stage, flipped spherical triangles,
# and checks that the reconstructions at level 0 and at the coarsest level (n halved while even; tetra
# n = 181 has only level 0) are closed and manifold.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build.sh >/dev/null
SHARED=${SHARED:-../shared/data/meshes}
OUT=${OUT:-out/bench_sphere}
MESHES=${MESHES:-bunny_closed cow camel fist foot bunny}
mkdir -p "$OUT"
rm -f "$OUT/sphere.h5"
printf '| mesh | faces | domain | n | PSNR (dB) | S->M eff. | D->S eff. | D->M eff. | flipped | masked samples | simplify s | optimize s | sample s | total s | recon L0 / coarsest: boundary loops, non-manifold edges |\n'
printf '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n'
for m in $MESHES; do
  domains="octa tetra cube flat-octa"
  [ "$m" = bunny ] && domains="octa"
  for d in $domains; do
    case $d in tetra) n=181 ;; cube) n=104 ;; *) n=128 ;; esac
    name="${m}_$d"
    build/gimforge -q -j 1 convert "$SHARED/$m.ply" --method sphere --domain "$d" --n "$n" --name "$name" \
      -o "$OUT/sphere.h5" --json > "$OUT/$name.json"
    # The coarsest level: n divided by 2 while even.
    coarsest=0; k=$n
    while [ $((k % 2)) -eq 0 ]; do k=$((k / 2)); coarsest=$((coarsest + 1)); done
    recon=""
    levels="0"; [ "$coarsest" -gt 0 ] && levels="0 $coarsest"
    for level in $levels; do
      build/gimforge -q reconstruct "$OUT/sphere.h5" --name "spherical/$name" --level "$level" -o "$OUT/${name}_L$level.ply" > /dev/null
      build/gimforge -q info "$OUT/${name}_L$level.ply" --json > "$OUT/${name}_L$level.json"
      recon+=$(python3 -c "import json; j=json.load(open('$OUT/${name}_L$level.json')); print(f\"{j['boundary_loops']},{j['nonmanifold_edges']}\", end='')")
      [ "$level" = 0 ] && [ "$coarsest" -gt 0 ] && recon+=" / "
    done
    python3 - "$OUT/$name.json" "$m" "$recon" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
print(f"| {sys.argv[2]} | {j.get('input_faces', '')} | {j['domain']} | {j['n']} | {j['psnr']:.2f} | {j['map_efficiency']:.3f} | "
      f"{j['domain_efficiency']:.4f} | {j['efficiency_domain_to_mesh']:.3f} | {j['flipped_triangles']:.0f} | {j['masked_samples']:.0f} | "
      f"{j['seconds_simplify']:.2f} | {j['seconds_optimize']:.1f} | {j['seconds_sample']:.2f} | {j['seconds_total']:.1f} | {sys.argv[3]} |")
PY
  done
done
