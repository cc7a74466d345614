#include "engine/viz/level_groups.h"

namespace mktree {

LevelGroup GroupAtLevel(const MKTree& tree, uint32_t leaf, const Box3f& object_box, int k) {
  if (k < 0 || leaf >= tree.leaves.size()) return LevelGroup::kAboveLevel;
  const uint32_t target = tree.leaves[leaf].node;
  uint32_t cur = 0;
  // DFS preorder: the left subtree of n is [n + 1, child[1]), so the path to `target` is found by index.
  for (int d = 0; d < k; ++d) {
    const TreeNode& n = tree.nodes[cur];
    if (n.is_leaf()) return LevelGroup::kAboveLevel;
    cur = target < n.child[1] ? n.child[0] : n.child[1];
  }
  const TreeNode& n = tree.nodes[cur];
  if (n.is_leaf()) return LevelGroup::kAboveLevel;
  const int w = n.axis;
  if (n.a < n.b && object_box.max[w] > n.a && object_box.min[w] < n.b) return LevelGroup::kOverlap;
  return target < n.child[1] ? LevelGroup::kSn1 : LevelGroup::kSn2;
}

}  // namespace mktree
