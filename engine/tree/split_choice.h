// The split choice of the Splitting Overlap Algorithm (SOA): where an internal node's cut plane goes.
// The rule, in the paper's notation (docs/design.md §3, "The Splitting Overlap Algorithm"):
//
//   A node n holding Sn is a leaf when InPage(Sn): its leaf payload fits in one page of
//   MemPage = d x BlockSize bytes (or Sn is one object). Otherwise, with N = |Sn| and balance ratio r:
//   1. For each axis w and each sort key (min_w, max_w) order Sn by the key; cut k puts the first k
//      objects in Sn1 and the rest in Sn2, with ceil(r N) <= k <= floor((1 - r) N) and 1 <= k <= N - 1.
//   2. a = min over Sn2 of min_w (plane pi0), b = max over Sn1 of max_w (plane pi1). If a >= b the
//      children are disjoint along w; otherwise the slab a <= w <= b is the overlap region, and
//      Sm = { objects with max_w > a and min_w < b } is the overlap set.
//   3. Take the cut with the fewest objects in Sm, then the thinner slab (b - a), then the better balance.
//   4. The paper's groups: WW (entirely below a) and W (crossing pi0 only) go to Sn1, BB (entirely above
//      b) and B (crossing pi1 only) to Sn2; In objects (inside the slab) may go to either side.
//
// Here: InPage is IsLeaf; step 1's window of k is BalancedCuts (past depth kDepthGuard, r is at least
// kGuardBalance); steps 2-3 are SplitChooser::Choose, in O(N) per axis over the presorted keys: along
// either key order a(k) and b(k) never decrease, so |Sm| = #(min_w < b) - #(max_w <= a) is counted by two
// cursors moving forward. Candidate::BetterThan is step 3's order, with two refinements that
// BuildTuning (build_tuning.h) switches: near the leaves (fill_aware), page waste ranks first among the
// candidates whose |Sm| is within the fill slack of the least; under SplitPolicy::kCompact only the
// node's wide axes are tried and ties go to the smaller N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) before
// the slab. With kSoa and fill_aware off the choice is the rule above exactly.
// Step 4 is SubtreeBuilder's (subtree_builder.cc: AssignSides, GatherSlabItems), and the SplitTree
// (split_tree_builder.h) gives the In objects their side.
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>

#include "engine/tree/build_memory.h"
#include "engine/tree/build_state.h"
#include "engine/tree/page_budget.h"

namespace mktree::build {

// InPage (with the one-object leaf): a node of `count` objects whose entries take `bytes` is a leaf.
inline bool IsLeaf(uint32_t count, uint64_t bytes, uint64_t mem_page) {
  return count == 1 || FitsInOnePage(bytes, mem_page);
}

// Past this depth r is at least kGuardBalance: with r near 0 the SOA may peel one object off per level.
inline constexpr uint32_t kDepthGuard = 100;
inline constexpr double kGuardBalance = 0.25;

// The cuts k in [k_lo, k_hi] that step 1 allows.
struct CutRange {
  uint32_t k_lo = 0, k_hi = 0;
};
// Step 1's window for a node of n >= 2 objects at `depth` (r near 0.5 with a tiny n leaves no k in
// [ceil(r n), floor((1 - r) n)]: then the middle cut alone).
CutRange BalancedCuts(uint32_t n, uint32_t depth, double balance_r);

// One candidate split: cut k of list 2*w + key, its planes and the keys it is ranked by.
struct Candidate {
  int list = -1;  // 2*w + key
  uint32_t k = 0;
  float a = 0, b = 0;
  uint32_t sm = 0;
  uint32_t primary = 0;  // sm, or 0 when within the fill slack of the minimum
  uint32_t waste = 0;
  float margin = 0;  // kCompact: N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)); 0 under kSoa
  double slab = 0;
  uint32_t imbalance = 0;
  uint64_t left_bytes = 0;  // encoded bytes of Sn1 (known only when fill_aware)
  bool fill_aware = false;
  bool BetterThan(const Candidate& o) const {
    if (o.list < 0) return true;
    if (primary != o.primary) return primary < o.primary;
    if (waste != o.waste) return waste < o.waste;
    if (margin != o.margin) return margin < o.margin;
    if (sm != o.sm) return sm < o.sm;
    if (slab != o.slab) return slab < o.slab;
    return imbalance < o.imbalance;
  }
};

// The candidate of cut k of `list` in a node of n objects, with its slab (b - a, 0 when disjoint) and
// imbalance |2k - n|.
inline Candidate MakeCandidate(int list, uint32_t k, uint32_t n, float a, float b, uint32_t sm,
                               uint32_t primary, uint32_t waste, uint64_t left_bytes, bool fill_aware) {
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

// How the candidates of one node are ranked (beyond SplitPolicy).
struct Ranking {
  bool fill_aware = false;  // near the leaves: page waste first among the |Sm| within the fill slack
  uint32_t sm_min = 0;      // the minimal |Sm| over the candidates (known when fill_aware)
};

// Per sort list, the candidates with the list's best (primary, waste) (kCompact's first pass).
struct ListTies {
  uint64_t key = 0;  // primary << 32 | waste
  uint32_t count = 0, k_min = 0, k_max = 0;
  Candidate first;
};

// What ScanKeys computes over the cuts of one axis. Each mode reads and writes only the fields of
// ScanRequest and ScanOutcome that name it.
enum class ScanMode : uint8_t {
  kLeastSm,      // the least |Sm| into ScanOutcome::sm_min (the fill slack's first pass)
  kBest,         // every cut ranked by BetterThan into ScanOutcome::best, margins not computed (kSoa)
  kTies,         // per key, the cuts reaching the list's best (primary, waste) into ScanOutcome::ties,
                 // margins not computed (kCompact's first pass)
  kTiedMargins,  // only the cuts of ScanRequest::tied reaching ScanRequest::tie_key, with their margins,
                 // ranked into ScanOutcome::best (kCompact's second pass)
};
struct ScanRequest {
  ScanRequest(ScanMode mode, int axis, CutRange cuts, const Ranking& ranking = Ranking())
      : mode(mode), axis(axis), cuts(cuts), ranking(ranking) {}
  ScanMode mode;
  int axis;
  CutRange cuts;
  Ranking ranking;
  // kBest, kTies: a (primary << 32 | waste) key that the chosen candidate is known to reach; cuts that
  // cannot reach it may be skipped.
  uint64_t bound = std::numeric_limits<uint64_t>::max();
  // kTiedMargins: the key the cuts must reach, and per key what kTies found along this axis.
  uint64_t tie_key = 0;
  std::array<ListTies, 2> tied;
};
struct ScanOutcome {
  Candidate best;                                          // kBest, kTiedMargins: the best so far (in, out)
  uint32_t sm_min = std::numeric_limits<uint32_t>::max();  // kLeastSm: lowered to the least |Sm| (in, out)
  std::array<ListTies, 2> ties;                            // kTies: per key (out)
};

// Chooses the split of one node after another (one per builder thread: it keeps the sweeps' scratch).
class SplitChooser {
 public:
  explicit SplitChooser(const BuildState& s)
      : s_(s), box_(s.box), bytes_(s.bytes), mem_page_(s.params.mem_page()) {}

  // The best candidate among the cuts of `cuts` of the node of `t` (steps 2-3, as BuildTuning ranks).
  Candidate Choose(const Task& t, CutRange cuts);

  // List l over the node's range, indexed from 0 (position t.lo). In RAM; for a spilled node
  // (Task::spilled) read from the spill file into window `slot` (1: only the second thread of a
  // cooperative root), which holds one list at a time and keeps its pages from node to node (loading into
  // the lists' own storage faulted them in at every load). The pointer stays valid until the slot loads
  // another list or the node ends (NodeDone).
  const uint32_t* Range(const Task& t, int l, int slot = 0) {
    if (!t.spilled) return s_.lists[l].data() + t.lo;
    if (held_[slot] != l) {
      Window(slot, t.hi - t.lo);
      s_.spill->Read(l, t.lo, t.hi, window_[slot].data());
      held_[slot] = l;
    }
    return window_[slot].data();
  }
  // Window `slot` with room for n positions, for the builder's own use (its list partitions).
  uint32_t* Window(int slot, size_t n) {
    window_[slot].Fit(n);
    held_[slot] = -1;
    return window_[slot].data();
  }
  // The node is done: the windows' contents are not its lists any more. A spilled node's windows give
  // their pages back (between its sweeps, its SplitTree and its children they would add to the peak; a
  // window faults its pages in once a node, not once a list).
  void NodeDone(const Task& t) {
    held_[0] = held_[1] = -1;
    if (t.spilled)
      for (Scratch<uint32_t>& w : window_) w.Reset(0);
  }

  // Gives back the scratch beyond what a node of n objects needs.
  void ShrinkScratch(size_t n);
  size_t ScratchObjects() const { return sorted_min_.capacity(); }

  // Room for n object indices in the storage of the node's sorted keys (which = 0: min_w, 1: max_w),
  // dead once Choose has returned: the list partitions' buffers, so that they add nothing to the peak.
  uint32_t* PartitionBuffer(int which, size_t n) {
    return (which == 0 ? sorted_min_ : sorted_max_).StorageAs<uint32_t>(n);
  }

 private:
  uint64_t Pages(uint64_t bytes) const { return PagesForLeaf(bytes, mem_page_); }
  void CompactAxes(const Task& t, bool axis_ok[3]) const;
  uint32_t LeastSm(const Task& t, CutRange cuts, const bool axis_ok[3]);
  Candidate ChooseSoa(const Task& t, CutRange cuts, const Ranking& ranking, const bool axis_ok[3]);
  Candidate ChooseCompact(const Task& t, CutRange cuts, const Ranking& ranking, const bool axis_ok[3]);
  void ScanWasteMargins(const Task& t, int w, CutRange cuts, Candidate* best);
  float SplitMargin(const Task& t, int list, uint32_t k);
  void ScanKeys(const Task& t, const ScanRequest& req, ScanOutcome* out);
  template <int kKey>
  void ScanKey(const Task& t, const ScanRequest& req, uint64_t* bound, ScanOutcome* out);

  // The key sweeps (split_key_sweeps.cc).
  void PrefixSuffixMargins(const Task& t, int list, uint32_t k_min32, uint32_t k_max32);
  void GatherAxis(const Task& t, int w, CutRange cuts);
  template <bool kFar>
  void GatherRuns(const Task& t, int w, uint32_t k_lo32, uint32_t k_hi32);

  // kCompact's margin pass: N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) of cut k (PrefixSuffixMargins done).
  float CutMargin(uint32_t k, uint32_t n) const {
    return static_cast<float>(static_cast<double>(k) * margin_pre_[k - margin_base_] +
                              static_cast<double>(n - k) * margin_suf_[k - margin_base_]);
  }

  const BuildState& s_;
  const BuildVector<Box3f>& box_;
  const BuildVector<uint32_t>& bytes_;
  const uint64_t mem_page_;
  Scratch<float> sorted_min_, prefix_max_, sorted_max_, suffix_min_;
  uint32_t window_base_ = 0;                // prefix_max_ / suffix_min_ index of the cut k_lo
  Scratch<float> margin_pre_, margin_suf_;  // kCompact only
  Scratch<uint32_t> block_pa_, block_pb_;   // ScanKeys' counts at its block ends
  uint32_t margin_base_ = 0;                // margin_pre_ / margin_suf_ index of the cut k_min
  Scratch<uint32_t> window_[2];             // a spilled node's lists (Range)
  int held_[2] = {-1, -1};                  // the list each window holds, -1: none
};

}  // namespace mktree::build
