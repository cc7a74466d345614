// BuildMKTree: constructs the MKtree (DESIGN.md §2) from per-object records only (id, AABB, encoded
// bytes; never geometry), in RAM, in O(N log^2 N) time and well under 100 bytes per object.
//
// Node layout: nodes in DFS preorder (root 0, left child n+1, right child after the left subtree), so a
// subtree is the contiguous index range [n, child-range end); leaves numbered in DFS order; a leaf's pages
// follow the previous leaf's (LeafInfo::first_page/page_count from PagesForLeaf in storage/leaf_format.h).
//
// Splitting: the SOA of §2.1 over all 6 sort keys; ties on |Sm| broken by page waste near the leaves (see
// BuildTuning), then by the thinner slab, then by balance. Objects entirely inside the slab ("In") are
// given a side by the SplitTree builder (split_tree_builder.h); TreeNode::a/b are then recomputed from
// the final children (they can only narrow the slab), so that a = min over Sn2 of min_w and
// b = max over Sn1 of max_w always hold for the stored tree.
//
// Guard: past depth 100 the builder uses r = max(r, 0.25). With r near 0 the SOA may peel one object off
// per level (quadratic build time, heights beyond TreeNode::depth's 8 bits); the guard bounds the height
// by about 100 + log_{4/3} N and leaves normal trees untouched.
//
// Empty input yields a valid empty tree: no nodes, no leaves, leaf_offsets = {0}.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/tree/mktree.h"
#include "engine/tree/tree_stats.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

struct BuildResult {
  MKTree tree;
  // Objects of leaf i: leaf_objects[leaf_offsets[i] .. leaf_offsets[i+1]), in no particular order.
  std::vector<ObjectId> leaf_objects;
  std::vector<uint64_t> leaf_offsets;  // leaves + 1 entries
  TreeStats stats;
};

// Knobs that change the tree's quality but not its contract; defaults are what the benchmarks measured best.
struct BuildTuning {
  // Near the leaves (a node of at most `fill_aware_pages` pages of data), rank the SOA candidates whose
  // |Sm| is within `fill_sm_slack` + `fill_sm_slack_rel` x minimum first by page waste
  // (ceil(D1/C) + ceil(D2/C) - ceil(D/C)), then by |Sm|, slab and balance, and keep the page counts when
  // free objects change side. Off: plain SOA (|Sm|, slab, balance). Measured on the 200k tanker: plain SOA
  // fills pages to 62 %; slack 1 to 65 %; the default (waste first near the leaves) to 82 %, for 13 % more
  // leaves visited per random point (2.50 vs 2.22 extra leaves) and 24 % fewer leaves.
  bool fill_aware = true;
  uint32_t fill_aware_pages = 4;
  uint32_t fill_sm_slack = 1u << 30;
  double fill_sm_slack_rel = 0;
  // A SplitTree cut is made only when it saves at least this share of the routing cost of a point spread
  // over the overlap region Q (see split_tree_builder.h): it keeps SplitTrees to the cuts that matter.
  double split_min_gain = 0.01;
  // Threads used (1 or 2): with 2, the two subtrees of the root are built concurrently. Default 1: on the
  // shared 2-core bench machine 2 threads took 1.68 s vs 2.33 s at 1M in one run and 2.20 vs 2.17 s in
  // another, while merging the subtrees' outputs raised the peak from 114 to 159 bytes/object.
  int threads = 1;
};

// REQUIRES nothing of `records` beyond the checks below, which return InvalidArgument naming the object:
// finite boxes with min <= max, unique ids; params: 0 <= balance_r < 0.5, a page larger than its headers.
// params.split_tree_node_budget = 0 builds no SplitTrees (slab points then go to both sides).
Result<BuildResult> BuildMKTree(std::vector<ObjectRecord> records, const BuildParams& params,
                                const BuildTuning& tuning = BuildTuning());

}  // namespace mktree
