#!/usr/bin/env bash
# The ctest tests Package_installed and Package_subdirectory (label package, docs/package.md): builds the
# consumer project (consumer/) out of tree, in a temporary directory removed afterwards, and runs it on a
# grid scene whose answers it checks by brute force; the consumer also builds the grid through the build
# API (mktree/build.h) and checks that store the same way.
#   installed     cmake --install of BUILD into a temporary prefix; checks what is installed and
#                 `mktree --version`; the consumer through find_package (static and shared; from a C++
#                 project and from one that enables C too) and through pkg-config (shared and static).
#                 Reuses BUILD's libraries: compiles only main.cc.
#   subdirectory  the consumer through add_subdirectory of SOURCE (as FetchContent does): compiles the
#                 library (only its targets) from the source tree.
# Usage: run.sh installed|subdirectory CMAKE SOURCE BUILD CXX [LAUNCHER]
set -euo pipefail
[[ $# -ge 5 ]] || { echo "usage: run.sh installed|subdirectory CMAKE SOURCE BUILD CXX [LAUNCHER]" >&2; exit 2; }
mode=$1 cmake=$2 src=$3 build=$4 cxx=$5 launcher=${6:-}
version=$(sed -nE 's/^project\(mktree .*VERSION ([0-9.]+)\)$/\1/p' "$src/CMakeLists.txt")
[[ -n $version ]] || { echo "FAIL: no project VERSION in $src/CMakeLists.txt" >&2; exit 1; }
jobs=$(nproc)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/mktree_package.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
step() { echo "== $* ($SECONDS s)"; }

# The scene: n^3 unit cubes, cube (i, j, k) at 2 * (i, j, k), named cube_i_j_k (consumer/main.cc).
n=8
awk -v n=$n 'BEGIN {
  split("1 3 2,2 3 4,5 6 7,6 8 7,1 2 5,2 6 5,3 7 4,4 7 8,1 5 3,3 5 7,2 4 6,4 8 6", faces, ",")
  v = 0
  for (i = 0; i < n; i++) for (j = 0; j < n; j++) for (k = 0; k < n; k++) {
    printf "o cube_%d_%d_%d\n", i, j, k
    for (c = 0; c < 8; c++) printf "v %d %d %d\n", 2 * i + c % 2, 2 * j + int(c / 2) % 2, 2 * k + int(c / 4)
    for (t = 1; t <= 12; t++) { split(faces[t], f, " "); printf "f %d %d %d\n", v + f[1], v + f[2], v + f[3] }
    v += 8
  }
}' >"$tmp/grid.obj"

run_consumer() {  # run_consumer PROGRAM: runs it on the grid store, checks its version line
  local out
  out=$("$1" "$tmp/grid.mkt" $n) || { echo "$out"; fail "$1"; }
  echo "$out"
  [[ $(head -n1 <<<"$out") == "mktree $version ("* ]] || fail "$1 printed no 'mktree $version' line"
}

configure=("$cmake" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER="$cxx")
[[ -n $launcher ]] && configure+=(-DCMAKE_CXX_COMPILER_LAUNCHER="$launcher")

case "$mode" in
  installed)
    prefix=$tmp/prefix
    step "cmake --install $build --prefix $prefix"
    "$cmake" --install "$build" --prefix "$prefix" >/dev/null
    # Only the public headers, the libraries, the STEP reader's module, the package files, the tool and the
    # licence.
    unexpected=$(find "$prefix" \( -type f -o -type l \) | sed "s|^$prefix/||" | grep -vE \
      '^include/mktree/[a-z_]+\.h$|^lib(64|/[a-z0-9_-]+)?/(libmktree\.(a|so(\.[0-9.]+)?)|mktree/libmktree_step\.so|cmake/mktree/mktree(Config|ConfigVersion|Targets(-[a-z]+)?)\.cmake|pkgconfig/mktree\.pc)$|^bin/mktree$|^share/doc/mktree/LICENSE$' || true)
    [[ -z $unexpected ]] || fail "installed beyond the package: $unexpected"
    for h in "$src"/include/mktree/*.h version.h; do
      [[ -f $prefix/include/mktree/$(basename "$h") ]] || fail "not installed: include/mktree/$(basename "$h")"
    done
    count() { find "$1" -maxdepth 1 -type f | wc -l; }
    [[ $(count "$prefix/include/mktree") -eq $(($(count "$src/include/mktree") + 1)) ]] ||
      fail "include/mktree holds other headers than the source tree's and version.h"
    pc=$(find "$prefix" -name mktree.pc)
    [[ -n $pc ]] || fail "no mktree.pc"
    [[ $("$prefix/bin/mktree" --version) == "mktree $version" ]] || fail "mktree --version"
    "$prefix/bin/mktree" build "$tmp/grid.obj" -o "$tmp/grid.mkt" -q
    # The installed tool finds the installed STEP module beside the libraries (engine/scene/step_reader.h).
    [[ -n $(find "$prefix" -name libmktree_step.so) ]] || fail "libmktree_step.so is not installed"
    "$prefix/bin/mktree" build "$src/tests/data/step/engine_assembly.step" -o "$tmp/engine.mkt" -q ||
      fail "the installed mktree does not read STEP"

    step "find_package(mktree) against the install"
    "${configure[@]}" -S "$src/tests/package/consumer" -B "$tmp/fp" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
    "$cmake" --build "$tmp/fp" -j "$jobs" >/dev/null
    run_consumer "$tmp/fp/consumer"
    # (ldd's output is read whole: grep -q would close the pipe early, which pipefail reports.)
    [[ $(ldd "$tmp/fp/consumer") != *libmktree* ]] || fail "consumer (mktree::mktree) is not linked statically"
    # libmktree.so unless BUILD has MKTREE_BUILD_SHARED off.
    shared=$(find "$prefix" -name libmktree.so)
    if [[ -n $shared ]]; then
      [[ -x $tmp/fp/consumer_shared ]] || fail "the install has libmktree.so but no mktree::mktree_shared"
      [[ $(ldd "$tmp/fp/consumer_shared") == *"$prefix/"*libmktree.so* ]] ||
        fail "consumer_shared does not load the installed libmktree.so"
      run_consumer "$tmp/fp/consumer_shared"
    fi
    step "find_package(mktree) from a project that enables C (HDF5 through FindHDF5)"
    "${configure[@]}" -S "$src/tests/package/consumer" -B "$tmp/fpc" -DCMAKE_PREFIX_PATH="$prefix" \
      -DMKTREE_CONSUMER_ENABLE_C=ON >/dev/null
    "$cmake" --build "$tmp/fpc" --target consumer >/dev/null
    run_consumer "$tmp/fpc/consumer"

    step "pkg-config mktree"
    PKG_CONFIG_PATH=$(dirname "$pc")
    export PKG_CONFIG_PATH
    [[ $(pkg-config --modversion mktree) == "$version" ]] || fail "pkg-config --modversion mktree"
    libdir=$(pkg-config --variable=libdir mktree)
    if [[ -n $shared ]]; then
      # shellcheck disable=SC2046  # pkg-config prints one flag per word
      "$cxx" -std=c++20 -O1 "$src/tests/package/consumer/main.cc" -o "$tmp/pc_shared" $(pkg-config --cflags mktree) \
        $(pkg-config --libs mktree) -Wl,-rpath,"$libdir"
      run_consumer "$tmp/pc_shared"
    fi
    # With both installed, -lmktree finds libmktree.so: the archive is named (docs/package.md).
    # shellcheck disable=SC2046
    "$cxx" -std=c++20 -O1 "$src/tests/package/consumer/main.cc" -o "$tmp/pc_static" $(pkg-config --cflags mktree) \
      $(pkg-config --static --libs mktree | sed -E 's/-lmktree( |$)/-l:libmktree.a /')
    [[ $(ldd "$tmp/pc_static") != *libmktree* ]] || fail "pc_static is not linked statically"
    run_consumer "$tmp/pc_static"
    ;;
  subdirectory)
    "$build/mktree" build "$tmp/grid.obj" -o "$tmp/grid.mkt" -q
    step "add_subdirectory($src)"
    # No build type (no -O, no -g): the library compiles faster unoptimised, and mktree leaves the
    # parent's build type alone.
    "${configure[@]}" -S "$src/tests/package/consumer" -B "$tmp/sub" -DMKTREE_CONSUMER_VIA=add_subdirectory \
      -DMKTREE_SOURCE_DIR="$src" -DMKTREE_BUILD_SHARED=OFF -DCMAKE_BUILD_TYPE= >/dev/null
    "$cmake" --build "$tmp/sub" -j "$jobs" --target consumer >/dev/null
    run_consumer "$tmp/sub/consumer"
    ;;
  *) fail "unknown mode $mode" ;;
esac
step "passed"
