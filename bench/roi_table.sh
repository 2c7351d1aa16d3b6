#!/usr/bin/env bash
# The region-of-interest table of adaptive geometry images (issue #18 §4, paper Table 2; BENCHMARKS.md
# "Region of interest"): each mesh converted with --sampling adaptive --roi at the paper's rate rounded to a
# geometry-image size (fist 80 → 65, foot 150 → 129, cathead 40 → 65), and the directed Hausdorff distance
# from the ROI's reconstruction to the input (what the moves minimize) on the uniform start grid and at the
# end, the other direction inside the ROI, the figures outside it, the ROI's samples, the metric's PSNR of
# the whole image against the same conversion with uniform sampling, and the wall time and peak memory of
# the whole command (/usr/bin/time -v).
# METHOD sphere converts the same rows as flat-octahedron spherical images of the same width (--method sphere
# --domain flat-octa --n (N - 1) / 2; cathead, a disk, is left out: spherical adaptive sampling takes closed
# meshes).
#   bench/roi_table.sh [BUILD_DIR] [MESH_DIR] [OUT_DIR] [ROI] [GAIN] [METHOD]
set -euo pipefail
build=${1:-build}
meshes=${2:-../shared/data/meshes}
out=${3:-/tmp/gimforge_roi_table}
roi=${4:-auto}
gain=${5:-4}
mkdir -p "$out"
method=${6:-gim}
rows=("fist 65" "foot 129" "foot 193" "cathead 65")
[ "$method" = sphere ] && rows=("fist 65" "foot 129" "foot 193")
printf '| mesh | n | ROI samples before → after | ROI→input max before | after | ratio | ROI→input rms ratio | input→ROI max ratio | outside max ratio | PSNR uniform / ROI | command s | peak MiB |\n'
printf '|---|---|---|---|---|---|---|---|---|---|---|---|\n'
for row in "${rows[@]}"; do
  read -r mesh n <<<"$row"
  rm -f "$out/${mesh}_${n}_u.h5" "$out/${mesh}_${n}_roi.h5"
  image=(--method gim --size "$n")
  [ "$method" = sphere ] && image=(--method sphere --domain flat-octa --n $(((n - 1) / 2)))
  "$build/gimforge" convert "$meshes/$mesh.ply" "${image[@]}" -o "$out/${mesh}_${n}_u.h5" --json >"$out/${mesh}_${n}_u.json"
  /usr/bin/time -v "$build/gimforge" convert "$meshes/$mesh.ply" "${image[@]}" --sampling adaptive \
    --roi "$roi" --roi-gain "$gain" -o "$out/${mesh}_${n}_roi.h5" --json >"$out/${mesh}_${n}_roi.json" 2>"$out/${mesh}_${n}_roi.time"
  python3 - "$out" "$mesh" "$n" <<'PY'
import json, re, sys
out, mesh, n = sys.argv[1:]
u = json.load(open(f"{out}/{mesh}_{n}_u.json"))
a = json.load(open(f"{out}/{mesh}_{n}_roi.json"))
t = open(f"{out}/{mesh}_{n}_roi.time").read()
wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", t).group(1).split(":")
secs = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall)))
mem = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", t).group(1)) / 1024
r = lambda k: a[f"{k}_after"] / a[f"{k}_before"]
print(f"| {mesh} | {n} | {int(a['roi_samples_before'])} → {int(a['roi_samples_after'])} | "
      f"{a['roi_max_d2_before']:.3g} | {a['roi_max_d2_after']:.3g} | {r('roi_max_d2'):.2f} | {r('roi_rms_d2'):.2f} | "
      f"{r('roi_max_d1'):.2f} | {r('outside_max_d2'):.2f} | {u['psnr']:.2f} / {a['psnr']:.2f} | {secs:.1f} | {mem:.0f} |")
PY
done
