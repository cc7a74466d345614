#!/usr/bin/env bash
# mktree-mpi query and clash on a sharded store that has taken changes (docs/shards.md, "On MPI ranks";
# docs/changes.md, "Sharded stores"): at every kept revision, before and after a compaction, on R ranks
# and on 1, with K shards (K > R: a rank owns two; K < R: a rank owns no shard, and no delta, as deltas go
# with their shards), the hits of every query and the pair lines (with names) are those of `mktree query`
# and `mktree clash` on the one-process Database of the same revision. Batches replace
# objects with others across the scene, remove some and add a second tanker's. A revision that is not
# kept, a damaged delta store and a damaged delta id file fail every rank, naming them, printing nothing.
#   tests/mpi/changes.sh R K MKTREE_MPI MKTREE MPIEXEC
set -euo pipefail
ranks=$1 k=$2 mpi=$3 m=$4 mpiexec=$5
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
source "$(dirname "$0")/common.sh"
hits() {  # each query's hits, one line a query
  python3 -c '
import json, sys
for l in open(sys.argv[1]):
    print(json.loads(l)["hits"])' "$1"
}
s="$dir/c.mkts"
"$m" build tanker:6000:3 -o "$s" --shards $k -q
"$m" generate tanker --objects 60 --seed 7 -o "$dir/moved.obj" >/dev/null
"$m" generate tanker --objects 60 --seed 9 -o "$dir/moved2.obj" >/dev/null
"$m" generate tanker --objects 300 --seed 8 -o "$dir/more.obj" >/dev/null
"$m" build tanker:6000:3 -o "$dir/plain.mkt" -q  # the queries fall in its bounds
"$m" generate queries "$dir/plain.mkt" -o "$dir/q" --count 60 --seed 4 >/dev/null
# Answers of revision $1 (empty: the newest) through both tools; with $2 = full, exact queries and the
# clash on 1 rank too.
check() {
  local rev=() tag=${1:-newest}
  [[ -n ${1:-} ]] && rev=(--revision "$1")
  "$m" query "$s" --queries "$dir/q" "${rev[@]}" >"$dir/one.q"
  run "$mpi" query "$s" --queries "$dir/q" "${rev[@]}" >"$dir/mpi.q" 2>"$dir/err"
  cmp <(hits "$dir/one.q") <(hits "$dir/mpi.q") || { echo "query hits differ at revision $tag"; exit 1; }
  if [[ ${2:-} == full ]]; then
    "$m" query "$s" --queries "$dir/q" --exact "${rev[@]}" >"$dir/one.q"
    run "$mpi" query "$s" --queries "$dir/q" --exact "${rev[@]}" >"$dir/mpi.q" 2>/dev/null
    cmp <(hits "$dir/one.q") <(hits "$dir/mpi.q") || { echo "exact hits differ at revision $tag"; exit 1; }
  fi
  "$m" clash "$s" --threads 1 --names --clearance 0.01 "${rev[@]}" >"$dir/one.c"
  run "$mpi" clash "$s" --names --clearance 0.01 "${rev[@]}" >"$dir/mpi.c" 2>"$dir/err.c"
  cmp <(by_pair "$dir/one.c") "$dir/mpi.c" || { echo "pairs differ at revision $tag"; exit 1; }
  [[ $(grep -c . "$dir/mpi.c") -gt 100 ]]
  if [[ ${2:-} == full ]]; then
    run_on 1 "$mpi" clash "$s" --names --clearance 0.01 "${rev[@]}" >"$dir/mpi1.c" 2>/dev/null
    cmp "$dir/mpi.c" "$dir/mpi1.c"
  fi
}
check
# Removed by name: none of them is among the replaced (the first 60 of each kind's numbering at most).
printf 'pipe_001000\npipe_002000\nplate_000500\nequipment_000100\npipe_003599\n' >"$dir/gone1"
printf 'pipe_000900\nplate_001700\nequipment_000300\n' >"$dir/gone2"
printf 'pipe_000100\n' >"$dir/gone3"
"$m" update "$s" --replace "$dir/moved.obj" --remove-names "$dir/gone1" --compact-threshold 0 >/dev/null
check
grep -q "over $ranks ranks" "$dir/err"
# One delta a shard the batch touched (routed by box), each answered by its shard's rank.
deltas=$(grep -c '^delta ' "$s.changes/rev-000000000001.rev")
[[ $deltas -ge 1 && $deltas -le $k ]]
grep -q "$k shards and $deltas delta stores (revision 1)" "$dir/err.c"
"$m" update "$s" --replace "$dir/moved2.obj" --add "$dir/more.obj" --remove-names "$dir/gone2" \
  --compact-threshold 0 >/dev/null
"$m" update "$s" --remove-ids 6001,6002 --remove-names "$dir/gone3" --compact-threshold 0 >/dev/null
check "" full
check 1
check 2
"$m" compact "$s" >/dev/null
check "" full
check 2
# Refusals: every rank fails, naming the revision or the file; nothing on stdout.
refused() {  # refused TEXT COMMAND...
  local want=$1
  shift
  if run "$mpi" "$@" >"$dir/out" 2>"$dir/err"; then
    echo "not refused: $*"
    exit 1
  fi
  grep -q -- "$want" "$dir/err" || { echo "no '$want' in:"; cat "$dir/err"; exit 1; }
  [[ ! -s "$dir/out" ]]
}
refused "revision 99 is not kept" query "$s" --queries "$dir/q" --revision 99
refused "revision 99 is not kept" clash "$s" --revision 99
refused "must be a whole number" query "$s" --queries "$dir/q" --revision x
"$m" update "$s" --add "$dir/moved.obj" --remove-ids 100 --compact-threshold 0 >/dev/null
delta=$(ls -t "$s.changes" | grep -E '^delta-.*\.mkt$' | head -1)
ids=$(ls -t "$s.changes" | grep -E '^delta-.*\.ids$' | head -1)
cp "$s.changes/$ids" "$dir/ids.bak"
printf 'x' | dd of="$s.changes/$ids" bs=1 seek=40 conv=notrunc status=none
refused "$ids" query "$s" --queries "$dir/q"
refused "$ids" clash "$s"
cp "$dir/ids.bak" "$s.changes/$ids"
truncate -s -100 "$s.changes/$delta"
refused "$delta" query "$s" --queries "$dir/q"
refused "$delta" clash "$s"
echo "mpi changes $ranks ranks: ok"
