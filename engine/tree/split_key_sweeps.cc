// The key sweeps of SplitChooser (split_choice.h): a node's keys along one axis in sorted order with
// their running extremes, and the margins of the unions of boxes along one key order.
#include <limits>

#include "engine/tree/box_lanes.h"
#include "engine/tree/build_threads.h"
#include "engine/tree/split_choice.h"

namespace mktree::build {

// Margin of the union of the boxes of order[lo .. lo+i] for i in [k_min-1, k_max-1] at
// margin_pre_[i - (k_min-1)], and of order[lo+i .. hi) for i in [k_min, k_max] at margin_suf_[i - k_min]:
// what the cuts k in [k_min, k_max] need. Each sweep runs in two stretches (without, then with a margin
// stored) over the boxes as vectors.
void SplitChooser::PrefixSuffixMargins(const Task& t, int list, uint32_t k_min32, uint32_t k_max32) {
  const size_t n = t.hi - t.lo, k_min = k_min32, k_max = k_max32;  // (64-bit: no zero-extensions)
  margin_base_ = k_min32;
  margin_pre_.Fit(k_max - k_min + 1);
  margin_suf_.Fit(k_max - k_min + 1);
  const uint32_t* ord = Range(t, list);
  const Box3f* box = box_.data();
  float* const pre_out = margin_pre_.data();
  float* const suf_out = margin_suf_.data();
  // kFar: as in GatherRuns (large nodes tie on |Sm| = 0 over long runs of cuts, whose boxes are far apart).
  auto sweeps = [&]<bool kFar>() {
    LanesUnion pre;
    auto add_pre = [&](size_t j) {
      if (kFar && j + kPrefetch < n) __builtin_prefetch(&box[ord[j + kPrefetch]]);
      pre.Add(box[ord[j]]);
    };
    size_t i = 0;
    for (; i + 1 < k_min; ++i) add_pre(i);
    for (; i < k_max; ++i) add_pre(i), pre_out[i + 1 - k_min] = pre.Margin();
    LanesUnion suf;
    auto add_suf = [&](size_t j) {
      if (kFar && j >= kPrefetch) __builtin_prefetch(&box[ord[j - kPrefetch]]);
      suf.Add(box[ord[j]]);
    };
    i = n;
    while (i > k_max + 1) add_suf(--i);
    while (i > k_min) --i, add_suf(i), suf_out[i - k_min] = suf.Margin();
  };
  if (n >= kPrefetchObjects)
    sweeps.template operator()<true>();
  else
    sweeps.template operator()<false>();
}

// The node's min_w in sorted order with the running max of max_w along it, and its max_w in sorted
// order with the suffix min of min_w along it: all ScanKeys needs of axis w.
void SplitChooser::GatherAxis(const Task& t, int w, CutRange cuts) {
  const uint32_t n = t.hi - t.lo;
  const uint32_t k_lo = cuts.k_lo, k_hi = cuts.k_hi;
  // The running extremes are kept for the cuts k in [k_lo, k_hi] only: less scratch at the root.
  window_base_ = k_lo;
  sorted_min_.Fit(n + 1);
  prefix_max_.Fit(k_hi - k_lo + 1);
  sorted_max_.Fit(n + 1);
  suffix_min_.Fit(k_hi - k_lo + 1);
  sorted_min_[n] = sorted_max_[n] = std::numeric_limits<float>::infinity();
  if (n >= kPrefetchObjects)
    GatherRuns<true>(t, w, k_lo, k_hi);
  else
    GatherRuns<false>(t, w, k_lo, k_hi);
}

// GatherAxis' two sweeps, each in three stretches (before, in and after the cut window) so that the
// window test is not made per object. kFar: the records are read in key order, scattered over RAM in
// large nodes, so each is prefetched kPrefetch objects ahead.
template <bool kFar>
void SplitChooser::GatherRuns(const Task& t, int w, uint32_t k_lo32, uint32_t k_hi32) {
  // (64-bit positions: no zero-extensions in the loops.)
  const size_t n = t.hi - t.lo, k_lo = k_lo32, k_hi = k_hi32;
  const Box3f* box = box_.data();
  const uint32_t* by_min = nullptr;  // (a spilled node's: one window at a time on one thread)
  const uint32_t* by_max = nullptr;
  float* smin = sorted_min_.data();
  float* smax = sorted_max_.data();
  float* pmax = prefix_max_.data();  // [k - k_lo]: max of max_w over the first k objects
  float* smn = suffix_min_.data();   // [k - k_lo]: min of min_w over objects k..n-1
  auto sweep_up = [&] {
    float run = -std::numeric_limits<float>::infinity();
    auto up = [&](size_t i) {
      if (kFar && i + kPrefetch < n) __builtin_prefetch(&box[by_min[i + kPrefetch]]);
      const Box3f& bx = box[by_min[i]];
      smin[i] = bx.min[w];
      run = std::max(run, bx.max[w]);
    };
    size_t i = 0;
    for (; i + 1 < k_lo; ++i) up(i);
    for (; i < k_hi; ++i) up(i), pmax[i + 1 - k_lo] = run;
    for (; i < n; ++i) up(i);
  };
  auto sweep_down = [&] {
    float run = std::numeric_limits<float>::infinity();
    auto down = [&](size_t i) {
      if (kFar && i >= kPrefetch) __builtin_prefetch(&box[by_max[i - kPrefetch]]);
      const Box3f& bx = box[by_max[i]];
      smax[i] = bx.max[w];
      run = std::min(run, bx.min[w]);
    };
    size_t i = n;
    for (; i > k_hi + 1;) down(--i);
    for (; i > k_lo;) --i, down(i), smn[i - k_lo] = run;
    for (; i > 0;) down(--i);
  };
  if (t.cooperative) {
    by_min = Range(t, 2 * w, 0);
    by_max = Range(t, 2 * w + 1, 1);
    Together(sweep_up, sweep_down);
  } else {
    by_min = Range(t, 2 * w);
    sweep_up();
    by_max = Range(t, 2 * w + 1);
    sweep_down();
  }
}

}  // namespace mktree::build
