// The order of the self-clash's work, planned before any page is read: a sweep of the leaves along the
// scene's longest axis, each leaf read when it is first needed and kept in a window of decoded leaves
// (budgeted in bytes) while it still has partners to come. When the window is full, the leaf needed again
// last is evicted (Belady's rule: the future is known) and read again when it is needed; the plan counts
// those reads.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/clash/leaf_pairs.h"
#include "engine/tree/mktree.h"

namespace mktree::clash {

// A batch: the leaves it reads and the pairs it tests, with the window kept within budget around them.
struct SweepBatch {
  std::vector<uint32_t> evict;  // leaves to drop before the reads (still needed later: read again then)
  std::vector<uint32_t> load;   // leaves to read and decode, in increasing sweep rank
  size_t pair_begin = 0, pair_end = 0;  // into SweepPlan::pairs
  std::vector<uint32_t> drop;           // leaves with no partner left after this batch
};

struct SweepPlan {
  int axis = 0;
  std::vector<LeafPair> pairs;  // the work in its order: by the later leaf's sweep rank, then the other's
  std::vector<SweepBatch> batches;
  uint64_t leaf_reads = 0, leaf_rereads = 0;
  uint64_t peak_window_bytes = 0;  // by the leaves' estimates
};

// Plans the sweep of `pairs` with a window of `window_bytes` bytes of decoded leaves, leaf i counted as
// leaf_bytes[i] (a batch always holds the leaves its own pairs need, even beyond the budget), and batches
// of at most `batch_pairs` pairs whose leaves take at most a quarter of the window (or one pair).
SweepPlan PlanSweep(const MKTree& tree, std::vector<LeafPair> pairs, const std::vector<uint64_t>& leaf_bytes,
                    uint64_t window_bytes, size_t batch_pairs);
// The same over leaves numbered by the caller (several stores' leaves in one frame): the sweep runs along
// the longest axis of `root`, leaf i's box is leaf_boxes[i].
SweepPlan PlanSweep(const Box3f& root, const std::vector<Box3f>& leaf_boxes, std::vector<LeafPair> pairs,
                    const std::vector<uint64_t>& leaf_bytes, uint64_t window_bytes, size_t batch_pairs);

}  // namespace mktree::clash
