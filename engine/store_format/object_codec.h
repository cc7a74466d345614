// One object's leaf entry: a fixed 48-byte entry header, then its geometry (raw or zstd-compressed).
// Every object is encoded alone at ingest, so its entry size (BuildObject::encoded_bytes) is exact and a
// leaf's size is the sum of its entries (engine/tree/page_budget.h).
//
// Coordinates. A store has a frame: store coordinates = world coordinates - the store's origin (a double
// triple chosen at ingest, kept in the store header). The entry's AABB is in the store frame, float32,
// rounded outward. The vertices are float32 in the object's local frame: per axis, local = vertex -
// box.min + 2^k, with 2^k the power of two just above the box's extent (2^-100 when it is 0), so every
// local coordinate of an axis has the same exponent and the decoder recovers vertex = box.min + (local -
// 2^k) in double. A vertex so keeps 2^-22 of the object's own size wherever the object lies, and stays in
// its box. Why, against world float32 coordinates, which lose a small object's shape at UTM-sized
// coordinates: bench/coordinate_bench.cc and bench/README.md.
//
// Entry layout (little-endian):
//   offset size field
//   0      4    object id
//   4      24   float32 AABB in the store frame: min x, y, z, max x, y, z (rounded outward)
//   28     1    codec: 0 none, 1 zstd, 2 zstd with the store's dictionary
//   29     1    transform: 0 none, 1 shuffle (see below)
//   30     1    shape flags (ShapeFlags): what ingest learnt of the mesh; 0 = unknown
//   31     1    reserved, 0
//   32     4    vertex count
//   36     4    triangle count
//   40     4    raw geometry bytes = 12 * (vertex count + triangle count)
//   44     4    stored geometry bytes (what follows the header)
//   48     ...  geometry
// Raw geometry: float32 local vertices (x, y, z interleaved), then uint32 triangle indices.
// Transform 1 (lossless, applied before zstd, so that zstd finds more to shrink; bench/README.md): vertex
// floats are split into x, y, z planes and each value's bits are XORed with the previous
// value in its plane (repeated coordinates become zero); triangle indices become zigzag-encoded deltas;
// then both arrays are byte-shuffled (all byte 0s, then all byte 1s, ...).
// An entry whose compressed geometry would not be smaller than the raw bytes is stored raw (codec 0).
//
// Thread safety: all functions are reentrant (codec contexts are per thread).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <vector>

#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// kZstdDict: a zstd frame compressed with the store's dictionary (store format 6; an entry codec only,
// the store's parameters say kZstd).
enum class Codec : uint8_t { kNone = 0, kZstd = 1, kZstdDict = 2 };

}  // namespace mktree

struct ZSTD_CDict_s;
struct ZSTD_DDict_s;

namespace mktree {

// A store's zstd dictionary (store format 6): trained at ingest on the first objects' geometry
// (TrainDictionary), kept once in the store and shared by all its zstd entries (codec kZstdDict). Each
// object's frame then needs no literal table of its own: less compression CPU and fewer geometry bytes
// (bench/dict_bench.cc; the figures are in bench/README.md).
// Thread safety: immutable once loaded; any number of threads may compress or decompress with it.
class CodecDictionary {
 public:
  // Loads `bytes` (a zstd dictionary, as TrainDictionary gives), for compression at `compress_level` if
  // given. Corruption when zstd does not take them as a dictionary.
  static Result<std::shared_ptr<const CodecDictionary>> Load(std::vector<uint8_t> bytes,
                                                             std::optional<int> compress_level);
  ~CodecDictionary();
  CodecDictionary(const CodecDictionary&) = delete;
  CodecDictionary& operator=(const CodecDictionary&) = delete;

  const std::vector<uint8_t>& bytes() const { return bytes_; }
  const ZSTD_CDict_s* cdict() const { return cdict_; }  // null unless loaded with a level
  const ZSTD_DDict_s* ddict() const { return ddict_; }

 private:
  CodecDictionary() = default;
  std::vector<uint8_t> bytes_;
  ZSTD_CDict_s* cdict_ = nullptr;
  ZSTD_DDict_s* ddict_ = nullptr;
};

// What ingest trains a dictionary on: the packed geometry (PackObjectGeometry) of the first objects, whole
// objects up to this many bytes: the size that stored the benchmark scenes in the fewest bytes
// (bench/README.md, dict_bench).
inline constexpr size_t kDictionarySampleBytes = size_t{4} << 20;
// zstd's fastCover search steps over its segment sizes k (50 to 2000): 1 tries k = 50 and 2000. Training
// runs on one core before any object is encoded, and more steps cost time for no better stores overall
// (bench/README.md, session 33).
inline constexpr unsigned kDictionaryTrainingSteps = 1;

// Trains a dictionary for zstd level `level` on `samples` (objects' packed geometry back to back, their
// sizes in `sizes`), of sample bytes / 64 clamped to 4-64 KiB (smaller scenes fit smaller dictionaries).
// Returns no bytes (no dictionary) when zstd cannot train on the sample (a few objects) or when, on the
// sample, the dictionary would not save more than its own size. Deterministic: one training thread.
std::vector<uint8_t> TrainDictionary(std::span<const uint8_t> samples, std::span<const size_t> sizes,
                                     int level);

struct CodecOptions {
  Codec codec = Codec::kZstd;  // how geometry is stored in leaf entries
  // zstd compression level, as mktree/build.h allows: ZSTD_minCLevel() (negative: fast modes) to
  // ZSTD_maxCLevel() (22); 0: zstd's default. 3, because pages are what queries pay for: on scenes read
  // from OBJ text (how users' scenes arrive), level -1 stores more pages and builds no faster (the OBJ
  // parser bounds it); from the generator, -1 builds faster for a few more pages: pass --zstd-level -1
  // where ingest speed matters more than pages. Levels 1 and 3 cost the same on small objects. (The
  // figures: bench/README.md, "Figures that used to sit in code comments".)
  int zstd_level = 3;
  bool shuffle = true;  // apply transform 1 before zstd (ignored with kNone)
  // The store's dictionary (with kZstd): entries are compressed with it (codec kZstdDict). Null: none.
  std::shared_ptr<const CodecDictionary> dictionary;
};

inline constexpr uint32_t kObjectEntryHeaderBytes = 48;

// Facts about an object's mesh that ingest computes once so that exact queries need not (the edge check
// is O(T log T), paid per query otherwise).
enum ShapeFlags : uint8_t {
  kShapeKnown = 1,      // the other bits are meaningful
  kShapeEvenEdges = 2,  // every undirected edge is used an even number of times (ray parity applies)
  kShapeClosed = 4,     // every edge used exactly twice, with opposite orientations
};

// Appends the entry for `obj` (world coordinates) in the frame of a store whose origin is `origin` to
// *out; returns the entry size (BuildObject::encoded_bytes) and sets *box to the entry's AABB (store
// frame). InvalidArgument, naming the object, for an empty mesh, a non-finite coordinate, a coordinate
// beyond float32's range in the store frame, or geometry over 4 GiB; nothing is appended then.
Result<uint32_t> EncodeObjectEntry(const SceneObject& obj, const Vec3d& origin, const CodecOptions& opts,
                                   std::vector<uint8_t>* out, uint8_t shape_flags = 0, Box3f* box = nullptr);
// The same for a store whose origin is (0, 0, 0); returns 0 (appending nothing) where that fails.
uint32_t EncodeObjectEntry(const SceneObject& obj, const CodecOptions& opts, std::vector<uint8_t>* out,
                           uint8_t shape_flags = 0);

// Appends the bytes EncodeObjectEntry hands zstd for `obj` (its local vertices and triangles, transformed
// when `shuffle`) to *out: what a store's dictionary is trained on. InvalidArgument as EncodeObjectEntry.
Status PackObjectGeometry(const SceneObject& obj, const Vec3d& origin, bool shuffle,
                          std::vector<uint8_t>* out);

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

// Appends a copy of `entry` (one whole entry, as ParseObjectEntry reads it) to *out under the id `id`,
// its geometry bytes as they are: for a store with the frame and dictionary of the store it came from (a
// compaction keeps both). Returns the parsed copy (its geometry points into *out until *out grows).
// Corruption, appending nothing, when the header is inconsistent or its size is not entry.size().
Result<ObjectEntryView> CopyObjectEntry(std::span<const uint8_t> entry, ObjectId id,
                                        std::vector<uint8_t>* out);

// How far a vertex inside `box` (the entry's AABB) may lie from where the input put it: per axis one
// float32 ulp of its local coordinate plus the double arithmetic of encoding and decoding. Two objects
// whose input surfaces touch exactly are at most the sum of their resolutions apart once stored.
double CoordinateResolution(const Box3f& box);

// Decompresses and un-transforms an entry's geometry into *mesh, in the store frame (box.min + local).
// `dictionary` is the store's (CodecOptions::dictionary), needed by kZstdDict entries. Corruption on bad
// data (zstd failure, size mismatch, a triangle index out of range, a vertex outside the entry's box, a
// kZstdDict entry without a dictionary).
Status DecodeObjectMesh(const ObjectEntryView& e, Mesh* mesh, const CodecDictionary* dictionary = nullptr);

}  // namespace mktree
