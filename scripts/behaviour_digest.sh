#!/usr/bin/env bash
# Prints digests of what a build of mktree answers, to show that a change left behaviour unchanged:
#   scripts/behaviour_digest.sh MKTREE DIR     (then diff the output of two binaries)
# Builds the 200k tanker (seed 1) into both backends, runs 300 points and 300 boxes of each side (seed 5)
# cold, in AABB and exact mode, and prints the SHA-256 of the paged-file store (HDF5 files carry
# timestamps) and of each answer file (hits, pages read and touched, cache hits, leaves, candidates; the
# timings removed). Takes about a minute.
set -euo pipefail
[[ $# -eq 2 ]] || { echo "usage: scripts/behaviour_digest.sh MKTREE DIR" >&2; exit 2; }
m=$1
out=$2
mkdir -p "$out"
for b in pagefile hdf5; do
  "$m" build tanker:200000:1 -o "$out/t_$b.mkt" --backend "$b" -q
done
"$m" generate queries "$out/t_pagefile.mkt" --count 300 --seed 5 -o "$out/q.txt"
echo "pagefile store $(sha256sum <"$out/t_pagefile.mkt" | cut -c1-16)"
for b in pagefile hdf5; do
  for mode in aabb exact; do
    flag=()
    [[ $mode == exact ]] && flag=(--exact)
    "$m" query "$out/t_$b.mkt" --queries "$out/q.txt" --cold "${flag[@]}" |
      sed -E 's/"(seconds|micros[a-z_]*)": [0-9.e+-]*,? ?//g' >"$out/answers_${b}_$mode.jsonl"
    echo "$b $mode answers $(sha256sum <"$out/answers_${b}_$mode.jsonl" | cut -c1-16)"
  done
done
