// The MKtree as it lives in RAM after building: flat arrays of plain structs, so that the store can
// write them as-is (HDF5 compound datasets, paged-file sections) and read them back without rebuilding.
// Leaves are only referenced here; their objects live in the leaf pages of the store.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "mktree/geometry.h"
#include "mktree/query_stats.h"

namespace mktree {

inline constexpr uint32_t kNoIndex = 0xffffffffu;

// Build parameters, persisted with the store.
struct BuildParams {
  uint32_t block_size = 4096;            // bytes per disk block
  uint32_t blocks_per_page = 3;          // d: MemPage = d * block_size
  double balance_r = 0.3;                // SOA balance ratio, 0 <= r < 0.5
  uint32_t split_tree_node_budget = 64;  // max SplitTree nodes per internal node
  uint64_t mem_page() const { return uint64_t{block_size} * blocks_per_page; }
};

// One MKtree node. Internal: axis in {0,1,2}, both children set, `leaf` = kNoIndex.
// Leaf: axis = 3, children kNoIndex, `leaf` indexes MKTree::leaves.
struct TreeNode {
  Box3f box;    // R(Sn): union of the boxes of the node's objects
  float a = 0;  // plane pi0: min over Sn2 of min_w
  float b = 0;  // plane pi1: max over Sn1 of max_w; a >= b means no overlap slab
  uint32_t child[2] = {kNoIndex, kNoIndex};
  uint32_t leaf = kNoIndex;
  uint32_t split_root = kNoIndex;  // root of this node's SplitTree in MKTree::split_nodes, or kNoIndex
  uint8_t axis = 3;
  uint8_t depth = 0;
  bool is_leaf() const { return axis == 3; }
};

// How RouteBox walks the tree. kAuto picks by the tree's size: depth first, no prefetching, for trees the
// CPU caches hold; breadth first with prefetching for bigger ones. The answer and the statistics are the
// same either way; the other two force one walk (tests, benchmarks).
enum class RouteWalk : uint8_t { kAuto, kDepthFirst, kBreadthFirst };

enum class CellLabel : uint8_t { kEmpty = 0, kLeft = 1, kRight = 2, kBoth = 3 };

// One SplitTree node. Inner: axis in {0,1,2}, cut plane at `cut`, child[0] below, child[1] above.
// Cell (leaf of the SplitTree): axis = 3, `label` says which children may hold objects there.
struct SplitNode {
  float cut = 0;
  uint32_t child[2] = {kNoIndex, kNoIndex};
  uint8_t axis = 3;
  CellLabel label = CellLabel::kEmpty;
  bool is_cell() const { return axis == 3; }
};

// A leaf: its objects are in pages [first_page, first_page + page_count) of the store.
struct LeafInfo {
  Box3f box;
  uint32_t node = kNoIndex;  // its TreeNode
  uint32_t object_count = 0;
  uint64_t payload_bytes = 0;  // encoded leaf bytes (LeafPayloadBytes of its objects)
  uint64_t first_page = 0;
  uint32_t page_count = 1;
};

struct MKTree {
  BuildParams params;
  // The store frame: every box here (nodes, leaves, leaf filter, entries) is in coordinates world - origin
  // (engine/store_format/object_codec.h). Queries are moved into it before routing.
  Vec3d origin;
  std::vector<TreeNode> nodes;  // nodes[0] is the root (when not empty)
  std::vector<SplitNode> split_nodes;
  std::vector<LeafInfo> leaves;  // in page order
  // The leaf filter (engine/tree/leaf_filter.h): kLeafFilterBytesPerObject bytes per object, leaf by
  // leaf in leaf order, each leaf's objects in page order. Empty: no filter (every routed leaf is read).
  std::vector<uint8_t> leaf_filter;
  // Derived, not persisted: where leaf i's entries start in leaf_filter (leaves + 1 entries). Set by
  // IndexLeafFilter() after leaf_filter is filled or loaded.
  std::vector<uint64_t> leaf_filter_begin;

  bool empty() const { return nodes.empty(); }
  // The scene's bounds in world coordinates: the root's box plus the origin; empty for an empty tree.
  Box3d WorldBounds() const;
  // Leaves a point query must read, in leaf order, each once; counts internal/SplitTree nodes in stats.
  void RoutePoint(const Vec3d& p, std::vector<uint32_t>* leaves_out, QueryStats* stats) const;
  // Leaves a box query must read, in leaf order, each once.
  void RouteBox(const Box3d& box, std::vector<uint32_t>* leaves_out, QueryStats* stats,
                RouteWalk walk = RouteWalk::kAuto) const;
  // Bytes of RAM held by nodes, split nodes and leaf infos (the leaf filter is FilterMemoryBytes()).
  uint64_t MemoryBytes() const;
  uint64_t FilterMemoryBytes() const { return leaf_filter.capacity() + 8 * leaf_filter_begin.capacity(); }
  // Computes leaf_filter_begin from the leaves' object counts; false if leaf_filter's size disagrees.
  bool IndexLeafFilter();
};

}  // namespace mktree
