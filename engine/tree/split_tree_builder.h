// SplitTree construction (docs/design.md §4): a small kd-tree over the overlap region Q of one internal node
// whose cells say which children may hold objects there.
//
// Input: the objects whose boxes meet the closed slab a <= w <= b, each clipped to Q, with a side: fixed
// LEFT (it reaches below a, so it must live in Sn1), fixed RIGHT (it reaches above b), or FREE (entirely in
// the slab: either child may take it).
// Cost model: a query point in a cell is routed to as many children as the label names, so a cell costs
// (its share of Q's volume) x (1 for LEFT/RIGHT, 2 for BOTH, 0 for EMPTY). Cuts (any axis) are taken
// best-first by the cost they save: EMPTY space is carved off and the two sides are pulled apart. The
// cost of a side within a cell only changes just past the extremes of that side's boxes, so the best cut
// of a cell is found in O(items) from 4 candidates per axis.
// Order: cut with the fixed objects alone (half the budget), then give each free object the side that
// adds the least cost to the cells it meets (ties: its default side, within a balance window), then
// spend the rest of the budget with every object placed. Cells are closed: an object touching a cut
// meets both cells.
//
// Invariant: every item whose (clipped) box meets a cell has its final side allowed by the cell's label.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "engine/tree/mktree.h"

namespace mktree {

struct SplitItem {
  static constexpr uint8_t kLeft = 0, kRight = 1, kFree = 2;
  Box3f box;                 // clipped to Q
  uint8_t side = kFree;      // kLeft, kRight or kFree; the builder replaces kFree by the side it chose
  uint8_t default_side = 0;  // for free items: the SOA candidate's side
  uint32_t bytes = 0;        // encoded bytes of the object (for the page window)
};

// How many free items may change side: the count of objects on the left (all objects of the node, not
// only the items) must stay in [min_left, max_left], and the encoded bytes of each side within its limit
// (so that a split chosen to fill pages keeps its page counts).
struct BalanceWindow {
  int64_t left = 0;
  int64_t min_left = 0;
  int64_t max_left = 0;
  uint64_t left_bytes = 0;
  uint64_t total_bytes = 0;
  uint64_t max_left_bytes = UINT64_MAX;
  uint64_t max_right_bytes = UINT64_MAX;
  bool Allows(int64_t new_left, uint64_t new_left_bytes) const {
    return new_left >= min_left && new_left <= max_left && new_left_bytes <= max_left_bytes &&
           total_bytes - new_left_bytes <= max_right_bytes;
  }
};

// Buffers reused from one BuildSplitTree call to the next (one per builder thread).
struct SplitTreeScratch {
  struct Buffers;
  std::unique_ptr<Buffers> buffers;
  SplitTreeScratch();
  ~SplitTreeScratch();
  void Release();  // gives the buffers' memory back
};

// Builds the SplitTree of region `q` into `out` (cleared; root at index 0, child indices local to `out`)
// with at most `budget` nodes (budget >= 1), and resolves every kFree item to kLeft or kRight. A cut is
// only made when it lowers the routing cost by at least `min_gain` (a share of Q's volume, see .cc).
// `scratch` keeps the working buffers between calls (one per thread).
void BuildSplitTree(const Box3f& q, std::span<SplitItem> items, uint32_t budget, BalanceWindow* window,
                    std::vector<SplitNode>* out, double min_gain, SplitTreeScratch* scratch);

}  // namespace mktree
