// TreeStats: the shape of a built MKtree, for `mktree info`, benchmarks and tuning. Plain data, computed
// once after building (or after loading a tree, without the overlap counts that only the builder knows).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "engine/tree/mktree.h"

namespace mktree {

struct LevelStats {
  uint32_t depth = 0;
  uint64_t nodes = 0;  // nodes at this depth (internal and leaves)
  uint64_t internal_nodes = 0;
  uint64_t overlap_nodes = 0;       // internal nodes with an overlap slab (a < b)
  uint64_t overlap_objects = 0;     // sum of |Sm| over the internal nodes of this depth
  double mean_overlap_objects = 0;  // overlap_objects / internal_nodes
  double mean_slab_rel_width = 0;   // mean over internal nodes of max(0, b - a) / extent of R(Sn) along w
  uint64_t split_tree_nodes = 0;    // SplitTree nodes (inner + cells) of this depth's internal nodes
  uint64_t split_tree_cells = 0;
  uint64_t both_cells = 0;
  double both_cell_share = 0;    // both_cells / split_tree_cells
  double both_volume_share = 0;  // volume of BOTH cells in Q / volume of Q, over nodes with volume
};

struct TreeStats {
  uint64_t objects = 0;
  uint32_t height = 0;  // levels: 1 for a single leaf, 0 for an empty tree
  uint64_t internal_nodes = 0;
  uint64_t leaves = 0;
  uint64_t pages = 0;
  uint64_t multi_page_leaves = 0;  // leaves of one oversized object spanning several pages
  uint32_t min_objects_per_leaf = 0;
  double mean_objects_per_leaf = 0;
  uint32_t max_objects_per_leaf = 0;
  uint64_t mem_page = 0;
  double mean_page_fill = 0;  // mean over single-page leaves of payload_bytes / MemPage
  double min_page_fill = 0;
  uint64_t split_tree_nodes = 0;
  uint32_t max_split_tree_nodes = 0;  // the largest SplitTree (bounded by split_tree_node_budget)
  uint64_t both_cells = 0;
  uint64_t split_tree_cells = 0;
  bool has_overlap_counts = false;  // |Sm| known (false when computed from a loaded tree)
  uint64_t overlap_objects = 0;     // sum of |Sm| over internal nodes
  // RAM of internal TreeNodes + SplitNodes per object: the in-RAM index proper.
  double index_bytes_per_object = 0;
  // MKTree::MemoryBytes() per object: all nodes (leaf nodes included), SplitTrees and LeafInfos.
  double tree_bytes_per_object = 0;
  std::vector<LevelStats> levels;

  std::string ToJson() const;    // one JSON object
  std::string ToString() const;  // human-readable, multi-line
};

// `overlap_counts[n]` = |Sm| of node n (0 for leaves), as the builder reports it; empty when unknown.
// threads >= 2: the SplitTrees are measured on two threads (the same statistics, bit for bit).
TreeStats ComputeTreeStats(const MKTree& tree, uint64_t object_count,
                           std::span<const uint32_t> overlap_counts, int threads = 1);

}  // namespace mktree
