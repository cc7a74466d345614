// Which leaf holds each object id, as far as the leaves read so far show. A leaf's id digest proves its
// entries but for a collision, which a crafted store can aim for (docs/store_format.md); CheckLeafEntries
// (leaf_reader.h) so claims a leaf's ids the first time its entries pass, and refuses a leaf that holds
// an id another leaf claimed first. An id in two leaves is then a Corruption at whichever of them is read
// second, on every path that reads leaves (queries of every kind, batches, counts, clash, export), and it
// costs nothing once a leaf is claimed: one bit per object (zeroed pages that are never touched are never
// mapped) and a byte per leaf, each id claimed once per process.
// Not part of an ObjectTable's value: a copy starts with no claims, an assignment drops them, and ==
// ignores them.
// Thread safety: any number of threads may claim at once.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <unordered_map>
#include <vector>

namespace mktree {

class LeafClaims {
 public:
  static constexpr uint64_t kNone = ~uint64_t{0};

  LeafClaims();
  LeafClaims(const LeafClaims&);
  LeafClaims& operator=(const LeafClaims&);
  ~LeafClaims();
  bool operator==(const LeafClaims&) const { return true; }

  // Whether leaf `leaf` has claimed its ids (then it need not again).
  bool Claimed(uint32_t leaf) const;
  // Claims `ids` (one leaf's: each below `objects`, none twice) for leaf `leaf` of `leaves`. Returns kNone,
  // or an id another leaf claimed first (then it claims none, and refuses the leaf with it again later).
  uint64_t Claim(uint32_t leaf, uint64_t leaves, uint64_t objects, std::span<const uint32_t> ids) const;

 private:
  struct State;
  State* StateFor(uint64_t leaves, uint64_t objects) const;  // REQUIRES: mu_ held

  mutable std::mutex mu_;
  mutable std::atomic<State*> state_{nullptr};
  mutable std::vector<std::unique_ptr<State>> retired_;  // read lock-free by Claimed; freed with *this
};

}  // namespace mktree
