#!/usr/bin/env bash
# The MPI build (docs/shards.md, "On MPI ranks") and its tests: installs Open MPI if missing, configures
# build-mpi/ with -DMKTREE_MPI=ON, builds only mktree and mktree-mpi, and runs the tests labelled mpi
# (tests/mpi/ranks.sh at 2, 3 and 4 ranks). Usage: scripts/mpi_test.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
dir=${1:-build-mpi}
MKTREE_MPI=1 scripts/setup.sh --no-build
cmake -S . -B "$dir" -DCMAKE_BUILD_TYPE=Release -DMKTREE_MPI=ON ${CMAKE_CXX_COMPILER_LAUNCHER:+-DCMAKE_CXX_COMPILER_LAUNCHER="$CMAKE_CXX_COMPILER_LAUNCHER"} >/dev/null
cmake --build "$dir" -j "$(nproc)" --target mktree mktree-mpi
ctest --test-dir "$dir" -L mpi --output-on-failure
