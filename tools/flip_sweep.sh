#!/bin/bash
# Damages an archive one byte at a time and sorts what `gimforge reconstruct` makes of each copy: the same
# mesh (the byte was unused or redundant), one error line, a silently different mesh (a defect: a damaged
# archive must not decode to a wrong surface), or a crash. BENCHMARKS.md, "Archive integrity".
#
#   tools/flip_sweep.sh ARCHIVE STEP [GIMFORGE]     # flips the byte at every STEP-th offset (XOR 0x10)
#
# Prints the counts, then the offsets of silent differences and crashes. Runs in a temporary folder.
set -u
archive=$(realpath "$1"); step=$2; gimforge=$(realpath "${3:-build/gimforge}")
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
cd "$work"
"$gimforge" -q reconstruct "$archive" -o ref.ply > /dev/null 2>&1 || { echo "$archive: does not reconstruct"; exit 1; }
size=$(stat -c %s "$archive")
same=0; errors=0; silent=0; crash=0; notes=""
for ((i = 0; i < size; i += step)); do
  cp "$archive" f.h5
  byte=$(od -An -tu1 -j"$i" -N1 "$archive" | tr -d ' ')
  printf "$(printf '\\x%02x' $((byte ^ 0x10)))" | dd of=f.h5 bs=1 seek="$i" conv=notrunc 2> /dev/null
  rm -f o.ply
  timeout 60 "$gimforge" -q reconstruct f.h5 -o o.ply > /dev/null 2>&1
  rc=$?
  if [ $rc -eq 0 ]; then
    if cmp -s o.ply ref.ply; then same=$((same + 1)); else silent=$((silent + 1)); notes+=" silent@$i"; fi
  elif [ $rc -eq 1 ]; then errors=$((errors + 1))
  else crash=$((crash + 1)); notes+=" rc$rc@$i"; fi
done
echo "flips=$(( (size + step - 1) / step )) same=$same errors=$errors silent=$silent crash=$crash"
[ -n "$notes" ] && echo "offsets:$notes"
exit 0
