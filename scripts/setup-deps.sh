#!/usr/bin/env bash
# Installs every Debian 12 package gimforge needs to build, test and run. Idempotent: when everything is
# present it only checks (well under a second). Needs root or sudo for the install step.
#   scripts/setup-deps.sh            build, tests, demo
#   scripts/setup-deps.sh --bench    also Draco and matplotlib for bench/rd_curves.py
set -euo pipefail

# Every package here is used by the build, the tests or the demo (docs/development.md "Dependencies"):
# pkg-config and libboost-iostreams-dev are what OpenVDB's CMake find modules need; libopenmesh-dev is the
# quadric decimater of huge-scan proxies (kernels/scan/decimate.cpp). Not installed: GoogleMock (no test
# needs a mock).
PACKAGES=(
  build-essential cmake ninja-build pkg-config ccache
  libopenmpi-dev openmpi-bin
  libhdf5-openmpi-dev
  libembree-dev libtbb-dev libeigen3-dev
  libopenvdb-dev libboost-iostreams-dev
  libgtest-dev
  libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  libpng-dev
  # JPEG 2000 (kernels/codec: ROI coding of adaptive geometry images; the codec layer of compression)
  libopenjp2-7-dev
  libopenmesh-dev
  libtomlplusplus-dev
  # clang and its runtimes (libFuzzer, ASan, UBSan) for the fuzz harnesses: scripts/fuzz.sh, tests/fuzz.
  clang libclang-rt-14-dev
  python3 python3-h5py python3-numpy
  # Slurm for slurm/ and its test (tests/slurm): daemons, client commands, munge authentication.
  # libpmix-dev: Slurm's mpi/pmix plugin dlopens pmix2/lib/libpmix.so, which only the -dev package has
  # (without it: "srun: error: mpi/pmix_v4: init: ... can not load PMIx library").
  slurmctld slurmd slurm-client munge libpmix-dev
)

# With --bench also what only the benchmarks use: Draco's command-line coder (the baseline of
# bench/rd_curves.py, docs/compression.md) and matplotlib for its plots.
if [ "${1:-}" = "--bench" ]; then
  PACKAGES+=(draco python3-matplotlib)
fi

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup-deps: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "setup-deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then
  command -v sudo >/dev/null || { echo "setup-deps: need root or sudo to install packages" >&2; exit 1; }
  SUDO="sudo"
fi
export DEBIAN_FRONTEND=noninteractive
# Installing munge, slurmd and slurmctld must not start system daemons (the Slurm test starts its own in a
# temporary folder): while apt-get runs, a policy-rc.d forbids service starts, unless one exists already.
policy=/usr/sbin/policy-rc.d
if [ ! -e "$policy" ]; then
  printf '#!/bin/sh\n# temporary, from gimforge scripts/setup-deps.sh\nexit 101\n' | $SUDO tee "$policy" >/dev/null
  $SUDO chmod 755 "$policy"
  trap '$SUDO rm -f "$policy"' EXIT
fi
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
echo "setup-deps: done"
