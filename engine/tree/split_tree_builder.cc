#include "engine/tree/split_tree_builder.h"

#include <algorithm>
#include <queue>

namespace mktree {
namespace {

constexpr uint8_t kLeftBit = 1, kRightBit = 2;

struct Cell {
  Box3f region;
  std::vector<uint32_t> items;  // items whose clipped box meets the closed region
  uint32_t left = 0, right = 0; // fixed items of each side
  uint32_t node = 0;            // its SplitNode in `out`
  uint32_t mixing() const { return std::min(left, right); }
};

struct Cut {
  int axis = -1;
  float pos = 0;
  uint32_t cost = 0;
  double off_center = 0;
};

// count of values <= c (le) or < c (lt) in a sorted array, with a pointer that only moves forward.
struct Cursor {
  const std::vector<float>* v;
  size_t i = 0;
  size_t Le(float c) {
    while (i < v->size() && (*v)[i] <= c) ++i;
    return i;
  }
  size_t Lt(float c) {
    while (i < v->size() && (*v)[i] < c) ++i;
    return i;
  }
};

// The cut of `cell` leaving the fewest items on its wrong side; cost = mixing of the cell if none helps.
Cut BestCut(const Cell& cell, const std::vector<SplitItem>& items) {
  Cut best;
  best.cost = cell.mixing();
  std::vector<float> lmin, lmax, rmin, rmax, fmin, fmax, all;
  for (int u = 0; u < 3; ++u) {
    const float lo = cell.region.min[u], hi = cell.region.max[u];
    if (!(lo < hi)) continue;
    lmin.clear(); lmax.clear(); rmin.clear(); rmax.clear(); fmin.clear(); fmax.clear(); all.clear();
    for (uint32_t i : cell.items) {
      const SplitItem& it = items[i];
      const float mn = std::max(it.box.min[u], lo), mx = std::min(it.box.max[u], hi);
      auto& vmin = it.side == SplitItem::kLeft ? lmin : (it.side == SplitItem::kRight ? rmin : fmin);
      auto& vmax = it.side == SplitItem::kLeft ? lmax : (it.side == SplitItem::kRight ? rmax : fmax);
      vmin.push_back(mn);
      vmax.push_back(mx);
      all.push_back(mn);
      all.push_back(mx);
    }
    for (auto* v : {&lmin, &lmax, &rmin, &rmax, &fmin, &fmax, &all}) std::sort(v->begin(), v->end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    Cursor c_lmin{&lmin}, c_rmin{&rmin}, c_fmin{&fmin}, c_lmax{&lmax}, c_rmax{&rmax}, c_fmax{&fmax};
    const double center = 0.5 * (double{lo} + double{hi}), extent = double{hi} - double{lo};
    for (size_t g = 0; g + 1 < all.size(); ++g) {
      // One cut per gap between consecutive endpoints covers every distinct way to split the items.
      const float c = static_cast<float>(0.5 * (double{all[g]} + double{all[g + 1]}));
      if (!(c > lo && c < hi)) continue;
      // Closed cells: the lower cell gets items with min <= c, the upper one items with max >= c.
      const size_t l_low = c_lmin.Le(c), r_low = c_rmin.Le(c), f_low = c_fmin.Le(c);
      const size_t l_high = lmax.size() - c_lmax.Lt(c), r_high = rmax.size() - c_rmax.Lt(c);
      const size_t f_both = f_low - c_fmax.Lt(c);  // free items with min <= c <= max
      const uint32_t cost = static_cast<uint32_t>(std::min(r_low + l_high, l_low + r_high) + f_both);
      const double off = std::abs(double{c} - center) / extent;
      if (cost < best.cost || (cost == best.cost && best.axis >= 0 && off < best.off_center)) {
        best = Cut{u, c, cost, off};
      }
    }
  }
  return best;
}

}  // namespace

void BuildSplitTree(const Box3f& q, std::vector<SplitItem>* items_ptr, uint32_t budget, BalanceWindow* window,
                    std::vector<SplitNode>* out) {
  std::vector<SplitItem>& items = *items_ptr;
  out->clear();
  std::vector<Cell> cells(1);
  cells[0].region = q;
  cells[0].items.resize(items.size());
  for (uint32_t i = 0; i < items.size(); ++i) {
    cells[0].items[i] = i;
    cells[0].left += items[i].side == SplitItem::kLeft;
    cells[0].right += items[i].side == SplitItem::kRight;
  }
  out->push_back(SplitNode{});

  // Best-first: the most mixed cell is cut first, so a small budget goes where it helps most.
  auto less_mixed = [&](uint32_t x, uint32_t y) { return cells[x].mixing() < cells[y].mixing(); };
  std::priority_queue<uint32_t, std::vector<uint32_t>, decltype(less_mixed)> open(less_mixed);
  open.push(0);
  std::vector<uint32_t> terminal;
  while (!open.empty()) {
    const uint32_t ci = open.top();
    open.pop();
    if (cells[ci].mixing() == 0 || out->size() + 2 > budget) {
      terminal.push_back(ci);
      continue;
    }
    const Cut cut = BestCut(cells[ci], items);
    if (cut.axis < 0) {
      terminal.push_back(ci);
      continue;
    }
    Cell lower, upper;
    lower.region = upper.region = cells[ci].region;
    lower.region.max[cut.axis] = cut.pos;
    upper.region.min[cut.axis] = cut.pos;
    for (uint32_t i : cells[ci].items) {
      const SplitItem& it = items[i];
      for (Cell* c : {&lower, &upper}) {
        if (c == &lower ? it.box.min[cut.axis] <= cut.pos : it.box.max[cut.axis] >= cut.pos) {
          c->items.push_back(i);
          c->left += it.side == SplitItem::kLeft;
          c->right += it.side == SplitItem::kRight;
        }
      }
    }
    std::vector<uint32_t>().swap(cells[ci].items);
    SplitNode& inner = (*out)[cells[ci].node];
    inner.axis = static_cast<uint8_t>(cut.axis);
    inner.cut = cut.pos;
    inner.child[0] = static_cast<uint32_t>(out->size());
    inner.child[1] = inner.child[0] + 1;
    lower.node = inner.child[0];
    upper.node = inner.child[1];
    out->push_back(SplitNode{});
    out->push_back(SplitNode{});
    cells.push_back(std::move(lower));
    cells.push_back(std::move(upper));
    open.push(static_cast<uint32_t>(cells.size() - 2));
    open.push(static_cast<uint32_t>(cells.size() - 1));
  }

  // Free items: the cells each one meets (CSR), and each cell's mask of fixed sides.
  std::vector<uint8_t> fixed_mask(terminal.size(), 0);
  std::vector<std::pair<uint32_t, uint32_t>> free_cells;  // (item, terminal cell)
  for (uint32_t t = 0; t < terminal.size(); ++t) {
    for (uint32_t i : cells[terminal[t]].items) {
      const uint8_t s = items[i].side;
      if (s == SplitItem::kFree) {
        free_cells.emplace_back(i, t);
      } else {
        fixed_mask[t] |= s == SplitItem::kLeft ? kLeftBit : kRightBit;
      }
    }
  }
  std::sort(free_cells.begin(), free_cells.end());
  // A free item takes the side that makes the fewest one-sided cells BOTH, then the side it joins in the
  // most cells; items meeting no fixed object keep the SOA's side (the balance the SOA chose).
  for (size_t f = 0; f < free_cells.size();) {
    const uint32_t item = free_cells[f].first;
    uint32_t to_both[2] = {0, 0}, joins[2] = {0, 0};
    size_t e = f;
    for (; e < free_cells.size() && free_cells[e].first == item; ++e) {
      const uint8_t m = fixed_mask[free_cells[e].second];
      if (m == kRightBit) ++to_both[0];
      if (m == kLeftBit) ++to_both[1];
      if (m & kLeftBit) ++joins[0];
      if (m & kRightBit) ++joins[1];
    }
    SplitItem& it = items[item];
    const uint8_t dflt = it.default_side;
    uint8_t want = dflt;
    if (to_both[0] != to_both[1]) {
      want = to_both[0] < to_both[1] ? SplitItem::kLeft : SplitItem::kRight;
    } else if (joins[0] != joins[1]) {
      want = joins[0] > joins[1] ? SplitItem::kLeft : SplitItem::kRight;
    }
    if (want != dflt) {
      const int64_t left_after = window->left + (want == SplitItem::kLeft ? 1 : -1);
      if (left_after >= window->min_left && left_after <= window->max_left) {
        window->left = left_after;
      } else {
        want = dflt;
      }
    }
    it.side = want;
    f = e;
  }
  // A free item meeting no cell cannot happen (cells cover Q and items lie in Q), but never leave kFree.
  for (SplitItem& it : items)
    if (it.side == SplitItem::kFree) it.side = it.default_side;

  for (uint32_t t = 0; t < terminal.size(); ++t) {
    uint8_t mask = 0;
    for (uint32_t i : cells[terminal[t]].items) mask |= items[i].side == SplitItem::kLeft ? kLeftBit : kRightBit;
    SplitNode& cell = (*out)[cells[terminal[t]].node];
    cell.axis = 3;
    cell.label = static_cast<CellLabel>(mask);
  }
}

}  // namespace mktree
