#!/usr/bin/env bash
# The main job, end to end: set up (install what is missing, build), generate a 200k-object tanker,
# build a store, run a mixed query file cold, print disk accesses per query kind, take one batch of changes
# and query both revisions, and render level 1.
# Usage: scripts/main_job.sh [OBJECTS]   (default 200000; outputs in out/)
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
N="${1:-200000}"
mkdir -p out
MK=build/mktree
echo "== generate: tanker of $N objects"
$MK generate tanker --objects "$N" --seed 1 -o out/tanker.obj
echo "== build: out/tanker.mkt (HDF5 backend, 12 KiB pages, zstd)"
$MK build out/tanker.obj -o out/tanker.mkt
echo "== info"
$MK info out/tanker.mkt | sed -n "1,8p"  # sed, not head: head would close the pipe (SIGPIPE under pipefail)
echo "== queries: 1000 points, 1000 boxes each of 0.5 m, 2 m and 8 m, seeded, cold cache"
$MK generate queries out/tanker.mkt --count 1000 --seed 7 -o out/queries.txt
$MK query out/tanker.mkt --queries out/queries.txt --cold --summary
echo "== a change: 2,000 objects of another tanker added, ids 1-1000 removed, one revision"
$MK generate tanker --objects 2000 --seed 2 -o out/more.obj
$MK update out/tanker.mkt --add out/more.obj --remove-ids "$(seq -s, 1 1000)" --message "main job: a change"
$MK log out/tanker.mkt
echo "== the same queries at the new revision, then at revision 0 (kept)"
$MK query out/tanker.mkt --queries out/queries.txt --cold --summary
$MK query out/tanker.mkt --queries out/queries.txt --cold --summary --revision 0
if $MK render --help >/dev/null 2>&1; then
  echo "== render: level 1 (blue Sn1, red Sn2, green overlap) -> out/tanker_level1.png"
  $MK render out/tanker.mkt --level 1 -o out/tanker_level1.png
fi
