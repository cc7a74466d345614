#!/usr/bin/env bash
# Regenerates the seed corpora (tests/fuzz/corpus/<target>/seed-*) from ../shared/data and small stores
# built by the tool. Only the HDF5 stores differ from run to run (HDF5 records object times). Run it again after a change of the store or scene formats (the replay tests'
# --min-accepted check fails when the seeds no longer parse). Units merged in by `scripts/fuzz.sh --merge`
# (named by their SHA-1) are left alone.
#   tests/fuzz/make_seeds.sh [BUILD_DIR]     (default: build; needs mktree and fuzz_seed_tool built there)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=$(cd "${1:-$root/build}" && pwd)
data=$(cd "$root/../shared/data" && pwd)
mktree="$build/mktree"
tool="$build/tests/fuzz/fuzz_seed_tool"
[[ -x $mktree && -x $tool ]] || { echo "build mktree and fuzz_seed_tool in $build first" >&2; exit 1; }
corpus="$here/corpus"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for t in obj mks queries store_open store_hdf5 leaf; do
  mkdir -p "$corpus/$t"
  rm -f "$corpus/$t"/seed-*
done
slice() { python3 "$here/obj_slice.py" "$data/$1" "$2" "$3"; }

# OBJ: slices of the real scenes (self-contained, re-indexed), the generator's output, and small files
# with the syntax the real scenes do not use.
slice buildings/duplex.obj 0 3 >"$corpus/obj/seed-duplex-0-3.obj"
slice buildings/duplex.obj 200 5 >"$corpus/obj/seed-duplex-200-5.obj"
slice city/denhaag_01.obj 10 8 >"$corpus/obj/seed-denhaag-10-8.obj"
slice city/denhaag_01.obj 1500 20 >"$corpus/obj/seed-denhaag-1500-20.obj"
slice buildings/steel_mini_project.obj 107 6 >"$corpus/obj/seed-steel-107-6.obj"
head -c 3000 "$data/buildings/duplex.obj" >"$corpus/obj/seed-duplex-truncated.obj"
"$mktree" generate tanker --objects 3 --seed 7 -o "$tmp/tanker.obj" >/dev/null
cp "$tmp/tanker.obj" "$corpus/obj/seed-tanker-3.obj"
printf '%s\n' '# every vertex and face form' 'mtllib a.mtl' 'v 0 0 0' 'v 1 0 0' 'v 1 1 0' 'v 0 1 0 1.0' \
  'v 0 0 1 0.5 0.5 0.5' 'vt 0 0' 'vt 1 0' 'vt 1 1' 'vn 0 0 1' 'vp 0.5' 'o quad' 'usemtl red' 's off' \
  'f 1/1/1 2/2/1 3/3/1 4/1/1' 'f -5//1 -4//1 -3//1' 'l 1 2' 'p 3' 'g ignored' 'o tet' 'f 1 2 \' ' 5' \
  'f 1/1 3/3 5/2' 'f 2 3 5' >"$corpus/obj/seed-forms.obj"
printf 'v 0 0 0\r\nv 1 0 0\r\nv 0 1 0\r\nv 0 0 1\r\ng a\r\nf 1 2 3\r\ng b\r\nf 1 2 4\r\ng a\r\nf 1 3 4' \
  >"$corpus/obj/seed-groups-crlf.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\no named\nv 0 0 1\nf -1 -2 -3\n' >"$corpus/obj/seed-unnamed-first.obj"

# .mks: the same scenes converted, and the generator's.
for f in duplex-0-3 denhaag-10-8 forms; do "$tool" obj2mks "$corpus/obj/seed-$f.obj" "$corpus/mks/seed-$f.mks"; done
"$mktree" generate tanker --objects 2 --seed 3 -o "$corpus/mks/seed-tanker-2.mks" >/dev/null

# Stores of a few objects with small pages (multi-page leaves too), both backends and both codecs.
build_store() {  # NAME BACKEND BLOCK BLOCKS CODEC SCENE
  "$mktree" build "$6" -o "$tmp/$1" --backend "$2" --block-size "$3" --blocks-per-page "$4" --codec "$5" -q
}
build_store duplex.pf pagefile 512 1 zstd "$corpus/obj/seed-duplex-0-3.obj"
build_store denhaag.pf pagefile 1024 1 none "$corpus/obj/seed-denhaag-10-8.obj"
build_store tanker.pf pagefile 512 2 zstd tanker:6:1
build_store forms.pf pagefile 512 1 zstd "$corpus/obj/seed-forms.obj"
build_store duplex.h5 hdf5 512 1 zstd "$corpus/obj/seed-duplex-0-3.obj"
build_store tanker.h5 hdf5 512 1 none tanker:3:2

# Queries: hand-written forms and the tool's generated queries over a store.
printf '%s\n' '# point and box queries' 'point 1 2 3' 'box 0 0 0 1 1 1' 'point 1e3,2.5e-3,-7' \
  '  box -1 -1 -1    2 2 2   # trailing comment' '' 'point -0 0 0.5' >"$corpus/queries/seed-forms.txt"
printf 'point 1 2 3\r\nbox 0,0,0,1,1,1\r\n\tpoint\t4\t5\t6\r\n' >"$corpus/queries/seed-crlf.txt"
(cd "$tmp" && "$mktree" generate queries tanker.pf -o "$corpus/queries/seed-generated.txt" --count 12 --seed 5 >/dev/null)
printf '1,2,3' >"$corpus/queries/seed-arg-point.txt"

# store_open: raw (mode 0), resealed (mode 1) and structured (mode 2) inputs; store_hdf5: the files.
"$tool" store_raw "$tmp/duplex.pf" 0 "$corpus/store_open/seed-raw-duplex"
for s in duplex denhaag tanker; do
  "$tool" store_raw "$tmp/$s.pf" 1 "$corpus/store_open/seed-resealed-$s"
  "$tool" store_struct "$tmp/$s.pf" "$corpus/store_open/seed-struct-$s"
done
"$tool" store_struct "$tmp/forms.pf" "$corpus/store_open/seed-struct-forms"
"$tool" store_struct "$tmp/tanker.h5" "$corpus/store_open/seed-struct-tanker-h5"
cp "$tmp/duplex.h5" "$corpus/store_hdf5/seed-duplex.h5"
cp "$tmp/tanker.h5" "$corpus/store_hdf5/seed-tanker.h5"

# leaf: each leaf's pages and its first entries.
mkdir -p "$tmp/leaf"
"$tool" leaves "$tmp/duplex.pf" "$tmp/leaf" 4 && for f in "$tmp/leaf"/*; do mv "$f" "$corpus/leaf/seed-duplex-${f##*/}"; done
"$tool" leaves "$tmp/denhaag.pf" "$tmp/leaf" 4 && for f in "$tmp/leaf"/*; do mv "$f" "$corpus/leaf/seed-denhaag-${f##*/}"; done
"$tool" leaves "$tmp/tanker.pf" "$tmp/leaf" 2 && for f in "$tmp/leaf"/*; do mv "$f" "$corpus/leaf/seed-tanker-${f##*/}"; done

du -sh "$corpus"/*
