#!/usr/bin/env bash
# Pages per query of sharded stores against the unsharded store of the same scene (issue 23: within 5 %):
#   bench/shard_pages.sh DIR MKTREE [N] [K...]       (defaults: N = 1000000, K = 2 4)
# Builds tanker:N:1 (paged file, 12 KiB pages) unsharded and with --shards K in DIR, writes 2,000 queries
# (`generate queries --count 500 --seed 1`: 500 points, 1,500 boxes of 0.5/2/8 m), runs them cold in AABB
# and exact mode, and prints per store: build seconds, objects per shard, pages read (points, boxes, all),
# the ratio to the unsharded store and whether every answer is identical. Not CI: about 3 minutes at 1M.
set -euo pipefail
[[ $# -ge 2 ]] || { echo "usage: bench/shard_pages.sh DIR MKTREE [N] [K...]" >&2; exit 2; }
dir=$1 m=$2 n=${3:-1000000}
shift $(($# >= 3 ? 3 : 2))
ks=("$@")
((${#ks[@]})) || ks=(2 4)
mkdir -p "$dir"
echo "# shard_pages: tanker:$n:1, paged file, 12 KiB pages, 2,000 cold queries (seed 1); $(nproc) cores"
build() {  # store, extra args; prints seconds
  local start
  start=$(date +%s.%N)
  "$m" build "tanker:$n:1" -o "$dir/$1" --backend pagefile -q "${@:2}"
  awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { print b - a }'
}
t0=$(build plain.mkt)
"$m" generate queries "$dir/plain.mkt" --count 500 --seed 1 -o "$dir/q.txt"
for mode in aabb exact; do
  "$m" query "$dir/plain.mkt" --queries "$dir/q.txt" --cold $([[ $mode == exact ]] && echo --exact) >"$dir/plain.$mode"
done
printf '%-8s %8s  %-40s %8s %8s %8s %7s %s\n' store build objects/shard points boxes pages ratio answers
report() {  # name, seconds, objects per shard
  python3 - "$dir" "$1" "$2" "$3" <<'PY'
import json, sys
d, name, secs, per = sys.argv[1:]
def load(f): return [json.loads(l) for l in open(f)]
a, b = load(f"{d}/plain.aabb"), load(f"{d}/{name}.aabb")
same = all(x["hits"] == y["hits"] for x, y in zip(a, b)) and len(a) == len(b)
ea, eb = load(f"{d}/plain.exact"), load(f"{d}/{name}.exact")
same = same and all(x["hits"] == y["hits"] for x, y in zip(ea, eb))
pts = sum(y["pages_read"] for y in b if y["kind"] == "point")
box = sum(y["pages_read"] for y in b if y["kind"] == "box")
ref = sum(x["pages_read"] for x in a)
print(f"{name:<8} {float(secs):7.1f}s  {per:<40} {pts:8d} {box:8d} {pts + box:8d} {(pts + box) / ref:7.4f} "
      f"{'identical' if same else 'DIFFER'}")
PY
}
cp "$dir/plain.aabb" "$dir/plain.mkt.aabb"
cp "$dir/plain.exact" "$dir/plain.mkt.exact"
report plain.mkt "$t0" "$n"
for k in "${ks[@]}"; do
  s=s$k.mkts
  t=$(build "$s" --shards "$k")
  for mode in aabb exact; do
    "$m" query "$dir/$s" --queries "$dir/q.txt" --cold $([[ $mode == exact ]] && echo --exact) >"$dir/$s.$mode"
  done
  per=$("$m" info "$dir/$s" --json | python3 -c 'import json,sys; print(",".join(str(s["objects"]) for s in json.load(sys.stdin)["shard_files"]))')
  report "$s" "$t" "$per"
done
