#include "engine/clash/leaf_pairs.h"

#include <algorithm>

#include "engine/clash/pair_rules.h"
#include "engine/tree/leaf_filter.h"

namespace mktree::clash {

namespace {

double Volume(const Box3f& b) {
  return (double{b.max[0]} - b.min[0]) * (double{b.max[1]} - b.min[1]) * (double{b.max[2]} - b.min[2]);
}

struct Traversal {
  const MKTree& tree;
  double c;
  std::vector<LeafPair>* out;

  void Emit(uint32_t n, uint32_t m) {
    uint32_t p = tree.nodes[n].leaf, q = tree.nodes[m].leaf;
    if (p > q) std::swap(p, q);
    out->push_back({p, q});
  }
  void Self(uint32_t n) {
    const TreeNode& node = tree.nodes[n];
    if (node.is_leaf()) {
      Emit(n, n);
      return;
    }
    Self(node.child[0]);
    Self(node.child[1]);
    Two(node.child[0], node.child[1]);
  }
  void Two(uint32_t n, uint32_t m) {
    const TreeNode& a = tree.nodes[n];
    const TreeNode& b = tree.nodes[m];
    if (!GrownMeet(ToBox3d(a.box), ToBox3d(b.box), c)) return;
    if (a.is_leaf() && b.is_leaf()) {
      Emit(n, m);
      return;
    }
    const bool split_a = !a.is_leaf() && (b.is_leaf() || Volume(a.box) >= Volume(b.box));
    if (split_a) {
      Two(a.child[0], m);
      Two(a.child[1], m);
    } else {
      Two(n, b.child[0]);
      Two(n, b.child[1]);
    }
  }
};

}  // namespace

std::vector<LeafPair> TreeLeafPairs(const MKTree& tree, double c) {
  std::vector<LeafPair> out;
  if (tree.empty()) return out;
  Traversal t{tree, c, &out};
  t.Self(0);
  return out;
}

void FilterLeafPairs(const MKTree& tree, double c, WorkPool& pool, std::vector<LeafPair>* pairs,
                     NeededObjects* needed) {
  if (tree.leaf_filter.empty() || tree.leaf_filter_begin.size() != tree.leaves.size() + 1) {
    needed->all = true;
    return;
  }
  const uint64_t objects = tree.leaf_filter_begin.back() / kLeafFilterBytesPerObject;
  needed->flags = std::make_unique<std::atomic<uint8_t>[]>(objects);
  for (uint64_t i = 0; i < objects; ++i) needed->flags[i].store(0, std::memory_order_relaxed);
  std::vector<uint8_t> keep(pairs->size(), 0);
  constexpr size_t kChunk = 256;
  const size_t chunks = (pairs->size() + kChunk - 1) / kChunk;
  pool.For(chunks, [&](size_t chunk) {
    // The objects of each leaf that meet the other leaf's box, as dequantised boxes.
    std::vector<Box3d> ba, bb;
    std::vector<uint32_t> ia, ib;
    auto near = [&](uint32_t leaf, const Box3d& other, std::vector<Box3d>* boxes,
                    std::vector<uint32_t>* idx) {
      boxes->clear();
      idx->clear();
      const LeafInfo& info = tree.leaves[leaf];
      const uint8_t* q = tree.leaf_filter.data() + tree.leaf_filter_begin[leaf];
      for (uint32_t i = 0; i < info.object_count; ++i) {
        const Box3d b = DequantizeBox(info.box, q + i * kLeafFilterBytesPerObject);
        if (!GrownMeet(b, other, c)) continue;
        boxes->push_back(b);
        idx->push_back(i);
      }
    };
    const size_t end = std::min(pairs->size(), (chunk + 1) * kChunk);
    for (size_t k = chunk * kChunk; k < end; ++k) {
      const LeafPair lp = (*pairs)[k];
      near(lp.p, ToBox3d(tree.leaves[lp.q].box), &ba, &ia);
      near(lp.q, ToBox3d(tree.leaves[lp.p].box), &bb, &ib);
      const uint64_t base_p = tree.leaf_filter_begin[lp.p] / kLeafFilterBytesPerObject,
                     base_q = tree.leaf_filter_begin[lp.q] / kLeafFilterBytesPerObject;
      bool any = false;
      for (size_t i = 0; i < ba.size(); ++i) {
        for (size_t j = lp.p == lp.q ? i + 1 : 0; j < bb.size(); ++j) {
          if (!GrownMeet(ba[i], bb[j], c)) continue;
          any = true;
          needed->flags[base_p + ia[i]].store(1, std::memory_order_relaxed);
          needed->flags[base_q + ib[j]].store(1, std::memory_order_relaxed);
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

}  // namespace mktree::clash
