#include "engine/clash/leaf_pairs.h"

#include <algorithm>

#include "engine/clash/pair_rules.h"
#include "engine/tree/leaf_filter.h"

namespace mktree::clash {

namespace {

double Volume(const Box3f& b) {
  return (double{b.max[0]} - b.min[0]) * (double{b.max[1]} - b.min[1]) * (double{b.max[2]} - b.min[2]);
}

// A dual traversal of trees a and b (the same tree for a self-clash); with focus marks (fa, fb) only
// into node pairs of which one holds a focused object, and with partner marks (pa, pb) as well, only into
// those where one side holds a focused object and the other a partner.
struct Traversal {
  const MKTree& a;
  const MKTree& b;
  double c;
  std::vector<LeafPair>* out;
  const FocusMarks* fa = nullptr;
  const FocusMarks* fb = nullptr;
  const FocusMarks* pa = nullptr;
  const FocusMarks* pb = nullptr;

  static bool Marked(const FocusMarks* f, uint32_t n) { return !f || f->node(n); }
  // Whether a pair of node n (of a) and node m (of b) may hold a focused object and a partner.
  bool Scoped(uint32_t n, uint32_t m) const {
    if (!fa) return true;
    if (!pa) return fa->node(n) || fb->node(m);
    return (fa->node(n) && Marked(pb, m)) || (Marked(pa, n) && fb->node(m));
  }

  void Emit(uint32_t n, uint32_t m) {
    uint32_t p = a.nodes[n].leaf, q = b.nodes[m].leaf;
    if (&a == &b && p > q) std::swap(p, q);
    out->push_back({p, q});
  }
  void Self(uint32_t n) {
    if (fa && !(fa->node(n) && Marked(pa, n))) return;
    const TreeNode& node = a.nodes[n];
    if (node.is_leaf()) {
      Emit(n, n);
      return;
    }
    Self(node.child[0]);
    Self(node.child[1]);
    Two(node.child[0], node.child[1]);
  }
  void Two(uint32_t n, uint32_t m) {
    if (!Scoped(n, m)) return;
    const TreeNode& x = a.nodes[n];
    const TreeNode& y = b.nodes[m];
    if (!GrownMeet(ToBox3d(x.box), ToBox3d(y.box), c)) return;
    if (x.is_leaf() && y.is_leaf()) {
      Emit(n, m);
      return;
    }
    const bool split_a = !x.is_leaf() && (y.is_leaf() || Volume(x.box) >= Volume(y.box));
    if (split_a) {
      Two(x.child[0], m);
      Two(x.child[1], m);
    } else {
      Two(n, y.child[0]);
      Two(n, y.child[1]);
    }
  }
};

}  // namespace

std::vector<LeafPair> TreeLeafPairs(const MKTree& tree, double c, const FocusMarks* focus,
                                    const FocusMarks* partner) {
  std::vector<LeafPair> out;
  if (tree.empty()) return out;
  Traversal t{tree, tree, c, &out, focus, focus, partner, partner};
  t.Self(0);
  return out;
}

std::vector<LeafPair> CrossLeafPairs(const MKTree& a, const MKTree& b, double c, const FocusMarks* focus_a,
                                     const FocusMarks* focus_b, const FocusMarks* partner_a,
                                     const FocusMarks* partner_b) {
  std::vector<LeafPair> out;
  if (a.empty() || b.empty()) return out;
  Traversal t{a, b, c, &out, focus_a, focus_b, partner_a, partner_b};
  t.Two(0, 0);
  return out;
}

bool InitNeeded(const MKTree& tree, NeededObjects* needed) {
  if (tree.leaf_filter.empty() || tree.leaf_filter_begin.size() != tree.leaves.size() + 1) {
    needed->all = true;
    return false;
  }
  const uint64_t objects = tree.leaf_filter_begin.back() / kLeafFilterBytesPerObject;
  needed->flags = std::make_unique<std::atomic<uint8_t>[]>(objects);
  for (uint64_t i = 0; i < objects; ++i) needed->flags[i].store(0, std::memory_order_relaxed);
  return true;
}

namespace {

// Keeps the pairs (p of ta, q of tb; `same`: one tree, p == q the pairs inside a leaf) whose leaf
// filters admit two distinct objects whose boxes grown by c meet (with focus marks fa, fb: one of them
// marked; with partner marks pa, pb: one focus-marked and the other partner-marked), marking them.
void FilterPairs(const MKTree& ta, const MKTree& tb, bool same, double c, WorkPool& pool,
                 std::vector<LeafPair>* pairs, NeededObjects* na, NeededObjects* nb, const FocusMarks* fa,
                 const FocusMarks* fb, const FocusMarks* pa, const FocusMarks* pb) {
  std::vector<uint8_t> keep(pairs->size(), 0);
  constexpr size_t kChunk = 256;
  const size_t chunks = (pairs->size() + kChunk - 1) / kChunk;
  pool.For(chunks, [&](size_t chunk) {
    // The objects of each leaf that meet the other leaf's box, as dequantised boxes, and whether each may
    // be focused and a partner (all are without a focus, and partners without a partner set).
    std::vector<Box3d> ba, bb;
    std::vector<uint32_t> ia, ib;
    std::vector<uint8_t> focused_a, focused_b, partner_a, partner_b;
    // Whether position `at` of the marks' slots is marked, the cursor `slot` advancing in increasing order.
    auto marked = [](const FocusMarks* marks, std::vector<uint64_t>::const_iterator* slot, uint64_t at) {
      if (!marks) return true;
      while (*slot != marks->slots.end() && **slot < at) ++*slot;
      return *slot != marks->slots.end() && **slot == at;
    };
    auto start = [](const FocusMarks* marks, uint64_t base) {
      return marks ? std::lower_bound(marks->slots.begin(), marks->slots.end(), base)
                   : std::vector<uint64_t>::const_iterator();
    };
    auto near = [&](const MKTree& tree, const FocusMarks* focus, const FocusMarks* partner, uint32_t leaf,
                    const Box3d& other, std::vector<Box3d>* boxes, std::vector<uint32_t>* idx,
                    std::vector<uint8_t>* focused, std::vector<uint8_t>* partnered) {
      boxes->clear();
      idx->clear();
      focused->clear();
      partnered->clear();
      const LeafInfo& info = tree.leaves[leaf];
      const uint64_t base = tree.leaf_filter_begin[leaf] / kLeafFilterBytesPerObject;
      const uint8_t* q = tree.leaf_filter.data() + tree.leaf_filter_begin[leaf];
      auto slot = start(focus, base), partner_slot = start(partner, base);
      for (uint32_t i = 0; i < info.object_count; ++i) {
        const bool in_focus = marked(focus, &slot, base + i);
        const bool in_partner = marked(partner, &partner_slot, base + i);
        const Box3d b = DequantizeBox(info.box, q + i * kLeafFilterBytesPerObject);
        if (!GrownMeet(b, other, c)) continue;
        boxes->push_back(b);
        idx->push_back(i);
        focused->push_back(in_focus);
        partnered->push_back(in_partner);
      }
    };
    const size_t end = std::min(pairs->size(), (chunk + 1) * kChunk);
    for (size_t k = chunk * kChunk; k < end; ++k) {
      const LeafPair lp = (*pairs)[k];
      near(ta, fa, pa, lp.p, ToBox3d(tb.leaves[lp.q].box), &ba, &ia, &focused_a, &partner_a);
      near(tb, fb, pb, lp.q, ToBox3d(ta.leaves[lp.p].box), &bb, &ib, &focused_b, &partner_b);
      const uint64_t base_p = ta.leaf_filter_begin[lp.p] / kLeafFilterBytesPerObject,
                     base_q = tb.leaf_filter_begin[lp.q] / kLeafFilterBytesPerObject;
      const bool one_leaf = same && lp.p == lp.q;
      bool any = false;
      for (size_t i = 0; i < ba.size(); ++i) {
        for (size_t j = one_leaf ? i + 1 : 0; j < bb.size(); ++j) {
          const bool scoped = (focused_a[i] && partner_b[j]) || (partner_a[i] && focused_b[j]);
          if (!scoped || !GrownMeet(ba[i], bb[j], c)) continue;
          any = true;
          na->flags[base_p + ia[i]].store(1, std::memory_order_relaxed);
          nb->flags[base_q + ib[j]].store(1, std::memory_order_relaxed);
        }
      }
      keep[k] = any;
    }
  });
  size_t w = 0;
  for (size_t k = 0; k < pairs->size(); ++k)
    if (keep[k]) (*pairs)[w++] = (*pairs)[k];
  pairs->resize(w);
}

}  // namespace

void FilterCrossLeafPairs(const MKTree& a, const MKTree& b, double c, WorkPool& pool,
                          std::vector<LeafPair>* pairs, NeededObjects* needed_a, NeededObjects* needed_b,
                          const FocusMarks* focus_a, const FocusMarks* focus_b, const FocusMarks* partner_a,
                          const FocusMarks* partner_b) {
  FilterPairs(a, b, false, c, pool, pairs, needed_a, needed_b, focus_a, focus_b, partner_a, partner_b);
}

void FilterLeafPairs(const MKTree& tree, double c, WorkPool& pool, std::vector<LeafPair>* pairs,
                     NeededObjects* needed, const FocusMarks* focus, const FocusMarks* partner) {
  if (!InitNeeded(tree, needed)) return;
  FilterPairs(tree, tree, true, c, pool, pairs, needed, needed, focus, focus, partner, partner);
}

}  // namespace mktree::clash
