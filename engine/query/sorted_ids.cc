#include "engine/query/sorted_ids.h"

#include <algorithm>
#include <cstdint>
#include <utility>

namespace mktree {

// Sorts ids ascending: from 64 ids by radix, 8 bits a pass over the bits the largest id has, a pass
// skipped when all ids share its digit (std::sort takes ~log2(n) mispredicted comparisons per id).
void SortIds(std::vector<ObjectId>* ids) {
  constexpr size_t kRadixFrom = 64;
  const size_t n = ids->size();
  if (n < kRadixFrom) {
    std::sort(ids->begin(), ids->end());
    return;
  }
  ObjectId largest = 0;
  for (ObjectId id : *ids) largest = std::max(largest, id);
  const int passes = largest == 0 ? 0 : (32 - __builtin_clz(largest) + 7) / 8;
  uint32_t counts[4][256] = {};
  for (ObjectId id : *ids)
    for (int pass = 0; pass < passes; ++pass) ++counts[pass][(id >> (8 * pass)) & 255];
  thread_local std::vector<ObjectId> other;
  other.resize(n);
  std::vector<ObjectId>* from = ids;
  std::vector<ObjectId>* to = &other;
  for (int pass = 0; pass < passes; ++pass) {
    const int shift = 8 * pass;
    if (counts[pass][(from->front() >> shift) & 255] == n) continue;  // one digit: order unchanged
    uint32_t at = 0;
    for (uint32_t& c : counts[pass]) at += std::exchange(c, at);
    for (ObjectId id : *from) (*to)[counts[pass][(id >> shift) & 255]++] = id;
    std::swap(from, to);
  }
  if (from != ids) ids->swap(other);  // the sorted ids are in `other`
}

// After SortIds: an id twice is an object in two leaves, which the open and leaf checks let through only
// for leaf id digests crafted to collide (docs/store_format.md). Ids missing from that store go unseen.
Status CheckNoRepeatedIds(const std::vector<ObjectId>& sorted, const std::string& path) {
  const auto twice = std::adjacent_find(sorted.begin(), sorted.end());
  if (twice == sorted.end()) return Status::Ok();
  return Status::Corruption(path + ": object " + std::to_string(*twice) +
                            " is in two leaves (their id digests were made to collide)");
}

}  // namespace mktree
