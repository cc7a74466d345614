#!/usr/bin/env bash
# mktree-mpi clash on R ranks (tools/mpi/mpi_clash.cc): the pairs (every field) and the counts of the
# unsharded store's `mktree clash`, with a clearance, with group exclusions and a cap, on K = R + 1 shards
# (a rank owns two) and on K = R - 1 (a rank owns none). The lines come sorted by (a, b): byte for byte the
# unsharded lines sorted so, and the same on 1 rank as on R; the cap keeps the first N of that order;
# --names gives the unsharded --names lines; runs of a few pairs (MKTREE_MPI_TEST_SORT_RUN_BYTES) give
# the same bytes through the external sort's files and merge levels, which go to $TMPDIR. A missing
# shard fails every rank, printing nothing. (A store that has taken changes: tests/mpi/changes.sh.)
#   tests/mpi/clash.sh R MKTREE_MPI MKTREE MPIEXEC
set -euo pipefail
ranks=$1 mpi=$2 m=$3 mpiexec=$4
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
source "$(dirname "$0")/common.sh"
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
    run_on 1 "$mpi" clash "$dir/s$k.mkts" --summary $opts >"$dir/mpi1" 2>/dev/null
    cmp <(head -n -1 "$dir/mpi1") <(head -n -1 "$dir/mpi")
    if [[ $opts != --max-pairs* ]]; then
      cmp <(by_pair "$dir/one") <(head -n -1 "$dir/mpi")
      [[ $(grep -c . "$dir/mpi") -gt 1000 ]]
    else
      "$m" clash "$dir/plain.mkt" --threads 1 >"$dir/all"
      cmp <(by_pair "$dir/all" | head -100) <(head -n -1 "$dir/mpi")
      [[ $(grep -c . "$dir/mpi") -eq 101 ]]
    fi
  done
  "$m" clash "$dir/plain.mkt" --threads 1 --names >"$dir/one"
  run "$mpi" clash "$dir/s$k.mkts" --names >"$dir/mpi" 2>/dev/null
  cmp <(by_pair "$dir/one") "$dir/mpi"
  grep -q '"name_a": "pipe_' "$dir/mpi"
  # Runs of 5 pairs (hundreds of run files a rank, merged 64 at a time into the next level), with names.
  MKTREE_MPI_TEST_SORT_RUN_BYTES=520 run -x MKTREE_MPI_TEST_SORT_RUN_BYTES "$mpi" clash "$dir/s$k.mkts" \
    --names >"$dir/runs" 2>/dev/null
  cmp "$dir/mpi" "$dir/runs"
done
# Sort runs spill to unnamed files in $TMPDIR: the same bytes with a TMPDIR of the caller's, nothing left
# there. (A missing TMPDIR cannot be tested here: mpirun creates it for its session directory.)
mkdir "$dir/tmp"
TMPDIR="$dir/tmp" MKTREE_MPI_TEST_SORT_RUN_BYTES=520 run -x TMPDIR -x MKTREE_MPI_TEST_SORT_RUN_BYTES "$mpi" clash \
  "$dir/s$k.mkts" --names >"$dir/runs" 2>/dev/null
cmp "$dir/mpi" "$dir/runs"
[[ -z "$(ls -A "$dir/tmp")" ]]
k=$((ranks + 1))
rm "$dir/s$k.mkts.shard-1.mkt"
if run "$mpi" clash "$dir/s$k.mkts" >"$dir/out" 2>"$dir/err"; then exit 1; fi
grep -q "s$k.mkts.shard-1.mkt" "$dir/err"
[[ ! -s "$dir/out" ]]
echo "mpi clash $ranks ranks: ok"
