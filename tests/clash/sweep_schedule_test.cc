// The sweep plan against its promises, by replaying it: every pair's leaves are decoded when it is tested,
// the window stays within its byte budget (or holds one pair's two leaves when they alone exceed it), and
// the read counts are the replay's.
#include "engine/clash/sweep_schedule.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <set>
#include <vector>

namespace mktree::clash {
namespace {

MKTree RandomLeaves(size_t n, std::mt19937_64& rng) {
  MKTree tree;
  tree.nodes.emplace_back();
  std::uniform_real_distribution<float> at(0, 100), size(0.5f, 8);
  for (size_t i = 0; i < n; ++i) {
    LeafInfo l;
    for (int k = 0; k < 3; ++k) {
      l.box.min[k] = at(rng);
      l.box.max[k] = l.box.min[k] + size(rng);
    }
    tree.leaves.push_back(l);
  }
  Box3f& root = tree.nodes[0].box;
  root = tree.leaves[0].box;
  for (const LeafInfo& l : tree.leaves)
    for (int k = 0; k < 3; ++k) {
      root.min[k] = std::min(root.min[k], l.box.min[k]);
      root.max[k] = std::max(root.max[k], l.box.max[k]);
    }
  return tree;
}

TEST(SweepSchedule, ReplayKeepsEveryPairsLeavesWithinTheBudget) {
  std::mt19937_64 rng(3);
  for (int round = 0; round < 40; ++round) {
    const size_t n = 2 + rng() % 60;
    const MKTree tree = RandomLeaves(n, rng);
    std::vector<uint64_t> bytes(n);
    for (uint64_t& b : bytes) b = 1 + rng() % 1000;
    std::set<std::pair<uint32_t, uint32_t>> want;
    const size_t m = rng() % (3 * n);
    for (size_t k = 0; k < m; ++k) {
      uint32_t p = rng() % n, q = rng() % n;
      if (p > q) std::swap(p, q);
      want.insert({p, q});
    }
    std::vector<LeafPair> pairs;
    for (const auto& [p, q] : want) pairs.push_back({p, q});
    std::shuffle(pairs.begin(), pairs.end(), rng);
    const uint64_t total = std::accumulate(bytes.begin(), bytes.end(), uint64_t{0});
    for (uint64_t budget : {uint64_t{1}, uint64_t{1500}, total / 4, total}) {
      SCOPED_TRACE("round " + std::to_string(round) + " budget " + std::to_string(budget));
      const SweepPlan plan = PlanSweep(tree, pairs, bytes, budget, 7);
      ASSERT_EQ(plan.pairs.size(), pairs.size());
      std::set<std::pair<uint32_t, uint32_t>> got;
      for (const LeafPair& p : plan.pairs) got.insert({p.p, p.q});
      EXPECT_EQ(got, want);
      std::vector<uint8_t> in(n, 0), seen(n, 0);
      uint64_t used = 0, reads = 0, rereads = 0, peak = 0;
      size_t next = 0;
      for (const SweepBatch& b : plan.batches) {
        ASSERT_EQ(b.pair_begin, next);
        ASSERT_GT(b.pair_end, b.pair_begin);
        ASSERT_LE(b.pair_end - b.pair_begin, 7u);
        next = b.pair_end;
        for (uint32_t l : b.evict) {
          ASSERT_TRUE(in[l]);
          in[l] = 0;
          used -= bytes[l];
        }
        for (uint32_t l : b.load) {
          ASSERT_FALSE(in[l]);
          in[l] = 1;
          used += bytes[l];
          ++reads;
          rereads += seen[l];
          seen[l] = 1;
        }
        std::set<uint32_t> need;
        for (size_t k = b.pair_begin; k < b.pair_end; ++k) {
          ASSERT_TRUE(in[plan.pairs[k].p] && in[plan.pairs[k].q]);
          need.insert(plan.pairs[k].p);
          need.insert(plan.pairs[k].q);
        }
        uint64_t need_bytes = 0;
        for (uint32_t l : need) need_bytes += bytes[l];
        if (need_bytes > budget) {
          EXPECT_EQ(b.pair_end - b.pair_begin, 1u);  // only one pair may exceed the budget
          EXPECT_EQ(used, need_bytes);               // and then the window holds nothing else
        } else {
          EXPECT_LE(used, budget);
        }
        peak = std::max(peak, used);
        for (uint32_t l : b.drop) {
          ASSERT_TRUE(in[l]);
          for (size_t k = b.pair_end; k < plan.pairs.size(); ++k)
            EXPECT_TRUE(plan.pairs[k].p != l && plan.pairs[k].q != l);
          in[l] = 0;
          used -= bytes[l];
        }
      }
      EXPECT_EQ(next, plan.pairs.size());
      EXPECT_EQ(reads, plan.leaf_reads);
      EXPECT_EQ(rereads, plan.leaf_rereads);
      EXPECT_EQ(peak, plan.peak_window_bytes);
      if (budget >= total) {
        EXPECT_EQ(rereads, 0u);
      }
    }
  }
}

}  // namespace
}  // namespace mktree::clash
