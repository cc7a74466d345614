// The parts of a clash over several stores (ClashPart: the shards of one sharded store) numbered as one:
// their leaves one after the other (part k's from leaf_base(k)), their pages likewise, their objects by
// global id. A self-clash of one store is one part, numbered as itself. Thread safety: immutable once made.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/tree/mktree.h"
#include "mktree/status.h"

namespace mktree::clash {

class PartNumbering {
 public:
  // Internal when a part's id map or hidden flags do not match its objects. `parts` must outlive the
  // numbering.
  static Result<PartNumbering> Make(const std::vector<ClashPart>& parts);

  size_t part_count() const { return parts_->size(); }
  const LeafSource& store(size_t k) const { return *(*parts_)[k].leaves; }
  const MKTree& tree(size_t k) const { return *trees_[k]; }
  const std::string& path(size_t k) const { return *paths_[k]; }

  uint32_t leaf_count() const { return leaf_base_.back(); }  // of all parts
  uint32_t leaf_base(size_t k) const { return leaf_base_[k]; }
  uint64_t page_base(size_t k) const { return page_base_[k]; }
  uint32_t part_of(uint32_t leaf) const { return part_of_[leaf]; }
  // The leaf's info in its part's tree.
  const LeafInfo& leaf_info(uint32_t leaf) const {
    return trees_[part_of_[leaf]]->leaves[leaf - leaf_base_[part_of_[leaf]]];
  }

  const std::vector<ObjectId>* ids(size_t k) const { return (*parts_)[k].ids; }  // null: local = global
  ObjectId global_id(size_t k, ObjectId id) const { return (*parts_)[k].ids ? (*(*parts_)[k].ids)[id] : id; }
  // Is part k's object `id` (local) hidden (ClashPart::hidden)?
  bool hidden(size_t k, ObjectId id) const {
    const std::vector<bool>* h = (*parts_)[k].hidden;
    return h && (*h)[id];
  }
  uint64_t object_count(size_t k) const { return object_counts_[k]; }
  uint64_t global_count() const { return global_count_; }  // above every global id

  uint64_t store_pages() const { return store_pages_; }  // of all parts' leaves
  uint64_t cache_bytes() const { return cache_bytes_; }  // of all parts' page caches

 private:
  const std::vector<ClashPart>* parts_ = nullptr;
  std::vector<const MKTree*> trees_;
  std::vector<const std::string*> paths_;
  std::vector<uint64_t> object_counts_;
  std::vector<uint32_t> leaf_base_, part_of_;
  std::vector<uint64_t> page_base_;
  uint64_t global_count_ = 0, store_pages_ = 0, cache_bytes_ = 0;
};

}  // namespace mktree::clash
