#!/usr/bin/env bash
# The Python module's tests (docs/python.md), as .ci/run runs them: builds the module in BUILD (default
# build), installs it alone into a temporary prefix (`cmake --install --component python`), and runs
# pytest on python/tests with that prefix on PYTHONPATH, with the interpreter CMake built it for.
# pytest's exit code 5 (no test collected) is a failure.
#   python/run_tests.sh [BUILD]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
scripts/setup.sh --no-build  # pybind11-dev, python3-numpy, python3-pytest among the rest
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release -DMKTREE_BUILD_PYTHON=ON >/dev/null
cmake --build "$build" -j "$(nproc)" --target mktree_python
py=$(sed -n 's/^Python_EXECUTABLE:FILEPATH=//p' "$build/CMakeCache.txt")
[[ -x $py ]] || { echo "FAIL: no Python_EXECUTABLE in $build/CMakeCache.txt" >&2; exit 1; }
prefix=$(mktemp -d "${TMPDIR:-/tmp}/mktree_python.XXXXXX")
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --component python --prefix "$prefix" >/dev/null
site=$(dirname "$(find "$prefix" -name 'mktree*.so' | head -n1)")
[[ $site == "$prefix"/* ]] || { echo "FAIL: the python component installed no module" >&2; exit 1; }
# The installed module, not the build tree's, is the one tested.
PYTHONPATH=$site "$py" -c "import mktree, sys; assert mktree.__file__.startswith('$prefix'), mktree.__file__"
rc=0
PYTHONPATH=$site "$py" -m pytest -q -p no:cacheprovider python/tests || rc=$?
if ((rc == 5)); then
  echo "FAIL: pytest collected no test in python/tests" >&2
  exit 1
fi
exit "$rc"
