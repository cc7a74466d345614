// The broad phase over the in-RAM tree: which leaves can hold a pair of objects closer than C, found
// without reading any leaf page.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "engine/clash/work_pool.h"
#include "engine/tree/leaf_filter.h"
#include "engine/tree/mktree.h"

namespace mktree::clash {

struct LeafPair {
  uint32_t p = 0, q = 0;  // p <= q; p == q: the pairs inside one leaf
  bool operator==(const LeafPair&) const = default;
};

// Where the objects of a focused clash (MultiClashScope::focus) may be in one tree, from their records
// (engine/clash/clash_focus.h): the nodes whose subtrees hold one, and the objects, indexed as the leaf
// filter is (NeededObjects), whose quantised boxes may be theirs (a superset: every position of a leaf
// whose box alone cannot tell).
struct FocusMarks {
  std::vector<uint8_t> nodes;   // per node of the tree
  std::vector<uint64_t> slots;  // increasing
  bool node(uint32_t n) const { return nodes[n] != 0; }
};

// Every unordered pair of leaves (a leaf with itself included) whose node boxes grown by c meet, by a
// dual traversal from the root: a node with itself descends to its children's three pairs, two nodes
// descend the larger. Each unordered pair once, in traversal order. With `focus`: only the pairs with a
// leaf under a focus-marked node (the traversal does not descend elsewhere); with `partner` marks too,
// only the pairs with a leaf under a focus-marked node and the other under a partner-marked one.
std::vector<LeafPair> TreeLeafPairs(const MKTree& tree, double c, const FocusMarks* focus = nullptr,
                                    const FocusMarks* partner = nullptr);

// Objects of the store indexed as the leaf filter is: leaf_filter_begin[leaf] (bytes) / 8 + position.
struct NeededObjects {
  std::unique_ptr<std::atomic<uint8_t>[]> flags;
  bool all = false;  // no leaf filter: every object may be needed
  bool operator()(const MKTree& tree, uint32_t leaf, uint32_t pos) const {
    return all || flags[tree.leaf_filter_begin[leaf] / kLeafFilterBytesPerObject + pos].load(
                      std::memory_order_relaxed) != 0;
  }
};

// Keeps the pairs in which the leaf filter's quantised boxes (which contain the objects' float32 boxes)
// admit a pair of distinct objects whose boxes grown by c meet (with `focus`: one of them focus-marked;
// with `partner` too: one focus-marked and the other partner-marked),
// and marks those objects in *needed. A pair dropped here cannot hold a candidate pair, so its leaves
// need not be read for it. Without a leaf filter every pair is kept and every object needed.
void FilterLeafPairs(const MKTree& tree, double c, WorkPool& pool, std::vector<LeafPair>* pairs,
                     NeededObjects* needed, const FocusMarks* focus = nullptr,
                     const FocusMarks* partner = nullptr);

// Two stores in one frame (shards of one sharded store): every pair (p leaf of a, q leaf of b) whose
// node boxes grown by c meet, by the same dual traversal from both roots. With focus marks (both or
// neither): only the pairs with a leaf under a focus-marked node; with partner marks (both or neither,
// with focus marks), as TreeLeafPairs.
std::vector<LeafPair> CrossLeafPairs(const MKTree& a, const MKTree& b, double c,
                                     const FocusMarks* focus_a = nullptr, const FocusMarks* focus_b = nullptr,
                                     const FocusMarks* partner_a = nullptr,
                                     const FocusMarks* partner_b = nullptr);

// Readies *needed for FilterLeafPairs' marks (all zero); false when the tree has no leaf filter (then
// every object is needed).
bool InitNeeded(const MKTree& tree, NeededObjects* needed);

// FilterLeafPairs for CrossLeafPairs' pairs, marking in *needed_a and *needed_b (both readied by
// InitNeeded, both trees with a leaf filter).
// With focus marks (both or neither): only pairs with a focus-marked object.
void FilterCrossLeafPairs(const MKTree& a, const MKTree& b, double c, WorkPool& pool,
                          std::vector<LeafPair>* pairs, NeededObjects* needed_a, NeededObjects* needed_b,
                          const FocusMarks* focus_a = nullptr, const FocusMarks* focus_b = nullptr,
                          const FocusMarks* partner_a = nullptr, const FocusMarks* partner_b = nullptr);

}  // namespace mktree::clash
