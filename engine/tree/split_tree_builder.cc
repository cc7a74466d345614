#include "engine/tree/split_tree_builder.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <queue>

namespace mktree {
namespace {

constexpr uint8_t kLeftBit = 1, kRightBit = 2;

inline uint8_t SideBit(uint8_t side) { return side == SplitItem::kLeft ? kLeftBit : side == SplitItem::kRight ? kRightBit : 0; }

constexpr float kInf = std::numeric_limits<float>::infinity();

struct Cell {
  Box3f region;
  std::vector<uint32_t> items;  // items whose clipped box meets the closed region
  uint32_t node = 0;            // its SplitNode in `out`
  uint8_t label = 0;            // sides of the resolved items meeting it
  // [side][axis]: extremes of the resolved items' boxes within the region (kept up to date by Split, so
  // that a cut's children need no second pass over their items).
  float lo_of[2][3], hi_of[2][3];

  void ResetExtremes() {
    for (int s = 0; s < 2; ++s)
      for (int u = 0; u < 3; ++u) lo_of[s][u] = kInf, hi_of[s][u] = -kInf;
  }
  void AddExtremes(const SplitItem& it) {
    for (int u = 0; u < 3; ++u) {
      lo_of[it.side][u] = std::min(lo_of[it.side][u], std::max(it.box.min[u], region.min[u]));
      hi_of[it.side][u] = std::max(hi_of[it.side][u], std::min(it.box.max[u], region.max[u]));
    }
  }
  void ComputeExtremes(const std::vector<SplitItem>& all) {
    ResetExtremes();
    for (uint32_t i : items)
      if (all[i].side != SplitItem::kFree) AddExtremes(all[i]);
  }
};

struct Cut {
  int axis = -1;
  float pos = 0;
  double gain = 0;
};

// Routing cost model: a point of Q in a cell is sent to popcount(label) children. A cell's cost is its
// share of Q's volume times that count; a cut's gain is how much it lowers the cost. (Axes along which Q
// is flat are left out of the volume, so flat regions still compare by area.)
class CostModel {
 public:
  explicit CostModel(const Box3f& q) {
    for (int u = 0; u < 3; ++u) inv_extent_[u] = q.max[u] > q.min[u] ? 1.0 / (double{q.max[u]} - q.min[u]) : 0;
  }
  double Volume(const Box3f& b) const {
    double v = 1;
    for (int u = 0; u < 3; ++u)
      if (inv_extent_[u] > 0) v *= (double{b.max[u]} - b.min[u]) * inv_extent_[u];
    return v;
  }

 private:
  double inv_extent_[3];
};

// The best cut of a cell: the label of the part below a cut c has L iff some L item has min <= c, and
// the part above has L iff some L item has max >= c, so the cost only changes just past the extremes of
// each side's items; the candidates are the floats just outside them.
Cut BestCut(const Cell& cell, const CostModel& cm) {
  Cut best;
  const double vol = cm.Volume(cell.region);
  if (vol <= 0 || cell.label == 0) return best;
  const int cost_now = std::popcount(cell.label);
  const auto& lo_of = cell.lo_of;
  const auto& hi_of = cell.hi_of;
  for (int u = 0; u < 3; ++u) {
    const float lo = cell.region.min[u], hi = cell.region.max[u];
    if (!(lo < hi)) continue;
    float cand[4];
    int nc = 0;
    for (int s = 0; s < 2; ++s) {
      if (lo_of[s][u] == kInf) continue;
      cand[nc++] = std::nextafter(lo_of[s][u], -kInf);
      cand[nc++] = std::nextafter(hi_of[s][u], kInf);
    }
    for (int k = 0; k < nc; ++k) {
      const float c = cand[k];
      if (!(c > lo && c < hi)) continue;
      int below = 0, above = 0;
      for (int s = 0; s < 2; ++s) {
        if (lo_of[s][u] == kInf) continue;
        below += lo_of[s][u] <= c;
        above += hi_of[s][u] >= c;
      }
      const double f = (double{c} - lo) / (double{hi} - lo);
      const double gain = vol * (cost_now - (f * below + (1 - f) * above));
      if (gain > best.gain) best = Cut{u, c, gain};
    }
  }
  return best;
}

class Builder {
 public:
  Builder(const Box3f& q, std::vector<SplitItem>* items, uint32_t budget, std::vector<SplitNode>* out)
      : items_(*items), budget_(budget), out_(*out), cm_(q) {
    out_.clear();
    cells_.resize(1);
    cells_[0].region = q;
    cells_[0].items.resize(items_.size());
    for (uint32_t i = 0; i < items_.size(); ++i) {
      cells_[0].items[i] = i;
      cells_[0].label |= SideBit(items_[i].side);
    }
    out_.push_back(SplitNode{});
    node_cell_.push_back(0);
    leaves_.push_back(0);
  }

  // Best-first: cut the cell with the largest gain until the budget is spent or no cut gains at least
  // `min_gain` (a share of Q's volume): small gains are not worth 32 bytes of RAM per cut.
  void Refine(uint32_t node_limit, double min_gain) {
    node_limit = std::min(node_limit, budget_);
    using Entry = std::pair<double, uint32_t>;  // (gain, cell)
    std::priority_queue<Entry> open;
    std::vector<Cut> cut_of(cells_.size());
    auto consider = [&](uint32_t ci) {
      if (cut_of.size() <= ci) cut_of.resize(ci + 1);
      cut_of[ci] = BestCut(cells_[ci], cm_);
      if (cut_of[ci].axis >= 0 && cut_of[ci].gain >= min_gain) open.push({cut_of[ci].gain, ci});
    };
    for (uint32_t ci : leaves_) {
      cells_[ci].ComputeExtremes(items_);  // items resolved since the last Refine count now
      consider(ci);
    }
    while (!open.empty() && out_.size() + 2 <= node_limit) {
      const uint32_t ci = open.top().second;
      open.pop();
      const auto [lower, upper] = Split(ci, cut_of[ci]);
      consider(lower);
      consider(upper);
    }
  }

  // Free items take the side that adds the least cost (volume of cells that would gain that side), ties
  // to their default side, within the balance window. Labels are updated as items are placed.
  void ResolveFree(BalanceWindow* window) {
    std::vector<uint32_t> met;
    for (uint32_t i = 0; i < items_.size(); ++i) {
      SplitItem& it = items_[i];
      if (it.side != SplitItem::kFree) continue;
      met.clear();
      CellsMeeting(it.box, &met);
      double added[2] = {0, 0};
      for (uint32_t ci : met) {
        const double v = cm_.Volume(cells_[ci].region);
        if (!(cells_[ci].label & kLeftBit)) added[0] += v;
        if (!(cells_[ci].label & kRightBit)) added[1] += v;
      }
      uint8_t want = it.default_side;
      if (added[0] != added[1]) want = added[0] < added[1] ? SplitItem::kLeft : SplitItem::kRight;
      if (want != it.default_side) {
        const bool to_left = want == SplitItem::kLeft;
        const int64_t left_after = window->left + (to_left ? 1 : -1);
        const uint64_t bytes_after = to_left ? window->left_bytes + it.bytes : window->left_bytes - it.bytes;
        if (window->Allows(left_after, bytes_after)) {
          window->left = left_after;
          window->left_bytes = bytes_after;
        } else {
          want = it.default_side;
        }
      }
      it.side = want;
      for (uint32_t ci : met) cells_[ci].label |= SideBit(want);
    }
  }

  // Labels from the items each cell holds (all resolved by now): the invariant by construction.
  void WriteLabels() {
    for (uint32_t ci : leaves_) {
      uint8_t label = 0;
      for (uint32_t i : cells_[ci].items) label |= SideBit(items_[i].side);
      SplitNode& sn = out_[cells_[ci].node];
      sn.axis = 3;
      sn.label = static_cast<CellLabel>(label);
    }
  }

 private:
  std::pair<uint32_t, uint32_t> Split(uint32_t ci, const Cut& cut) {
    Cell lower, upper;
    lower.region = upper.region = cells_[ci].region;
    lower.region.max[cut.axis] = cut.pos;
    upper.region.min[cut.axis] = cut.pos;
    lower.ResetExtremes();
    upper.ResetExtremes();
    // Closed cells: an item touching the cut meets both.
    for (uint32_t i : cells_[ci].items) {
      const SplitItem& it = items_[i];
      const bool resolved = it.side != SplitItem::kFree;
      if (it.box.min[cut.axis] <= cut.pos) {
        lower.items.push_back(i);
        lower.label |= SideBit(it.side);
        if (resolved) lower.AddExtremes(it);
      }
      if (it.box.max[cut.axis] >= cut.pos) {
        upper.items.push_back(i);
        upper.label |= SideBit(it.side);
        if (resolved) upper.AddExtremes(it);
      }
    }
    std::vector<uint32_t>().swap(cells_[ci].items);
    const uint32_t node = cells_[ci].node;
    const uint32_t first = static_cast<uint32_t>(out_.size());
    out_[node].axis = static_cast<uint8_t>(cut.axis);
    out_[node].cut = cut.pos;
    out_[node].child[0] = first;
    out_[node].child[1] = first + 1;
    out_.push_back(SplitNode{});
    out_.push_back(SplitNode{});
    lower.node = first;
    upper.node = first + 1;
    const uint32_t lc = static_cast<uint32_t>(cells_.size());
    cells_.push_back(std::move(lower));
    cells_.push_back(std::move(upper));
    node_cell_.push_back(lc);
    node_cell_.push_back(lc + 1);
    std::replace(leaves_.begin(), leaves_.end(), ci, lc);
    leaves_.push_back(lc + 1);
    return {lc, lc + 1};
  }

  void CellsMeeting(const Box3f& b, std::vector<uint32_t>* met) {
    stack_.assign(1, 0);
    while (!stack_.empty()) {
      const uint32_t n = stack_.back();
      stack_.pop_back();
      const SplitNode& sn = out_[n];
      if (sn.is_cell()) {
        met->push_back(node_cell_[n]);
        continue;
      }
      if (b.max[sn.axis] >= sn.cut) stack_.push_back(sn.child[1]);
      if (b.min[sn.axis] <= sn.cut) stack_.push_back(sn.child[0]);
    }
  }

  std::vector<SplitItem>& items_;
  uint32_t budget_;
  std::vector<SplitNode>& out_;
  CostModel cm_;
  std::vector<Cell> cells_;
  std::vector<uint32_t> leaves_;     // cells that are not cut
  std::vector<uint32_t> node_cell_;  // SplitNode -> its cell
  std::vector<uint32_t> stack_;
};

}  // namespace

void BuildSplitTree(const Box3f& q, std::vector<SplitItem>* items, uint32_t budget, BalanceWindow* window,
                    std::vector<SplitNode>* out, double min_gain) {
  Builder b(q, items, std::max<uint32_t>(budget, 1), out);
  // First carve with the fixed items alone, then place the free items against those cells, then spend
  // what is left of the budget with every item placed.
  b.Refine(std::max<uint32_t>(1, budget / 2) | 1, min_gain);
  b.ResolveFree(window);
  b.Refine(budget, min_gain);
  b.WriteLabels();
}

}  // namespace mktree
