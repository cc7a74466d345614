#include "engine/tree/split_choice.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace mktree::build {
namespace {

// Cuts per block of the pruned candidate scan (ScanKeys).
constexpr uint32_t kPruneBlock = 64;

// First index i >= from with arr[i] > x (upper) or arr[i] >= x (lower), by galloping forward: arr is
// sorted and arr[n] = +inf stops it; the answer is known to be >= from.
template <bool kUpper>
uint32_t Gallop(const float* arr, uint32_t n, uint32_t from, float x) {
  auto before = [x](float v) { return kUpper ? v <= x : v < x; };
  uint32_t lo = from, hi = from, step = 1;
  while (before(arr[hi])) {  // stops at the sentinel arr[n] at the latest
    lo = hi + 1;
    hi = std::min(n, hi + step);
    step <<= 1;
  }
  const float* r = kUpper ? std::upper_bound(arr + lo, arr + hi, x) : std::lower_bound(arr + lo, arr + hi, x);
  return static_cast<uint32_t>(r - arr);
}

// The cursors of a walk over the cuts in increasing order: pa = #(max_w <= a) in the sorted max_w, pb =
// #(min_w < b) in the sorted min_w; `placed` once they hold the counts of a cut.
struct SmCursors {
  uint32_t pa = 0, pb = 0;
  bool placed = false;
};

// |Sm| = pb - pa of the cut with planes a, b (0 when a >= b), the cursors walking on from where they are.
inline uint32_t SmWalking(const float* smin, const float* smax, uint32_t n, float a, float b, SmCursors& c) {
  if (!(a < b)) return 0;
  if (!c.placed) {  // first use: a binary search instead of walking past the first ~k_lo objects
    c.pa = static_cast<uint32_t>(std::upper_bound(smax, smax + n, a) - smax);
    c.pb = static_cast<uint32_t>(std::lower_bound(smin, smin + n, b) - smin);
    c.placed = true;
  }
  // The cursors mostly move by 0-2 a step: two branch-free moves, then a loop that rarely runs (+inf
  // sentinels at [n] stop them).
  uint32_t pa = c.pa, pb = c.pb;
  pa += smax[pa] <= a;
  pa += smax[pa] <= a;
  while (smax[pa] <= a) ++pa;
  pb += smin[pb] < b;
  pb += smin[pb] < b;
  while (smin[pb] < b) ++pb;
  c.pa = pa;
  c.pb = pb;
  return pb - pa;
}

// As SmWalking, the cursors galloping: near the leaves, where only a few cuts need |Sm|.
inline uint32_t SmGalloping(const float* smin, const float* smax, uint32_t n, float a, float b,
                            SmCursors& c) {
  if (!(a < b)) return 0;
  c.pa = Gallop<true>(smax, n, c.pa, a);
  c.pb = Gallop<false>(smin, n, c.pb, b);
  return c.pb - c.pa;
}

// The planes of cut k along the order of key kKey (GatherAxis done): a(k) = min over Sn2 of min_w (key
// 0: the k-th min_w), b(k) = max over Sn1 of max_w (key 1: the (k-1)-th max_w).
template <int kKey>
struct CutPlanes {
  const float* smin;  // sorted min_w, +inf at [n]
  const float* smax;  // sorted max_w, +inf at [n]
  const float* pmax;  // [k - base]: max of max_w over the first k objects in min_w order
  const float* smn;   // [k - base]: min of min_w over objects k..n-1 in max_w order
  uint32_t base;
  float a(uint32_t k) const { return kKey == 0 ? smin[k] : smn[k - base]; }
  float b(uint32_t k) const { return kKey == 0 ? pmax[k - base] : smax[k - 1]; }
};

// Runs eval(k_begin, k_end, cursors) over the cuts [k_first, k_last]: at once, or when `prunable` and
// there are enough cuts, block by block (see ScanKeys). The block ends are p_j = k_first + j * kPruneBlock
// (j < blocks) and p_blocks = k_last; their counts go to block_pa, block_pb, and *bound is lowered to the
// exact |Sm| key of those cuts before any block is scanned. eval may lower *bound.
template <int kKey, typename Eval>
void ScanBlocks(const CutPlanes<kKey>& planes, uint32_t n, uint32_t k_first, uint32_t k_last, bool prunable,
                Scratch<uint32_t>* block_pa, Scratch<uint32_t>* block_pb, uint64_t* bound, Eval&& eval) {
  const uint32_t cuts = k_last - k_first + 1;
  if (!prunable || cuts < 2 * kPruneBlock) {
    eval(k_first, k_last, SmCursors{});
    return;
  }
  const uint32_t blocks = (cuts + kPruneBlock - 1) / kPruneBlock;
  block_pa->Fit(blocks + 1);
  block_pb->Fit(blocks + 1);
  uint32_t pa = 0, pb = 0;
  for (uint32_t j = 0; j <= blocks; ++j) {
    const uint32_t p = j < blocks ? k_first + j * kPruneBlock : k_last;
    pa = Gallop<true>(planes.smax, n, pa, planes.a(p));
    pb = Gallop<false>(planes.smin, n, pb, planes.b(p));
    (*block_pa)[j] = pa;
    (*block_pb)[j] = pb;
    if (pb > pa)
      *bound = std::min(*bound, uint64_t{pb - pa} << 32);
    else
      *bound = 0;  // a cut with |Sm| = 0: only such cuts can tie
  }
  for (uint32_t j = 0; j < blocks; ++j) {
    const uint32_t p = k_first + j * kPruneBlock;
    const uint32_t q = j + 1 < blocks ? p + kPruneBlock - 1 : k_last;
    const uint32_t lower = (*block_pb)[j] > (*block_pa)[j + 1] ? (*block_pb)[j] - (*block_pa)[j + 1] : 0;
    if ((uint64_t{lower} << 32) > *bound) continue;
    eval(p, q, SmCursors{(*block_pa)[j], (*block_pb)[j], true});
  }
}

// kTies: counts a cut whose key is tie_key towards the list's best; true when it is a new best (the
// caller then makes its Candidate: most cuts are not).
inline bool Tally(ListTies* lt, uint64_t tie_key, uint32_t k) {
  if (lt->count == 0 || tie_key < lt->key) {
    lt->key = tie_key;
    lt->count = 1;
    lt->k_min = lt->k_max = k;
    return true;
  }
  if (tie_key == lt->key) {
    ++lt->count;
    lt->k_max = k;
  }
  return false;
}

}  // namespace

CutRange BalancedCuts(uint32_t n, uint32_t depth, double balance_r) {
  const double r = depth >= kDepthGuard ? std::max(balance_r, kGuardBalance) : balance_r;
  int64_t k_lo = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(r * n - 1e-9)));
  int64_t k_hi = std::min<int64_t>(n - 1, static_cast<int64_t>(std::floor((1 - r) * n + 1e-9)));
  if (k_lo > k_hi) k_lo = k_hi = std::clamp<int64_t>(n / 2, 1, n - 1);  // r near 0.5 and tiny n
  return CutRange{static_cast<uint32_t>(k_lo), static_cast<uint32_t>(k_hi)};
}

void SplitChooser::ShrinkScratch(size_t n) {
  for (auto* v : {&sorted_min_, &prefix_max_, &sorted_max_, &suffix_min_, &margin_pre_, &margin_suf_})
    if (v->capacity() > n + 1) v->Reset(n + 1);
  for (int slot = 0; slot < 2; ++slot)
    if (window_[slot].capacity() > n) window_[slot].Reset(n), held_[slot] = -1;
}

Candidate SplitChooser::Choose(const Task& t, CutRange cuts) {
  const BuildTuning& tu = s_.tuning;
  Ranking ranking;
  ranking.fill_aware = tu.fill_aware && Pages(t.bytes) <= tu.fill_aware_pages;
  const bool compact = tu.split_policy == SplitPolicy::kCompact;
  bool axis_ok[3] = {true, true, true};
  if (compact) CompactAxes(t, axis_ok);
  // First pass: the minimal |Sm|, to know which candidates are within the slack (no need when the
  // slack admits every candidate, as by default).
  if (ranking.fill_aware && tu.fill_sm_slack < t.hi - t.lo) ranking.sm_min = LeastSm(t, cuts, axis_ok);
  if (!compact) return ChooseSoa(t, cuts, ranking, axis_ok);
  // Near the leaves every |Sm| is within the fill slack (by default): the key is the page waste, then
  // the margin, and nearly every list ties on the waste, so the margins are computed with it.
  const double slack = tu.fill_sm_slack + tu.fill_sm_slack_rel * ranking.sm_min;
  if (ranking.fill_aware && ranking.sm_min + slack >= t.hi - t.lo) {
    Candidate best;
    for (int w = 0; w < 3; ++w)
      if (axis_ok[w]) ScanWasteMargins(t, w, cuts, &best);
    return best;
  }
  return ChooseCompact(t, cuts, ranking, axis_ok);
}

uint32_t SplitChooser::LeastSm(const Task& t, CutRange cuts, const bool axis_ok[3]) {
  ScanOutcome out;
  for (int w = 0; w < 3; ++w) {
    if (!axis_ok[w]) continue;
    GatherAxis(t, w, cuts);
    ScanKeys(t, ScanRequest(ScanMode::kLeastSm, w, cuts), &out);
  }
  return out.sm_min;
}

// kSoa: every candidate ranked by BetterThan (no margins).
Candidate SplitChooser::ChooseSoa(const Task& t, CutRange cuts, const Ranking& ranking,
                                  const bool axis_ok[3]) {
  ScanOutcome out;
  for (int w = 0; w < 3; ++w) {
    if (!axis_ok[w]) continue;
    GatherAxis(t, w, cuts);
    ScanRequest req(ScanMode::kBest, w, cuts, ranking);
    if (out.best.list >= 0) req.bound = uint64_t{out.best.primary} << 32 | out.best.waste;
    ScanKeys(t, req, &out);
  }
  return out.best;
}

// Evaluates the candidates of both keys of axis req.axis (GatherAxis done), as req.mode says. In O(n):
// along either order, a(k) and b(k) never decrease, so |Sm| = #(min_w < b) - #(max_w <= a) is counted with
// two cursors moving forward over the sorted min_w and max_w arrays.
// Pruning (kBest and kTies without fill_aware, where |Sm| ranks first): cut k's |Sm| is pb(k) - pa(k) (or
// 0), and both counts grow with k, so over a block of cuts [p, q] |Sm| >= pb(p) - pa(q). Both are found
// at every block's ends by galloping; a block whose bound exceeds the best key so far holds no candidate
// that wins or ties, and is skipped.
void SplitChooser::ScanKeys(const Task& t, const ScanRequest& req, ScanOutcome* out) {
  uint64_t bound = req.bound;  // lowered by the better cuts found, along both keys
  ScanKey<0>(t, req, &bound, out);
  ScanKey<1>(t, req, &bound, out);
}

// One key of ScanKeys, the key a constant: the cut loop reads a(k) and b(k) without a select.
template <int kKey>
void SplitChooser::ScanKey(const Task& t, const ScanRequest& req, uint64_t* bound_io, ScanOutcome* out) {
  const ScanMode mode = req.mode;
  const bool fill_aware = req.ranking.fill_aware;
  const uint32_t sm_min = req.ranking.sm_min;
  const uint32_t n = t.hi - t.lo;
  const double slack = s_.tuning.fill_sm_slack + s_.tuning.fill_sm_slack_rel * sm_min;
  // |Sm| ranks first (so a lower bound on it bounds the key) unless the fill slack zeroes it.
  const bool prunable = !fill_aware && (mode == ScanMode::kBest || mode == ScanMode::kTies);
  // Near the leaves with the default slack every |Sm| is within it: the key is the page waste alone.
  const bool sm_free = fill_aware && mode != ScanMode::kLeastSm && sm_min + slack >= n;
  const bool tied_only = mode == ScanMode::kTiedMargins;  // the second kCompact pass: the tied cuts only
  const ListTies& tied = req.tied[kKey];
  if (tied_only) {
    if (tied.count == 0 || tied.key != req.tie_key) return;
    PrefixSuffixMargins(t, 2 * req.axis + kKey, tied.k_min, tied.k_max);
  }
  const uint32_t k_first = tied_only ? tied.k_min : req.cuts.k_lo;
  const uint32_t k_last = tied_only ? tied.k_max : req.cuts.k_hi;
  const int list = 2 * req.axis + kKey;
  // (Locals, not members or the request's fields, which the outcome's counters could alias.)
  const CutPlanes<kKey> planes{sorted_min_.data(), sorted_max_.data(), prefix_max_.data(), suffix_min_.data(),
                               window_base_};
  const float* const smin = planes.smin;
  const float* const smax = planes.smax;
  const uint64_t tie_key_wanted = req.tie_key;
  uint64_t bound = *bound_io;
  // Bytes only near the leaves (PrefixSuffixMargins has loaded the list for the tied cuts).
  const uint32_t* const ord = fill_aware ? Range(t, list) : nullptr;
  const uint32_t* const bytes = bytes_.data();
  uint64_t left_bytes = 0;      // encoded bytes of the first k objects
  if (fill_aware && tied_only)  // the first pass's candidate at k_first has them
    left_bytes = tied.first.left_bytes - bytes[ord[k_first - 1]];
  else if (fill_aware)
    for (uint32_t i = 0; i + 1 < k_first; ++i) left_bytes += bytes[ord[i]];
  PageSplit pages(left_bytes, t.bytes, mem_page_);

  // Cuts [k_begin, k_end], the cursors at k_begin.
  auto eval = [&](uint32_t k_begin, uint32_t k_end, SmCursors cur) {
    for (size_t k = k_begin; k <= k_end; ++k) {  // (64-bit: no zero-extensions)
      // Bytes only matter near the leaves (and are a random read per object, so not gathered above).
      uint64_t waste_key = 0;
      if (fill_aware) {
        left_bytes += bytes[ord[k - 1]];
        waste_key = pages.Waste(left_bytes);
      }
      // With the waste alone as the key (kSoa near the leaves), only a cut that may win or tie matters.
      if (sm_free && waste_key > bound) continue;
      const float a = planes.a(k), b = planes.b(k);
      const uint32_t sm =
          sm_free ? SmGalloping(smin, smax, n, a, b, cur) : SmWalking(smin, smax, n, a, b, cur);
      if (mode == ScanMode::kLeastSm) {
        out->sm_min = std::min(out->sm_min, sm);
        continue;
      }
      uint32_t primary = sm, waste = 0;
      if (fill_aware) {
        if (sm <= sm_min + slack) primary = 0;
        waste = static_cast<uint32_t>(waste_key);
      }
      const uint64_t tie_key = uint64_t{primary} << 32 | waste;
      if (mode == ScanMode::kTies) {
        if (Tally(&out->ties[kKey], tie_key, k)) {
          out->ties[kKey].first = MakeCandidate(list, k, n, a, b, sm, primary, waste, left_bytes, fill_aware);
          bound = std::min(bound, tie_key);
        }
        continue;
      }
      if (tied_only && tie_key != tie_key_wanted) continue;
      Candidate c = MakeCandidate(list, k, n, a, b, sm, primary, waste, left_bytes, fill_aware);
      if (tied_only) c.margin = CutMargin(k, n);
      if (c.BetterThan(out->best)) {
        out->best = c;
        bound = std::min(bound, tie_key);
      }
    }
  };

  ScanBlocks(planes, n, k_first, k_last, prunable, &block_pa_, &block_pb_, &bound, eval);
  *bound_io = bound;
}

}  // namespace mktree::build
