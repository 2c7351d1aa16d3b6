#!/usr/bin/env bash
# Configures and builds gimforge (Release, warnings as errors) into build/. The executable is build/gimforge.
#   scripts/build.sh [extra cmake -D options]
# Environment: BUILD_DIR (default build), BUILD_TYPE (default Release), JOBS (default: nproc), TARGET (default
# all), GIMFORGE_CCACHE=0 (do not use ccache).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
BUILD_TYPE=${BUILD_TYPE:-Release}
JOBS=${JOBS:-$(nproc)}
GEN=()
command -v ninja >/dev/null && GEN=(-G Ninja)
# ccache (installed by setup-deps.sh) with the source root as its base directory: builds in other build
# directories or other clones of the repository reuse each other's objects.
LAUNCHER=()
if command -v ccache >/dev/null && [ "${GIMFORGE_CCACHE:-1}" != 0 ]; then
  LAUNCHER=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  export CCACHE_BASEDIR="$PWD" CCACHE_NOHASHDIR=1
fi
if [ ! -f "$BUILD_DIR/CMakeCache.txt" ]; then
  cmake -S . -B "$BUILD_DIR" "${GEN[@]}" -DCMAKE_BUILD_TYPE="$BUILD_TYPE" -DGIMFORGE_WERROR=ON "${LAUNCHER[@]}" "$@"
elif [ $# -gt 0 ]; then
  cmake -S . -B "$BUILD_DIR" "$@"
fi
cmake --build "$BUILD_DIR" -j "$JOBS" --target "${TARGET:-all}"
