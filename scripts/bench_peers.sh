#!/usr/bin/env bash
# Side-by-side benchmark of mktree against libspatialindex, SQLite R*Tree and Boost.Geometry (bench/README.md).
#
# Usage: scripts/bench_peers.sh [--smoke] [--objects N ...] [--queries Q] [--seed S] [--no-real] [--run NAME]
#   --objects N ...  tanker sizes (default: 100000 1000000); several may follow one --objects
#   --queries Q      queries per small workload (default 200; big boxes use fewer, see bench/peers_bench.cc)
#   --no-real        skip the real scenes of shared/data
#   --no-tanker      only the real scenes (e.g. to add them to an existing --run folder)
#   --engines LIST   comma-separated subset of peers_bench's engines (default: all)
#   --run NAME       report folder bench/results/NAME (default: the date)
#   --smoke          CI check: a 100k tanker and one small real scene, few queries, report in a temporary
#                    folder that is removed; fails (non-zero) on any answer mismatch between engines.
# Builds into $BENCH_BUILD (default build-bench/).
# Big temporary files go to $BENCH_TMP (default /work/tmp-bench, else a temporary folder); they are removed.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

args="$*"
smoke=0; objects=(); queries=200; seed=1; real=1; run=""; extra=(); tanker=1
while (($#)); do
  case "$1" in
    --smoke) smoke=1 ;;
    --objects) shift; while (($#)) && [[ "$1" =~ ^[0-9]+$ ]]; do objects+=("$1"); shift; done; continue ;;
    --queries) shift; queries="$1" ;;
    --seed) shift; seed="$1" ;;
    --no-real) real=0 ;;
    --no-tanker) tanker=0 ;;
    --engines) shift; extra+=(--engines "$1") ;;
    --run) shift; run="$1" ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    *) echo "error: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
  shift
done

data="${MKTREE_DATA:-$(cd "$repo/.." && pwd)/shared/data}"
real_scenes=(ships/truman.ac buildings/steel_mini_project.obj buildings/duplex.obj city/denhaag_01.obj)
if ((smoke)); then
  ((${#objects[@]})) || objects=(100000)
  queries=20; real_scenes=(buildings/duplex.obj); extra+=(--smoke)
fi
((${#objects[@]})) || objects=(100000 1000000)

if [ -n "${BENCH_TMP:-}" ]; then tmp="$BENCH_TMP"
elif mkdir -p /work/tmp-bench 2>/dev/null && [ -w /work/tmp-bench ]; then tmp=/work/tmp-bench
else tmp=$(mktemp -d); fi
mkdir -p "$tmp"
work=$(mktemp -d "$tmp/peers.XXXXXX")
trap 'rm -rf "$work"' EXIT

if ((smoke)); then out="$work/report"
else out="$repo/bench/results/${run:-$(date +%Y-%m-%d)}"; fi
mkdir -p "$out"

scripts/setup.sh --no-build  # the libraries (peers included); installs only what is missing
# Plots need matplotlib: Debian's python3-matplotlib (the bench's own need, so not in setup.sh; not for --smoke).
py=""
for p in /usr/bin/python3 python3; do
  if "$p" -c "import matplotlib" 2>/dev/null; then py=$p; break; fi
done
if [ -z "$py" ] && ((!smoke)); then
  SUDO=""; [ "$(id -u)" -eq 0 ] || SUDO="sudo"
  if DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends python3-matplotlib >/dev/null 2>&1 ||
     { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends python3-matplotlib >/dev/null; }; then
    py=/usr/bin/python3
  fi
fi
build="${BENCH_BUILD:-build-bench}"  # CI passes the build/ that scripts/test.sh made
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$build" --target peers_bench -j 2 >/dev/null
bench="$build/bench/peers_bench"

cpu=$( (grep -m1 'model name' /proc/cpuinfo || echo 'model name: unknown') | sed 's/.*: //')
ram=$(awk '/MemTotal/ {printf "%.1f GiB", $2 / 1048576}' /proc/meminfo)
lsi_pkg=$(dpkg-query -W -f='${Version}' libspatialindex6 2>/dev/null || echo unknown)
sqlite_pkg=$(dpkg-query -W -f='${Version}' libsqlite3-0 2>/dev/null || echo unknown)
echo "\`scripts/bench_peers.sh $args\` on $(date -u '+%Y-%m-%d %H:%M UTC'), commit $(git rev-parse --short HEAD 2>/dev/null || echo '?')" >> "$out/runs.txt"
{
  echo "# mktree vs libspatialindex, SQLite R*Tree, Boost.Geometry"
  echo
  echo "Runs into this folder (each scene's section comes from the latest run that measured it):"
  echo
  sed 's/^/- /' "$out/runs.txt"
  echo
  echo "- Machine: $(nproc) cores, $cpu, $ram RAM, $(uname -sr), work files on $(df -h "$tmp" | awk 'NR==2 {print $1 " (" $2 ")"}')"
  echo "- Load when the run started: $(cut -d' ' -f1-3 /proc/loadavg) (1/5/15 min); timings are wall-clock, page counts exact."
  # `|| true`: grep -v selects nothing on a clean tree and exits 1, which pipefail would make fatal.
  dirty=$( (git status --short --untracked-files=no 2>/dev/null || true) | { grep -v -e ' bench/' -e ' scripts/' || true; } |
    awk '{print $2}' | tr '\n' ' ')
  [ -z "$dirty" ] || echo "- Work tree had uncommitted changes (measured as built): $dirty"
  echo "- Libraries: $($bench --versions) (Debian libspatialindex6 $lsi_pkg, libsqlite3-0 $sqlite_pkg)"
  echo "- Pages: 12 KiB (mktree MemPage = 4096 x 3; libspatialindex disk storage manager page size 12288);"
  echo "  SQLite page_size 16384 (powers of two only; 8 KiB and 16 KiB are equally far from 12 KiB, 16 KiB holds at least as much)."
  echo "- Seeds: tanker scene seed 1; query seed $seed; $queries queries per small workload (fewer for big boxes, see the tables)."
  echo "- Geometry: every paged engine stores each object's mktree leaf entry (object_codec.h, zstd level 3 + shuffle) —"
  echo "  mktree-*-none stores it uncompressed. libspatialindex keeps it inline in leaf nodes; SQLite in a rowid table."
  echo "- Cold: engine cache emptied before each query, and the OS page cache bypassed (O_DIRECT, mktree paged file)"
  echo "  or dropped with posix_fadvise(POSIX_FADV_DONTNEED) on the engine's files (all others). Warm: a 64 MiB engine cache"
  echo "  (libspatialindex: our LRU in front of its disk manager), one filling pass, then the timed pass; OS cache left warm."
  echo "- Build: each engine built in its own child process; peak RSS is that process's own (VmHWM, bench/peak_rss.h). mktree builds single-threaded (its default)."
  echo "- Answers: every engine's AABB answers are compared with Boost.Geometry's on every query (Boost itself with a brute-force"
  echo "  scan on the first queries of each workload); a mismatch fails the run."
  echo
} > "$out/header.md.tmp"

status=0
scenes=()
if ((tanker)); then
  for n in "${objects[@]}"; do scenes+=("tanker:$n:1|tanker_$n"); done
fi
if ((real)); then
  if [ -d "$data" ]; then
    for f in "${real_scenes[@]}"; do scenes+=("$data/$f|$(basename "${f%.*}")"); done
  else
    echo "bench_peers: $data not found; real scenes skipped" | tee -a "$out/header.md.tmp"
  fi
fi
for s in "${scenes[@]}"; do
  spec="${s%|*}"; name="${s#*|}"
  echo "== $name ($spec)"
  if ! "$bench" --scene "$spec" --name "$name" --queries "$queries" --seed "$seed" --dir "$work" --out "$out" \
       ${extra[@]+"${extra[@]}"} 2>&1 | tee "$out/$name.log"; then
    echo "bench_peers: $name FAILED" >&2; status=1
  fi
done
# The report: the header, then every scene measured into this folder (tankers by size, then the real scenes).
mv "$out/header.md.tmp" "$out/REPORT.md"
for f in $(cd "$out" && ls | grep '^tanker_.*\.md$' | sort -t_ -k2 -n) $(cd "$out" && ls | grep '\.md$' | grep -v -e '^tanker_' -e '^REPORT\.md$'); do
  cat "$out/$f" >> "$out/REPORT.md"
done

if [ -n "$py" ]; then
  "$py" scripts/plot_bench.py "$out" >> "$out/REPORT.md"
elif ((!smoke)); then
  echo "bench_peers: python3-matplotlib missing (apt-get install python3-matplotlib); no plots" | tee -a "$out/REPORT.md"
fi
((smoke)) || echo "bench_peers: report in $out/REPORT.md"
((status == 0)) && echo "bench_peers: all answers agree"
exit $status
