#include "engine/tree/mktree.h"

#include <algorithm>
#include <type_traits>

#include "engine/tree/leaf_filter.h"
#include "engine/tree/split_tree_walk.h"

namespace mktree {
namespace {

constexpr uint8_t kLeftBit = 1;
constexpr uint8_t kRightBit = 2;

// Sides a point in the slab may find objects of: the label of the SplitTree cell holding it.
uint8_t PointSides(const MKTree& t, const TreeNode& n, const Vec3d& p, QueryStats* stats) {
  if (n.split_root == kNoIndex) return kLeftBit | kRightBit;  // no SplitTree: the slab is shared
  uint8_t sides = 0;
  ForEachSplitCell(
      t.split_nodes, n.split_root, p,
      [&](const SplitNode& cell) {
        sides = static_cast<uint8_t>(cell.label);
        return true;
      },
      &stats->split_nodes_visited);
  return sides;
}

// Union of the labels of the cells a box meets, stopping once both sides are found.
uint8_t BoxSides(const MKTree& t, const TreeNode& n, const Box3d& q, QueryStats* stats) {
  if (n.split_root == kNoIndex) return kLeftBit | kRightBit;
  uint8_t sides = 0;
  const bool all = ForEachSplitCell(
      t.split_nodes, n.split_root, q,
      [&](const SplitNode& cell) {
        sides |= static_cast<uint8_t>(cell.label);
        return sides != (kLeftBit | kRightBit);
      },
      &stats->split_nodes_visited);
  return all ? sides : kLeftBit | kRightBit;  // ended early: both found, or too deep to finish
}

// A leaf the routing reached: read it unless the leaf filter says none of its objects meets the query.
template <typename QueryShape>
void EmitLeaf(const MKTree& t, uint32_t leaf, const QueryShape& q, std::vector<uint32_t>* leaves_out,
              QueryStats* stats) {
  if (!t.leaf_filter_begin.empty()) {
    const LeafInfo& info = t.leaves[leaf];
    const uint8_t* boxes = t.leaf_filter.data() + t.leaf_filter_begin[leaf];
    bool meets;
    if constexpr (std::is_same_v<QueryShape, Vec3d>)
      meets = FilterMeetsPoint(info.box, boxes, info.object_count, q);
    else
      meets = FilterMeetsBox(info.box, boxes, info.object_count, q);
    if (!meets) {
      ++stats->leaves_filtered;
      return;
    }
  }
  ++stats->leaves_visited;
  leaves_out->push_back(leaf);
}

// Queues node `i` for a later visit and starts loading what that visit reads: its children's boxes and
// its SplitTree root, or its leaf's info and filter bytes. A box query reaches hundreds of nodes spread
// over a tree of megabytes, and each visit would otherwise wait for memory.
void QueuePrefetched(const MKTree& t, uint32_t i, std::vector<uint32_t>* queue) {
  const TreeNode& n = t.nodes[i];
  if (n.is_leaf()) {
    __builtin_prefetch(&t.leaves[n.leaf]);
    if (!t.leaf_filter_begin.empty()) __builtin_prefetch(t.leaf_filter.data() + t.leaf_filter_begin[n.leaf]);
  } else {
    for (uint32_t c : n.child) {
      __builtin_prefetch(&t.nodes[c]);
      __builtin_prefetch(reinterpret_cast<const char*>(&t.nodes[c] + 1) -
                         1);  // a node may straddle two lines
    }
    if (n.split_root != kNoIndex) __builtin_prefetch(&t.split_nodes[n.split_root]);
  }
  queue->push_back(i);
}

}  // namespace

Box3d MKTree::WorldBounds() const {
  Box3d b;
  if (empty()) return b;
  for (int i = 0; i < 3; ++i) {
    b.min[i] = origin[i] + nodes[0].box.min[i];
    b.max[i] = origin[i] + nodes[0].box.max[i];
  }
  return b;
}

void MKTree::RoutePoint(const Vec3d& p, std::vector<uint32_t>* leaves_out, QueryStats* stats) const {
  QueryStats local;
  if (stats == nullptr) stats = &local;
  if (nodes.empty() || !nodes[0].box.Contains(p)) return;
  std::vector<uint32_t> stack{0};
  while (!stack.empty()) {
    const TreeNode& n = nodes[stack.back()];
    stack.pop_back();
    if (n.is_leaf()) {
      EmitLeaf(*this, n.leaf, p, leaves_out, stats);
      continue;
    }
    ++stats->internal_nodes_visited;
    const double pw = p[n.axis];
    uint8_t sides;
    if (n.a >= n.b) {
      sides = kLeftBit | kRightBit;  // disjoint children: their boxes decide
    } else if (pw < n.a) {
      sides = kLeftBit;
    } else if (pw > n.b) {
      sides = kRightBit;
    } else {
      sides = PointSides(*this, n, p, stats);
    }
    // Right pushed first so that leaves come out in DFS (= leaf index) order.
    if ((sides & kRightBit) && nodes[n.child[1]].box.Contains(p)) stack.push_back(n.child[1]);
    if ((sides & kLeftBit) && nodes[n.child[0]].box.Contains(p)) stack.push_back(n.child[0]);
  }
}

void MKTree::RouteBox(const Box3d& q, std::vector<uint32_t>* leaves_out, QueryStats* stats) const {
  QueryStats local;
  if (stats == nullptr) stats = &local;
  if (nodes.empty() || q.empty() || !nodes[0].box.Intersects(q)) return;
  // Breadth first, so that a node is visited only after the rest of its level, by when the loads its
  // queuing started have arrived (depth first, the next node is nearly always the one just pushed).
  // The nodes visited, and so the statistics, are the same in any order; the leaves found are sorted
  // back into leaf (= depth-first) order. The queue is per thread: a query allocates nothing.
  thread_local std::vector<uint32_t> queue;
  queue.assign(1, 0);
  const size_t first_out = leaves_out->size();
  for (size_t head = 0; head < queue.size(); ++head) {
    const TreeNode& n = nodes[queue[head]];
    if (n.is_leaf()) {
      EmitLeaf(*this, n.leaf, q, leaves_out, stats);
      continue;
    }
    ++stats->internal_nodes_visited;
    const TreeNode& left = nodes[n.child[0]];
    const TreeNode& right = nodes[n.child[1]];
    const bool meets_left = left.box.Intersects(q);
    const bool meets_right = right.box.Intersects(q);
    uint8_t sides = 0;
    if (n.a >= n.b) {
      sides = kLeftBit | kRightBit;
    } else if (meets_left || meets_right) {
      const int w = n.axis;
      // Beyond the slab only one side lives: below a only Sn1, above b only Sn2.
      if (q.min[w] < n.a) sides |= kLeftBit;
      if (q.max[w] > n.b) sides |= kRightBit;
      const bool meets_slab = q.max[w] >= n.a && q.min[w] <= n.b;
      const uint8_t wanted = (meets_left ? kLeftBit : 0) | (meets_right ? kRightBit : 0);
      if (meets_slab && (sides & wanted) != wanted) sides |= BoxSides(*this, n, q, stats);
    }
    if ((sides & kLeftBit) && meets_left) QueuePrefetched(*this, n.child[0], &queue);
    if ((sides & kRightBit) && meets_right) QueuePrefetched(*this, n.child[1], &queue);
  }
  std::sort(leaves_out->begin() + static_cast<std::ptrdiff_t>(first_out), leaves_out->end());
}

bool MKTree::IndexLeafFilter() {
  leaf_filter_begin.clear();
  if (leaf_filter.empty()) return true;
  leaf_filter_begin.reserve(leaves.size() + 1);
  uint64_t at = 0;
  for (const LeafInfo& l : leaves) {
    leaf_filter_begin.push_back(at);
    at += uint64_t{kLeafFilterBytesPerObject} * l.object_count;
  }
  leaf_filter_begin.push_back(at);
  if (at != leaf_filter.size()) {
    leaf_filter_begin.clear();
    return false;
  }
  return true;
}

uint64_t MKTree::MemoryBytes() const {
  return nodes.capacity() * sizeof(TreeNode) + split_nodes.capacity() * sizeof(SplitNode) +
         leaves.capacity() * sizeof(LeafInfo);
}

}  // namespace mktree
