// ForEachSplitCell on hand-built SplitTrees: which cells a point, a closed box and a region meet, in which
// order, with which regions, how many nodes are entered, and where the walk stops.
#include "engine/tree/split_tree_walk.h"

#include <gtest/gtest.h>

#include <array>
#include <utility>
#include <vector>

namespace mktree {
namespace {

SplitNode Inner(int axis, float cut, uint32_t lower, uint32_t upper) {
  SplitNode n;
  n.axis = static_cast<uint8_t>(axis);
  n.cut = cut;
  n.child[0] = lower;
  n.child[1] = upper;
  return n;
}

SplitNode Cell(CellLabel label) {
  SplitNode n;
  n.label = label;
  return n;
}

// x < 5: cell 1 (LEFT); x >= 5: cut at y = 2 into cell 3 (RIGHT) below and cell 4 (BOTH) above.
const std::vector<SplitNode> kTree = {Inner(0, 5, 1, 2), Cell(CellLabel::kLeft), Inner(1, 2, 3, 4),
                                      Cell(CellLabel::kRight), Cell(CellLabel::kBoth)};

Box3d BoxOf(double x0, double y0, double x1, double y1) {
  Box3d b;
  b.min = {x0, y0, 0};
  b.max = {x1, y1, 1};
  return b;
}

// The cells (as indices into kTree) a query meets, in the walk's order.
template <typename Query>
std::vector<uint32_t> Cells(const Query& q, uint64_t* entered, bool* complete = nullptr) {
  std::vector<uint32_t> cells;
  const bool all = ForEachSplitCell(
      kTree, 0, q,
      [&](const SplitNode& cell) {
        cells.push_back(static_cast<uint32_t>(&cell - kTree.data()));
        return true;
      },
      entered);
  if (complete) *complete = all;
  return cells;
}

TEST(SplitTreeWalkTest, APointMeetsOneCellAndGoesUpOnACut) {
  uint64_t entered = 0;
  EXPECT_EQ(Cells(Vec3d{1, 9, 0}, &entered), std::vector<uint32_t>{1});
  EXPECT_EQ(entered, 2u);
  entered = 0;
  EXPECT_EQ(Cells(Vec3d{5, 0, 0}, &entered), std::vector<uint32_t>{3});  // on x = 5: the upper side
  EXPECT_EQ(entered, 3u);
  EXPECT_EQ(Cells(Vec3d{7, 2, 0}, &entered), std::vector<uint32_t>{4});  // on y = 2: the upper side
  EXPECT_EQ(Cells(Vec3d{4.999, 2, 0}, &entered), std::vector<uint32_t>{1});
}

TEST(SplitTreeWalkTest, AClosedBoxMeetsBothSidesOfACutItTouches) {
  uint64_t entered = 0;
  EXPECT_EQ(Cells(BoxOf(0, 0, 4, 9), &entered), std::vector<uint32_t>{1});
  EXPECT_EQ(entered, 2u);
  entered = 0;
  EXPECT_EQ(Cells(BoxOf(4, 0, 6, 1), &entered), (std::vector<uint32_t>{1, 3}));  // lower side first
  EXPECT_EQ(entered, 4u);
  EXPECT_EQ(Cells(BoxOf(5, 2, 6, 3), &entered), (std::vector<uint32_t>{1, 3, 4}));  // touches both cuts
  EXPECT_EQ(Cells(BoxOf(6, 2.5, 7, 3), &entered), std::vector<uint32_t>{4});
}

TEST(SplitTreeWalkTest, TheVisitorEndsTheWalk) {
  uint64_t entered = 0;
  std::vector<uint32_t> seen;
  const bool all = ForEachSplitCell(
      kTree, 0, BoxOf(0, 0, 9, 9),
      [&](const SplitNode& cell) {
        seen.push_back(static_cast<uint32_t>(&cell - kTree.data()));
        return false;
      },
      &entered);
  EXPECT_FALSE(all);
  EXPECT_EQ(seen, std::vector<uint32_t>{1});
  EXPECT_EQ(entered, 2u);
}

TEST(SplitTreeWalkTest, ARegionVisitsEveryCellWithItsPart) {
  Box3f slab;
  slab.min = {0, 0, 0};
  slab.max = {10, 4, 1};
  std::vector<std::pair<uint32_t, Box3f>> seen;
  uint64_t entered = 0;
  EXPECT_TRUE(ForEachSplitCell(
      kTree, 0, SplitRegion{slab},
      [&](const SplitNode& cell, const Box3f& region) {
        seen.push_back({static_cast<uint32_t>(&cell - kTree.data()), region});
        return true;
      },
      &entered));
  EXPECT_EQ(entered, 5u);
  ASSERT_EQ(seen.size(), 3u);
  const std::array<float, 3> lows[3] = {{0, 0, 0}, {5, 0, 0}, {5, 2, 0}};
  const std::array<float, 3> highs[3] = {{5, 4, 1}, {10, 2, 1}, {10, 4, 1}};
  const uint32_t cells[3] = {1, 3, 4};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(seen[i].first, cells[i]);
    EXPECT_EQ(seen[i].second.min, lows[i]) << i;
    EXPECT_EQ(seen[i].second.max, highs[i]) << i;
  }
  // A region that misses a cut's side still visits the cell there, with an empty part.
  slab.max[0] = 3;
  seen.clear();
  ForEachSplitCell(kTree, 0, SplitRegion{slab}, [&](const SplitNode& cell, const Box3f& region) {
    seen.push_back({static_cast<uint32_t>(&cell - kTree.data()), region});
    return true;
  });
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_GT(seen[1].second.min[0], seen[1].second.max[0]);
}

// A chain whose lower children go on down while each upper child waits on the stack: a box or region
// walk holds one pending node per level, and stops (returning false) past kSplitWalkStack of them; a
// point holds none.
TEST(SplitTreeWalkTest, TooDeepForTheStackIsReportedNotOverrun) {
  auto chain = [](int levels) {
    std::vector<SplitNode> t;
    for (int i = 0; i < levels - 1; ++i) {
      t.push_back(Inner(0, static_cast<float>(-i), static_cast<uint32_t>(2 * i + 2),
                        static_cast<uint32_t>(2 * i + 1)));
      t.push_back(Cell(CellLabel::kRight));
    }
    t.push_back(Cell(CellLabel::kLeft));
    return t;
  };
  const Box3d everything = BoxOf(-1000, 0, 1000, 1);
  auto walk = [&](const std::vector<SplitNode>& t, const auto& q) {
    return ForEachSplitCell(t, 0, q, [](const SplitNode&) { return true; });
  };
  EXPECT_TRUE(walk(chain(kSplitWalkStack), everything));  // 64 levels: what a store may hold
  EXPECT_FALSE(walk(chain(kSplitWalkStack + 8), everything));
  EXPECT_TRUE(walk(chain(kSplitWalkStack + 8), Vec3d{-1000, 0, 0}));
  uint64_t entered = 0;
  ForEachSplitCell(
      chain(kSplitWalkStack + 8), 0, Vec3d{-1000, 0, 0}, [](const SplitNode&) { return true; }, &entered);
  EXPECT_EQ(entered, static_cast<uint64_t>(kSplitWalkStack + 8));
}

}  // namespace
}  // namespace mktree
