// The records of a store's in-RAM structure (tree arrays, build parameters and codec, object table), each
// described once by a record schema (storage/record_schema.h) that gives both its canonical byte encoding
// and its HDF5 compound type. The paged file stores the canonical bytes as sections; both backends
// checksum them (XXH3-64), so a flipped byte in the metadata is detected at open. All little-endian and
// packed (see docs/store_format.md for the record layouts).
// Thread safety: pure functions; ObjectTable is a plain value but for its claims (leaf_claims.h).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "engine/store_format/leaf_claims.h"
#include "engine/store_format/object_codec.h"
#include "engine/tree/mktree.h"
#include "mktree/scene.h"
#include "mktree/status.h"
#include "storage/record_schema.h"

namespace mktree {

// The object table, what a store keeps of its objects in RAM, O(leaves + record pages): the object count,
// each leaf's id digest (LeafIdDigest of the ids it holds: CheckLeafEntries proves a leaf's entries by
// it), the record directory (the first object id of each record page, engine/store_format/record_codec.h) and
// the sources table (the distinct input files). Each object's leaf, name and attributes live in its
// record, in the record pages.
struct ObjectTable {
  uint64_t count = 0;                      // objects, ids 0 .. count - 1
  std::vector<uint64_t> leaf_digest;       // per leaf: LeafIdDigest of its objects' ids
  std::vector<uint32_t> record_directory;  // first object id of each record page
  std::vector<std::string> sources;        // the distinct input files, by index
  LeafClaims claims;                       // the leaf each id was read in first (not part of the value)

  uint64_t size() const { return count; }
  bool operator==(const ObjectTable&) const = default;
};

// One id's term of a leaf's id digest: a 64-bit mix, so that sums of different id sets differ except by
// chance (2^-64 for damage; a crafted file can find a collision: this is a checksum, not a proof).
inline uint64_t ObjectIdHash(uint32_t id) {
  uint64_t x = (uint64_t{id} + 1) * 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
// A leaf's id digest: the sum (mod 2^64) of ObjectIdHash over the ids it holds. The digests of a store's
// leaves add up to AllIdsDigest(object count) exactly when the leaves hold every id once (but for a
// collision), which ValidateStructure checks at open; CheckLeafEntries checks each leaf's entries against
// its digest when it is read.
inline uint64_t AllIdsDigest(uint64_t count) {
  uint64_t sum = 0;
  for (uint64_t id = 0; id < count; ++id) sum += ObjectIdHash(static_cast<uint32_t>(id));
  return sum;
}

// The parameter record: the build parameters and the codec, as stored.
struct ParamsRecord {
  uint32_t block_size = 0;
  uint32_t blocks_per_page = 0;
  double balance_r = 0;
  uint32_t split_tree_node_budget = 0;
  uint8_t codec = 0;    // Codec
  uint8_t shuffle = 0;  // 0 or 1
  int32_t zstd_level = 0;
};

// The record schemas. Field names are the HDF5 compound members' (and the HDF5 attributes' for the
// parameters); changing a name, type or order changes both store formats.
inline constexpr const char* kCellLabelNames[] = {"EMPTY", "LEFT", "RIGHT", "BOTH"};
inline constexpr RecordField kNodeFields[] = {
    MKTREE_RECORD_FIELD("box_min", TreeNode, box.min, kF32),
    MKTREE_RECORD_FIELD("box_max", TreeNode, box.max, kF32),
    MKTREE_RECORD_FIELD("a", TreeNode, a, kF32),
    MKTREE_RECORD_FIELD("b", TreeNode, b, kF32),
    MKTREE_RECORD_FIELD("child", TreeNode, child, kU32),
    MKTREE_RECORD_FIELD("leaf", TreeNode, leaf, kU32),
    MKTREE_RECORD_FIELD("split_root", TreeNode, split_root, kU32),
    MKTREE_RECORD_FIELD("axis", TreeNode, axis, kU8),
    MKTREE_RECORD_FIELD("depth", TreeNode, depth, kU8),
    ReservedField(FieldType::kU16),
};
inline constexpr RecordSchema kNodeRecord{"node", sizeof(TreeNode), kNodeFields};
inline constexpr RecordField kSplitNodeFields[] = {
    MKTREE_RECORD_FIELD("cut", SplitNode, cut, kF32),
    MKTREE_RECORD_FIELD("child", SplitNode, child, kU32),
    MKTREE_RECORD_FIELD("axis", SplitNode, axis, kU8),
    MKTREE_RECORD_FIELD("label", SplitNode, label, kU8, kCellLabelNames),
    ReservedField(FieldType::kU16),
};
inline constexpr RecordSchema kSplitNodeRecord{"split node", sizeof(SplitNode), kSplitNodeFields};
inline constexpr RecordField kLeafFields[] = {
    MKTREE_RECORD_FIELD("box_min", LeafInfo, box.min, kF32),
    MKTREE_RECORD_FIELD("box_max", LeafInfo, box.max, kF32),
    MKTREE_RECORD_FIELD("node", LeafInfo, node, kU32),
    MKTREE_RECORD_FIELD("object_count", LeafInfo, object_count, kU32),
    MKTREE_RECORD_FIELD("payload_bytes", LeafInfo, payload_bytes, kU64),
    MKTREE_RECORD_FIELD("first_page", LeafInfo, first_page, kU64),
    MKTREE_RECORD_FIELD("page_count", LeafInfo, page_count, kU32),
    ReservedField(FieldType::kU32),
};
inline constexpr RecordSchema kLeafRecord{"leaf", sizeof(LeafInfo), kLeafFields};
inline constexpr RecordField kParamsFields[] = {
    MKTREE_RECORD_FIELD("block_size", ParamsRecord, block_size, kU32),
    MKTREE_RECORD_FIELD("blocks_per_page", ParamsRecord, blocks_per_page, kU32),
    MKTREE_RECORD_FIELD("balance_r", ParamsRecord, balance_r, kF64),
    MKTREE_RECORD_FIELD("split_tree_node_budget", ParamsRecord, split_tree_node_budget, kU32),
    MKTREE_RECORD_FIELD("codec", ParamsRecord, codec, kU8),
    MKTREE_RECORD_FIELD("shuffle", ParamsRecord, shuffle, kU8),
    ReservedField(FieldType::kU16),
    MKTREE_RECORD_FIELD("zstd_level", ParamsRecord, zstd_level, kI32),
};
inline constexpr RecordSchema kParamsRecord{"parameter", sizeof(ParamsRecord), kParamsFields};
// The object table's columns (leaf = row, record page = row); the sources and the leaf filter are
// kByteColumn.
inline constexpr RecordField kLeafDigestFields[] = {
    MakeRecordField("id_digest", 0, sizeof(uint64_t), FieldType::kU64)};
inline constexpr RecordSchema kLeafDigestColumn{"leaf id digest", sizeof(uint64_t), kLeafDigestFields, false};
inline constexpr RecordField kRecordDirectoryFields[] = {
    MakeRecordField("first_object", 0, sizeof(uint32_t), FieldType::kU32)};
inline constexpr RecordSchema kRecordDirectoryColumn{"record directory", sizeof(uint32_t),
                                                     kRecordDirectoryFields, false};

inline constexpr size_t kNodeRecordBytes = kNodeRecord.encoded_bytes();
inline constexpr size_t kSplitNodeRecordBytes = kSplitNodeRecord.encoded_bytes();
inline constexpr size_t kLeafRecordBytes = kLeafRecord.encoded_bytes();
inline constexpr size_t kParamsRecordBytes = kParamsRecord.encoded_bytes();
static_assert(kNodeRecordBytes == 52 && kSplitNodeRecordBytes == 16 && kLeafRecordBytes == 56 &&
              kParamsRecordBytes == 28);
static_assert(FieldsFitRecord(kNodeRecord) && FieldsFitRecord(kSplitNodeRecord) &&
              FieldsFitRecord(kLeafRecord) && FieldsFitRecord(kParamsRecord) &&
              FieldsFitRecord(kLeafDigestColumn) && FieldsFitRecord(kRecordDirectoryColumn) &&
              FieldsFitRecord(kByteColumn));

ParamsRecord ToParamsRecord(const BuildParams& p, const CodecOptions& c);

std::vector<uint8_t> EncodeParams(const BuildParams& p, const CodecOptions& c);
Status DecodeParams(std::span<const uint8_t> in, BuildParams* p, CodecOptions* c);
std::vector<uint8_t> EncodeNodes(const std::vector<TreeNode>& nodes);
Status DecodeNodes(std::span<const uint8_t> in, std::vector<TreeNode>* nodes);
std::vector<uint8_t> EncodeSplitNodes(const std::vector<SplitNode>& nodes);
Status DecodeSplitNodes(std::span<const uint8_t> in, std::vector<SplitNode>* nodes);
std::vector<uint8_t> EncodeLeaves(const std::vector<LeafInfo>& leaves);
Status DecodeLeaves(std::span<const uint8_t> in, std::vector<LeafInfo>* leaves);
std::vector<uint8_t> EncodeLeafDigests(const ObjectTable& t);
// Rebuilds a table of `count` objects from its three sections (leaf id digests, record directory,
// sources table).
Status DecodeObjectTable(uint64_t count, std::span<const uint8_t> leaf_digests,
                         std::span<const uint8_t> directory, std::span<const uint8_t> sources,
                         ObjectTable* t);

uint64_t Checksum(std::span<const uint8_t> bytes);
// Checksum of the canonical encoding of the records, encoded a block at a time (no copy of them all).
uint64_t RecordsChecksum(const RecordSchema& s, const void* records, size_t n);
template <const RecordSchema& S, typename T>
uint64_t RecordsChecksum(const std::vector<T>& records) {
  static_assert(sizeof(T) == S.ram_bytes, "the schema describes another record");
  return RecordsChecksum(S, records.data(), records.size());
}
inline uint64_t Checksum(std::string_view s) {
  return Checksum(std::span<const uint8_t>(reinterpret_cast<const uint8_t*>(s.data()), s.size()));
}

// SplitTrees are at most this many levels deep: routing walks them with a fixed 64-entry stack (BoxSides
// in engine/tree/mktree.cc), which holds at most one pending node per level.
inline constexpr uint32_t kMaxSplitTreeLevels = 64;

// Whether `inner` lies within `outer` (closed; an empty box, such as an empty mesh's, lies within any).
inline bool BoxWithin(const Box3f& inner, const Box3f& outer) {
  if (inner.empty()) return true;
  for (int i = 0; i < 3; ++i)
    if (!(outer.min[i] <= inner.min[i] && inner.max[i] <= outer.max[i])) return false;
  return true;
}

// Checks that the structure is the one the builder writes, so that routing and leaf reads terminate and
// can trust it (a tampered store with valid checksums is refused here), in time and memory linear in its
// size: the nodes are in depth-first preorder from the root (left child first), which rules out cycles,
// shared children and orphans; depths count from 0 at the root (so the tree has at most 256 levels);
// every child's box lies within its parent's, a leaf node's box is its leaf's, a = R(child 1).min[axis]
// and b = R(child 0).max[axis] (docs/design.md §3.3); leaves are numbered in that order, each referenced by
// exactly one node that it references back, with page ranges in order, disjoint, within `page_count` and
// as many as its payload needs; each SplitTree is a tree (no split node reached twice, none left over) of
// at most kMaxSplitTreeLevels levels; there is one id digest per leaf, the leaves' object_counts add up to
// the object count and their digests to AllIdsDigest of it; the leaf filter is empty or 8 bytes per
// object.
// `page_count` is the store's, record pages included: the record directory has one entry per record page,
// which follow the leaf pages, and is the writer's (ValidateRecordDirectory). Errors are Corruption, prefixed
// with `what` (the file).
Status ValidateStructure(const MKTree& tree, const ObjectTable& objects, uint64_t page_count,
                         const std::string& what);

// Checks the build statistics a store carries (TreeStats::ToJson): empty, or one JSON object whose keys
// are TreeStats' (each at most once) with number values, "levels" being an array of at most 256 such
// objects with LevelStats' keys. Anything else (another key, a nested object, a string, trailing bytes)
// is Corruption: `mktree info --json` prints the statistics as they are, so they must be valid JSON with
// only known keys.
Status ValidateStatsJson(std::string_view json);

// Field-by-field equality of the persisted tree (the structs have no operator==).
bool SameTree(const MKTree& a, const MKTree& b);

}  // namespace mktree
