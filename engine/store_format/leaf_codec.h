// A leaf on disk: its payload is a 16-byte leaf header followed by its objects' entries
// (engine/store_format/object_codec.h), cut into PagesForLeaf() pages of MemPage bytes, each with a page
// header (storage/page_codec.h).
//
// Leaf header (little-endian):
//   offset size field
//   0      4    object count
//   4      4    leaf index
//   8      8    payload bytes (this header included) = LeafPayloadBytes(sum of entry sizes)
//
// Thread safety: EncodeLeafPages is reentrant; a LeafView is immutable after Parse and may be read from
// many threads.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "engine/store_format/object_codec.h"
#include "engine/tree/page_budget.h"
#include "mktree/status.h"

namespace mktree {

// Splits the leaf payload (leaf header + `entries`, in order) into PagesForLeaf(sum of entry sizes,
// mem_page) pages of `mem_page` bytes, seals each (header + checksum) and calls emit(page) for each page
// in order; `page` is valid only during the call. Stops at and returns the first error from emit.
Status EncodeLeafPages(uint32_t leaf_index, const std::vector<std::span<const uint8_t>>& entries,
                       uint64_t mem_page, const std::function<Status(const uint8_t*)>& emit);

// A parsed leaf: its entries, as views into the pages it was parsed from (single-page leaf) or into its
// own joined copy (multi-page leaf). REQUIRES: the pages passed to Parse outlive the LeafView (keep the
// PageHandles pinned while using it).
class LeafView {
 public:
  LeafView() = default;
  // Move-only: entries may point into joined_, which a copy would not carry along.
  LeafView(const LeafView&) = delete;
  LeafView& operator=(const LeafView&) = delete;
  LeafView(LeafView&&) = default;
  LeafView& operator=(LeafView&&) = default;

  // Verifies every page's header (and checksum, when `verify_checksums`), that the pages belong to leaf
  // `leaf_index` in order (page i of the leaf is store page first_page + i), joins the payload and parses
  // the entries. Errors are Corruption naming `store_name` and the store page index.
  static Result<LeafView> Parse(const std::string& store_name, uint32_t leaf_index, uint64_t first_page,
                                const std::vector<const uint8_t*>& pages, uint64_t mem_page,
                                bool verify_checksums);
  // The same, into *out, reusing its buffers: a reader that parses leaf after leaf into one LeafView
  // allocates only for a leaf larger than any before. On error *out is left empty.
  static Status Parse(const std::string& store_name, uint32_t leaf_index, uint64_t first_page,
                      const std::vector<const uint8_t*>& pages, uint64_t mem_page, bool verify_checksums,
                      LeafView* out);
  // Empties the view (keeping its buffers), so that it points into no page.
  void Clear();

  size_t size() const { return entries_.size(); }
  const ObjectEntryView& entry(size_t i) const { return entries_[i]; }
  const std::vector<ObjectEntryView>& entries() const { return entries_; }
  uint32_t leaf_index() const { return leaf_index_; }
  uint64_t payload_bytes() const { return payload_bytes_; }

 private:
  uint32_t leaf_index_ = 0;
  uint64_t payload_bytes_ = 0;
  std::vector<uint8_t> joined_;  // multi-page leaves only; moving a vector keeps its data in place
  std::vector<ObjectEntryView> entries_;
};

}  // namespace mktree
