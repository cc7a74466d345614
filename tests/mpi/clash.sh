#!/usr/bin/env bash
# mktree-mpi clash on R ranks (tools/mpi/mpi_clash.cc): the pairs (every field) and the counts of the
# unsharded store's `mktree clash`, with a clearance, with group exclusions and a cap, on K = R + 1 shards
# (a rank owns two) and on K = R - 1 (a rank owns none); a missing shard fails every rank, printing nothing.
#   tests/mpi/clash.sh R MKTREE_MPI MKTREE MPIEXEC
set -euo pipefail
ranks=$1 mpi=$2 m=$3 mpiexec=$4
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
run() { "$mpiexec" -n "$ranks" --allow-run-as-root --oversubscribe "$@"; }
"$m" build tanker:12000:5 -o "$dir/plain.mkt" -q
counts() {  # the summary's pair counts
  tail -1 "$1" | python3 -c '
import json, sys
j = json.load(sys.stdin)
print([j[k] for k in ("pairs", "hard", "touch", "clearance", "reported_pairs", "capped_pairs",
                      "unreported_touches", "candidate_pairs", "excluded_pairs")])'
}
for k in $((ranks + 1)) $((ranks - 1)); do
  "$m" build tanker:12000:5 -o "$dir/s$k.mkts" --shards $k -q
  for opts in "--clearance 0.01" "--exclude-group _ --no-touch" "--max-pairs 100"; do
    "$m" clash "$dir/plain.mkt" --threads 1 --summary $opts >"$dir/one"
    run "$mpi" clash "$dir/s$k.mkts" --summary $opts >"$dir/mpi" 2>"$dir/err"
    grep -q "clash of $k shards over $ranks ranks" "$dir/err"
    [[ "$(counts "$dir/one")" == "$(counts "$dir/mpi")" ]]
    if [[ $opts != --max-pairs* ]]; then
      cmp <(head -n -1 "$dir/one" | sort) <(head -n -1 "$dir/mpi" | sort)
      [[ $(grep -c . "$dir/mpi") -gt 1000 ]]
    else
      [[ $(grep -c . "$dir/mpi") -eq 101 ]]
    fi
  done
done
k=$((ranks + 1))
rm "$dir/s$k.mkts.shard-1.mkt"
if run "$mpi" clash "$dir/s$k.mkts" >"$dir/out" 2>"$dir/err"; then exit 1; fi
grep -q "s$k.mkts.shard-1.mkt" "$dir/err"
[[ ! -s "$dir/out" ]]
echo "mpi clash $ranks ranks: ok"
