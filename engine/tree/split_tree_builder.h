// SplitTree construction (DESIGN.md §2.2): a small kd-tree over the overlap region Q of one internal node
// whose cells say which children may hold objects there.
//
// Input: the objects whose boxes meet the closed slab a <= w <= b, each clipped to Q, with a side: fixed
// LEFT (it reaches below a, so it must live in Sn1), fixed RIGHT (it reaches above b), or FREE (entirely in
// the slab: either child may take it). Cuts (any axis) are chosen best-first on the cell with the most
// mixing: the cut that leaves the fewest objects on the wrong side of it (fixed objects of the other side,
// plus free objects it crosses), taken only if that count is below min(#LEFT, #RIGHT) of the cell, which
// makes every cut strictly reduce the mixing and the construction terminate. Free objects then take the
// side that turns the fewest fixed-labelled cells into BOTH (else they keep their default side), within
// a balance window. Cells are closed: an object touching a cut meets both cells.
//
// Invariant: every item whose (clipped) box meets a cell has its final side allowed by the cell's label.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/tree/mktree.h"

namespace mktree {

struct SplitItem {
  static constexpr uint8_t kLeft = 0, kRight = 1, kFree = 2;
  Box3f box;                 // clipped to Q
  uint8_t side = kFree;      // kLeft, kRight or kFree; the builder replaces kFree by the side it chose
  uint8_t default_side = 0;  // for free items: the SOA candidate's side
};

// How many free items may change side: the count of items on the left (all objects of the node, not only
// the items) must stay in [min_left, max_left].
struct BalanceWindow {
  int64_t left = 0;
  int64_t min_left = 0;
  int64_t max_left = 0;
};

// Builds the SplitTree of region `q` into `out` (cleared; root at index 0, child indices local to `out`)
// with at most `budget` nodes (budget >= 1), and resolves every kFree item to kLeft or kRight.
void BuildSplitTree(const Box3f& q, std::vector<SplitItem>* items, uint32_t budget, BalanceWindow* window,
                    std::vector<SplitNode>* out);

}  // namespace mktree
