#include "engine/tree/tree_stats.h"

#include <gtest/gtest.h>

#include <unordered_map>

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

// GroupAtLevel against the definitions: at the depth-k ancestor, Sm membership first, else the side.
TEST(TreeStats, GroupAtLevelFollowsTheDefinition) {
  auto recs = MakeScene(SceneKind::kUniform, 3000, 8);
  BuildParams p;
  p.block_size = 1024;
  auto r = BuildMKTree(recs, p);
  ASSERT_TRUE(r.ok());
  const MKTree& t = r->tree;
  std::unordered_map<ObjectId, Box3f> box;
  for (const auto& rc : recs) box[rc.id] = rc.box;
  // Ancestors of each node by walking down from the root.
  std::vector<uint32_t> parent(t.nodes.size(), kNoIndex);
  for (uint32_t i = 0; i < t.nodes.size(); ++i)
    if (!t.nodes[i].is_leaf()) parent[t.nodes[i].child[0]] = parent[t.nodes[i].child[1]] = i;
  int counts[4] = {0, 0, 0, 0};
  for (int k : {0, 1, 3, 6, 1000}) {
    for (uint32_t l = 0; l < t.leaves.size(); ++l) {
      std::vector<uint32_t> path;  // root ... leaf node
      for (uint32_t n = t.leaves[l].node; n != kNoIndex; n = parent[n]) path.insert(path.begin(), n);
      for (uint64_t pos = r->leaf_offsets[l]; pos < r->leaf_offsets[l + 1]; ++pos) {
        const Box3f& b = box.at(r->leaf_objects[pos]);
        const LevelGroup g = GroupAtLevel(t, l, b, k);
        ++counts[static_cast<int>(g)];
        if (static_cast<size_t>(k) + 1 >= path.size()) {
          EXPECT_EQ(g, LevelGroup::kAboveLevel);
          continue;
        }
        const TreeNode& n = t.nodes[path[k]];
        const int w = n.axis;
        const bool in_sm = n.a < n.b && b.max[w] > n.a && b.min[w] < n.b;
        const LevelGroup side = path[k + 1] == n.child[0] ? LevelGroup::kSn1 : LevelGroup::kSn2;
        EXPECT_EQ(g, in_sm ? LevelGroup::kOverlap : side);
        // The group rules: an object below a is in Sn1, above b in Sn2.
        if (b.min[w] < n.a) {
          EXPECT_EQ(side, LevelGroup::kSn1);
        }
        if (b.max[w] > n.b) {
          EXPECT_EQ(side, LevelGroup::kSn2);
        }
      }
    }
  }
  for (int g = 0; g < 4; ++g) EXPECT_GT(counts[g], 0) << "group " << g << " never seen";
  EXPECT_EQ(GroupAtLevel(t, static_cast<uint32_t>(t.leaves.size()), recs[0].box, 0), LevelGroup::kAboveLevel);
  EXPECT_EQ(GroupAtLevel(t, 0, recs[0].box, -1), LevelGroup::kAboveLevel);
}

}  // namespace
}  // namespace mktree
