// The clash's broad phase (docs/clash.md §3, steps 1 to 3): which leaves can hold a pair, found from the
// in-RAM trees before any leaf page is read. The self-clash's: the leaf pairs of each part's dual
// traversal and of the traversals between parts, refined by the leaf filter, then the sweep plan that
// orders them for the window. Collide's: the leaves the query box reaches, refined by the leaf filter.
// Thread safety: the functions use `pool`'s threads and return when done; call them from one thread.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/clash/clash_focus.h"
#include "engine/clash/leaf_pairs.h"
#include "engine/clash/part_numbering.h"
#include "engine/clash/sweep_schedule.h"
#include "engine/clash/work_pool.h"
#include "mktree/clash.h"

namespace mktree::clash {

// The leaf pairs a self-clash tests, in the parts' numbering, and the objects that need a shape.
struct ClashLeafPairs {
  std::vector<LeafPair> pairs;  // each part's own in traversal order, then part i's with part j's (i < j)
  std::vector<NeededObjects> needed;  // per part
};

// The leaf pairs through each tree and between the trees of parts whose roots grown by c meet, those of
// the part pairs `want` accepts (null: all), kept where the leaf filter admits a pair; with `focus`
// (null: none) only those with a leaf that may hold a focused object, kept where the leaf filter admits a
// pair with one. Sets s->leaf_pairs_tree (before the filter) and s->leaf_pairs_visited (after).
ClashLeafPairs FindLeafPairs(const PartNumbering& parts, const ClashPartPairs& want, const ClashFocus* focus,
                             double c, WorkPool& pool, ClashStats* s);

// The sweep plan of `pairs` for a window of `window_bytes`, each leaf counted as DecodedLeafEstimate.
SweepPlan PlanClashSweep(const PartNumbering& parts, std::vector<LeafPair> pairs, uint64_t window_bytes);

// The leaves of `tree` whose boxes meet `grown` (in leaf order), then those whose leaf filter admits an
// object box meeting it. Sets s->leaf_pairs_tree (before the filter), s->leaf_pairs_visited and
// s->leaf_reads (after).
std::vector<uint32_t> CollideLeaves(const MKTree& tree, const Box3d& grown, ClashStats* s);

}  // namespace mktree::clash
