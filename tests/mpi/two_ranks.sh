#!/usr/bin/env bash
# The sharded build on two MPI ranks (tools/mpi/mpi_build.cc): every answer of its manifest, AABB and
# exact, equals the unsharded store's and the single-process sharded build's; a failed build leaves no file.
#   tests/mpi/two_ranks.sh MKTREE_MPI MKTREE MPIEXEC
set -euo pipefail
mpi=$1 m=$2 mpiexec=$3
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
run() { "$mpiexec" -n 2 --allow-run-as-root --oversubscribe "$@"; }
"$m" build tanker:30000:4 -o "$dir/plain.mkt" -q
"$m" build tanker:30000:4 -o "$dir/one.mkts" --shards 3 -q
run "$mpi" tanker:30000:4 -o "$dir/two.mkts" --shards 3 --backend pagefile --threads 1
"$m" generate queries "$dir/plain.mkt" --count 200 --seed 3 -o "$dir/q.txt"
for mode in "" --exact; do
  for s in plain.mkt one.mkts two.mkts; do
    "$m" query "$dir/$s" --queries "$dir/q.txt" $mode | python3 -c '
import json, sys
for line in sys.stdin:
    print(json.dumps(json.loads(line)["hits"]))' >"$dir/$s.hits"
  done
  cmp "$dir/plain.mkt.hits" "$dir/two.mkts.hits"
  cmp "$dir/one.mkts.hits" "$dir/two.mkts.hits"
  [[ $(grep -c . "$dir/two.mkts.hits") -eq 800 ]]
  [[ $(grep -vc '^\[\]$' "$dir/two.mkts.hits") -gt 100 ]]
done
# The same shards as the single-process build (the top levels do not depend on the ranks).
"$m" info "$dir/one.mkts" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["top_levels"])' >"$dir/one.top"
"$m" info "$dir/two.mkts" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["top_levels"])' >"$dir/two.top"
cmp "$dir/one.top" "$dir/two.top"
# Too many shards for the scene: an error on every rank, no file left.
if run "$mpi" tanker:3:1 -o "$dir/bad.mkts" --shards 5 2>"$dir/err"; then exit 1; fi
grep -q "cannot make 5 shards" "$dir/err"
[[ -z $(ls "$dir" | grep '^bad') ]]
echo "mpi two ranks: ok"
