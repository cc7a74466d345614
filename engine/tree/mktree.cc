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

// The children of internal node n a point query enters: kLeftBit, kRightBit or both.
inline uint8_t PointChildren(const MKTree& t, const TreeNode& n, const Vec3d& p, QueryStats* stats) {
  const double pw = p[n.axis];
  uint8_t sides;
  if (n.a >= n.b) {
    sides = kLeftBit | kRightBit;  // disjoint children: their boxes decide
  } else if (pw < n.a) {
    sides = kLeftBit;
  } else if (pw > n.b) {
    sides = kRightBit;
  } else {
    sides = PointSides(t, n, p, stats);
  }
  uint8_t enter = 0;
  if ((sides & kLeftBit) && t.nodes[n.child[0]].box.Contains(p)) enter |= kLeftBit;
  if ((sides & kRightBit) && t.nodes[n.child[1]].box.Contains(p)) enter |= kRightBit;
  return enter;
}

// The children of internal node n a box query enters.
// Box3f::Intersects without its early exits: on a small tree the walk's time goes to mispredicted branches.
inline bool Meets(const Box3f& b, const Box3d& q) {
  return !(q.max[0] < b.min[0]) & !(q.max[1] < b.min[1]) & !(q.max[2] < b.min[2]) & !(q.min[0] > b.max[0]) &
         !(q.min[1] > b.max[1]) & !(q.min[2] > b.max[2]);
}

inline uint8_t BoxChildren(const MKTree& t, const TreeNode& n, const Box3d& q, QueryStats* stats) {
  const bool meets_left = Meets(t.nodes[n.child[0]].box, q);
  const bool meets_right = Meets(t.nodes[n.child[1]].box, q);
  const uint8_t wanted = (meets_left ? kLeftBit : 0) | (meets_right ? kRightBit : 0);
  if (n.a >= n.b) return wanted;
  if (wanted == 0) return 0;
  const int w = n.axis;
  uint8_t sides = 0;
  // Beyond the slab only one side lives: below a only Sn1, above b only Sn2.
  if (q.min[w] < n.a) sides |= kLeftBit;
  if (q.max[w] > n.b) sides |= kRightBit;
  const bool meets_slab = q.max[w] >= n.a && q.min[w] <= n.b;
  if (meets_slab && (sides & wanted) != wanted) sides |= BoxSides(t, n, q, stats);
  return sides & wanted;
}

// Pending nodes of a depth-first walk: one sibling per level at most, and no tree the store loads or the
// builder makes has more than 256 levels (TreeNode::depth is a byte). FixedStack says when it is full.
constexpr int kFixedStackNodes = 258;
struct FixedStack {
  uint32_t node[kFixedStackNodes];
  int top = 0;
  bool HasRoomForTwo() const { return top + 2 <= kFixedStackNodes; }
  void Push(uint32_t i) { node[top++] = i; }
  uint32_t Pop() { return node[--top]; }
  bool empty() const { return top == 0; }
};
struct GrowingStack {
  std::vector<uint32_t> node;
  static bool HasRoomForTwo() { return true; }
  void Push(uint32_t i) { node.push_back(i); }
  uint32_t Pop() {
    const uint32_t i = node.back();
    node.pop_back();
    return i;
  }
  bool empty() const { return node.empty(); }
};

// Depth first from the root, the right child pushed first: leaves come out in depth-first order, which is
// leaf index order (the builder numbers them so; the store loader checks it), so nothing is sorted after.
// Returns false if the stack filled up (then the caller undoes what was found and walks again).
template <typename Stack, typename Query, typename Children>
bool WalkDepthFirst(const MKTree& t, const Query& q, Children&& children, std::vector<uint32_t>* leaves_out,
                    QueryStats* stats) {
  Stack stack;
  stack.Push(0);
  while (!stack.empty()) {
    const TreeNode& n = t.nodes[stack.Pop()];
    if (n.is_leaf()) {
      EmitLeaf(t, n.leaf, q, leaves_out, stats);
      continue;
    }
    ++stats->internal_nodes_visited;
    const uint8_t enter = children(n);
    if (!stack.HasRoomForTwo()) return false;
    if (enter & kRightBit) stack.Push(n.child[1]);
    if (enter & kLeftBit) stack.Push(n.child[0]);
  }
  return true;
}

template <typename Query, typename Children>
void RouteDepthFirst(const MKTree& t, const Query& q, Children&& children, std::vector<uint32_t>* leaves_out,
                     QueryStats* stats) {
  const QueryStats before = *stats;
  const size_t first_out = leaves_out->size();
  if (WalkDepthFirst<FixedStack>(t, q, children, leaves_out, stats)) return;
  *stats = before;
  leaves_out->resize(first_out);
  WalkDepthFirst<GrowingStack>(t, q, children, leaves_out, stats);
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

// Breadth first, so that a node is visited only after the rest of its level, by when the loads its
// queuing started have arrived (depth first, the next node is nearly always the one just pushed). The
// nodes visited, and so the statistics, are the same in any order; the leaves found are sorted back
// into leaf (= depth-first) order. The queue is per thread: a query allocates nothing.
void RouteBoxBreadthFirst(const MKTree& t, const Box3d& q, std::vector<uint32_t>* leaves_out,
                          QueryStats* stats) {
  thread_local std::vector<uint32_t> queue;
  queue.assign(1, 0);
  const size_t first_out = leaves_out->size();
  for (size_t head = 0; head < queue.size(); ++head) {
    const TreeNode& n = t.nodes[queue[head]];
    if (n.is_leaf()) {
      EmitLeaf(t, n.leaf, q, leaves_out, stats);
      continue;
    }
    ++stats->internal_nodes_visited;
    const uint8_t enter = BoxChildren(t, n, q, stats);
    if (enter & kLeftBit) QueuePrefetched(t, n.child[0], &queue);
    if (enter & kRightBit) QueuePrefetched(t, n.child[1], &queue);
  }
  std::sort(leaves_out->begin() + static_cast<std::ptrdiff_t>(first_out), leaves_out->end());
}

// Bytes a box query may read in RAM: nodes, SplitTrees, leaf infos and the leaf filter. Up to this the
// depth-first walk is the faster; beyond, waiting for memory is most of a walk and the prefetching one
// wins (bench/README.md).
constexpr uint64_t kDepthFirstMaxTreeBytes = uint64_t{6} << 20;

uint64_t RoutedBytes(const MKTree& t) {
  return t.nodes.size() * sizeof(TreeNode) + t.split_nodes.size() * sizeof(SplitNode) +
         t.leaves.size() * sizeof(LeafInfo) + t.leaf_filter.size();
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
  RouteDepthFirst(
      *this, p, [&](const TreeNode& n) { return PointChildren(*this, n, p, stats); }, leaves_out, stats);
}

void MKTree::RouteBox(const Box3d& q, std::vector<uint32_t>* leaves_out, QueryStats* stats,
                      RouteWalk walk) const {
  QueryStats local;
  if (stats == nullptr) stats = &local;
  if (nodes.empty() || q.empty() || !nodes[0].box.Intersects(q)) return;
  if (walk == RouteWalk::kAuto)
    walk = RoutedBytes(*this) <= kDepthFirstMaxTreeBytes ? RouteWalk::kDepthFirst : RouteWalk::kBreadthFirst;
  if (walk == RouteWalk::kBreadthFirst) {
    RouteBoxBreadthFirst(*this, q, leaves_out, stats);
    return;
  }
  RouteDepthFirst(
      *this, q, [&](const TreeNode& n) { return BoxChildren(*this, n, q, stats); }, leaves_out, stats);
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
