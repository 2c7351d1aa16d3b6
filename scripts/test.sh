#!/usr/bin/env bash
# Installs dependencies, builds, and runs the tests (the table of what each stage costs, and what --full
# adds, is in docs/development.md "Test suite and CI budget"):
#   1. Release build (build/): every ctest suite — unit, pipeline, cli (end-to-end, bad input, batch with kills
#      and resume), python (h5py), mpi (2 and 4 ranks), tools, slurm — except the long trials (label "full").
#   2. ASan+UBSan build (build-asan/, -O1, line tables only): the unit suite (bad-input and hostile-file
#      cases included) and the CLI's bad-input, bad-option and damaged-archive cases again.
#
#   scripts/test.sh          what CI runs (.ci/run): fits the 25-minute budget on the 2-core machine
#   scripts/test.sh --full   also the long trials: ctest label "full", GIMFORGE_FULL_TESTS=1 (10 kills of a
#                            batch instead of 4, 10 concurrent-convert trials instead of 3), and every CLI,
#                            batch and MPI test under ASan+UBSan
# Set GIMFORGE_SKIP_ASAN=1 to skip step 2 during development.
set -euo pipefail
cd "$(dirname "$0")/.."
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
JOBS=${JOBS:-$(nproc)}
FULL=0
for arg in "$@"; do
  case "$arg" in
    --full) FULL=1 ;;
    *) echo "usage: scripts/test.sh [--full]" >&2; exit 2 ;;
  esac
done

STAGES=()
stage_start=$(date +%s)
# stage NAME: records how long the previous stage took, under NAME.
stage() {
  local now
  now=$(date +%s)
  STAGES+=("$(printf '%-34s %4d s' "$1" $((now - stage_start)))")
  stage_start=$now
}

scripts/setup-deps.sh
if [ -d ../shared/data/meshes ]; then
  echo "test: ../shared/data/meshes found: tests that use the shared meshes will run"
else
  echo "test: ../shared/data/meshes absent: tests that need it will be reported as skipped"
fi
stage "dependencies"

SELECT=(-LE full)
if [ "$FULL" = 1 ]; then
  export GIMFORGE_FULL_TESTS=1
  SELECT=()
fi

echo "== Release build"
scripts/build.sh
stage "release build"
echo "== Release tests"
(cd build && ctest -j "$JOBS" "${SELECT[@]}" --output-on-failure --timeout 600)
stage "release tests"

if [ "${GIMFORGE_SKIP_ASAN:-0}" != 1 ]; then
  echo "== ASan+UBSan build"
  # -O1 with line tables: what the sanitizers need for exact reports, at a fraction of -O2 -g's compile time.
  TARGET=$([ "$FULL" = 1 ] && echo all || echo asan_suite) BUILD_DIR=build-asan BUILD_TYPE=RelWithDebInfo \
    scripts/build.sh -DGIMFORGE_SANITIZE=ON -DGIMFORGE_BUILD_BENCH=OFF -DGIMFORGE_BUILD_TOOLS=OFF \
    "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG" "-DCMAKE_C_FLAGS_RELWITHDEBINFO=-O1 -g1 -DNDEBUG"
  stage "asan build"
  echo "== ASan+UBSan tests"
  export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  if [ "$FULL" = 1 ]; then
    (cd build-asan && ctest -j "$JOBS" -L "unit|pipeline|cli|mpi|python" --output-on-failure --timeout 1800)
  else
    # The longest conversions under ASan (77-88 s each, the pass's tail; the multi-chart ones 17-33 s) run in
    # the release pass and under ASan with --full; the other adaptive-sphere, batch-run, packing and
    # multi-chart tests cover their code under ASan here.
    (cd build-asan && ctest -j "$JOBS" -L unit -LE full --output-on-failure --timeout 900 \
       -E '^(SphereAdapt\.FlatOctahedronSamplesMoveAndStayGlued|BatchRunTest\.EveryMethodStoresTheStatisticsConvertRecords|McgimConvert\.(ClosedMeshesOfGenusZeroToThreeReconstructWatertight|AutoChartsKeepsTheCloserCountUnlessATie)|Pack\.(RefinementRaisesTheScaleWithinTheLastStep|ReproducibleAtAnyThreadCount)|AdaptiveGim\.ClosedSurfacesStayWatertight|SampleAdjust\.TheLargestDistanceNeverGrowsAndFalls|LocalFrameTest\.SphericalImagesDoNotDependOnTheTranslation)$')
    # The CLI's refusals of bad input, bad options and damaged archives (small files, no long conversions).
    (cd build-asan && ctest -j "$JOBS" -L cli -LE full --output-on-failure --timeout 900 \
       -R '^(Cli\.(HelpAndVersion|UsageErrorsExitWithTwo|InfoRepairsWithWarning)|CliBadInput\.|CliHostileArchive\.|CliGim\.RefusesMeshesItCannotConvert|CliSphere\.RefusesOtherGenusAndMisplacedOptions|CliRelief\.(DamagedArchiveIsOneClearError|BadOptionValuesAreUsageErrors)|RenderCli\.BadInput|CliCompress\.(DamagedPayloadsAndImpossibleRequestsAreOneLine|MultiChartImagesAreQuantizedAndCodedAndStayWatertight))')
  fi
  stage "asan tests"
fi

echo "== Stages"
printf '%s\n' "${STAGES[@]}"
echo "test: all suites passed"
