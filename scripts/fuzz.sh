#!/usr/bin/env bash
# Runs the libFuzzer targets of tests/fuzz, one target after the other, each for a given time.
#
#   scripts/fuzz.sh [--time SECONDS] [--jobs N] [--merge] [--timeout S] [--rss-limit-mb MB] [target...]
#
#   --time S         seconds per target (default 300)
#   --jobs N         fuzzing processes per target, sharing its working corpus (default 1)
#   --merge          afterwards, minimise the working corpus into the git corpus (tests/fuzz/corpus/<t>):
#                    only units that add coverage and replay clean are added (--time 0 --merge: merge only)
#   --timeout S      an input running longer is a finding (timeout-*; default 10)
#   --rss-limit-mb M a process using more, or a single allocation larger, is a finding (oom-*; default 2048)
#   target           obj obj_chunks mks queries store_open store_hdf5 leaf revision (default: all)
#
# Installs clang-14 and libclang-rt-14-dev (libFuzzer) when missing, then configures and builds build-fuzz
# (MKTREE_BUILD_FUZZERS: ASan + UBSan + coverage) if needed.
# Each target fuzzes a working corpus, build-fuzz/fuzz-work/<t>/corpus (the git seeds copied in, and what
# earlier runs found), never the git corpus itself; tests/fuzz/regressions/<t> is read as extra seeds.
# A run that stops on a finding is restarted for the time left, so one campaign collects every finding;
# a working-corpus unit that fails at start-up (kept by a run with the knobs below, or the code changed)
# is moved to build-fuzz/fuzz-work/<t>/set-aside.
# Findings (crash-*, leak-*, timeout-*, oom-*) stay in build-fuzz/fuzz-work/<t>/artifacts; one input per
# distinct finding (error and source line) is copied to tests/fuzz/regressions/<t>/, where ctest replays
# it: fix the bug, or move the input to tests/fuzz/open_findings/<t>/ (not replayed) and list it there.
# Prints per target: executions, exec/s, coverage (cov/ft), new corpus units, crashes/timeouts/OOMs.
#
# To look past a known bug that stops nearly every run: UBSAN_OPTIONS=suppressions=FILE (e.g. a line
# `nonnull-attribute:object_codec.cc`), MKTREE_FUZZ_NO_ANSWER_CHECK=1 (store targets: no answer check).
set -euo pipefail
shopt -s nullglob
cd "$(dirname "$0")/.."
root=$PWD

time_per_target=300
jobs=1
merge=0
timeout=10
rss=2048
targets=()
all_targets=(obj obj_chunks mks queries store_open store_hdf5 leaf revision)
while (($#)); do
  case $1 in
    --time) time_per_target=$2; shift 2 ;;
    --jobs) jobs=$2; shift 2 ;;
    --merge) merge=1; shift ;;
    --timeout) timeout=$2; shift 2 ;;
    --rss-limit-mb) rss=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
((${#targets[@]})) || targets=("${all_targets[@]}")
for t in "${targets[@]}"; do
  [[ " ${all_targets[*]} " == *" $t "* ]] || { echo "fuzz.sh: unknown target $t (${all_targets[*]})" >&2; exit 2; }
done
[[ $time_per_target =~ ^[0-9]+$ && $jobs =~ ^[1-9][0-9]*$ ]] || { echo "fuzz.sh: bad --time or --jobs" >&2; exit 2; }

# Inputs larger than this are not tried (the seeds are smaller; a store of a few objects is ~10 KB).
max_len() {
  case $1 in
    queries) echo 4096 ;;
    leaf) echo 16384 ;;
    *) echo 65536 ;;
  esac
}

# The libraries (scripts/setup.sh), then clang 14 and its libFuzzer runtime, only what is missing.
scripts/setup.sh --no-build
missing=()
for p in clang-14 libclang-rt-14-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "fuzz.sh: installing ${missing[*]}"
  sudo=""
  [[ $(id -u) -eq 0 ]] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

build=$root/build-fuzz
if [[ ! -f $build/CMakeCache.txt ]]; then
  launcher=()
  command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  CC=clang-14 CXX=clang++-14 cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DMKTREE_BUILD_FUZZERS=ON \
    -DMKTREE_BUILD_BENCH=OFF "${launcher[@]}" >/dev/null
fi
nice -n 10 cmake --build "$build" -j "$(( jobs > 2 ? jobs : 2 ))" --target "${targets[@]/#/fuzz_}" >/dev/null

# UBSan is built recoverable so that a suppressions file can look past a known finding
# (UBSAN_OPTIONS=...:suppressions=FILE); halt_on_error makes every other report a finding.
# Options given in the environment are added after these (a later option wins).
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
export LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp${LSAN_OPTIONS:+:$LSAN_OPTIONS}"

# One fuzzing process, restarted after each finding until `end` (epoch seconds).
worker() {  # target bin work worker-index end
  local t=$1 bin=$2 work=$3 w=$4 end=$5 i=0 now log
  local args=(-timeout="$timeout" -rss_limit_mb="$rss" -max_len="$(max_len "$t")" -print_final_stats=1
              -artifact_prefix="$work/artifacts/")
  local dict=$root/tests/fuzz/${t%_chunks}.dict  # obj_chunks reads OBJ files too
  [[ -f $dict ]] && args+=(-dict="$dict")
  while now=$(date +%s); ((now < end)); do
    log=$work/logs/w$w-$i.log
    i=$((i + 1))
    nice -n 10 "$bin" "$work/corpus" "$root/tests/fuzz/regressions/$t" -max_total_time=$((end - now)) "${args[@]}" \
      >"$log" 2>&1 || true
    if ! grep -q 'INITED' "$log"; then
      # A unit of the working corpus fails (kept by a run that looked past a known bug, or the code
      # changed): set it aside and go on. Anything else (a failing regression input) stops the target.
      local artifact sum unit
      artifact=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
      sum=$([[ -f $artifact ]] && sha1sum <"$artifact" | cut -c1-40)
      unit=$work/corpus/$sum
      [[ -n $sum && -f $unit ]] || unit=$(cd "$work/corpus" && sha1sum -- * | awk -v s="$sum" '$1 == s {print $2; exit}')
      [[ -n $unit && $unit != /* ]] && unit=$work/corpus/$unit
      if [[ -z $sum || -z $unit || ! -f $unit ]] || ((i > 100)); then
        echo "  $t: the fuzzer stopped before fuzzing (a seed or regression input fails?): $log" >&2
        return
      fi
      mkdir -p "$work/set-aside"
      mv "$unit" "$work/set-aside/"
      echo "  $t: set aside a working-corpus unit that fails: $work/set-aside/${unit##*/}" >&2
    fi
  done
}

# What a finding is: its error line and the first frame in our sources (file:line), digits and addresses
# dropped, so that the same bug found twice reads the same.
signature() {  # log
  local what frame
  what=$(grep -m1 -E 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error:' "$1" |
    sed -E 's/^==[0-9]+== ?//; s/^[^ ]*: runtime error/runtime error/; s/ on address 0x[0-9a-f]+.*//; s/0x[0-9a-f]+/ADDR/g; s/-?nan/nan/; s/[0-9]+/N/g')
  frame=$(grep -E '^ +#[0-9]+ 0x[0-9a-f]+ in .* [^ ]+:[0-9]+:[0-9]+$' "$1" | grep -F "$root/" | grep -v LLVMFuzzerTestOneInput |
    head -1 | sed -E 's/.* ([^ ]+):([0-9]+):[0-9]+$/\1:\2/; s#.*/\.\./##; s#^'"$root"'/##')
  echo "${what:-unknown} at ${frame:-?}"
}

declare -A summary
for t in "${targets[@]}"; do
  bin=$build/tests/fuzz/fuzz_$t
  work=$build/fuzz-work/$t
  mkdir -p "$work/corpus" "$work/artifacts" "$work/logs" "$work/set-aside" "$root/tests/fuzz/regressions/$t"
  rm -f "$work"/logs/*.log
  cp -n "$root/tests/fuzz/corpus/$t"/* "$work/corpus/" 2>/dev/null || true
  units_before=$(( $(find "$work/corpus" -maxdepth 1 -type f | wc -l) + $(find "$work/set-aside" -type f | wc -l) ))
  artifacts_before=$(find "$work/artifacts" -maxdepth 1 -type f | sort)
  echo "fuzzing $t for ${time_per_target}s with $jobs process(es) ($units_before corpus units)"
  start=$(date +%s)
  end=$((start + time_per_target))
  pids=()
  for ((w = 0; w < jobs; w++)); do
    worker "$t" "$bin" "$work" "$w" "$end" &
    pids+=($!)
  done
  wait "${pids[@]}"
  elapsed=$(( $(date +%s) - start ))

  logs=("$work"/logs/w*.log)
  execs=$(cat /dev/null "${logs[@]}" | sed -n 's/^stat::number_of_executed_units: *//p' | awk '{s += $1} END {print s + 0}')
  cov=$(cat /dev/null "${logs[@]}" | { grep -o 'cov: [0-9]* ft: [0-9]*' || true; } | awk '$2 > c {c = $2} $4 > f {f = $4} END {print c + 0 "/" f + 0}')
  units_after=$(( $(find "$work/corpus" -maxdepth 1 -type f | wc -l) + $(find "$work/set-aside" -type f | wc -l) ))
  new=$(comm -13 <(echo "$artifacts_before") <(find "$work/artifacts" -maxdepth 1 -type f | sort) | grep -v '/slow-unit-' || true)
  count() { grep -c "/$1" <<<"$new" || true; }
  crashes=$(( $(count crash-) + $(count leak-) + $(count deadly-signal-) ))
  summary[$t]=$(printf '%-11s %6ss %12s %8s %13s %10s %7s %8s %5s' "$t" "$elapsed" "$execs" \
    "$(( elapsed > 0 ? execs / elapsed : 0 ))" "$cov" "$((units_after - units_before))" "$crashes" \
    "$(count timeout-)" "$(count oom-)")
  # One reproducer per distinct finding (same error at the same source line) goes to regressions/<t>/.
  declare -A first=() times=()
  for log in "${logs[@]}"; do
    artifact=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
    [[ -n $artifact && -f $artifact ]] || continue
    sig=$(signature "$log")
    times[$sig]=$(( ${times[$sig]:-0} + 1 ))
    [[ -n ${first[$sig]:-} ]] || first[$sig]=$artifact
  done
  saved=$(sha1sum /dev/null "$root"/tests/fuzz/{regressions,open_findings}/"$t"/* | cut -c1-40)
  for sig in "${!first[@]}"; do
    f=${first[$sig]}
    dest=tests/fuzz/regressions/$t/${f##*/}
    if grep -qx "$(sha1sum <"$f" | cut -c1-40)" <<<"$saved"; then
      dest="(already saved under regressions/ or open_findings/)"
    else
      cp "$f" "$root/$dest"
    fi
    printf '  %5d x %s\n          -> %s\n' "${times[$sig]}" "$sig" "$dest"
  done
  unset first times
  if ((merge)); then
    # Minimise into a scratch copy of the git corpus, then keep only the new units that replay clean with
    # the default checks (a run with MKTREE_FUZZ_NO_ANSWER_CHECK or a UBSan suppressions file may have
    # kept units that fail them).
    out=$work/merge
    rm -rf "$out"
    mkdir -p "$out"
    cp "$root/tests/fuzz/corpus/$t"/* "$out/"
    # (Units that fail during the merge leave their crash-* files in merge-artifacts/, not in the cwd.)
    mkdir -p "$work/merge-artifacts"
    nice -n 10 "$bin" -merge=1 -max_len="$(max_len "$t")" -timeout="$timeout" -rss_limit_mb="$rss" \
      -artifact_prefix="$work/merge-artifacts/" "$out" "$work/corpus" >"$work/logs/merge.log" 2>&1 ||
      echo "  merge failed: $work/logs/merge.log"
    added=0 refused=0
    for f in "$out"/*; do
      [[ -e $root/tests/fuzz/corpus/$t/${f##*/} ]] && continue
      if env -u MKTREE_FUZZ_NO_ANSWER_CHECK UBSAN_OPTIONS=halt_on_error=1 \
          LSAN_OPTIONS="suppressions=$root/tests/fuzz/lsan.supp" "$bin" -runs=0 \
          -artifact_prefix="$work/merge-artifacts/" "$f" >/dev/null 2>&1; then
        cp "$f" "$root/tests/fuzz/corpus/$t/"
        added=$((added + 1))
      else
        refused=$((refused + 1))
      fi
    done
    echo "  merged $added units into tests/fuzz/corpus/$t ($refused left out: they fail the default checks)"
  fi
done

echo
printf '%-11s %7s %12s %8s %13s %10s %7s %8s %5s\n' target time executions exec/s cov/ft "new units" crashes timeouts ooms
for t in "${targets[@]}"; do echo "${summary[$t]}"; done
echo "logs: $build/fuzz-work/<target>/logs; working corpora: $build/fuzz-work/<target>/corpus"
if ((merge)); then echo "git corpus: $(du -sh "$root/tests/fuzz/corpus" | cut -f1) (keep it under ~3 MB)"; fi
