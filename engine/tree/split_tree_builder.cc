#include "engine/tree/split_tree_builder.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

namespace mktree {
namespace {

constexpr uint8_t kLeftBit = 1, kRightBit = 2;

// kLeft -> kLeftBit, kRight -> kRightBit, kFree -> 0.
inline uint8_t SideBit(uint8_t side) { return static_cast<uint8_t>((1u << side) & 3u); }

constexpr float kInf = std::numeric_limits<float>::infinity();

// Float neighbours of a finite x (std::nextafter without the library call: BestCut asks for 12 a cell).
inline float NextDown(float x) {
  if (x == 0) return -std::numeric_limits<float>::denorm_min();
  const uint32_t u = std::bit_cast<uint32_t>(x);
  return std::bit_cast<float>(x > 0 ? u - 1 : u + 1);
}
inline float NextUp(float x) {
  if (x == 0) return std::numeric_limits<float>::denorm_min();
  const uint32_t u = std::bit_cast<uint32_t>(x);
  return std::bit_cast<float>(x > 0 ? u + 1 : u - 1);
}

struct Cell {
  Box3f region;
  uint32_t begin = 0, end = 0;  // its items (those whose clipped box meets the closed region): pool[begin, end)
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
      cand[nc++] = NextDown(lo_of[s][u]);
      cand[nc++] = NextUp(hi_of[s][u]);
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

}  // namespace

// Buffers one SplitTree build leaves behind for the next (no allocation per cell or per tree).
struct SplitTreeScratch::Buffers {
  std::vector<Cell> cells;
  std::vector<uint32_t> pool;       // the cells' item lists, each a range
  std::vector<uint32_t> upper;      // Split's upper items before they join the pool
  std::vector<uint32_t> leaves;     // cells that are not cut
  std::vector<uint32_t> node_cell;  // SplitNode -> its cell
  std::vector<uint32_t> stack, met;
  std::vector<Cut> cut_of;
  std::vector<std::pair<double, uint32_t>> open;  // heap of (gain, cell)
};

SplitTreeScratch::SplitTreeScratch() : buffers(std::make_unique<Buffers>()) {}
SplitTreeScratch::~SplitTreeScratch() = default;
void SplitTreeScratch::Release() { buffers = std::make_unique<Buffers>(); }

namespace {

class Builder {
 public:
  Builder(const Box3f& q, std::vector<SplitItem>* items, uint32_t budget, std::vector<SplitNode>* out,
          SplitTreeScratch::Buffers* b)
      : items_(*items), budget_(budget), out_(*out), cm_(q), b_(*b) {
    out_.clear();
    b_.cells.clear();
    b_.pool.clear();
    b_.leaves.clear();
    b_.node_cell.clear();
    Cell root;
    root.region = q;
    root.end = static_cast<uint32_t>(items_.size());
    b_.pool.resize(items_.size());
    for (uint32_t i = 0; i < items_.size(); ++i) {
      b_.pool[i] = i;
      root.label |= SideBit(items_[i].side);
    }
    b_.cells.push_back(root);
    out_.push_back(SplitNode{});
    b_.node_cell.push_back(0);
    b_.leaves.push_back(0);
  }

  // Best-first: cut the cell with the largest gain until the budget is spent or no cut gains at least
  // `min_gain` (a share of Q's volume): small gains are not worth 32 bytes of RAM per cut.
  void Refine(uint32_t node_limit, double min_gain) {
    node_limit = std::min(node_limit, budget_);
    std::vector<std::pair<double, uint32_t>>& open = b_.open;
    std::vector<Cut>& cut_of = b_.cut_of;
    open.clear();
    cut_of.assign(b_.cells.size(), Cut{});
    auto consider = [&](uint32_t ci) {
      if (cut_of.size() <= ci) cut_of.resize(ci + 1);
      cut_of[ci] = BestCut(b_.cells[ci], cm_);
      if (cut_of[ci].axis >= 0 && cut_of[ci].gain >= min_gain) {
        open.push_back({cut_of[ci].gain, ci});
        std::push_heap(open.begin(), open.end());
      }
    };
    for (uint32_t ci : b_.leaves) {
      ComputeExtremes(&b_.cells[ci]);  // items resolved since the last Refine count now
      consider(ci);
    }
    while (!open.empty() && out_.size() + 2 <= node_limit) {
      std::pop_heap(open.begin(), open.end());
      const uint32_t ci = open.back().second;
      open.pop_back();
      const auto [lower, upper] = Split(ci, cut_of[ci]);
      consider(lower);
      consider(upper);
    }
  }

  // Free items take the side that adds the least cost (volume of cells that would gain that side), ties
  // to their default side, within the balance window. Labels are updated as items are placed.
  void ResolveFree(BalanceWindow* window) {
    std::vector<uint32_t>& met = b_.met;
    for (uint32_t i = 0; i < items_.size(); ++i) {
      SplitItem& it = items_[i];
      if (it.side != SplitItem::kFree) continue;
      met.clear();
      CellsMeeting(it.box, &met);
      double added[2] = {0, 0};
      for (uint32_t ci : met) {
        const Cell& c = b_.cells[ci];
        const double v = cm_.Volume(c.region);
        if (!(c.label & kLeftBit)) added[0] += v;
        if (!(c.label & kRightBit)) added[1] += v;
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
      for (uint32_t ci : met) b_.cells[ci].label |= SideBit(want);
    }
  }

  // Labels from the items each cell holds (all resolved by now): the invariant by construction.
  void WriteLabels() {
    for (uint32_t ci : b_.leaves) {
      const Cell& c = b_.cells[ci];
      uint8_t label = 0;
      for (uint32_t k = c.begin; k < c.end; ++k) label |= SideBit(items_[b_.pool[k]].side);
      SplitNode& sn = out_[c.node];
      sn.axis = 3;
      sn.label = static_cast<CellLabel>(label);
    }
  }

 private:
  void ComputeExtremes(Cell* c) const {
    c->ResetExtremes();
    for (uint32_t k = c->begin; k < c->end; ++k) {
      const SplitItem& it = items_[b_.pool[k]];
      if (it.side != SplitItem::kFree) c->AddExtremes(it);
    }
  }

  std::pair<uint32_t, uint32_t> Split(uint32_t ci, const Cut& cut) {
    Cell lower, upper;
    lower.region = upper.region = b_.cells[ci].region;
    lower.region.max[cut.axis] = cut.pos;
    upper.region.min[cut.axis] = cut.pos;
    lower.ResetExtremes();
    upper.ResetExtremes();
    // The children's items go to the end of the pool: lower's, then upper's.
    const uint32_t begin = b_.cells[ci].begin, end = b_.cells[ci].end;
    const uint32_t base = static_cast<uint32_t>(b_.pool.size());
    b_.pool.reserve(size_t{base} + 2 * size_t{end - begin});  // the parent's range stays put below
    b_.upper.clear();
    // Closed cells: an item touching the cut meets both.
    for (uint32_t k = begin; k < end; ++k) {
      const uint32_t i = b_.pool[k];
      const SplitItem& it = items_[i];
      const bool resolved = it.side != SplitItem::kFree;
      if (it.box.min[cut.axis] <= cut.pos) {
        b_.pool.push_back(i);
        lower.label |= SideBit(it.side);
        if (resolved) lower.AddExtremes(it);
      }
      if (it.box.max[cut.axis] >= cut.pos) {
        b_.upper.push_back(i);
        upper.label |= SideBit(it.side);
        if (resolved) upper.AddExtremes(it);
      }
    }
    lower.begin = base;
    lower.end = upper.begin = static_cast<uint32_t>(b_.pool.size());
    b_.pool.insert(b_.pool.end(), b_.upper.begin(), b_.upper.end());
    upper.end = static_cast<uint32_t>(b_.pool.size());
    const uint32_t node = b_.cells[ci].node;
    const uint32_t first = static_cast<uint32_t>(out_.size());
    out_[node].axis = static_cast<uint8_t>(cut.axis);
    out_[node].cut = cut.pos;
    out_[node].child[0] = first;
    out_[node].child[1] = first + 1;
    out_.push_back(SplitNode{});
    out_.push_back(SplitNode{});
    lower.node = first;
    upper.node = first + 1;
    const uint32_t lc = static_cast<uint32_t>(b_.cells.size());
    b_.cells.push_back(lower);
    b_.cells.push_back(upper);
    b_.node_cell.push_back(lc);
    b_.node_cell.push_back(lc + 1);
    std::replace(b_.leaves.begin(), b_.leaves.end(), ci, lc);
    b_.leaves.push_back(lc + 1);
    return {lc, lc + 1};
  }

  void CellsMeeting(const Box3f& b, std::vector<uint32_t>* met) {
    std::vector<uint32_t>& stack = b_.stack;
    stack.assign(1, 0);
    while (!stack.empty()) {
      const uint32_t n = stack.back();
      stack.pop_back();
      const SplitNode& sn = out_[n];
      if (sn.is_cell()) {
        met->push_back(b_.node_cell[n]);
        continue;
      }
      if (b.max[sn.axis] >= sn.cut) stack.push_back(sn.child[1]);
      if (b.min[sn.axis] <= sn.cut) stack.push_back(sn.child[0]);
    }
  }

  std::vector<SplitItem>& items_;
  uint32_t budget_;
  std::vector<SplitNode>& out_;
  CostModel cm_;
  SplitTreeScratch::Buffers& b_;
};

}  // namespace

void BuildSplitTree(const Box3f& q, std::vector<SplitItem>* items, uint32_t budget, BalanceWindow* window,
                    std::vector<SplitNode>* out, double min_gain, SplitTreeScratch* scratch) {
  SplitTreeScratch local;
  Builder b(q, items, std::max<uint32_t>(budget, 1), out, (scratch ? scratch : &local)->buffers.get());
  // First carve with the fixed items alone, then place the free items against those cells, then spend
  // what is left of the budget with every item placed.
  b.Refine(std::max<uint32_t>(1, budget / 2) | 1, min_gain);
  b.ResolveFree(window);
  b.Refine(budget, min_gain);
  b.WriteLabels();
}

}  // namespace mktree
