#!/usr/bin/env bash
# The adaptive geometry images' table (issue #18, BENCHMARKS.md "Adaptive sampling"): every mesh converted
# with --sampling uniform and --sampling adaptive at the same size, the PSNR and the max (not RMS)
# Hausdorff distance of `gimforge convert`'s fidelity report for both, the wall time and peak memory of the
# whole command (/usr/bin/time -v), and the boundary / non-manifold edges of the adaptive image's
# reconstruction (`gimforge reconstruct`, then `gimforge info`).
# With METHOD=sphere in the environment: the flat-octahedron spherical image instead (--method sphere
# --domain flat-octa --n N, a (2N+1)² image), on closed genus-0 meshes; meshes not in MESH_DIR are taken
# from tests/data.
#   [METHOD=sphere] bench/adaptive_table.sh [BUILD_DIR] [MESH_DIR] [OUT_DIR] [extra convert options...]
set -euo pipefail
build=${1:-build}
meshes=${2:-../shared/data/meshes}
out=${3:-/tmp/gimforge_adaptive_table}
shift $(( $# < 3 ? $# : 3 ))
mkdir -p "$out"
rows=("cathead 65" "camel 193" "foot 193" "bunny_closed 129" "bunny_closed 257" "eight 129" "kitten 65" "kitten 129")
image=(--method gim --size)
if [ "${METHOD:-gim}" = sphere ]; then
  rows=("fist 64" "cow 64" "bunny_closed 64" "bunny_closed 128" "sphere_r1 16" "sphere_r1 32")
  image=(--method sphere --domain flat-octa --n)
fi
data=$(dirname "$0")/../tests/data
printf '| mesh | faces | n | uniform PSNR | adaptive PSNR | gain dB | uniform max | adaptive max | max ratio | start | rounds | moves | adjust s | command s (uniform / adaptive) | peak MiB | adaptive reconstruction boundary / non-manifold edges |\n'
printf '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n'
for row in "${rows[@]}"; do
  read -r mesh n <<<"$row"
  file="$meshes/$mesh.ply"
  [ -f "$file" ] || file="$data/$mesh.ply"
  for sampling in uniform adaptive; do
    rm -f "$out/${mesh}_${n}_$sampling.h5"
    /usr/bin/time -v "$build/gimforge" convert "$file" "${image[@]}" "$n" --sampling "$sampling" \
      "$@" -o "$out/${mesh}_${n}_$sampling.h5" --json >"$out/${mesh}_${n}_$sampling.json" 2>"$out/${mesh}_${n}_$sampling.time"
  done
  faces=$("$build/gimforge" info "$file" --json | python3 -c 'import json, sys; print(json.load(sys.stdin)["faces"])')
  rm -f "$out/${mesh}_${n}_adaptive.ply"
  "$build/gimforge" -q reconstruct "$out/${mesh}_${n}_adaptive.h5" -o "$out/${mesh}_${n}_adaptive.ply" >/dev/null
  edges=$("$build/gimforge" info "$out/${mesh}_${n}_adaptive.ply" --json |
    python3 -c 'import json, sys; d = json.load(sys.stdin); print(d["boundary_edges"], "/", d["nonmanifold_edges"])')
  python3 - "$out" "$mesh" "$n" "$faces" "$edges" <<'PY'
import json, re, sys
out, mesh, n, faces, edges = sys.argv[1:]
def load(s):
    d = json.load(open(f"{out}/{mesh}_{n}_{s}.json"))
    t = open(f"{out}/{mesh}_{n}_{s}.time").read()
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", t).group(1).split(":")
    secs = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall)))
    mem = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1)) / 1024
    return d.get("numbers", d), secs, mem
u, tu, mu = load("uniform")
a, ta, ma = load("adaptive")
print(f"| {mesh} | {int(faces):,} | {n} | {u['psnr']:.2f} | {a['psnr']:.2f} | "
      f"{a['psnr'] - u['psnr']:+.2f} | {u['hausdorff_max']:.3g} | {a['hausdorff_max']:.3g} | "
      f"{a['hausdorff_max'] / u['hausdorff_max']:.2f} | {'strips' if a.get('adapt_start_strips') else 'uniform'} | "
      f"{int(a['adapt_rounds_run'])} | {int(a['adapt_moves'])} | {a['seconds_adapt']:.1f} | {tu:.1f} / {ta:.1f} | {max(mu, ma):.0f} | {edges} |")
PY
done
