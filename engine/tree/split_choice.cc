#include "engine/tree/split_choice.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <type_traits>

#include "engine/tree/box_lanes.h"

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

// |Sm| of the cut with planes a, b over the sorted min_w / max_w arrays, the counts pa, pb galloping on
// from where they are (cuts visited in increasing order): near the leaves, where only a few cuts need it.
uint32_t SmGalloping(const float* smin, const float* smax, uint32_t n, float a, float b, uint32_t& pa,
                     uint32_t& pb) {
  if (!(a < b)) return 0;
  pa = Gallop<true>(smax, n, pa, a);
  pb = Gallop<false>(smin, n, pb, b);
  return pb - pa;
}

// Page waste Pages(left) + Pages(total - left) - Pages(total) of cuts in increasing order of their left
// bytes, without a division per cut: the page counts only step where the bytes cross a page.
class PageSplit {
 public:
  PageSplit(uint64_t left, uint64_t total, uint64_t mem_page)
      : cap_(PagePayloadCapacity(mem_page)),
        left_pages_(PagesForLeaf(left, mem_page)),
        right_pages_(PagesForLeaf(total - left, mem_page)),
        total_pages_(PagesForLeaf(total, mem_page)) {
    // The left side takes another page once left > left_limit_; the right one gives one back once
    // left >= right_limit_ (never below one page).
    left_limit_ = left_pages_ * cap_ - kLeafHeaderBytes;
    right_limit_ = right_pages_ > 1 ? LeafPayloadBytes(total) - (right_pages_ - 1) * cap_
                                    : std::numeric_limits<uint64_t>::max();
  }
  uint64_t Waste(uint64_t left) {  // left never decreases from one call to the next
    while (left > left_limit_) ++left_pages_, left_limit_ += cap_;
    while (left >= right_limit_) {
      --right_pages_;
      right_limit_ = right_pages_ > 1 ? right_limit_ + cap_ : std::numeric_limits<uint64_t>::max();
    }
    return left_pages_ + right_pages_ - total_pages_;
  }

 private:
  uint64_t cap_, left_pages_, right_pages_, total_pages_, left_limit_, right_limit_;
};

Candidate MakeCandidate(int list, uint32_t k, uint32_t n, float a, float b, uint32_t sm, uint32_t primary,
                        uint32_t waste, uint64_t left_bytes, bool fill_aware) {
  Candidate c;
  c.list = list;
  c.k = k;
  c.a = a;
  c.b = b;
  c.sm = sm;
  c.primary = primary;
  c.waste = waste;
  c.slab = std::max(0.0, double{b} - double{a});
  c.imbalance = static_cast<uint32_t>(std::abs(2 * int64_t{k} - int64_t{n}));
  c.left_bytes = left_bytes;
  c.fill_aware = fill_aware;
  return c;
}

}  // namespace

CutRange BalancedCuts(uint32_t n, uint32_t depth, double balance_r) {
  const double r = depth >= kDepthGuard ? std::max(balance_r, kGuardBalance) : balance_r;
  int64_t k_lo = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(r * n - 1e-9)));
  int64_t k_hi = std::min<int64_t>(n - 1, static_cast<int64_t>(std::floor((1 - r) * n + 1e-9)));
  if (k_lo > k_hi) k_lo = k_hi = std::clamp<int64_t>(n / 2, 1, n - 1);  // r near 0.5 and tiny n
  return CutRange{static_cast<uint32_t>(k_lo), static_cast<uint32_t>(k_hi)};
}

Candidate SplitChooser::Choose(const Task& t, CutRange cuts) { return ChooseSplit(t, cuts.k_lo, cuts.k_hi); }

void SplitChooser::ShrinkScratch(size_t n) {
  for (auto* v : {&sorted_min_, &prefix_max_, &sorted_max_, &suffix_min_, &margin_pre_, &margin_suf_})
    if (v->capacity() > n + 1) v->Reset(n + 1);
}

Candidate SplitChooser::ChooseSplit(const Task& t, uint32_t k_lo, uint32_t k_hi) {
  const BuildTuning& tu = s_.tuning;
  const uint64_t pages = Pages(t.bytes);
  Mode m;
  m.fill_aware = tu.fill_aware && pages <= tu.fill_aware_pages;
  m.compact = tu.split_policy == SplitPolicy::kCompact;
  bool axis_ok[3] = {true, true, true};
  if (m.compact) CompactAxes(t, axis_ok);
  Candidate best;
  // First pass: the minimal |Sm|, to know which candidates are within the slack (no need when the
  // slack admits every candidate, as by default).
  if (m.fill_aware && tu.fill_sm_slack < t.hi - t.lo) {
    uint32_t sm_min = std::numeric_limits<uint32_t>::max();
    Mode first;
    for (int w = 0; w < 3; ++w)
      if (axis_ok[w]) Sweep(t, w, k_lo, k_hi, first, &best, &sm_min);
    m.sm_min = sm_min;
    best = Candidate();
  }
  if (!m.compact) {
    for (int w = 0; w < 3; ++w)
      if (axis_ok[w]) Sweep(t, w, k_lo, k_hi, m, &best, nullptr);
    return best;
  }
  // Near the leaves every |Sm| is within the fill slack (by default): the key is the page waste, then
  // the margin, and nearly every list ties on the waste, so the margins are computed with it.
  const double slack = tu.fill_sm_slack + tu.fill_sm_slack_rel * m.sm_min;
  if (m.fill_aware && m.sm_min + slack >= t.hi - t.lo) {
    for (int w = 0; w < 3; ++w)
      if (axis_ok[w]) ScanWasteMargins(t, w, k_lo, k_hi, &best);
    return best;
  }
  // kCompact: the margin only breaks ties on (primary, waste). Per axis, while its keys are gathered:
  // per list, the best (primary, waste) and the range of k reaching it; margins are computed only for
  // the candidates that tie with the best so far, and not at all when one candidate alone is best. Same
  // choice as ranking every candidate with its margin: the others lose on (primary, waste) anyway, and
  // the tied ones are compared in the same order (list, then k).
  Mode plain = m;
  plain.compact = false;
  uint64_t top = std::numeric_limits<uint64_t>::max();
  bool lone = false;  // `best` is the only candidate reaching `top` so far; its margin is not computed
  for (int w = 0; w < 3; ++w) {
    if (!axis_ok[w]) continue;
    ListTies ties[2];
    GatherAxis(t, w, k_lo, k_hi);
    ScanKeys(t, w, k_lo, k_hi, plain, nullptr, nullptr, ties, nullptr, nullptr, top);
    uint64_t local = std::numeric_limits<uint64_t>::max();
    uint32_t count = 0;
    for (const ListTies& lt : ties)
      if (lt.count > 0) local = std::min(local, lt.key);
    for (const ListTies& lt : ties) count += lt.count > 0 && lt.key == local ? lt.count : 0;
    if (count == 0 || local > top) continue;
    if (local < top) {
      top = local;
      best = Candidate();
      lone = false;
      if (count == 1) {
        best = ties[0].count > 0 && ties[0].key == local ? ties[0].first : ties[1].first;
        lone = true;
        continue;
      }
    }
    if (lone) {
      best.margin = SplitMargin(t, best.list, best.k);
      lone = false;
    }
    ScanKeys(t, w, k_lo, k_hi, m, &best, nullptr, nullptr, &top, ties);
  }
  return best;
}

// kCompact near the leaves, when every |Sm| is within the fill slack (primary 0): the cuts of both keys
// of axis w ranked by page waste, then margin, then as BetterThan says. Per list the least (waste,
// margin) is found first, with no candidate built, and only the cuts reaching it are evaluated, in
// order: the same choice as evaluating every cut, as BetterThan ranks those two first.
void SplitChooser::ScanWasteMargins(const Task& t, int w, uint32_t k_lo, uint32_t k_hi, Candidate* best) {
  const uint32_t n = t.hi - t.lo;
  const uint32_t* const bytes = bytes_.data();
  for (int key = 0; key < 2; ++key) {
    const int list = 2 * w + key;
    const BuildVector<uint32_t>& order = s_.lists[list];
    PrefixSuffixMargins(t, order, k_lo, k_hi);
    const uint32_t* const ord = order.data() + t.lo;
    uint64_t sum = 0;  // encoded bytes of the first k objects
    for (uint32_t i = 0; i + 1 < k_lo; ++i) sum += bytes[ord[i]];
    const uint64_t sum_begin = sum;
    const PageSplit pages_begin(sum, t.bytes, mem_page_);
    PageSplit pages = pages_begin;
    uint64_t least_waste = std::numeric_limits<uint64_t>::max();
    float least_margin = std::numeric_limits<float>::infinity();
    size_t least_k = 0, least_count = 0;
    uint64_t least_sum = 0;
    for (size_t k = k_lo; k <= k_hi; ++k) {  // (64-bit: no zero-extensions)
      sum += bytes[ord[k - 1]];
      const uint64_t waste = pages.Waste(sum);
      if (waste > least_waste) continue;
      const float margin = CutMargin(static_cast<uint32_t>(k), n);
      if (waste < least_waste || margin < least_margin) {
        least_waste = waste, least_margin = margin, least_k = k, least_sum = sum, least_count = 1;
      } else {
        least_count += margin == least_margin;
      }
    }
    if (least_count == 0 || (best->list >= 0 && (least_waste > best->waste || (least_waste == best->waste &&
                                                                               least_margin > best->margin))))
      continue;
    // The cut's planes and |Sm| straight from the boxes: only about half of these lists get here, so the
    // keys are not gathered for them (as GatherAxis and ScanKeys would find them).
    const Box3f* const box = box_.data();
    auto evaluate = [&](size_t k, uint64_t left) {
      float a = std::numeric_limits<float>::infinity(), b = -std::numeric_limits<float>::infinity();
      if (key == 0) {  // a: the k-th object's min_w, b: the max of max_w before it
        a = box[ord[k]].min[w];
        for (size_t i = 0; i < k; ++i) b = std::max(b, box[ord[i]].max[w]);
      } else {  // b: the (k-1)-th object's max_w, a: the min of min_w from the k-th on
        b = box[ord[k - 1]].max[w];
        for (size_t i = k; i < n; ++i) a = std::min(a, box[ord[i]].min[w]);
      }
      uint32_t sm = 0;  // #(min_w < b) - #(max_w <= a)
      if (a < b)
        for (size_t i = 0; i < n; ++i) sm += (box[ord[i]].min[w] < b) - (box[ord[i]].max[w] <= a);
      const uint32_t k32 = static_cast<uint32_t>(k);
      Candidate c = MakeCandidate(list, k32, n, a, b, sm, 0, static_cast<uint32_t>(least_waste), left, true);
      c.margin = least_margin;
      if (c.BetterThan(*best)) *best = c;
    };
    if (least_count == 1) {
      evaluate(least_k, least_sum);
      continue;
    }
    sum = sum_begin;  // several cuts reach it: again, in order
    pages = pages_begin;
    for (size_t k = k_lo; k <= k_hi; ++k) {
      sum += bytes[ord[k - 1]];
      if (pages.Waste(sum) == least_waste && CutMargin(static_cast<uint32_t>(k), n) == least_margin)
        evaluate(k, sum);
    }
  }
}

// kCompact: the axes along which the objects spread at least compact_axis_ratio x the longest spread.
// Spread along w: the mean of the spreads of min_w and of max_w (the ends of the two sorted lists), so
// one long object does not make an axis look long.
void SplitChooser::CompactAxes(const Task& t, bool axis_ok[3]) const {
  double spread[3], longest = 0;
  for (int w = 0; w < 3; ++w) {
    const BuildVector<uint32_t>& by_min = s_.lists[2 * w];
    const BuildVector<uint32_t>& by_max = s_.lists[2 * w + 1];
    spread[w] = 0.5 * ((double{box_[by_min[t.hi - 1]].min[w]} - box_[by_min[t.lo]].min[w]) +
                       (double{box_[by_max[t.hi - 1]].max[w]} - box_[by_max[t.lo]].max[w]));
    longest = std::max(longest, spread[w]);
  }
  // The longest axis always stays (whatever the ratio), so there is a candidate.
  for (int w = 0; w < 3; ++w)
    axis_ok[w] = spread[w] == longest || spread[w] >= s_.tuning.compact_axis_ratio * longest;
}

// N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) of one candidate, as ScanKeys computes it.
float SplitChooser::SplitMargin(const Task& t, int list, uint32_t k) const {
  const BuildVector<uint32_t>& order = s_.lists[list];
  LanesUnion lo, hi;
  for (uint32_t i = t.lo; i < t.lo + k; ++i) lo.Add(box_[order[i]]);
  for (uint32_t i = t.lo + k; i < t.hi; ++i) hi.Add(box_[order[i]]);
  const uint32_t n = t.hi - t.lo;
  return static_cast<float>(static_cast<double>(k) * lo.Margin() + static_cast<double>(n - k) * hi.Margin());
}

// Gathers axis w and evaluates its candidates (kSoa, and kCompact's |Sm| first pass).
void SplitChooser::Sweep(const Task& t, int w, uint32_t k_lo, uint32_t k_hi, const Mode& m, Candidate* best,
                         uint32_t* sm_min_out) {
  GatherAxis(t, w, k_lo, k_hi);
  const uint64_t bound =
      best->list >= 0 ? uint64_t{best->primary} << 32 | best->waste : std::numeric_limits<uint64_t>::max();
  ScanKeys(t, w, k_lo, k_hi, m, best, sm_min_out, nullptr, nullptr, nullptr, bound);
}

// Evaluates the candidates of both keys of axis w (GatherAxis(t, w) done). In O(n): along either order,
// a(k) and b(k) never decrease, so |Sm| = #(min_w < b) - #(max_w <= a) is counted with two cursors
// moving forward over the sorted min_w and max_w arrays.
// ties (kCompact, margins not computed): per key, the candidates of best (primary, waste).
// only (kCompact): evaluate only the candidates whose (primary, waste) is *only, with their margins
// computed over the k ranges of tied[key].
// bound: a (primary, waste) key that the chosen candidate is known to reach; cuts that cannot reach it
// may be skipped (kSoa: the best so far; kCompact: `top`).
// Pruning (|Sm| ranks first): cut k's |Sm| is pb(k) - pa(k) (or 0), and both counts grow with k, so over
// a block of cuts [p, q] |Sm| >= pb(p) - pa(q). Both are found at every block's ends by galloping; a
// block whose bound exceeds the best key so far holds no candidate that wins or ties, and is skipped.
void SplitChooser::ScanKeys(const Task& t, int w, uint32_t k_lo, uint32_t k_hi, const Mode& m,
                            Candidate* best, uint32_t* sm_min_out, ListTies* ties, const uint64_t* only,
                            const ListTies* tied, uint64_t bound) {
  const bool fill_aware = m.fill_aware;
  const uint32_t n = t.hi - t.lo;
  const BuildVector<uint32_t>& by_min = s_.lists[2 * w];
  const BuildVector<uint32_t>& by_max = s_.lists[2 * w + 1];
  const double slack = s_.tuning.fill_sm_slack + s_.tuning.fill_sm_slack_rel * m.sm_min;
  const float* smin = sorted_min_.data();
  const float* smax = sorted_max_.data();
  // |Sm| ranks first (so a lower bound on it bounds the key) unless the fill slack zeroes it.
  const bool prunable = !fill_aware && sm_min_out == nullptr && only == nullptr;
  // Near the leaves with the default slack every |Sm| is within it: the key is the page waste alone.
  const bool sm_free = fill_aware && sm_min_out == nullptr && m.sm_min + slack >= n;

  // Per key, with the key a constant: the cut loop reads a(k) and b(k) without a select.
  auto scan_key = [&](auto key_constant) {
    constexpr int key = decltype(key_constant)::value;
    const BuildVector<uint32_t>& order = key == 0 ? by_min : by_max;
    if (only != nullptr) {
      if (tied[key].count == 0 || tied[key].key != *only) return;
      PrefixSuffixMargins(t, order, tied[key].k_min, tied[key].k_max);
    }
    // The second kCompact pass looks at the tied cuts only.
    const uint32_t k_first = only != nullptr ? tied[key].k_min : k_lo;
    const uint32_t k_last = only != nullptr ? tied[key].k_max : k_hi;
    const int list = 2 * w + key;
    // (Locals, not members or the task's fields, which the ties' counters could alias.)
    const float* const pmax = prefix_max_.data();
    const float* const smn = suffix_min_.data();
    const uint32_t base = window_base_;
    auto a_of = [smin, smn, base](uint32_t k) { return key == 0 ? smin[k] : smn[k - base]; };
    auto b_of = [smax, pmax, base](uint32_t k) { return key == 0 ? pmax[k - base] : smax[k - 1]; };
    const uint32_t* const ord = order.data() + t.lo;
    const uint32_t* const bytes = bytes_.data();
    uint64_t left_bytes = 0;            // encoded bytes of the first k objects
    if (fill_aware && only != nullptr)  // the first pass's candidate at k_first has them
      left_bytes = tied[key].first.left_bytes - bytes[ord[k_first - 1]];
    else if (fill_aware)
      for (uint32_t i = 0; i + 1 < k_first; ++i) left_bytes += bytes[ord[i]];

    PageSplit pages(left_bytes, t.bytes, mem_page_);

    // Cuts [k_begin, k_end]; pa, pb: the counts at k_begin when `placed`.
    auto eval = [&](uint32_t k_begin, uint32_t k_end, uint32_t pa, uint32_t pb, bool placed) {
      for (size_t k = k_begin; k <= k_end; ++k) {  // (64-bit: no zero-extensions)
        // Bytes only matter near the leaves (and are a random read per object, so not gathered above).
        uint64_t waste_key = 0;
        if (fill_aware) {
          left_bytes += bytes[ord[k - 1]];
          waste_key = pages.Waste(left_bytes);
        }
        // With the waste alone as the key (kSoa near the leaves), only a cut that may win or tie matters.
        if (sm_free && waste_key > bound) continue;
        const float a = a_of(k), b = b_of(k);  // the cut's planes
        uint32_t sm = 0;
        if (sm_free) {
          sm = SmGalloping(smin, smax, n, a, b, pa, pb);
        } else if (a < b) {
          if (!placed) {  // first use: a binary search instead of walking past the first ~k_lo objects
            pa = static_cast<uint32_t>(std::upper_bound(smax, smax + n, a) - smax);
            pb = static_cast<uint32_t>(std::lower_bound(smin, smin + n, b) - smin);
            placed = true;
          }
          // The cursors mostly move by 0-2 a step: two branch-free moves, then a loop that rarely runs
          // (+inf sentinels at [n] stop them).
          pa += smax[pa] <= a;
          pa += smax[pa] <= a;
          while (smax[pa] <= a) ++pa;
          pb += smin[pb] < b;
          pb += smin[pb] < b;
          while (smin[pb] < b) ++pb;
          sm = pb - pa;
        }
        if (sm_min_out != nullptr) {
          *sm_min_out = std::min(*sm_min_out, sm);
          continue;
        }
        uint32_t primary = sm, waste = 0;
        if (fill_aware) {
          if (sm <= m.sm_min + slack) primary = 0;
          waste = static_cast<uint32_t>(waste_key);
        }
        const uint64_t tie_key = uint64_t{primary} << 32 | waste;
        if (ties != nullptr) {  // a Candidate only for a new best: most cuts are not
          ListTies& lt = ties[key];
          if (lt.count == 0 || tie_key < lt.key) {
            lt.key = tie_key;
            lt.count = 1;
            lt.k_min = lt.k_max = k;
            lt.first = MakeCandidate(list, k, n, a, b, sm, primary, waste, left_bytes, fill_aware);
            bound = std::min(bound, tie_key);
          } else if (tie_key == lt.key) {
            ++lt.count;
            lt.k_max = k;
          }
          continue;
        }
        if (only != nullptr && tie_key != *only) continue;
        Candidate c = MakeCandidate(list, k, n, a, b, sm, primary, waste, left_bytes, fill_aware);
        if (only != nullptr) c.margin = CutMargin(k, n);
        if (c.BetterThan(*best)) {
          *best = c;
          bound = std::min(bound, tie_key);
        }
      }
    };

    const uint32_t cuts = k_last - k_first + 1;
    if (!prunable || cuts < 2 * kPruneBlock) {
      eval(k_first, k_last, 0, 0, false);
      return;
    }
    // Block ends p_j = k_first + j * kPruneBlock (j < blocks) and p_blocks = k_last; the counts there,
    // and the exact |Sm| of those cuts to tighten the bound before any block is scanned.
    const uint32_t blocks = (cuts + kPruneBlock - 1) / kPruneBlock;
    block_pa_.Fit(blocks + 1);
    block_pb_.Fit(blocks + 1);
    uint32_t pa = 0, pb = 0;
    for (uint32_t j = 0; j <= blocks; ++j) {
      const uint32_t p = j < blocks ? k_first + j * kPruneBlock : k_last;
      pa = Gallop<true>(smax, n, pa, a_of(p));
      pb = Gallop<false>(smin, n, pb, b_of(p));
      block_pa_[j] = pa;
      block_pb_[j] = pb;
      if (pb > pa)
        bound = std::min(bound, uint64_t{pb - pa} << 32);
      else
        bound = 0;  // a cut with |Sm| = 0: only such cuts can tie
    }
    for (uint32_t j = 0; j < blocks; ++j) {
      const uint32_t p = k_first + j * kPruneBlock;
      const uint32_t q = j + 1 < blocks ? p + kPruneBlock - 1 : k_last;
      const uint32_t lower = block_pb_[j] > block_pa_[j + 1] ? block_pb_[j] - block_pa_[j + 1] : 0;
      if ((uint64_t{lower} << 32) > bound) continue;
      eval(p, q, block_pa_[j], block_pb_[j], true);
    }
  };
  scan_key(std::integral_constant<int, 0>{});
  scan_key(std::integral_constant<int, 1>{});
}

}  // namespace mktree::build
