#!/usr/bin/env bash
# Builds the tests with sanitizers (Debian's gcc; CMake option MKTREE_SANITIZE) into a build directory of
# their own and runs them with ctest.
#
# Usage: scripts/sanitize.sh address|thread [extra ctest arguments, e.g. -R PageCache]
#   address  ASan + UBSan (+ LeakSanitizer) in build-asan/: the whole suite, except the tests labelled rss
#            or memlimit (they assert on peak RSS or run under an address-space limit, which the
#            sanitizer's shadow memory makes meaningless) and heavy (the slowest under ASan, whose code
#            smaller tests cover; tests/CMakeLists.txt)
#   thread   TSan in build-tsan/: the tests labelled concurrency (tests/CMakeLists.txt), building only the
#            programs that hold them (target mktree_concurrency_tests)
# A finding fails its test (-fno-sanitize-recover=all; LeakSanitizer and TSan reports make the program
# exit non-zero); suppressions, only for libraries we do not own: tests/sanitizers/.
# Set CMAKE_CXX_COMPILER_LAUNCHER=ccache to rebuild faster; nothing here needs it.
set -euo pipefail
cd "$(dirname "$0")/.."

flavour="${1:-}"
case "$flavour" in
  address) build=build-asan; sanitize=address,undefined; select=(-LE "rss|memlimit|heavy"); targets=(all) ;;
  thread) build=build-tsan; sanitize=thread; select=(-L concurrency); targets=(mktree_concurrency_tests) ;;
  *) echo "usage: scripts/sanitize.sh address|thread [ctest arguments]" >&2; exit 2 ;;
esac
shift

scripts/setup.sh --no-build  # the libraries; gcc's sanitizer runtimes come with build-essential
jobs="$(nproc)"
# -O1 -g1, as the sanitizers' own documentation advises: optimized enough to run the suite, and the line
# tables their reports print. RelWithDebInfo's -O2 -g compiles twice as long (bench/README.md, "CI time").
flags="-O1 -g1 -DNDEBUG"
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="$flags" \
  -DCMAKE_C_FLAGS_RELWITHDEBINFO="$flags" -DMKTREE_SANITIZE="$sanitize" -DMKTREE_BUILD_BENCH=OFF >/dev/null
cmake --build "$build" -j "$jobs" --target "${targets[@]}"

# The sanitizers of gcc 12 map their shadow memory at fixed addresses, which kernels that randomise
# mmap with more than 28 bits can collide with; without address randomisation they work there too.
run=()
rnd_bits="$(cat /proc/sys/vm/mmap_rnd_bits 2>/dev/null || echo 28)"
if ((rnd_bits > 28)) && setarch "$(uname -m)" -R true 2>/dev/null; then
  run=(setarch "$(uname -m)" -R)
fi
"${run[@]}" ctest --test-dir "$build" --output-on-failure -j "$jobs" "${select[@]}" "$@"
