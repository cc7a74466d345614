#!/usr/bin/env bash
# Installs every dependency from Debian packages (only what is missing, so it is safe to run twice) and
# builds mktree into build/. Usage: scripts/setup.sh [--no-build]
set -euo pipefail
cd "$(dirname "$0")/.."

PACKAGES=(
  build-essential cmake pkg-config
  libhdf5-dev        # HDF5 page store backend
  libboost-dev       # Boost.Interprocess (paged-file locks), Boost.Geometry (bench peer)
  libzstd-dev        # page codec
  libxxhash-dev      # page checksums (XXH3)
  libfast-float-dev  # OBJ reader: correctly rounded, fast number parsing
  libgtest-dev       # tests
  libassimp-dev      # glTF/PLY/STL/OFF/AC3D/... scene input
  libcli11-dev       # command line
  libpng-dev         # mktree render
  libbenchmark-dev   # bench/
  libspatialindex-dev libsqlite3-dev  # bench/ peers
  libcgal-dev        # bench/ clash peer, tests/ exact oracle
  libfcl-dev         # bench/ clash peer
  nlohmann-json3-dev # clash-test files and other JSON (engine/coordination)
  libzip-dev         # BCF archives (engine/report)
  # STEP input through OpenCASCADE (engine/scene/step_reader.cc)
  libocct-data-exchange-dev libocct-modeling-algorithms-dev libocct-modeling-data-dev libocct-foundation-dev
  libocct-ocaf-dev
  libembree-dev      # bench/ ray and nearest peer
  chromium           # tests: the HTML clash report loads in headless Chromium
  libxml2-utils      # tests: xmllint validates BCF archives against buildingSMART's XSD files
  time               # /usr/bin/time: peak RSS of the engines scripts/bench_clash.py runs
  nodejs             # IFC input: tools/ifc/mktree-ifc.mjs runs web-ifc under Node (20; npm comes with it)
  # The Python module (python/, docs/python.md), for Debian's /usr/bin/python3: pybind11's headers and
  # CMake package, Python's headers, numpy (its arrays in and out), pytest (python/run_tests.sh).
  pybind11-dev python3-dev python3-numpy python3-pytest
)
# The MPI build (CMake -DMKTREE_MPI=ON: mktree-mpi, docs/shards.md), only when asked: MKTREE_MPI=1.
if [ "${MKTREE_MPI:-0}" = 1 ]; then PACKAGES+=(libopenmpi-dev openmpi-bin); fi
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing ${missing[*]}"
  SUDO=""
  [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# IFC input: web-ifc, pinned by tools/ifc/package-lock.json, when missing or older than the lock file.
if [ ! -f tools/ifc/node_modules/web-ifc/package.json ] ||
  [ tools/ifc/package-lock.json -nt tools/ifc/node_modules/.package-lock.json ]; then
  echo "setup: installing web-ifc into tools/ifc/node_modules"
  npm ci --prefix tools/ifc --no-audit --no-fund --loglevel=error >/dev/null
fi

[ "${1:-}" = "--no-build" ] && exit 0
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DMKTREE_MPI="$([ "${MKTREE_MPI:-0}" = 1 ] && echo ON || echo OFF)" >/dev/null
cmake --build build -j "$(nproc)"
