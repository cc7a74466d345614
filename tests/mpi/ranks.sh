#!/usr/bin/env bash
# The sharded build on R MPI ranks (tools/mpi/mpi_build.cc): every answer of its manifest, point, box and
# exact, equals the unsharded store's and the single-process sharded build's; the top levels do not depend
# on R; an .mks input read by byte ranges gives the same answers (and on 1 rank); a failed rank leaves no
# file; what a killed rank's build (or a killed single-process build) left is removed by the next build.
#   tests/mpi/ranks.sh R MKTREE_MPI MKTREE MPIEXEC
set -euo pipefail
ranks=$1 mpi=$2 m=$3 mpiexec=$4
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
run() { "$mpiexec" -n "$ranks" --allow-run-as-root --oversubscribe "$@"; }
k=$((ranks + 1))  # more shards than ranks: a rank builds two
"$m" build tanker:30000:4 -o "$dir/plain.mkt" -q
"$m" build tanker:30000:4 -o "$dir/one.mkts" --shards $k -q
# Small exchange rounds (64 KiB a sender): many rounds, the receivers' streams still in id order.
run "$mpi" tanker:30000:4 -o "$dir/mpi.mkts" --shards $k --backend pagefile --threads 1 --round-bytes 65536 >"$dir/out"
grep -q "disjoint id ranges" "$dir/out"
grep -q "bytes an object" "$dir/out"
[[ $(grep -o '[0-9]* rounds' "$dir/out" | cut -d' ' -f1) -gt 10 ]]
stores="plain.mkt one.mkts mpi.mkts"
# The same scene as an .mks: each rank reads the records starting in its byte range (ranges cut records,
# so every rank but 0 resyncs), ids numbered after MPI_Exscan of the counts.
"$m" generate tanker --objects 30000 --seed 4 -o "$dir/scene.mks" >/dev/null
run "$mpi" "$dir/scene.mks" -o "$dir/mks.mkts" --shards $k --threads 1 --round-bytes 65536 >"$dir/out"
grep -q "disjoint byte ranges" "$dir/out"
stores="$stores mks.mkts"
if [[ $ranks == 2 ]]; then
  "$mpiexec" -n 1 --allow-run-as-root "$mpi" "$dir/scene.mks" -o "$dir/mks1.mkts" --shards $k --threads 1 >"$dir/out"
  grep -q "on 1 ranks (disjoint byte ranges)" "$dir/out"
  "$m" build "$dir/scene.mks" -o "$dir/mksone.mkts" --shards $k -q
  stores="$stores mks1.mkts mksone.mkts"
  # A killed single-process build leaves staged shards; the next build of the path removes them.
  "$m" build tanker:200000:4 -o "$dir/sp.mkts" --shards 3 -q &
  pid=$!
  for _ in $(seq 1200); do
    [[ -e "$dir/sp.mkts.shard-0.mkt.new" ]] && break
    sleep 0.1
  done
  kill -9 $pid
  wait $pid && exit 1
  [[ -e "$dir/sp.mkts.shard-0.mkt.new" && ! -e "$dir/sp.mkts" ]]
  "$m" build tanker:30000:4 -o "$dir/sp.mkts" --shards $k -q
  [[ $(ls "$dir" | grep '^sp\.' | grep -vc '^sp\.mkts\(\.shard-[0-9]*\.\(mkt\|ids\)\)\?$') -eq 0 ]]
  stores="$stores sp.mkts"
fi
# A damaged record in a rank's part: an error naming the file, no file of the build left.
python3 -c '
import sys
b = bytearray(open(sys.argv[1], "rb").read())
b[len(b) * 3 // 4] ^= 0x40
open(sys.argv[2], "wb").write(b)' "$dir/scene.mks" "$dir/dmg.mks"
if run "$mpi" "$dir/dmg.mks" -o "$dir/dmg.mkts" --shards $k --threads 1 >/dev/null 2>"$dir/err"; then exit 1; fi
grep -q "dmg.mks: .*\(checksum mismatch\|do not chain\)" "$dir/err"
[[ -z $(ls "$dir" | grep '^dmg\.mkts') ]]
# A rank killed (SIGKILL) after the exchange (spills on disk), or with its first shard staged: mpirun ends
# the others; the next build of the same manifest removes what they left and is whole.
for point in exchanged staged; do
  if "$mpiexec" -n "$ranks" --allow-run-as-root --oversubscribe -x MKTREE_MPI_TEST_KILL=$((ranks - 1)):$point \
    "$mpi" "$dir/scene.mks" -o "$dir/kill.mkts" --shards $k --threads 1 >/dev/null 2>&1; then exit 1; fi
  [[ ! -e "$dir/kill.mkts" ]]
  ls "$dir" | grep '^kill' >"$dir/left"
  if [[ $point == exchanged ]]; then grep -q 'from-[0-9]*\.new$' "$dir/left"; else grep -q 'mkt\.new$' "$dir/left"; fi
  run "$mpi" "$dir/scene.mks" -o "$dir/kill.mkts" --shards $k --threads 1 >/dev/null
  [[ $(ls "$dir" | grep '^kill\.' | grep -vc '^kill\.mkts\(\.shard-[0-9]*\.\(mkt\|ids\)\)\?$') -eq 0 ]]
  rm "$dir"/kill.mkts*
done
run "$mpi" "$dir/scene.mks" -o "$dir/kill.mkts" --shards $k --threads 1 >/dev/null
stores="$stores kill.mkts"
# A live build's lock (held here with flock(1)): another build of the path is refused and removes nothing.
exec {lockfd}>"$dir/live.mkts.build-lock"
flock -n $lockfd
touch "$dir/live.mkts.shard-0.mkt.new"
if run "$mpi" tanker:3000:1 -o "$dir/live.mkts" --shards 2 >/dev/null 2>"$dir/err"; then exit 1; fi
grep -q "live.mkts: another build of this sharded store is running" "$dir/err"
if "$m" build tanker:3000:1 -o "$dir/live.mkts" --shards 2 -q 2>"$dir/err"; then exit 1; fi
grep -q "another build" "$dir/err"
[[ -e "$dir/live.mkts.shard-0.mkt.new" && ! -e "$dir/live.mkts" ]]
exec {lockfd}>&-
"$m" generate queries "$dir/plain.mkt" --count 200 --seed 3 -o "$dir/q.txt"
for mode in "" --exact; do
  for s in $stores; do
    "$m" query "$dir/$s" --queries "$dir/q.txt" --names $mode | python3 -c '
import json, sys
for line in sys.stdin:
    j = json.loads(line)
    print(json.dumps([j["hits"], j["names"]]))' >"$dir/$s.hits"
  done
  for s in $stores; do cmp "$dir/plain.mkt.hits" "$dir/$s.hits"; done
  [[ $(grep -c . "$dir/mpi.mkts.hits") -eq 800 ]]
  [[ $(grep -vc '^\[\[\], \[\]\]$' "$dir/mpi.mkts.hits") -gt 100 ]]
done
# The query batch over the ranks (mktree-mpi query, each rank its shards): per query the same ids and the
# same cold page, leaf and candidate counts as the one-process Database on the manifest.
for mode in "" --exact; do
  run "$mpi" query "$dir/mpi.mkts" --queries "$dir/q.txt" --cold --threads 1 $mode >"$dir/batch.mpi"
  "$m" query "$dir/mpi.mkts" --queries "$dir/q.txt" --cold $mode >"$dir/batch.one"
  python3 - "$dir/batch.mpi" "$dir/batch.one" <<'PY'
import json, sys
a = [json.loads(l) for l in open(sys.argv[1])]
b = [json.loads(l) for l in open(sys.argv[2])]
assert len(a) == len(b) == 800, (len(a), len(b))
keys = ["query", "kind", "hits", "pages_read", "pages_touched", "leaves_visited", "bytes_read",
        "candidates_tested", "hit_count"]
for x, y in zip(a, b):
    for k in keys:
        assert x[k] == y[k], (x["query"], k, x[k], y[k])
assert sum(x["pages_read"] for x in a) > 0
PY
done
if run "$mpi" query "$dir/mpi.mkts" --queries "$dir/missing.txt" 2>"$dir/err"; then exit 1; fi
grep -q "missing.txt" "$dir/err"
# The same top levels and shard sizes as the single-process build.
for s in one mpi mks; do
  "$m" info "$dir/$s.mkts" --json | python3 -c '
import json, sys
j = json.load(sys.stdin)
print(j["top_levels"], [s["objects"] for s in j["shard_files"]])' >"$dir/$s.top"
done
cmp "$dir/one.top" "$dir/mpi.top"
cmp "$dir/one.top" "$dir/mks.top"
# Too many shards for the scene: an error on every rank, no file left.
if run "$mpi" tanker:3:1 -o "$dir/bad.mkts" --shards 5 2>"$dir/err"; then exit 1; fi
grep -q "cannot make 5 shards" "$dir/err"
[[ -z $(ls "$dir" | grep '^bad') ]]
# A rank that cannot write its shard (a directory in the way of the last shard's staging file): no
# manifest, and every other rank's staged shards and received objects are removed.
mkdir -p "$dir/fail.mkts.shard-$((k - 1)).mkt.new/blocked"
if run "$mpi" tanker:30000:4 -o "$dir/fail.mkts" --shards $k --threads 1 >/dev/null 2>"$dir/err"; then exit 1; fi
grep -q "shard-$((k - 1)).mkt.new" "$dir/err"
[[ $(ls "$dir" | grep '^fail' | tr '\n' ' ') == "fail.mkts.shard-$((k - 1)).mkt.new " ]]
echo "mpi $ranks ranks: ok"
