// Stage 3 of BuildStore (build_stages.h; docs/design.md §10): writes a built tree's leaf pages, in leaf
// (= page) order, from objects' entries spilled in id order, and fills the tree's leaf filter with each
// entry's box as its leaf is written. The spill is in id order and leaves are not, so a leaf's entries are
// scattered: they are read a window of whole leaves at a time (up to kWindowBytes of entries, at least one
// leaf), sorted and gathered into few system calls (SpillFile::ReadMany), the next window on another thread
// while one is assembled into pages. Internal to engine/ingest.
//
// Thread safety: WriteLeafPages runs on the calling thread plus one read-ahead thread of its own; `entries`
// must not be written while it runs.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/ingest/build_stages.h"
#include "engine/tree/mktree_builder.h"
#include "storage/page_store.h"

namespace mktree {

// Where each object's entry lies in a spill that holds the entries of objects 0..n-1 back to back in id
// order: the offsets are the prefix sums of the sizes, one kept every kStride objects (8 bytes an object
// at the write stage's peak otherwise) and the rest summed when asked.
class SpilledEntries {
 public:
  // Indexes `file` by the entries' sizes. Internal error when the sizes do not add up to the file's size.
  static Result<SpilledEntries> Index(const SpillFile& file, std::vector<uint32_t> sizes);
  const SpillFile& file() const { return *file_; }
  uint64_t count() const { return sizes_.size(); }
  uint32_t size(ObjectId id) const { return sizes_[id]; }
  uint64_t offset(ObjectId id) const;

 private:
  static constexpr size_t kStride = 32;
  explicit SpilledEntries(const SpillFile& file) : file_(&file) {}
  const SpillFile* file_;
  std::vector<uint32_t> sizes_;
  std::vector<uint64_t> offsets_;  // offsets_[i]: object i * kStride's
};

// Writes the leaf pages of `built` (its tree's leaves, leaf_objects and leaf_offsets) through `pages`,
// pages 0 on, each leaf EncodeLeafPages' pages of `mem_page` bytes; fills built->tree.leaf_filter and
// indexes it. `entries` holds every object of the tree; it is consumed, so that its memory is freed as soon
// as the pages are written. Reports IngestStage::kWritePages. Returns the number of pages written. Errors:
// the spill's, the page store's, and Internal when an entry or the tree's page numbers disagree with what is
// written.
Result<uint64_t> WriteLeafPages(SpilledEntries entries, uint64_t mem_page, BuildResult* built,
                                PageStore& pages, const IngestOptions& options);

}  // namespace mktree
