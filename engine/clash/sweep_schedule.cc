#include "engine/clash/sweep_schedule.h"

#include <algorithm>
#include <limits>

namespace mktree::clash {

namespace {

constexpr uint64_t kBatchWindowShare = 4;
constexpr uint32_t kNoRank = std::numeric_limits<uint32_t>::max();
constexpr uint64_t kNever = std::numeric_limits<uint64_t>::max();

int LongestAxis(const Box3f& root) {
  int axis = 0;
  for (int i = 1; i < 3; ++i) {
    if (double{root.max[i]} - root.min[i] > double{root.max[axis]} - root.min[axis]) axis = i;
  }
  return axis;
}

// The sweep rank of every leaf in some pair, by its box's low end on the axis (kNoRank for the others),
// and the leaf of each rank.
struct SweepRanks {
  std::vector<uint32_t> rank, order;
};

SweepRanks RankLeaves(const std::vector<Box3f>& leaf_boxes, const std::vector<LeafPair>& pairs, int ax) {
  SweepRanks s;
  s.rank.assign(leaf_boxes.size(), kNoRank);
  for (const LeafPair& p : pairs) {
    if (s.rank[p.p] == kNoRank) s.rank[p.p] = 0, s.order.push_back(p.p);
    if (s.rank[p.q] == kNoRank) s.rank[p.q] = 0, s.order.push_back(p.q);
  }
  std::sort(s.order.begin(), s.order.end(), [&](uint32_t x, uint32_t y) {
    const float bx = leaf_boxes[x].min[ax], by = leaf_boxes[y].min[ax];
    return bx != by ? bx < by : x < y;
  });
  for (size_t r = 0; r < s.order.size(); ++r) s.rank[s.order[r]] = static_cast<uint32_t>(r);
  return s;
}

// A pair is tested at the step of its later leaf, after the pairs of earlier steps.
void OrderPairs(const std::vector<uint32_t>& rank, std::vector<LeafPair>* pairs) {
  auto step = [&](const LeafPair& p) { return std::max(rank[p.p], rank[p.q]); };
  auto other = [&](const LeafPair& p) { return std::min(rank[p.p], rank[p.q]); };
  std::sort(pairs->begin(), pairs->end(), [&](const LeafPair& x, const LeafPair& y) {
    const uint32_t sx = step(x), sy = step(y);
    return sx != sy ? sx < sy : other(x) < other(y);
  });
}

// Each leaf's uses: the indices of the pairs that need it, in order (CSR by rank).
class LeafUses {
 public:
  LeafUses(const std::vector<uint32_t>& rank, size_t ranked, const std::vector<LeafPair>& pairs)
      : begin_(ranked + 1, 0) {
    for (const LeafPair& p : pairs) {
      ++begin_[rank[p.p] + 1];
      if (p.q != p.p) ++begin_[rank[p.q] + 1];
    }
    for (size_t r = 0; r < ranked; ++r) begin_[r + 1] += begin_[r];
    uses_.resize(begin_.back());
    std::vector<uint64_t> fill(begin_.begin(), begin_.end() - 1);
    for (size_t k = 0; k < pairs.size(); ++k) {
      uses_[fill[rank[pairs[k].p]]++] = k;
      if (pairs[k].q != pairs[k].p) uses_[fill[rank[pairs[k].q]]++] = k;
    }
    next_.assign(begin_.begin(), begin_.end() - 1);
  }
  // The pair index at which leaf (by rank) is next needed at or after pair k; kNever when never. Calls for
  // one leaf must not decrease k.
  uint64_t NextAfter(uint32_t r, size_t k) {
    uint64_t& at = next_[r];
    while (at < begin_[r + 1] && uses_[at] < k) ++at;
    return at < begin_[r + 1] ? uses_[at] : kNever;
  }

 private:
  std::vector<uint64_t> begin_, uses_, next_;
};

// The sweep's batches, planned one after the other against the window as it will be.
class SweepPlanner {
 public:
  SweepPlanner(const SweepRanks& ranks, const std::vector<LeafPair>& pairs,
               const std::vector<uint64_t>& leaf_bytes, uint64_t window_bytes, size_t batch_pairs)
      : rank_(ranks.rank),
        order_(ranks.order),
        pairs_(pairs),
        leaf_bytes_(leaf_bytes),
        window_bytes_(window_bytes),
        batch_bytes_(window_bytes / kBatchWindowShare),
        batch_pairs_(batch_pairs),
        uses_(ranks.rank, ranks.order.size(), pairs),
        in_window_(order_.size(), 0),
        ever_read_(order_.size(), 0),
        in_batch_(order_.size(), 0) {}

  void Plan(SweepPlan* plan) {
    for (size_t k = 0; k < pairs_.size();) {
      SweepBatch b;
      b.pair_begin = k;
      b.pair_end = Grow(k);
      Evict(b.pair_end, &b);
      Load(&b, plan);
      DropDone(b.pair_end, &b);
      for (uint32_t r : need_) in_batch_[r] = 0;
      k = b.pair_end;
      plan->batches.push_back(std::move(b));
    }
  }

 private:
  // Grows the batch from pair k pair by pair while the leaves it needs (need_) fit its share of the window
  // (always at least one pair, so that a window smaller than a sweep step still holds just two leaves).
  // Returns its end.
  size_t Grow(size_t k) {
    need_.clear();
    uint64_t need_bytes = 0;
    size_t end = k;
    while (end < pairs_.size() && end - k < batch_pairs_) {
      uint32_t added[2];
      int n_added = 0;
      uint64_t added_bytes = 0;
      for (uint32_t leaf : {pairs_[end].p, pairs_[end].q}) {
        const uint32_t r = rank_[leaf];
        if (in_batch_[r] || (n_added == 1 && added[0] == r)) continue;
        added[n_added++] = r;
        added_bytes += leaf_bytes_[leaf];
      }
      if (end > k && need_bytes + added_bytes > batch_bytes_) break;
      for (int i = 0; i < n_added; ++i) {
        in_batch_[added[i]] = 1;
        need_.push_back(added[i]);
      }
      need_bytes += added_bytes;
      ++end;
    }
    return end;
  }

  // Lists the batch's reads and evicts what must go to make room for them: the leaf needed again last
  // (never one this batch needs; when all are, the window goes over budget).
  void Evict(size_t end, SweepBatch* b) {
    uint64_t load_bytes = 0;
    for (uint32_t r : need_) {
      if (in_window_[r]) continue;
      b->load.push_back(order_[r]);
      load_bytes += leaf_bytes_[order_[r]];
    }
    while (window_used_ + load_bytes > window_bytes_) {
      size_t victim = window_.size();
      uint64_t farthest = 0;
      for (size_t i = 0; i < window_.size(); ++i) {
        if (in_batch_[window_[i]]) continue;
        const uint64_t nu = uses_.NextAfter(window_[i], end);
        if (victim == window_.size() || nu > farthest) victim = i, farthest = nu;
      }
      if (victim == window_.size()) break;
      b->evict.push_back(order_[window_[victim]]);
      Remove(victim);
    }
  }

  // Reads the batch's leaves into the window, in sweep order.
  void Load(SweepBatch* b, SweepPlan* plan) {
    std::sort(b->load.begin(), b->load.end(), [&](uint32_t x, uint32_t y) { return rank_[x] < rank_[y]; });
    for (uint32_t leaf : b->load) {
      const uint32_t r = rank_[leaf];
      ++plan->leaf_reads;
      plan->leaf_rereads += ever_read_[r];
      ever_read_[r] = 1;
      in_window_[r] = 1;
      window_.push_back(r);
      window_used_ += leaf_bytes_[leaf];
    }
    plan->peak_window_bytes = std::max(plan->peak_window_bytes, window_used_);
  }

  // Leaves with no partner left after the batch leave the window at once.
  void DropDone(size_t end, SweepBatch* b) {
    for (size_t i = 0; i < window_.size();) {
      if (uses_.NextAfter(window_[i], end) == kNever) {
        b->drop.push_back(order_[window_[i]]);
        Remove(i);
      } else {
        ++i;
      }
    }
    std::sort(b->drop.begin(), b->drop.end());
  }

  // Takes window_[i] out of the window (the last one takes its place).
  void Remove(size_t i) {
    const uint32_t r = window_[i];
    in_window_[r] = 0;
    window_used_ -= leaf_bytes_[order_[r]];
    window_[i] = window_.back();
    window_.pop_back();
  }

  const std::vector<uint32_t>& rank_;
  const std::vector<uint32_t>& order_;
  const std::vector<LeafPair>& pairs_;
  const std::vector<uint64_t>& leaf_bytes_;
  const uint64_t window_bytes_;
  // A batch's leaves take at most this share of the window: the leaves behind the sweep front can leave
  // between batches, so that the window holds about the front, not a whole batch's span of the scene.
  const uint64_t batch_bytes_;
  const size_t batch_pairs_;
  LeafUses uses_;
  std::vector<uint8_t> in_window_, ever_read_, in_batch_;  // by rank
  std::vector<uint32_t> window_;                           // ranks
  uint64_t window_used_ = 0;
  std::vector<uint32_t> need_;  // the batch's leaves (ranks), in the order its pairs need them
};

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
  plan.axis = LongestAxis(root);
  const SweepRanks ranks = RankLeaves(leaf_boxes, pairs, plan.axis);
  OrderPairs(ranks.rank, &pairs);
  SweepPlanner(ranks, pairs, leaf_bytes, window_bytes, batch_pairs).Plan(&plan);
  plan.pairs = std::move(pairs);
  return plan;
}

}  // namespace mktree::clash
