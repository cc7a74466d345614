#include "engine/viz/level_groups.h"

#include <gtest/gtest.h>

#include <unordered_map>

#include "engine/tree/mktree_builder.h"
#include "tree/tree_test_util.h"

namespace mktree {
namespace {

using testing::MakeScene;
using testing::SceneKind;

// GroupAtLevel against the definitions: at the depth-k ancestor, Sm membership first, else the side.
TEST(LevelGroups, GroupAtLevelFollowsTheDefinition) {
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
