// Canonical byte encodings of a store's in-RAM structure (tree arrays, build parameters, codec, object
// table). The paged file stores these bytes as sections; both backends checksum them (XXH3-64), so a
// flipped byte in the metadata is detected at open. All little-endian and packed (see
// docs/store_format.md for the record layouts).
// Thread safety: pure functions; ObjectTable is a plain value.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "engine/store/object_codec.h"
#include "engine/tree/mktree.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// The object table: for object id i (0-based, dense), its leaf and its name.
struct ObjectTable {
  std::vector<uint32_t> leaf;      // leaf index per object
  std::vector<uint64_t> name_end;  // names of object i are names[name_end[i-1], name_end[i])
  std::string names;               // all names concatenated

  uint64_t size() const { return leaf.size(); }
  void Append(uint32_t leaf_index, std::string_view name) {
    leaf.push_back(leaf_index);
    names.append(name);
    name_end.push_back(names.size());
  }
  std::string_view name(uint64_t i) const {
    const uint64_t b = i == 0 ? 0 : name_end[i - 1];
    return std::string_view(names).substr(b, name_end[i] - b);
  }
  bool operator==(const ObjectTable&) const = default;
};

inline constexpr size_t kNodeRecordBytes = 52;
inline constexpr size_t kSplitNodeRecordBytes = 16;
inline constexpr size_t kLeafRecordBytes = 56;
inline constexpr size_t kParamsRecordBytes = 28;

std::vector<uint8_t> EncodeParams(const BuildParams& p, const CodecOptions& c);
Status DecodeParams(std::span<const uint8_t> in, BuildParams* p, CodecOptions* c);
std::vector<uint8_t> EncodeNodes(const std::vector<TreeNode>& nodes);
Status DecodeNodes(std::span<const uint8_t> in, std::vector<TreeNode>* nodes);
std::vector<uint8_t> EncodeSplitNodes(const std::vector<SplitNode>& nodes);
Status DecodeSplitNodes(std::span<const uint8_t> in, std::vector<SplitNode>* nodes);
std::vector<uint8_t> EncodeLeaves(const std::vector<LeafInfo>& leaves);
Status DecodeLeaves(std::span<const uint8_t> in, std::vector<LeafInfo>* leaves);
std::vector<uint8_t> EncodeObjectLeaves(const ObjectTable& t);
std::vector<uint8_t> EncodeObjectNameEnds(const ObjectTable& t);
// Rebuilds a table from its three sections; checks their sizes agree.
Status DecodeObjectTable(std::span<const uint8_t> leaves, std::span<const uint8_t> name_ends,
                         std::span<const uint8_t> names, ObjectTable* t);

uint64_t Checksum(std::span<const uint8_t> bytes);
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
// at most kMaxSplitTreeLevels levels; every object is in an existing leaf and each leaf's object_count is
// the number of objects the table puts in it; the leaf filter is empty or 8 bytes per object.
// Errors are Corruption, prefixed with `what` (the file).
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
