// LeafClaims (engine/store_format/leaf_claims.h): the first leaf to claim an id keeps it, a later leaf
// holding it is refused then and on every later claim, a leaf claims once, and copies and assignments of an
// object table start with no claims.
#include "engine/store_format/leaf_claims.h"

#include <gtest/gtest.h>

#include <atomic>
#include <thread>
#include <vector>

#include "engine/store_format/tree_codec.h"

namespace mktree {
namespace {

TEST(LeafClaimsTest, AnIdClaimedByOneLeafRefusesAnotherLeafEveryTime) {
  LeafClaims c;
  const std::vector<uint32_t> a = {0, 5, 64, 99}, b = {1, 2, 64}, d = {3, 4};
  EXPECT_FALSE(c.Claimed(0));
  EXPECT_EQ(c.Claim(0, 3, 100, a), LeafClaims::kNone);
  EXPECT_TRUE(c.Claimed(0));
  EXPECT_EQ(c.Claim(0, 3, 100, a), LeafClaims::kNone);  // the same leaf again
  EXPECT_EQ(c.Claim(1, 3, 100, b), 64u);
  EXPECT_FALSE(c.Claimed(1));
  EXPECT_EQ(c.Claim(1, 3, 100, b), 64u);  // refused again
  // A refused leaf claimed none of its ids.
  EXPECT_EQ(c.Claim(2, 3, 100, std::vector<uint32_t>{1, 2}), LeafClaims::kNone);
  EXPECT_EQ(c.Claim(2, 3, 100, d), LeafClaims::kNone);  // claimed already (with 1 and 2): not checked again
}

TEST(LeafClaimsTest, CopiesAndAssignmentsOfATableStartWithoutClaims) {
  ObjectTable t;
  t.count = 10;
  t.leaf_digest.assign(2, 0);
  EXPECT_EQ(t.claims.Claim(0, 2, 10, std::vector<uint32_t>{7}), LeafClaims::kNone);
  ObjectTable copy = t;
  EXPECT_TRUE(copy == t);
  EXPECT_FALSE(copy.claims.Claimed(0));
  EXPECT_EQ(copy.claims.Claim(1, 2, 10, std::vector<uint32_t>{7}), LeafClaims::kNone);
  t = ObjectTable();
  EXPECT_FALSE(t.claims.Claimed(0));
  EXPECT_EQ(t.claims.Claim(1, 2, 10, std::vector<uint32_t>{7}), LeafClaims::kNone);
  // Other sizes start again.
  EXPECT_EQ(t.claims.Claim(0, 3, 20, std::vector<uint32_t>{7, 19}), LeafClaims::kNone);
}

// Threads claiming leaves that share one id: exactly one of them keeps it.
TEST(LeafClaimsTest, ConcurrentClaimsOfOneIdLeaveExactlyOneOwner) {
  constexpr uint32_t kLeaves = 64;
  LeafClaims c;
  std::atomic<int> kept{0}, refused{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&, t] {
      for (uint32_t l = t; l < kLeaves; l += 4) {
        const std::vector<uint32_t> ids = {1000 + l, 5000};
        (c.Claim(l, kLeaves, 6000, ids) == LeafClaims::kNone ? kept : refused)++;
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(kept.load(), 1);
  EXPECT_EQ(refused.load(), static_cast<int>(kLeaves) - 1);
}

}  // namespace
}  // namespace mktree
