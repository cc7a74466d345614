#!/usr/bin/env bash
# Peak memory and time of `mktree query --queries` against the number of queries (issue 21, item 2):
#   bench/query_stream_rss.sh DIR MKTREE [MKTREE_BEFORE]     (MKTREE_BEFORE: a build without --threads)
# Builds the 1M tanker (seed 1, paged file) in DIR unless it is there, writes 2,000 and 20,000 queries
# (`generate queries --count 500|5000 --seed 7`: points and 0.5/2/8 m boxes), and runs each binary cold
# (JSON lines to /dev/null) on 1 and 2 threads. Peak RSS is the kernel's VmHWM (it counts the pages of the
# store's read-only mapping the queries touched); peak anon is RssAnon sampled every 10 ms (the heap: what
# the process holds of its own). With --direct-io there is no mapping: add it to ARGS via QUERY_ARGS.
# Not CI: about two minutes.
set -euo pipefail
[[ $# -ge 2 ]] || { echo "usage: bench/query_stream_rss.sh DIR MKTREE [MKTREE_BEFORE]" >&2; exit 2; }
dir=$1
shift
mkdir -p "$dir"
store=$dir/t1m.mkt
[[ -f $store ]] || "$1" build tanker:1000000:1 -o "$store" --backend pagefile -q
for n in 500 5000; do
  [[ -f $dir/q$n.txt ]] || "$1" generate queries "$store" --count $n --seed 7 -o "$dir/q$n.txt"
done

# Runs "$@", printing "seconds peak_rss_kib peak_anon_kib".
measure() {
  local start end pid anon=0 a hwm=0
  start=$(date +%s.%N)
  "$@" >/dev/null &
  pid=$!
  while kill -0 "$pid" 2>/dev/null; do
    if a=$(awk '/^RssAnon/ {print $2} /^VmHWM/ {h=$2} END {print h}' "/proc/$pid/status" 2>/dev/null | tr '\n' ' '); then
      read -r cur h <<<"$a" || true
      [[ -n ${cur:-} && $cur -gt $anon ]] && anon=$cur
      [[ -n ${h:-} && $h -gt $hwm ]] && hwm=$h
    fi
    sleep 0.01
  done
  if ! wait "$pid"; then
    echo "failed: $*" >&2
    echo "nan 0 0"
    return
  fi
  end=$(date +%s.%N)
  echo "$(echo "$end - $start" | bc) $hwm $anon"
}

echo "mktree query --queries FILE --cold (1M tanker, paged file, seed 1; queries seed 7); $(nproc) cores"
printf '%-8s %8s %8s %10s %12s %14s %12s\n' binary queries threads seconds "us/query" "peak RSS MiB" "peak anon MiB"
for bin in "$@"; do
  name=after
  [[ $bin == "${2:-}" ]] && name=before
  for n in 500 5000; do
    queries=$((4 * n))
    for t in 1 2; do
      args=(query "$store" --queries "$dir/q$n.txt" --cold ${QUERY_ARGS:-})
      if [[ $name == after ]]; then
        args+=(--threads $t)
      elif [[ $t != 1 ]]; then
        continue  # no --threads before
      fi
      read -r s hwm anon <<<"$(measure "$bin" "${args[@]}")"
      printf '%-8s %8d %8d %10.2f %12.1f %14.1f %12.1f\n' "$name" $queries $t "$s" \
        "$(echo "$s * 1000000 / $queries" | bc -l)" "$(echo "$hwm / 1024" | bc -l)" "$(echo "$anon / 1024" | bc -l)"
    done
  done
done
