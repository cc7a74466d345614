#!/usr/bin/env bash
# IFC ingest through web-ifc against the assimp path (bench/README.md, "IFC ingest"): for each IFC file,
# web-ifc's own conversion alone (tools/ifc/mktree-ifc.mjs to /dev/null), `mktree build` through web-ifc
# and through assimp (MKTREE_IFC_READER=assimp): wall time, objects/s, MB/s of IFC, peak RSS of mktree
# (its own summary) and of the process tree (/usr/bin/time -v: the largest of mktree and node). Then the
# objects by IFC type against the file's entity counts, and the self-clash counts of the two stores with
# the web-ifc store's pairs split by what the IFC relations say about them.
# Usage: bench/ifc_ingest.sh [IFC...]   (default: duplex.ifc and Office_A of ../shared/data/buildings)
set -euo pipefail
cd "$(dirname "$0")/.."
tool=build/mktree
reader=tools/ifc/mktree-ifc.mjs
files=("$@")
if ((${#files[@]} == 0)); then
  files=(../shared/data/buildings/duplex.ifc ../shared/data/buildings/Office_A_20110811.ifc)
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Wall seconds and peak RSS (KiB) of a command, from /usr/bin/time -v.
timed() {
  /usr/bin/time -v "$@" 2>"$tmp/time" >"$tmp/out" || { cat "$tmp/time" >&2; return 1; }
  wall=$(awk -F': ' '/Elapsed \(wall clock\)/{n=split($2,t,":"); s=0; for(i=1;i<=n;i++) s=s*60+t[i]; print s}' "$tmp/time")
  rss=$(awk -F': ' '/Maximum resident set size/{print $2}' "$tmp/time")
  cpu=$(awk -F': ' '/User time|System time/{s+=$2} END{print s}' "$tmp/time")
}

echo "load: $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) cores, node $(node --version), web-ifc $(node -p "require('./tools/ifc/node_modules/web-ifc/package.json').version")"
printf '%-24s %-21s %8s %8s %8s %10s %8s %11s %9s\n' file path seconds "cpu s" objects objects/s MB/s "mktree MiB" "tree MiB"
for f in "${files[@]}"; do
  name=$(basename "$f")
  mb=$(awk -v b="$(stat -c %s "$f")" 'BEGIN{printf "%.3f", b/1e6}')
  timed node "$reader" "$f"
  objects=$(python3 - "$tmp/out" <<'EOF'
import struct, sys
d = open(sys.argv[1], 'rb').read()
print(struct.unpack_from('<Q', d, len(d) - 8)[0])
EOF
)
  printf '%-24s %-21s %8.2f %8.2f %8d %10.0f %8.2f %11s %9.1f\n' "$name" "web-ifc alone" "$wall" "$cpu" "$objects" \
    "$(echo "$objects / $wall" | bc -l)" "$(echo "$mb / $wall" | bc -l)" - "$(echo "$rss / 1024" | bc -l)"
  for path in web-ifc assimp; do
    env=()
    [ "$path" = assimp ] && env=(MKTREE_IFC_READER=assimp)
    timed env "${env[@]}" "$tool" build "$f" -o "$tmp/$path.mkt"
    objects=$(awk '/^built/{print $3}' "$tmp/out")
    own=$(awk '/peak RSS/{print $(NF-1)}' "$tmp/out")
    printf '%-24s %-21s %8.2f %8.2f %8d %10.0f %8.2f %11s %9.1f\n' "$name" "mktree build $path" "$wall" "$cpu" "$objects" \
      "$(echo "$objects / $wall" | bc -l)" "$(echo "$mb / $wall" | bc -l)" "$own" "$(echo "$rss / 1024" | bc -l)"
  done
  node "$reader" "$f" >"$tmp/stream"
  "$tool" clash "$tmp/web-ifc.mkt" --summary --threads 1 >"$tmp/clash-web-ifc"
  "$tool" clash "$tmp/assimp.mkt" --summary --threads 1 >"$tmp/clash-assimp"
  python3 - "$f" "$tmp/stream" "$tmp/clash-web-ifc" "$tmp/clash-assimp" <<'EOF'
import collections, json, re, struct, sys
ifc, stream, clash_web, clash_assimp = sys.argv[1:]
d = open(stream, 'rb').read()
p = 16
objects = []
def u32():
    global p
    v = struct.unpack_from('<I', d, p)[0]; p += 4; return v
def s():
    global p
    n = u32(); v = d[p:p + n].decode(); p += n; return v
while True:
    tag = d[p:p + 4]; p += 4
    if tag == b'MKOB':
        s(); attrs = collections.defaultdict(list)
        for _ in range(u32()):
            k = s(); attrs[k].append(s())
        nv, nt = u32(), u32(); p += 24 * nv + 12 * nt
        objects.append(attrs)
    elif tag in (b'MKWN', b'MKER'):
        s()
    else:
        break
counts = collections.Counter(re.findall(r'^#\d+\s*=\s*(IFC[A-Z0-9]+)\(', open(ifc, encoding='latin1').read(), re.M))
by_type = collections.Counter(o['ifc_type'][0] for o in objects)
print('  objects by type (file entities):', ', '.join(f"{t} {n} ({counts[t.upper()]})" for t, n in by_type.most_common()))
def pairs(path):
    lines = [json.loads(l) for l in open(path) if l.startswith('{"a"')]
    summary = json.loads(open(path).read().splitlines()[-1])
    return lines, summary
for name, path in (('assimp', clash_assimp), ('web-ifc', clash_web)):
    _, sm = pairs(path)
    print(f"  clash {name}: {sm['pairs']} pairs ({sm['hard']} hard, {sm['touch']} touch)")
lines, _ = pairs(clash_web)
kinds = collections.Counter()
for l in lines:
    a, b = objects[l['a']], objects[l['b']]
    ga, gb = a['ifc_global_id'][0], b['ifc_global_id'][0]
    if 'true' in a.get('ifc_spatial', []) or 'true' in b.get('ifc_spatial', []):
        k = 'with an opening or space (ifc_spatial)'
    elif gb in a.get('ifc_fills', []) or ga in b.get('ifc_fills', []):
        k = 'door/window with its host (ifc_fills)'
    elif a.get('ifc_aggregate', [''])[0] in (gb, b.get('ifc_aggregate', [None])[0]) or \
         b.get('ifc_aggregate', [''])[0] == ga:
        k = 'parts of one whole (ifc_aggregate)'
    else:
        k = 'other'
    kinds[(k, l['class'])] += 1
for (k, c), n in sorted(kinds.items()):
    print(f"  web-ifc {c:5s} {k}: {n}")
EOF
done
