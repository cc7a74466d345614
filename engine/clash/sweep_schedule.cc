#include "engine/clash/sweep_schedule.h"

#include <algorithm>
#include <limits>

namespace mktree::clash {

namespace {
constexpr uint64_t kBatchWindowShare = 4;
}  // namespace

SweepPlan PlanSweep(const MKTree& tree, std::vector<LeafPair> pairs, const std::vector<uint64_t>& leaf_bytes,
                    uint64_t window_bytes, size_t batch_pairs) {
  if (pairs.empty()) return SweepPlan();
  std::vector<Box3f> boxes(tree.leaves.size());
  for (size_t i = 0; i < boxes.size(); ++i) boxes[i] = tree.leaves[i].box;
  return PlanSweep(tree.nodes[0].box, boxes, std::move(pairs), leaf_bytes, window_bytes, batch_pairs);
}

SweepPlan PlanSweep(const Box3f& root, const std::vector<Box3f>& leaf_boxes, std::vector<LeafPair> pairs,
                    const std::vector<uint64_t>& leaf_bytes, uint64_t window_bytes, size_t batch_pairs) {
  SweepPlan plan;
  if (pairs.empty()) return plan;
  for (int i = 1; i < 3; ++i) {
    if (double{root.max[i]} - root.min[i] > double{root.max[plan.axis]} - root.min[plan.axis]) plan.axis = i;
  }
  const size_t n = leaf_boxes.size();
  constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
  // Sweep rank of every leaf in some pair, by its box's low end on the axis.
  std::vector<uint32_t> rank(n, kNone), order;
  for (const LeafPair& p : pairs) {
    if (rank[p.p] == kNone) rank[p.p] = 0, order.push_back(p.p);
    if (rank[p.q] == kNone) rank[p.q] = 0, order.push_back(p.q);
  }
  const int ax = plan.axis;
  std::sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) {
    const float bx = leaf_boxes[x].min[ax], by = leaf_boxes[y].min[ax];
    return bx != by ? bx < by : x < y;
  });
  for (size_t r = 0; r < order.size(); ++r) rank[order[r]] = static_cast<uint32_t>(r);
  // A pair is tested at the step of its later leaf, after the pairs of earlier steps.
  auto step = [&](const LeafPair& p) { return std::max(rank[p.p], rank[p.q]); };
  auto other = [&](const LeafPair& p) { return std::min(rank[p.p], rank[p.q]); };
  std::sort(pairs.begin(), pairs.end(), [&](const LeafPair& x, const LeafPair& y) {
    const uint32_t sx = step(x), sy = step(y);
    return sx != sy ? sx < sy : other(x) < other(y);
  });
  // Each leaf's uses: the indices of the pairs that need it, in order (CSR by rank).
  std::vector<uint64_t> use_begin(order.size() + 1, 0);
  for (const LeafPair& p : pairs) {
    ++use_begin[rank[p.p] + 1];
    if (p.q != p.p) ++use_begin[rank[p.q] + 1];
  }
  for (size_t r = 0; r < order.size(); ++r) use_begin[r + 1] += use_begin[r];
  std::vector<uint64_t> uses(use_begin.back()), fill(use_begin.begin(), use_begin.end() - 1);
  for (size_t k = 0; k < pairs.size(); ++k) {
    uses[fill[rank[pairs[k].p]]++] = k;
    if (pairs[k].q != pairs[k].p) uses[fill[rank[pairs[k].q]]++] = k;
  }
  std::vector<uint64_t> next_use = std::vector<uint64_t>(use_begin.begin(), use_begin.end() - 1);
  // The pair index at which leaf (by rank) is next needed at or after pair k; infinity when never.
  auto next_after = [&](uint32_t r, size_t k) -> uint64_t {
    uint64_t& at = next_use[r];
    while (at < use_begin[r + 1] && uses[at] < k) ++at;
    return at < use_begin[r + 1] ? uses[at] : std::numeric_limits<uint64_t>::max();
  };
  auto bytes = [&](uint32_t leaf) -> uint64_t { return leaf_bytes[leaf]; };

  std::vector<uint8_t> in_window(order.size(), 0), ever_read(order.size(), 0), in_batch(order.size(), 0);
  std::vector<uint32_t> window;  // ranks
  uint64_t window_used = 0;
  // A batch's leaves take at most this share of the window: the leaves behind the sweep front can leave
  // between batches, so that the window holds about the front, not a whole batch's span of the scene.
  const uint64_t batch_bytes = window_bytes / kBatchWindowShare;
  size_t k = 0;
  while (k < pairs.size()) {
    // Grow the batch pair by pair while the leaves it needs fit its share (always at least one pair, so
    // that a window smaller than a sweep step still holds just two leaves).
    SweepBatch b;
    b.pair_begin = k;
    std::vector<uint32_t> need;  // ranks
    uint64_t need_bytes = 0;
    size_t end = k;
    while (end < pairs.size() && end - k < batch_pairs) {
      uint32_t added[2];
      int n_added = 0;
      uint64_t added_bytes = 0;
      for (uint32_t leaf : {pairs[end].p, pairs[end].q}) {
        const uint32_t r = rank[leaf];
        if (in_batch[r] || (n_added == 1 && added[0] == r)) continue;
        added[n_added++] = r;
        added_bytes += bytes(leaf);
      }
      if (end > k && need_bytes + added_bytes > batch_bytes) break;
      for (int i = 0; i < n_added; ++i) {
        in_batch[added[i]] = 1;
        need.push_back(added[i]);
      }
      need_bytes += added_bytes;
      ++end;
    }
    b.pair_end = end;
    // Reads, after evicting what must go to make room (never a leaf this batch needs).
    uint64_t load_bytes = 0;
    for (uint32_t r : need) {
      if (in_window[r]) continue;
      b.load.push_back(order[r]);
      load_bytes += bytes(order[r]);
    }
    while (window_used + load_bytes > window_bytes) {
      size_t victim = window.size();
      uint64_t farthest = 0;
      for (size_t i = 0; i < window.size(); ++i) {
        if (in_batch[window[i]]) continue;
        const uint64_t nu = next_after(window[i], end);
        if (victim == window.size() || nu > farthest) victim = i, farthest = nu;
      }
      if (victim == window.size()) break;  // everything held is needed now: the window goes over budget
      const uint32_t r = window[victim];
      b.evict.push_back(order[r]);
      in_window[r] = 0;
      window_used -= bytes(order[r]);
      window[victim] = window.back();
      window.pop_back();
    }
    std::sort(b.load.begin(), b.load.end(), [&](uint32_t x, uint32_t y) { return rank[x] < rank[y]; });
    for (uint32_t leaf : b.load) {
      const uint32_t r = rank[leaf];
      ++plan.leaf_reads;
      plan.leaf_rereads += ever_read[r];
      ever_read[r] = 1;
      in_window[r] = 1;
      window.push_back(r);
      window_used += bytes(leaf);
    }
    plan.peak_window_bytes = std::max(plan.peak_window_bytes, window_used);
    // Leaves with no partner left leave the window at once.
    for (size_t i = 0; i < window.size();) {
      const uint32_t r = window[i];
      if (next_after(r, end) == std::numeric_limits<uint64_t>::max()) {
        b.drop.push_back(order[r]);
        in_window[r] = 0;
        window_used -= bytes(order[r]);
        window[i] = window.back();
        window.pop_back();
      } else {
        ++i;
      }
    }
    std::sort(b.drop.begin(), b.drop.end());
    for (uint32_t r : need) in_batch[r] = 0;
    plan.batches.push_back(std::move(b));
    k = end;
  }
  plan.pairs = std::move(pairs);
  return plan;
}

}  // namespace mktree::clash
