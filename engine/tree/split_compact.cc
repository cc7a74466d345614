// SplitPolicy::kCompact's refinements of the split choice (split_choice.h): the node's wide axes only, and
// ties on (|Sm| or page waste) broken by N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) before the slab.
#include <algorithm>
#include <array>
#include <limits>

#include "engine/tree/box_lanes.h"
#include "engine/tree/split_choice.h"

namespace mktree::build {

// kCompact: the margin only breaks ties on (primary, waste). Per axis, while its keys are gathered: per
// list, the best (primary, waste) and the range of k reaching it; margins are computed only for the
// candidates that tie with the best so far, and not at all when one candidate alone is best. Same choice
// as ranking every candidate with its margin: the others lose on (primary, waste) anyway, and the tied
// ones are compared in the same order (list, then k).
Candidate SplitChooser::ChooseCompact(const Task& t, CutRange cuts, const Ranking& ranking,
                                      const bool axis_ok[3]) {
  ScanOutcome chosen;  // .best
  Candidate& best = chosen.best;
  uint64_t top = std::numeric_limits<uint64_t>::max();
  bool lone = false;  // `best` is the only candidate reaching `top` so far; its margin is not computed
  for (int w = 0; w < 3; ++w) {
    if (!axis_ok[w]) continue;
    GatherAxis(t, w, cuts);
    ScanRequest first(ScanMode::kTies, w, cuts, ranking);
    first.bound = top;
    ScanOutcome tally;  // .ties
    ScanKeys(t, first, &tally);
    const std::array<ListTies, 2>& ties = tally.ties;
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
    ScanRequest second(ScanMode::kTiedMargins, w, cuts, ranking);
    second.tie_key = top;
    second.tied = ties;
    ScanKeys(t, second, &chosen);
  }
  return best;
}

// kCompact near the leaves, when every |Sm| is within the fill slack (primary 0): the cuts of both keys
// of axis w ranked by page waste, then margin, then as BetterThan says. Per list the least (waste,
// margin) is found first, with no candidate built, and only the cuts reaching it are evaluated, in
// order: the same choice as evaluating every cut, as BetterThan ranks those two first.
void SplitChooser::ScanWasteMargins(const Task& t, int w, CutRange cuts, Candidate* best) {
  const uint32_t k_lo = cuts.k_lo, k_hi = cuts.k_hi;
  const uint32_t n = t.hi - t.lo;
  const uint32_t* const bytes = bytes_.data();
  for (int key = 0; key < 2; ++key) {
    const int list = 2 * w + key;
    PrefixSuffixMargins(t, list, k_lo, k_hi);
    const uint32_t* const ord = Range(t, list);
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
float SplitChooser::SplitMargin(const Task& t, int list, uint32_t k) {
  const uint32_t* const ord = Range(t, list);
  const uint32_t n = t.hi - t.lo;
  LanesUnion lo, hi;
  for (uint32_t i = 0; i < k; ++i) lo.Add(box_[ord[i]]);
  for (uint32_t i = k; i < n; ++i) hi.Add(box_[ord[i]]);
  return static_cast<float>(static_cast<double>(k) * lo.Margin() + static_cast<double>(n - k) * hi.Margin());
}

}  // namespace mktree::build
