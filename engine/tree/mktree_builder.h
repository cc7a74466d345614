// BuildMKTree: constructs the MKtree (docs/design.md §2) from per-object records only (id, AABB, encoded
// bytes; never geometry), in O(N log^2 N) time and about 60 bytes per object (BuildTuning: the key lists
// of the top levels in a spill file).
//
// Node layout: nodes in DFS preorder (root 0, left child n+1, right child after the left subtree), so a
// subtree is the contiguous index range [n, child-range end); leaves numbered in DFS order; a leaf's pages
// follow the previous leaf's (LeafInfo::first_page/page_count from PagesForLeaf in
// engine/tree/page_budget.h).
//
// Splitting (docs/design.md §3): SOA over the 6 sort keys, ranked per BuildTuning::split_policy (kSoa: page
// waste near the leaves, then |Sm|, slab, balance; kCompact: the wide axes only, margin before slab).
// Objects entirely inside the slab ("In") are given a side by the SplitTree builder
// (split_tree_builder.h); TreeNode::a/b are then recomputed from the final children (they can only narrow
// the slab), so that a = min over Sn2 of min_w and b = max over Sn1 of max_w always hold for the stored
// tree.
//
// Guard: past depth 100 the builder uses r = max(r, 0.25). With r near 0 the SOA may peel one object off
// per level (quadratic build time, heights beyond TreeNode::depth's 8 bits); the guard bounds the height
// by about 100 + log_{4/3} N and leaves normal trees untouched.
//
// Empty input yields a valid empty tree: no nodes, no leaves, leaf_offsets = {0}.
//
// The implementation, by concern (internal headers of engine/tree, namespace mktree::build): the checks
// (build_validation.h), the records' Morton layout and the six key sorts (build_layout.h), the build's
// allocator and scratch arrays (build_memory.h), the spill file of the top levels' lists (list_spill.h), the
// split choice (split_choice.h, with the SOA's rule in the paper's notation; split_compact.cc and
// split_key_sweeps.cc), node processing (subtree_builder.h), the multi-thread build (parallel_build.h), and
// the phases in order (mktree_builder.cc).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/tree/build_tuning.h"
#include "engine/tree/mktree.h"
#include "engine/tree/object_record.h"
#include "engine/tree/tree_stats.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// Wall seconds of the build's phases (what bench/tree_build_bench reports).
struct BuildTimings {
  double layout = 0;  // checks, Morton layout of the records
  double sorts = 0;   // the 6 key orders
  double nodes = 0;   // SOA splits, SplitTrees, list partitions (and the 2-thread stitch)
  double stitch = 0;  // of `nodes`: joining the 2-thread build's fragments into one tree
  double finish = 0;  // pages, leaf objects, statistics
  // The process's peak RSS (bytes, getrusage) at the end of each phase: what each phase adds to it.
  uint64_t peak_layout = 0, peak_sorts = 0, peak_nodes = 0, peak_finish = 0;
};

struct BuildResult {
  MKTree tree;
  // Objects of leaf i: leaf_objects[leaf_offsets[i] .. leaf_offsets[i+1]), in no particular order.
  std::vector<ObjectId> leaf_objects;
  std::vector<uint64_t> leaf_offsets;  // leaves + 1 entries
  TreeStats stats;
  BuildTimings timings;
};

// REQUIRES nothing of `records` beyond the checks below, which return InvalidArgument naming the object:
// finite boxes with min <= max, unique ids; params: 0 <= balance_r < 0.5, a page larger than its headers.
// params.split_tree_node_budget = 0 builds no SplitTrees (slab points then go to both sides).
Result<BuildResult> BuildMKTree(std::vector<BuildObject> records, const BuildParams& params,
                                const BuildTuning& tuning = BuildTuning());

}  // namespace mktree
