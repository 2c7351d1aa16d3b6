#!/usr/bin/env bash
# Installs dependencies, builds, and runs gimforge on the bundled sample meshes:
#   - `gimforge info` on each (topology: components, boundary loops, genus, flags),
#   - `gimforge metrics` between related meshes (symmetric Hausdorff distance and PSNR),
#   - `gimforge convert` to geometry images, spherical geometry images, relief maps and multi-chart
#     geometry images, reconstruct,
#     preview (and `render` the relief maps against the original meshes),
#   - `mpirun -n 2 gimforge batch` of a small collection into one consolidated archive.
# Uses tests/data (committed) and, when present, ../shared/data/meshes.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup-deps.sh
scripts/build.sh
GF=build/gimforge
OUT=${OUT:-out/demo}
mkdir -p "$OUT"

MESHES=(tests/data/cathead.ply tests/data/fist.ply tests/data/kitten.ply tests/data/sphere_r1.ply tests/data/cube.off tests/data/tetra.obj tests/data/cube_ascii.stl)
SHARED=../shared/data/meshes
if [ -d "$SHARED" ]; then
  for m in bunny bunny_closed cow camel eight hand buddha teapot dragon; do MESHES+=("$SHARED/$m.ply"); done
else
  echo "demo: $SHARED not found; using the meshes in tests/data only"
fi

echo "== gimforge info"
printf '%-26s %9s %9s %5s %6s %-12s %-6s %-8s %s\n' mesh vertices faces comps loops genus closed manifold bbox_diag
for m in "${MESHES[@]}"; do
  json="$OUT/$(basename "${m%.*}").info.json"
  "$GF" --quiet info "$m" --json > "$json"
  python3 - "$json" "$m" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
g = j["genus"]
genus = " ".join(str(x) for x in g[:4]) + (f" +{len(g)-4}" if len(g) > 4 else "")
print(f'{sys.argv[2].split("/")[-1]:<26} {j["vertices"]:>9} {j["faces"]:>9} {j["components"]:>5} {j["boundary_loops"]:>6} '
      f'{genus:<12} {str(j["closed"]).lower():<6} {str(j["manifold"]).lower():<8} {j["bbox_diagonal"]:.6g}')
PY
done

echo
echo "== gimforge metrics"
echo "-- concentric icospheres r = 1 and r = 1.01: expect d = 0.01, PSNR = 20 log10(3.464/0.01) = 50.8 dB"
"$GF" metrics tests/data/sphere_r1.ply tests/data/sphere_r1.01.ply --samples 500000
echo "-- a mesh against itself: distance 0 up to rounding"
"$GF" metrics tests/data/kitten.ply tests/data/kitten.ply --samples 200000 --json
if [ -d "$SHARED" ]; then
  echo "-- the 871K-face Stanford dragon against itself (2 x 1M samples + all vertices)"
  "$GF" --quiet metrics "$SHARED/dragon.ply" "$SHARED/dragon.ply"
fi
echo
# convert_all ARCHIVE SUFFIX LOD_LEVEL LOD_TAG "CONVERT OPTIONS" MESH...: converts every mesh into ARCHIVE, then
# reconstructs each at level 0 and at LOD_LEVEL and writes its previews.
convert_all() {
  local archive=$1 suffix=$2 level=$3 tag=$4 options=$5 m name
  shift 5
  rm -f "$archive"
  for m in "$@"; do
    # shellcheck disable=SC2086  # options are words
    "$GF" convert "$m" $options --metric-samples 300000 -o "$archive"
  done
  for m in "$@"; do
    name=$(basename "${m%.*}")
    "$GF" reconstruct "$archive" --name "$name" -o "$OUT/${name}_$suffix.ply"
    "$GF" reconstruct "$archive" --name "$name" --level "$level" -o "$OUT/${name}_${suffix}_$tag.ply"
    "$GF" preview "$archive" --name "$name" -o "$OUT/previews" > /dev/null
  done
}

echo "== gimforge convert --method gim (geometry images, 257x257, normal map 512x512)"
GIM_MESHES=(tests/data/kitten.ply tests/data/fist.ply tests/data/cathead.ply)
[ -d "$SHARED" ] && GIM_MESHES+=("$SHARED/bunny_closed.ply" "$SHARED/eight.ply")
convert_all "$OUT/gim.h5" gim 2 65 "--method gim --size 257" "${GIM_MESHES[@]}"
echo
echo "== gimforge convert --method sphere (spherical geometry images: octahedron, 257x257)"
SPHERE_MESHES=(tests/data/fist.ply tests/data/cathead.ply)   # closed genus 0; a disk (its hole is masked)
[ -d "$SHARED" ] && SPHERE_MESHES+=("$SHARED/bunny_closed.ply")
convert_all "$OUT/sphere.h5" sphere 5 n4 "--method sphere --domain octa --n 128" "${SPHERE_MESHES[@]}"
echo
echo "== gimforge convert --method relief (relief maps on cubic cells, 64x64 textures)"
rm -f "$OUT/relief.h5"
RELIEF_MESHES=(tests/data/kitten.ply:auto tests/data/cathead.ply:auto tests/data/fist.ply:auto)
[ -d "$SHARED" ] && RELIEF_MESHES+=("$SHARED/bunny_closed.ply:16" "$SHARED/teapot.ply:16" "$SHARED/dragon.ply:16")
for item in "${RELIEF_MESHES[@]}"; do
  m=${item%:*}
  "$GF" convert "$m" --method relief --grid "${item##*:}" --texture 64 --metric-samples 300000 -o "$OUT/relief.h5"
done
for item in "${RELIEF_MESHES[@]}"; do
  name=$(basename "${item%:*}" .ply)
  "$GF" reconstruct "$OUT/relief.h5" --name "relief/$name" -o "$OUT/${name}_relief.ply"
  "$GF" preview "$OUT/relief.h5" --name "relief/$name" -o "$OUT/previews" > /dev/null
  # CPU ray casting of the distance maps beside an Embree render of the original (image PSNR, IoU).
  "$GF" render "$OUT/relief.h5" --name "relief/$name" --view 30,20 --size 512 -o "$OUT/${name}_relief_render.png" \
    --reference "${item%:*}"
done
echo
echo "== gimforge convert --method mcgim (multi-chart geometry images, at most 66049 samples, 24 charts)"
rm -f "$OUT/mcgim.h5"
MCGIM_MESHES=(tests/data/fist.ply tests/data/kitten.ply)
[ -d "$SHARED" ] && MCGIM_MESHES+=("$SHARED/camel.ply" "$SHARED/teapot.ply")
for m in "${MCGIM_MESHES[@]}"; do
  "$GF" convert "$m" --method mcgim --samples 66049 --charts 24 --metric-samples 300000 -o "$OUT/mcgim.h5"
  name=$(basename "${m%.*}")
  "$GF" reconstruct "$OUT/mcgim.h5" --name "mcgim/$name" -o "$OUT/${name}_mcgim.ply"
  "$GF" preview "$OUT/mcgim.h5" --name "mcgim/$name" -o "$OUT/previews" > /dev/null
done
echo
echo "== gimforge compress: every geometry image within 8,000 stored bytes, decoded and fused by reconstruct"
rm -f "$OUT/gim_8k.h5"
"$GF" compress "$OUT/gim.h5" --bytes 8000 --metric-samples 100000 -o "$OUT/gim_8k.h5"
"$GF" reconstruct "$OUT/gim_8k.h5" --name gim/kitten -o "$OUT/kitten_8k.ply"
echo
echo "== gimforge batch under mpirun -n 2 (one consolidated archive; 1 master + 1 worker rank)"
rm -rf "$OUT/collection" "$OUT/batch.h5" "$OUT/batch.h5.work"
mkdir -p "$OUT/collection/closed" "$OUT/collection/open"
cp tests/data/fist.ply tests/data/kitten.ply tests/data/sphere_r1.ply "$OUT/collection/closed/"
cp tests/data/cathead.ply "$OUT/collection/open/"
[ -d "$SHARED" ] && cp "$SHARED/cow.ply" "$SHARED/foot.ply" "$OUT/collection/closed/"
MPIRUN=(mpirun -n 2 --oversubscribe --bind-to none)
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
"${MPIRUN[@]}" "$GF" batch --input "$OUT/collection" --method gim --size 129 -o "$OUT/batch.h5"
for py in /usr/bin/python3 python3; do  # Debian's python3 has h5py (setup-deps installs python3-h5py)
  if command -v "$py" >/dev/null && "$py" -c "import h5py" 2>/dev/null; then
    "$py" examples/load_archive.py "$OUT/batch.h5"
    break
  fi
done
echo "demo: batch archive $OUT/batch.h5 — load it with: python3 examples/load_archive.py $OUT/batch.h5"
echo
echo "demo: per-mesh JSON reports, reconstructions and previews are in $OUT/"
echo "demo: the archive is $OUT/gim.h5; load it with h5py: h5py.File('$OUT/gim.h5')['gim/kitten']['geometry'][...]"
