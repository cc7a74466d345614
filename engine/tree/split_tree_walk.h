// The one walk of a SplitTree. Node n's SplitTree (mktree.h) cuts n's overlap slab into cells, each
// labelled with the children of n whose objects may lie in it; routing, the tree statistics and the
// pictures all find cells the same way, here: depth first, lower child first, with one rule for which
// children of an inner SplitTree node a query enters:
//   - a point (Vec3d) enters one: the lower if it is below the cut, else the upper. A point on a cut goes
//     up: every object containing it meets both closed cells, so either cell's label allows it;
//   - a box (Box3d) is closed, as cells are: it enters each side it touches, both when it touches the cut;
//   - a SplitRegion enters both, each with the region clipped by the cut, so that every cell is visited
//     with its region (the part of the slab it covers).
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <type_traits>

#include "engine/tree/mktree.h"

namespace mktree {

// Every cell, each with its part of `box` (for a node's SplitTree, the node's slab).
struct SplitRegion {
  Box3f box;
};

// The children of inner node `sn` a query enters: bit 0 the lower (child[0]), bit 1 the upper (child[1]).
inline uint8_t SplitChildrenEntered(const SplitNode& sn, const Vec3d& p) {
  return p[sn.axis] < static_cast<double>(sn.cut) ? 1 : 2;
}
inline uint8_t SplitChildrenEntered(const SplitNode& sn, const Box3d& q) {
  const double cut = sn.cut;
  return (q.min[sn.axis] <= cut ? 1 : 0) | (q.max[sn.axis] >= cut ? 2 : 0);
}
inline uint8_t SplitChildrenEntered(const SplitNode&, const SplitRegion&) { return 3; }

// Pending nodes a walk holds at most: a store's SplitTrees have at most 64 levels (kMaxSplitTreeLevels,
// engine/store_format/tree_codec.h), and a walk keeps at most one pending sibling per level.
inline constexpr int kSplitWalkStack = 64;

// Calls visit(cell) for each cell of the SplitTree at `root` that `query` meets, or visit(cell, region)
// for a SplitRegion; visit returns false to end the walk. Adds the nodes entered (inner nodes and cells)
// to *entered unless it is null. Returns true if every cell the query meets was visited: false if visit ended
// the walk, or if the SplitTree is too deep for the walk's stack (no stored SplitTree is).
template <typename Query, typename Visit>
bool ForEachSplitCell(std::span<const SplitNode> nodes, uint32_t root, const Query& query, Visit&& visit,
                      uint64_t* entered = nullptr) {
  constexpr bool kRegions = std::is_same_v<Query, SplitRegion>;
  struct Item {
    uint32_t node;
    Box3f region;
  };
  using Pending = std::conditional_t<kRegions, Item, uint32_t>;
  Pending stack[kSplitWalkStack];
  int top = 0;
  if constexpr (kRegions)
    stack[top++] = {root, query.box};
  else
    stack[top++] = root;
  while (top > 0) {
    const Pending item = stack[--top];
    uint32_t i;
    if constexpr (kRegions)
      i = item.node;
    else
      i = item;
    const SplitNode& sn = nodes[i];
    if (entered) ++*entered;
    if (sn.is_cell()) {
      bool more;
      if constexpr (kRegions)
        more = visit(sn, item.region);
      else
        more = visit(sn);
      if (!more) return false;
      continue;
    }
    if (top + 2 > kSplitWalkStack) return false;
    const uint8_t enter = SplitChildrenEntered(sn, query);
    for (int side = 1; side >= 0; --side) {  // the upper pushed first: the lower is walked first
      if (!(enter & (1 << side))) continue;
      if constexpr (kRegions) {
        Box3f region = item.region;
        if (side == 0)
          region.max[sn.axis] = std::min(region.max[sn.axis], sn.cut);
        else
          region.min[sn.axis] = std::max(region.min[sn.axis], sn.cut);
        stack[top++] = {sn.child[side], region};
      } else {
        stack[top++] = sn.child[side];
      }
    }
  }
  return true;
}

}  // namespace mktree
