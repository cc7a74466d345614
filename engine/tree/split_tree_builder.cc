#include "engine/tree/split_tree_builder.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>

#include "engine/tree/box_lanes.h"

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace mktree {
namespace {

constexpr uint8_t kLeftBit = 1, kRightBit = 2;
constexpr uint32_t kMinRoom = 64;      // Builder::Grow's smallest room (fewer moves of small leaves)
constexpr uint32_t kOutReserve = 256;  // SplitNodes reserved up front (no regrowth up to that budget)

constexpr float kInf = std::numeric_limits<float>::infinity();

typedef int MaskLanes __attribute__((vector_size(16)));  // a lane-wise comparison of two Lanes

// Whether every lane of a comparison holds.
inline bool All(MaskLanes m) {
#if defined(__SSE__)
  return _mm_movemask_ps(reinterpret_cast<__m128>(m)) == 0xf;
#else
  return (m[0] & m[1] & m[2] & m[3]) != 0;
#endif
}
static_assert(offsetof(SplitItem, box) == 0 && sizeof(SplitItem) >= offsetof(Box3f, max) + sizeof(Lanes));

struct Cut {
  int axis = -1;
  float pos = 0;
  double gain = 0;
};

// A cell's index is also its SplitNode's index in `out` (both are made together, root first).
struct Cell {
  // [side]: extremes of its items' boxes (MinLanes, MaxLanes), not clipped to the region: BestCut only
  // takes cuts strictly inside the region, where clipped and unclipped extremes compare alike.
  Lanes lo_of[2], hi_of[2];
  Box3f region;
  double volume = 0;  // CostModel::Volume(region), asked for by every BestCut and every free item meeting it
  // Its resolved items (those whose clipped box meets the closed region), by side: side s in
  // pool[begin[s], end[s]). Free items join the leaves they meet as they are placed.
  uint32_t begin[2] = {0, 0}, end[2] = {0, 0};
  Cut cut;  // its best cut, from the last Refine that considered it

  bool has(int side) const { return end[side] > begin[side]; }
  uint8_t label() const { return static_cast<uint8_t>((has(0) ? kLeftBit : 0) | (has(1) ? kRightBit : 0)); }
};

// Routing cost model: a point of Q in a cell is sent to popcount(label) children. A cell's cost is its
// share of Q's volume times that count; a cut's gain is how much it lowers the cost. (Axes along which Q
// is flat are left out of the volume, so flat regions still compare by area.)
class CostModel {
 public:
  explicit CostModel(const Box3f& q) {
    for (int u = 0; u < 3; ++u)
      inv_extent_[u] = q.max[u] > q.min[u] ? 1.0 / (double{q.max[u]} - q.min[u]) : 0;
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

typedef int IntLanes __attribute__((vector_size(16)));

// The float neighbours of each lane, below and above (std::nextafter without the library call and without
// branches). An infinite lane gives a finite neighbour, which BestCut's tests then reject.
inline Lanes NextDownLanes(Lanes x) {
  const IntLanes u = reinterpret_cast<IntLanes>(x);
  const IntLanes moved = u + (x > 0) - (x < 0);  // (a true comparison is -1)
  const IntLanes zero = x == 0;
  return reinterpret_cast<Lanes>(
      (zero & IntLanes{INT32_MIN | 1, INT32_MIN | 1, INT32_MIN | 1, INT32_MIN | 1}) | (~zero & moved));
}
inline Lanes NextUpLanes(Lanes x) {
  const IntLanes u = reinterpret_cast<IntLanes>(x);
  const IntLanes moved = u - (x > 0) + (x < 0);
  const IntLanes zero = x == 0;
  return reinterpret_cast<Lanes>((zero & IntLanes{1, 1, 1, 1}) | (~zero & moved));
}

// Bits 0-2: which of lanes 0-2 of a comparison hold.
inline uint32_t LaneBits(IntLanes m) {
#if defined(__SSE__)
  return static_cast<uint32_t>(_mm_movemask_ps(reinterpret_cast<__m128>(m))) & 7;
#else
  return (m[0] != 0) | (m[1] != 0) << 1 | (m[2] != 0) << 2;
#endif
}

// The best cut of a cell: the label of the part below a cut c has L iff some L item has min <= c, and
// the part above has L iff some L item has max >= c, so the cost only changes just past the extremes of
// each side's items; the candidates are the floats just outside them: per axis u and side s, just below
// its items' least min and just above their greatest max (in that order; the first of the best gains
// wins). Which candidates lie inside the region is tested on all axes at once (those tests were the
// cost: a cell has about 2 of its 12), and only those are evaluated.
Cut BestCut(const Cell& cell) {
  Cut best;
  const double vol = cell.volume;
  const int cost_now = cell.has(0) + cell.has(1);
  if (vol <= 0 || cost_now == 0) return best;
  const double cost = cost_now;
  const Lanes lo = MinLanes(cell.region), hi = MaxToMinLanes(MaxLanes(cell.region));
  const IntLanes axis_ok = lo < hi;
  // A side without items has lo_of = kInf (never <= a cut inside the region); `top` gives it -kInf
  // (never >= a cut) whatever its hi_of.
  constexpr Lanes kInfLanes = {kInf, kInf, kInf, kInf};
  const Lanes lo_of[2] = {cell.lo_of[0], cell.lo_of[1]};
  Lanes top[2];
  for (int s = 0; s < 2; ++s) {
    const IntLanes none = lo_of[s] == kInfLanes;
    top[s] = reinterpret_cast<Lanes>((none & reinterpret_cast<IntLanes>(-kInfLanes)) |
                                     (~none & reinterpret_cast<IntLanes>(MaxToMinLanes(cell.hi_of[s]))));
  }
  // Candidate k = 2 s + (0: below lo_of[s], 1: above top[s]), lane u. A float just below lo_of can only
  // lie in (lo, hi) if lo_of is in (lo, hi], one just above top only if top is in [lo, hi).
  Lanes cand[4];
  uint32_t valid = 0;
  for (int s = 0; s < 2; ++s) {
    cand[2 * s] = NextDownLanes(lo_of[s]);
    cand[2 * s + 1] = NextUpLanes(top[s]);
    valid |= LaneBits(axis_ok & (lo_of[s] > lo) & (lo_of[s] <= hi) & (cand[2 * s] > lo)) << (8 * s);
    valid |= LaneBits(axis_ok & (top[s] >= lo) & (top[s] < hi) & (cand[2 * s + 1] < hi)) << (8 * s + 4);
  }
  double best_gain = 0;
  int best_order = -1;  // u * 4 + k of the best: the order of the candidates
  for (; valid != 0; valid &= valid - 1) {
    const int bit = std::countr_zero(valid), k = bit >> 2, u = bit & 3;
    const float c = cand[k][u];
    const int below = (lo_of[0][u] <= c) + (lo_of[1][u] <= c);
    const int above = (top[0][u] >= c) + (top[1][u] >= c);
    const double lo_d = lo[u];
    const double f = (double{c} - lo_d) / (double{hi[u]} - lo_d);
    const double gain = vol * (cost - (f * below + (1 - f) * above));
    const int order = 4 * u + k;
    if (gain > best_gain || (gain == best_gain && order < best_order)) {
      best_gain = gain;
      best_order = order;
      best = Cut{u, c, gain};
    }
  }
  return best;
}

// The last leaf that a free item met alone, and a box that a box with min <= max strictly inside meets
// that leaf alone (each cut on the way to the leaf sends the walk to its side only), so that it need not
// walk: the bounds of the leaf's region that are cuts (Q's bounds are none: no walk tests them), as
// (MinLanes, MaxLanes). Consecutive items often meet the same leaf alone.
struct LoneLeaf {
  uint32_t cell = 0;
  // (None yet: lanes 0-2 of lo are kInf. Lane 3 of lo and lane 0 of hi, which are no bounds, never fail
  // the test.)
  Lanes lo = {kInf, kInf, kInf, -kInf}, hi = {kInf, -kInf, -kInf, -kInf};

  bool Holds(const Box3f& b) const { return All((lo < MinLanes(b)) & (MaxLanes(b) < hi)); }
  // Leaf `c` of region r, in the SplitTree of region q.
  void Set(uint32_t c, const Box3f& r, const Box3f& q) {
    cell = c;
    float l[4], h[4];
    for (int u = 0; u < 3; ++u) {
      l[u] = r.min[u] == q.min[u] ? -kInf : r.min[u];
      h[u + kMaxLane] = r.max[u] == q.max[u] ? kInf : r.max[u];
    }
    l[3] = -kInf;
    h[0] = kInf;
    std::memcpy(&lo, l, sizeof l);
    std::memcpy(&hi, h, sizeof h);
  }
};

// The side free item `it` takes: the one that adds the least cost (added[s]: volume of the cells met that
// would gain side s), ties to its default side; a move from the default side only within the balance
// window, which it then updates.
uint8_t ChooseSide(const SplitItem& it, const double added[2], BalanceWindow* window) {
  uint8_t want = it.default_side;
  if (added[0] != added[1]) want = added[0] < added[1] ? SplitItem::kLeft : SplitItem::kRight;
  if (want == it.default_side) return want;
  const bool to_left = want == SplitItem::kLeft;
  const int64_t left_after = window->left + (to_left ? 1 : -1);
  const uint64_t bytes_after = to_left ? window->left_bytes + it.bytes : window->left_bytes - it.bytes;
  if (!window->Allows(left_after, bytes_after)) return it.default_side;
  window->left = left_after;
  window->left_bytes = bytes_after;
  return want;
}

}  // namespace

// Buffers one SplitTree build leaves behind for the next (no allocation per cell or per tree).
struct SplitTreeScratch::Buffers {
  std::vector<Cell> cells;           // cells[0, out.size()) are the tree's (never shrunk)
  std::unique_ptr<uint32_t[]> pool;  // the cells' item lists, each a range (see Builder::Take)
  size_t pool_size = 0;
  std::vector<uint32_t> stack, met;
  std::vector<uint8_t> changed;                   // per cell: ResolveFree gave it an item
  std::vector<std::pair<double, uint32_t>> open;  // heap of (gain, cell)
};

SplitTreeScratch::SplitTreeScratch() : buffers(std::make_unique<Buffers>()) {}
SplitTreeScratch::~SplitTreeScratch() = default;
void SplitTreeScratch::Release() { buffers = std::make_unique<Buffers>(); }

namespace {

// A cell's lists hold the resolved items meeting it, so its label and extremes are those of its lists.
// Free items stay out of the cells during the first Refine (they would neither label nor bound one) and
// join the leaves they meet when ResolveFree places them.
class Builder {
 public:
  Builder(const Box3f& q, std::span<SplitItem> items, uint32_t budget, std::vector<SplitNode>* out,
          SplitTreeScratch::Buffers* b)
      : items_(items), budget_(budget), out_(*out), cm_(q), b_(*b) {
    out_.clear();
    out_.reserve(std::min<uint32_t>(budget_, kOutReserve));
    // The root's lists: the fixed items, LEFT up from the block's start and RIGHT down from its end (each
    // item is written to both and kept by advancing: the two never pass each other, and where they meet
    // both write the same item), then RIGHT turned to item order.
    const uint32_t n = static_cast<uint32_t>(items_.size());
    const uint32_t at = Take(n);
    uint32_t* block = b_.pool.get() + at;
    size_t nl = 0, nr = 0;  // (64-bit: no zero-extensions)
    // (Also checks min <= max on every axis of every box, as (min[0..2], max[0]) <= (max[0..2], side..),
    // lanes 0-2: see valid_.)
    MaskLanes ok = {-1, -1, -1, -1};
    const SplitItem* const item = items_.data();
    for (size_t i = 0; i < n; ++i) {
      const uint8_t side = item[i].side;
      block[nl] = static_cast<uint32_t>(i);
      nl += side == SplitItem::kLeft;
      block[n - 1 - nr] = static_cast<uint32_t>(i);
      nr += side == SplitItem::kRight;
      Lanes mn, mx;
      const char* p = reinterpret_cast<const char*>(&item[i]);
      std::memcpy(&mn, p, sizeof mn);
      std::memcpy(&mx, p + offsetof(Box3f, max), sizeof mx);
      ok &= mn <= mx;
    }
    valid_ = (ok[0] & ok[1] & ok[2]) != 0;
    std::reverse(block + n - nr, block + n);
    free_count_ = static_cast<uint32_t>(n - nl - nr);
    Cell root;
    root.region = q;
    root.volume = cm_.Volume(q);
    root.begin[0] = at;
    root.end[0] = static_cast<uint32_t>(at + nl);
    root.begin[1] = static_cast<uint32_t>(at + n - nr);
    root.end[1] = at + n;
    ComputeExtremes(&root, 0);
    ComputeExtremes(&root, 1);
    if (b_.cells.empty()) b_.cells.resize(1);
    b_.cells[0] = root;
    out_.push_back(SplitNode{});
  }

  // Best-first: cut the cell with the largest gain until the budget is spent or no cut gains at least
  // `min_gain` (a share of Q's volume): small gains are not worth 32 bytes of RAM per cut.
  // `again`: the leaves already have their best cuts, from the last Refine, except those in b_.changed
  // (ResolveFree), so only those are asked for theirs again.
  void Refine(uint32_t node_limit, double min_gain, bool again) {
    node_limit = std::min(node_limit, budget_);
    std::vector<std::pair<double, uint32_t>>& open = b_.open;
    open.clear();
    auto push = [&](uint32_t ci) {
      const Cell& c = b_.cells[ci];
      if (c.cut.axis >= 0 && c.cut.gain >= min_gain) {
        open.push_back({c.cut.gain, ci});
        std::push_heap(open.begin(), open.end());
      }
    };
    auto consider = [&](uint32_t ci) {
      b_.cells[ci].cut = BestCut(b_.cells[ci]);
      push(ci);
    };
    // (The heap pops by (gain, cell), so the order in which cells are considered does not matter.)
    const bool any_changed = again && free_count_ > 0;  // (b_.changed is set only then)
    for (uint32_t ci = 0; ci < out_.size(); ++ci) {
      if (!out_[ci].is_cell()) continue;
      const bool stale = !again || (any_changed && b_.changed[ci]);
      if (stale) {
        consider(ci);
      } else {
        push(ci);
      }
    }
    while (!open.empty() && out_.size() + 2 <= node_limit) {
      std::pop_heap(open.begin(), open.end());
      const uint32_t ci = open.back().second;
      open.pop_back();
      const uint32_t lower = Split(ci);
      consider(lower);
      consider(lower + 1);
    }
  }

  // Free items take the side that adds the least cost (volume of cells that would gain that side), ties
  // to their default side, within the balance window. Each joins the leaves it meets as it is placed.
  void ResolveFree(BalanceWindow* window) {
    if (free_count_ == 0) return;
    CompactLeafLists();
    // A free item joins a leaf between its lists: LEFT grows up, RIGHT down (the walk makes room, see
    // Grow).
    unplaced_ = free_count_;
    b_.stack.resize(out_.size() + 1);
    b_.met.resize(out_.size());
    b_.changed.assign(out_.size(), 0);
    // (Local copies of the pointers and flags the loop reads: its byte stores, `changed` and the items'
    // sides, could alias the members, which the compiler would then read again after each.)
    uint8_t* const changed = b_.changed.data();
    uint32_t* const met = b_.met.data();
    uint32_t* const stack = b_.stack.data();
    Cell* const cell = b_.cells.data();
    const SplitNode* const nodes = out_.data();
    SplitItem* const items = items_.data();
    const uint32_t n_items = static_cast<uint32_t>(items_.size());
    const bool valid = valid_;  // (LoneLeaf holds for boxes with min <= max only)
    LoneLeaf alone;
    const Box3f& q = cell[0].region;
    for (uint32_t i = 0; i < n_items; ++i) {
      SplitItem& it = items[i];
      if (it.side != SplitItem::kFree) continue;
      double added[2] = {0, 0};
      uint32_t nm;
      if (valid && alone.Holds(it.box)) {
        met[0] = alone.cell;
        nm = 1;
        MeetLeaf(cell, alone.cell, added);
      } else {
        nm = CellsMeeting(it.box, cell, nodes, stack, met, added);
        if (valid && nm == 1) alone.Set(met[0], cell[met[0]].region, q);
      }
      --unplaced_;
      uint32_t* const pool = b_.pool.get();  // (MeetLeaf may have grown it)
      const uint8_t want = ChooseSide(it, added, window);
      it.side = want;
      const Lanes lo = MinLanes(it.box), hi = MaxLanes(it.box);
      for (uint32_t k = 0; k < nm; ++k) {
        changed[met[k]] = 1;
        Cell& c = cell[met[k]];
        pool[want == SplitItem::kLeft ? c.end[0]++ : --c.begin[1]] = i;
        c.lo_of[want] = Min(c.lo_of[want], lo);
        c.hi_of[want] = Max(c.hi_of[want], hi);
      }
    }
  }

  // Every leaf's label names the sides of the items in its lists: the invariant by construction.
  void WriteLabels() {
    for (uint32_t ci = 0; ci < out_.size(); ++ci)
      if (out_[ci].is_cell()) out_[ci].label = static_cast<CellLabel>(b_.cells[ci].label());
  }

 private:
  // Before ResolveFree: only the leaves' lists are still read; they move to the pool's start, in cell
  // order (which is pool order, so none is overwritten before it is read).
  void CompactLeafLists() {
    uint32_t* pool = b_.pool.get();
    used_ = 0;
    for (uint32_t ci = 0; ci < out_.size(); ++ci) {
      if (!out_[ci].is_cell()) continue;
      Cell& c = b_.cells[ci];
      for (int s = 0; s < 2; ++s) {
        const uint32_t n = c.end[s] - c.begin[s];
        std::memmove(pool + used_, pool + c.begin[s], n * sizeof *pool);
        c.begin[s] = used_;
        c.end[s] = used_ += n;
      }
    }
  }

  // Room for n more pool entries; returns where it starts. (The pool is never shrunk, and grows without
  // zero-filling: only the entries in use are copied, and only the pages written are resident.)
  uint32_t Take(uint32_t n) {
    const uint32_t at = used_;
    used_ += n;
    if (b_.pool_size < used_) {
      const size_t size = std::max<size_t>(used_, 2 * b_.pool_size);
      std::unique_ptr<uint32_t[]> pool = std::make_unique_for_overwrite<uint32_t[]>(size);
      std::copy(b_.pool.get(), b_.pool.get() + at, pool.get());
      b_.pool = std::move(pool);
      b_.pool_size = size;
    }
    return at;
  }

  // Gives leaf ci room between its lists: its block doubles (but no more than the unplaced free items can
  // fill), in place if it is the pool's last block (only RIGHT moves up), else as a new block at the end
  // (the old one is left unused), so the pool holds O(entries) for it. (Leaves start with no room.)
  [[gnu::noinline]] void Grow(uint32_t ci) {
    Cell& c = b_.cells[ci];
    const uint32_t nl = c.end[0] - c.begin[0], nr = c.end[1] - c.begin[1];
    const uint32_t room = std::min(unplaced_, std::max(nl + nr, kMinRoom));
    if (c.end[1] == used_) {
      Take(room);
      uint32_t* pool = b_.pool.get();
      std::copy_backward(pool + c.begin[1], pool + c.end[1], pool + c.end[1] + room);
      c.begin[1] += room;
      c.end[1] += room;
      return;
    }
    const uint32_t at = Take(nl + room + nr);
    uint32_t* pool = b_.pool.get();
    std::copy(pool + c.begin[0], pool + c.end[0], pool + at);
    std::copy(pool + c.begin[1], pool + c.end[1], pool + at + nl + room);
    c.begin[0] = at;
    c.end[0] = at + nl;
    c.begin[1] = at + nl + room;
    c.end[1] = c.begin[1] + nr;
  }

  void ComputeExtremes(Cell* c, int s) const {
    const uint32_t* pool = b_.pool.get();
    LanesUnion u;
    const SplitItem* const items = items_.data();
    for (size_t k = c->begin[s], end = c->end[s]; k < end; ++k) u.Add(items[pool[k]].box);
    c->lo_of[s] = u.lo;
    c->hi_of[s] = u.hi;
  }

  // Cuts cell ci at its cut; returns the lower child (the upper one follows it).
  uint32_t Split(uint32_t ci) {
    const uint32_t first = static_cast<uint32_t>(out_.size());
    if (b_.cells.size() < first + 2) b_.cells.resize(std::max<size_t>(first + 2, 2 * b_.cells.size()));
    // (Every field of the children is set here but `cut`, which the next BestCut sets before it is read.)
    const Cell& parent = b_.cells[ci];
    Cell& lower = b_.cells[first];
    Cell& upper = b_.cells[first + 1];
    const int axis = parent.cut.axis;
    const float pos = parent.cut.pos;
    lower.region = upper.region = parent.region;
    lower.region.max[axis] = pos;
    upper.region.min[axis] = pos;
    // Each item is written to both children's lists and kept by advancing (the tests are hard to
    // predict). Closed cells: an item touching the cut meets both.
    const uint32_t n = parent.end[0] - parent.begin[0] + parent.end[1] - parent.begin[1];
    const uint32_t at = Take(2 * n);
    uint32_t* pool = b_.pool.get();
    uint32_t* to_lower = pool + at;
    uint32_t* to_upper = to_lower + n;
    size_t nl = 0, nu = 0;
    for (int s = 0; s < 2; ++s) {
      const size_t nl0 = nl, nu0 = nu;
      lower.begin[s] = static_cast<uint32_t>(at + nl);
      upper.begin[s] = static_cast<uint32_t>(at + n + nu);
      const uint32_t* from = pool + parent.begin[s];
      const uint32_t* const to = pool + parent.end[s];
      const size_t ns = static_cast<size_t>(to - from);
      // A side whose items all lie on one side of the cut (as the side that gave the cut does) moves
      // whole: with every box valid (min <= max), min >= lo_of > pos puts each in the upper child only,
      // max <= hi_of < pos in the lower one only. The child it moves to has the same set, so the same
      // extremes (up to the sign of a zero, which no test and no NextDownLanes / NextUpLanes tells apart).
      if (valid_ && parent.lo_of[s][axis] > pos) {
        std::memcpy(to_upper + nu, from, ns * sizeof *from);
        nu += ns;
      } else if (valid_ && parent.hi_of[s][axis + kMaxLane] < pos) {
        std::memcpy(to_lower + nl, from, ns * sizeof *from);
        nl += ns;
      } else {
        for (; from < to; ++from) {
          const uint32_t i = *from;
          const Box3f& b = items_[i].box;
          to_lower[nl] = i;
          nl += b.min[axis] <= pos;
          to_upper[nu] = i;
          nu += b.max[axis] >= pos;
        }
      }
      lower.end[s] = static_cast<uint32_t>(at + nl);
      upper.end[s] = static_cast<uint32_t>(at + n + nu);
      if (nl - nl0 == ns) {
        lower.lo_of[s] = parent.lo_of[s];
        lower.hi_of[s] = parent.hi_of[s];
      } else {
        ComputeExtremes(&lower, s);
      }
      if (nu - nu0 == ns) {
        upper.lo_of[s] = parent.lo_of[s];
        upper.hi_of[s] = parent.hi_of[s];
      } else {
        ComputeExtremes(&upper, s);
      }
    }
    lower.volume = cm_.Volume(lower.region);
    upper.volume = cm_.Volume(upper.region);
    SplitNode& sn = out_[ci];
    sn.axis = static_cast<uint8_t>(axis);
    sn.cut = pos;
    sn.child[0] = first;
    sn.child[1] = first + 1;
    out_.push_back(SplitNode{});
    out_.push_back(SplitNode{});
    return first;
  }

  // Box b meets leaf n: gives it room for one more free item, adds its volume to added[s] if it has no
  // item of side s yet.
  void MeetLeaf(const Cell* cells, uint32_t n, double added[2]) {
    const Cell& c = cells[n];
    if (c.end[0] == c.begin[1]) Grow(n);
    if (!c.has(0)) added[0] += c.volume;
    if (!c.has(1)) added[1] += c.volume;
  }

  // The leaves meeting box b into met, in tree order (lower child first); returns how many. Adds to
  // added[s] the volume of each that has no item of side s yet, in that order. Each leaf met is given room
  // for one more free item.
  uint32_t CellsMeeting(const Box3f& b, const Cell* cells, const SplitNode* nodes, uint32_t* stack,
                        uint32_t* met, double added[2]) {
    // Down the one child a box meets without the stack (most boxes meet one leaf); the upper child is
    // stacked only when the box meets both.
    size_t depth = 0, nm = 0;  // (64-bit: no zero-extensions)
    uint32_t n = 0;
    for (;;) {
      const SplitNode& sn = nodes[n];
      if (sn.is_cell()) {
        met[nm++] = n;
        MeetLeaf(cells, n, added);
      } else {
        const bool lower = b.min[sn.axis] <= sn.cut, upper = b.max[sn.axis] >= sn.cut;
        if (lower | upper) {  // (neither: a NaN box, which meets no cell below)
          if (lower & upper) stack[depth++] = sn.child[1];
          n = lower ? sn.child[0] : sn.child[1];
          continue;
        }
      }
      if (depth == 0) break;
      n = stack[--depth];
    }
    return static_cast<uint32_t>(nm);
  }

  std::span<SplitItem> items_;
  uint32_t budget_;
  std::vector<SplitNode>& out_;
  CostModel cm_;
  SplitTreeScratch::Buffers& b_;
  uint32_t used_ = 0;  // pool entries in use
  uint32_t free_count_ = 0;
  uint32_t unplaced_ = 0;  // free items not yet given a side (ResolveFree)
  bool valid_ = false;     // every item's box has min <= max on every axis (no NaN)
};

}  // namespace

void BuildSplitTree(const Box3f& q, std::span<SplitItem> items, uint32_t budget, BalanceWindow* window,
                    std::vector<SplitNode>* out, double min_gain, SplitTreeScratch* scratch) {
  Builder b(q, items, std::max<uint32_t>(budget, 1), out, scratch->buffers.get());
  // First carve with the fixed items alone, then place the free items against those cells, then spend
  // what is left of the budget with every item placed.
  b.Refine(std::max<uint32_t>(1, budget / 2) | 1, min_gain, /*again=*/false);
  b.ResolveFree(window);
  b.Refine(budget, min_gain, /*again=*/true);
  b.WriteLabels();
}

}  // namespace mktree
