#include "engine/tree/tree_stats.h"

#include <gtest/gtest.h>

#include "engine/tree/mktree_builder.h"
#include "tree/tree_test_util.h"

namespace mktree {
namespace {

using testing::MakeScene;
using testing::SceneKind;

TEST(TreeStats, CountsAgreeWithTheTree) {
  auto recs = MakeScene(SceneKind::kShip, 20000, 5);
  auto r = BuildMKTree(recs, BuildParams());
  ASSERT_TRUE(r.ok());
  const TreeStats& s = r->stats;
  EXPECT_EQ(s.objects, recs.size());
  EXPECT_EQ(s.leaves, r->tree.leaves.size());
  EXPECT_EQ(s.internal_nodes + s.leaves, r->tree.nodes.size());
  uint64_t level_nodes = 0, level_split = 0, max_depth = 0;
  for (const LevelStats& L : s.levels) {
    level_nodes += L.nodes;
    level_split += L.split_tree_nodes;
  }
  for (const TreeNode& n : r->tree.nodes) max_depth = std::max<uint64_t>(max_depth, n.depth);
  EXPECT_EQ(level_nodes, r->tree.nodes.size());
  EXPECT_EQ(level_split, r->tree.split_nodes.size());
  EXPECT_EQ(s.height, max_depth + 1);
  EXPECT_EQ(s.levels[0].nodes, 1u);
  EXPECT_LE(s.max_split_tree_nodes, BuildParams().split_tree_node_budget);
  EXPECT_GT(s.mean_page_fill, 0.0);
  EXPECT_LE(s.mean_page_fill, 1.0);
  EXPECT_LE(s.min_page_fill, s.mean_page_fill);
  EXPECT_LE(s.min_objects_per_leaf, s.mean_objects_per_leaf);
  EXPECT_LE(s.mean_objects_per_leaf, s.max_objects_per_leaf);
  EXPECT_TRUE(s.has_overlap_counts);
  EXPECT_GT(s.index_bytes_per_object, 0.0);
  const std::string j = s.ToJson();
  for (const char* key : {"\"height\"", "\"leaves\"", "\"mean_page_fill\"", "\"levels\"",
                          "\"both_cell_share\"", "\"overlap_objects\"", "\"index_bytes_per_object\""})
    EXPECT_NE(j.find(key), std::string::npos) << key;
  EXPECT_EQ(j.front(), '{');
  EXPECT_EQ(j.back(), '}');
  EXPECT_NE(s.ToString().find("page fill"), std::string::npos);
  // Without the builder's overlap counts, |Sm| is reported as unknown.
  const TreeStats loaded = ComputeTreeStats(r->tree, recs.size(), {});
  EXPECT_FALSE(loaded.has_overlap_counts);
  EXPECT_EQ(loaded.ToJson().find("\"overlap_objects\""), std::string::npos);
  EXPECT_EQ(loaded.leaves, s.leaves);
}

// Two threads measure the SplitTrees in two halves: the same statistics, bit for bit.
TEST(TreeStats, TwoThreadsGiveTheSameStatistics) {
  auto recs = MakeScene(SceneKind::kShip, 20000, 4);
  auto r = BuildMKTree(recs, BuildParams());
  ASSERT_TRUE(r.ok());
  ASSERT_GE(r->tree.split_nodes.size(), 4096u);  // where the second thread starts
  std::vector<uint32_t> overlap(r->tree.nodes.size(), 1);
  EXPECT_EQ(ComputeTreeStats(r->tree, recs.size(), overlap, 1).ToJson(),
            ComputeTreeStats(r->tree, recs.size(), overlap, 2).ToJson());
}

}  // namespace
}  // namespace mktree
