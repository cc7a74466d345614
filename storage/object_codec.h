// One object's leaf entry: a fixed 48-byte entry header, then its geometry (raw or zstd-compressed).
// Every object is encoded alone at ingest, so its entry size (ObjectRecord::encoded_bytes) is exact and a
// leaf's size is the sum of its entries (storage/leaf_format.h).
//
// Entry layout (little-endian):
//   offset size field
//   0      4    object id
//   4      24   float32 AABB: min x, y, z, max x, y, z (rounded outward, SceneObject::Aabb)
//   28     1    codec: 0 none, 1 zstd
//   29     1    transform: 0 none, 1 shuffle (see below)
//   30     1    shape flags (ShapeFlags): what ingest learnt of the mesh; 0 = unknown
//   31     1    reserved, 0
//   32     4    vertex count
//   36     4    triangle count
//   40     4    raw geometry bytes = 12 * (vertex count + triangle count)
//   44     4    stored geometry bytes (what follows the header)
//   48     ...  geometry
// Raw geometry: float32 vertices (x, y, z interleaved), then uint32 triangle indices.
// Transform 1 (lossless, applied before zstd; measured to shrink pipe prisms ~1.4x and boxes ~1.3x
// further): vertex floats are split into x, y, z planes and each value's bits are XORed with the previous
// value in its plane (repeated coordinates become zero); triangle indices become zigzag-encoded deltas;
// then both arrays are byte-shuffled (all byte 0s, then all byte 1s, ...).
// An entry whose compressed geometry would not be smaller than the raw bytes is stored raw (codec 0).
//
// Thread safety: all functions are reentrant (codec contexts are per thread).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

enum class Codec : uint8_t { kNone = 0, kZstd = 1 };

struct CodecOptions {
  Codec codec = Codec::kZstd;  // how geometry is stored in leaf entries
  // zstd compression level (1..19; negative = fast modes). 3, because pages are what queries pay for:
  // measured on 1M tanker objects read back from OBJ text (how users' scenes arrive), level -1 stores
  // 11% more pages (26,804 vs 24,153) and builds no faster (the OBJ parser bounds it: 9.8 vs 9.6 s).
  // From the generator, -1 builds 22% faster (179k vs 147k objects/s) for 1.3% more pages: pass
  // --zstd-level -1 where ingest speed matters more than pages. Levels 1 and 3 cost the same on objects
  // this small (~660 B raw).
  int zstd_level = 3;
  bool shuffle = true;         // apply transform 1 before zstd (ignored with kNone)
};

inline constexpr uint32_t kObjectEntryHeaderBytes = 48;

// Facts about an object's mesh that ingest computes once so that exact queries need not (the edge check
// is O(T log T): 23 ms for a 52k-triangle mesh, paid per query otherwise).
enum ShapeFlags : uint8_t {
  kShapeKnown = 1,      // the other bits are meaningful
  kShapeEvenEdges = 2,  // every undirected edge is used an even number of times (ray parity applies)
  kShapeClosed = 4,     // every edge used exactly twice, with opposite orientations
};

// Appends the entry for `obj` (its id, obj.Aabb(), its geometry) to *out; returns the entry size, which
// is ObjectRecord::encoded_bytes. Objects whose geometry exceeds 4 GiB cannot be encoded (returns 0 and
// appends nothing; callers treat 0 as an error).
uint32_t EncodeObjectEntry(const SceneObject& obj, const CodecOptions& opts, std::vector<uint8_t>* out,
                           uint8_t shape_flags = 0);

// A parsed entry inside a leaf payload. `geometry` points into the payload it was parsed from.
struct ObjectEntryView {
  ObjectId id = 0;
  Box3f box;
  Codec codec = Codec::kNone;
  uint8_t transform = 0;
  uint8_t shape_flags = 0;  // ShapeFlags
  uint32_t vertex_count = 0;
  uint32_t triangle_count = 0;
  uint32_t raw_bytes = 0;
  std::span<const uint8_t> geometry;  // the stored geometry bytes
  uint32_t entry_bytes() const { return kObjectEntryHeaderBytes + static_cast<uint32_t>(geometry.size()); }
};

// Parses the entry starting at data[0] (n bytes available). Checks header consistency only (not the
// geometry). Corruption if the header is inconsistent or the entry runs past `n`.
Result<ObjectEntryView> ParseObjectEntry(const uint8_t* data, size_t n);
// The same into *out, which is meaningful only on Ok (for loops over a leaf's entries: no Result to
// build and copy per entry).
Status ParseObjectEntry(const uint8_t* data, size_t n, ObjectEntryView* out);

// Decompresses and un-transforms an entry's geometry into *mesh. Corruption on bad data (zstd failure,
// size mismatch, a triangle index out of range).
Status DecodeObjectMesh(const ObjectEntryView& e, Mesh* mesh);

}  // namespace mktree
