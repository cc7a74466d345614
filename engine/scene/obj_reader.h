// Streaming reader for Wavefront OBJ scenes.
//
// What it reads
//   - `o NAME` starts an object. `g NAME` starts an object only in a file that has no `o` line at all; in a
//     file with `o` lines, groups are ignored. Faces before the first `o`/`g` form an unnamed object.
//     A `g` that repeats an earlier group name starts a new object (a stream cannot merge them).
//   - `v x y z [w | r g b [a]]`: only x, y, z are used. `f` with every vertex form (`v`, `v/vt`, `v//vn`,
//     `v/vt/vn`), absolute (1-based) or relative (negative) indices; vt and vn indices are range-checked
//     and otherwise ignored. Polygons are triangulated as a fan (v0, vi, vi+1).
//   - Accepted and ignored: comments, blank lines, `vt`, `vn`, `vp`, `l`, `p`, `s`, `usemtl`, `mtllib`, and
//     the spec's display/render attributes (`lod`, `bevel`, `c_interp`, `d_interp`, `usemap`, `maplib`,
//     `shadow_obj`, `trace_obj`, `mg`). Lines may end in CRLF; a trailing `\` continues a line.
//   - Objects without faces are skipped and consume no id. Names: the `o`/`g` name, else "object_<id>".
//   - Each emitted mesh holds only the vertices its faces use, re-indexed compactly in first-use order.
//
// Errors (never a silently wrong scene): every malformed line is an error naming `file:line` and what was
// wrong: a bad number, too few or too many coordinates, NaN/Inf or out-of-range coordinates, an index
// that is 0 or out of range, a face with fewer than 3 vertices, free-form geometry (`curv`, `surf`, ...,
// which would otherwise be silently dropped), and any unknown directive. Unknown directives are errors
// rather than warnings because SceneSource has no warning channel and an unknown keyword means either a
// non-OBJ file or geometry we would drop; the harmless spec directives are listed above. A last line that
// fails to parse and lacks its newline is reported as a truncated file.
//
// Coordinates are read as doubles (the input's precision, whatever the distance from 0).
//
// Memory: OBJ vertex indices are global to the file, so the reader keeps the global vertex table (double
// x, y, z: 24 bytes per `v` line), up to ObjReadOptions::vertex_ram_bytes of the most recent vertices in
// RAM and the older ones in a spill file, plus the current object's mesh and its re-indexing map. Nothing
// else grows with the file: it is read (pread into reused buffers) and parsed in chunks (ObjReadOptions), a
// fixed number of them in flight. Not memory-mapped: a file truncated while being read is an IOError naming
// the file and the line where the missing bytes begin, where a mapping would die of SIGBUS.
//
// `g` versus `o` is decided lazily: if an `o` line comes before any `g` line, nothing more is needed. Only
// when a `g` line comes first does the reader scan ahead in the file (a separate read, stopping at the
// first line that starts with "o") to learn whether the file has `o` lines. Files with only `g` lines are
// therefore read twice; files written with `o` lines (the common case) are read once.
//
// Parallelism: worker threads parse chunks (numbers with fast_float, faces into OBJ indices, directives into
// operations: engine/scene/obj_chunk.h); the thread calling Next() applies them in file order (vertex
// counts, index checks, line numbers, objects), so objects, ids, errors and their lines are those of a
// sequential read whatever the thread count or chunk size.
//
// Each object's `source` is the path as given; its attributes are the groups (key "group", one per name
// of a `g` line) and materials (key "material", the `usemtl` name) in force for any of its faces, each
// once, in the order first met.
//
// Thread-safety: a source is used by one thread at a time; distinct sources are independent.
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "engine/scene/scene_source.h"
#include "storage/file_ops.h"

namespace mktree {

// Opens `path` (a regular file) for streaming. The first object gets id `first_id`, the next
// first_id + 1, and so on. Fails with NotFound or IOError, naming the file, when it cannot be opened.
// Parse errors come from Next(): Corruption for malformed input, Unsupported for free-form geometry.
Result<std::unique_ptr<SceneSource>> OpenObjFile(const std::string& path, ObjectId first_id = 0);

struct ObjReadOptions {
  // Parsing threads besides the caller's; 0 parses on the caller's thread. -1: one per hardware thread.
  int threads = -1;
  // Bytes per chunk (cut at the next line end); at most threads + 4 chunks are in flight.
  size_t chunk_bytes = size_t{1} << 18;
  // Every vertex is kept, as faces may use any earlier one (24 bytes each): this many bytes of the most
  // recent in RAM, older ones in a spill file, read back when a face uses them.
  size_t vertex_ram_bytes = size_t{64} << 20;
  // Where the spill file goes (unnamed, removed when the reader is); empty: $TMPDIR, else /tmp.
  std::string spill_dir;
  // The spill file's writes and reads (storage/file_ops.h); null: POSIX. Tests inject faults through it;
  // it must outlive the reader.
  FileOps* spill_file_ops = nullptr;
};
Result<std::unique_ptr<SceneSource>> OpenObjFile(const std::string& path, ObjectId first_id,
                                                 const ObjReadOptions& options);

}  // namespace mktree
