#include "engine/clash/part_numbering.h"

#include <algorithm>

#include "engine/clash/clash_reads.h"

namespace mktree::clash {

Result<PartNumbering> PartNumbering::Make(const std::vector<ClashPart>& parts) {
  const size_t np = parts.size();
  PartNumbering n;
  n.parts_ = &parts;
  n.leaf_base_.assign(np + 1, 0);
  n.page_base_.assign(np + 1, 0);
  for (size_t k = 0; k < np; ++k) {
    const StoreReader& r = parts[k].leaves->reader();
    const MKTree& t = r.tree();
    n.trees_.push_back(&t);
    n.paths_.push_back(&r.path());
    n.object_counts_.push_back(r.object_count());
    n.leaf_base_[k + 1] = n.leaf_base_[k] + static_cast<uint32_t>(t.leaves.size());
    n.part_of_.resize(n.leaf_base_[k + 1], static_cast<uint32_t>(k));
    n.page_base_[k + 1] = n.page_base_[k] + r.pages().page_count();
    n.store_pages_ += StorePages(t);
    const std::vector<ObjectId>* ids = parts[k].ids;
    if (ids && ids->size() != r.object_count())
      return Status::Internal(r.path() + ": the part's id map does not match its objects");
    if (parts[k].hidden && parts[k].hidden->size() != r.object_count())
      return Status::Internal(r.path() + ": the part's hidden flags do not match its objects");
    n.global_count_ = std::max<uint64_t>(
        n.global_count_, ids ? (ids->empty() ? 0 : ids->back() + uint64_t{1}) : r.object_count());
    n.cache_bytes_ += parts[k].leaves->cache().capacity() * t.params.mem_page();
  }
  return n;
}

}  // namespace mktree::clash
