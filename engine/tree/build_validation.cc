#include "engine/tree/build_validation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "engine/tree/build_threads.h"
#include "engine/tree/page_budget.h"

namespace mktree::build {
namespace {

std::string Describe(const BuildObject& r) { return "object " + std::to_string(r.id); }

}  // namespace

Status Validate(const std::vector<BuildObject>& records, const BuildParams& params, int threads,
                Box3f* bounds, ObjectId* max_id) {
  if (!(params.balance_r >= 0 && params.balance_r < 0.5))
    return Status::InvalidArgument("balance ratio r = " + std::to_string(params.balance_r) +
                                   " outside [0, 0.5)");
  if (params.block_size == 0 || params.blocks_per_page == 0 ||
      params.mem_page() <= kPageHeaderBytes + kLeafHeaderBytes)
    return Status::InvalidArgument("page of " + std::to_string(params.mem_page()) +
                                   " bytes is not larger than its headers (" +
                                   std::to_string(kPageHeaderBytes + kLeafHeaderBytes) + " bytes)");
  if (records.size() >= kNoIndex) return Status::InvalidArgument("too many objects for 32-bit indices");
  struct Half {
    size_t bad = std::numeric_limits<size_t>::max();  // its first record with a bad box
    ObjectId max_id = 0;
    Box3f box;
  };
  Half half[2];
  RunOnHalves(records.size(), threads, [&](size_t lo, size_t hi) {
    // Kept here and stored once: the two halves' results share a cache line, and stores to it from both
    // threads in the loop made each half slower than the whole on one thread.
    Half h;
    for (size_t i = lo; i < hi; ++i) {
      const Box3f& b = records[i].box;
      // Finite with min <= max is -inf < min <= max < inf (NaN fails every comparison).
      constexpr float kInf = std::numeric_limits<float>::infinity();
      bool ok = true;
      for (int a = 0; a < 3; ++a) ok &= (b.min[a] > -kInf) & (b.min[a] <= b.max[a]) & (b.max[a] < kInf);
      if (!ok) {
        h.bad = i;
        break;
      }
      h.max_id = std::max(h.max_id, records[i].id);
      h.box.Extend(b);
    }
    half[lo == 0 ? 0 : 1] = h;
  });
  if (const size_t bad = std::min(half[0].bad, half[1].bad); bad < records.size()) {
    const BuildObject& r = records[bad];
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(r.box.min[i]) || !std::isfinite(r.box.max[i]))
        return Status::InvalidArgument(Describe(r) + ": bounding box is not finite");
      if (r.box.min[i] > r.box.max[i])
        return Status::InvalidArgument(Describe(r) + ": bounding box has min > max on axis " +
                                       std::to_string(i));
    }
  }
  *max_id = std::max(half[0].max_id, half[1].max_id);
  *bounds = half[0].box;
  bounds->Extend(half[1].box);
  return Status::Ok();
}

Status CheckUniqueIds(const std::vector<BuildObject>& records, ObjectId max_id) {
  const size_t n = records.size();
  if (uint64_t{max_id} > 64 * uint64_t{n}) {
    std::vector<ObjectId> sorted(n);
    for (size_t i = 0; i < n; ++i) sorted[i] = records[i].id;
    std::sort(sorted.begin(), sorted.end());
    auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end())
      return Status::InvalidArgument("object " + std::to_string(*dup) + ": duplicate object id");
    return Status::Ok();
  }
  std::vector<uint64_t> seen(max_id / 64 + 1, 0);
  for (const BuildObject& r : records) {
    uint64_t& word = seen[r.id / 64];
    const uint64_t bit = uint64_t{1} << (r.id % 64);
    if (word & bit)
      return Status::InvalidArgument("object " + std::to_string(r.id) + ": duplicate object id");
    word |= bit;
  }
  return Status::Ok();
}

}  // namespace mktree::build
