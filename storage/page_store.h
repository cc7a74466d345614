// PageStore: fixed-size pages addressed by index, behind one interface (HDF5, paged file, memory,
// fault-injecting wrapper). Thread safety: ReadPage may be called from many threads at once; writes never
// run concurrently with reads. The file stores (paged file, HDF5) also take writes of distinct pages from
// two threads at once (a store's leaf pages and its record pages, engine/store_format/store_file.h); the
// others from one writer.
#pragma once

#include <cstdint>
#include <string>

#include "mktree/status.h"

namespace mktree {

// The error every backend gives for a page index past its end.
inline Status PageOutOfRange(const std::string& store, uint64_t index, uint64_t count) {
  return Status::InvalidArgument(store + ": page " + std::to_string(index) + " out of range (" +
                                 std::to_string(count) + " pages)");
}

class PageStore {
 public:
  virtual ~PageStore() = default;
  virtual uint64_t page_bytes() const = 0;
  virtual uint64_t page_count() const = 0;
  // Reads page `index` (page_bytes() bytes) into `out`. Error names the store and the page.
  virtual Status ReadPage(uint64_t index, uint8_t* out) const = 0;
  // Writes page `index`. The file stores accept any index (page_count() becomes the largest written + 1,
  // and the writer checks that no page is left out); the memory store only index <= page_count().
  virtual Status WritePage(uint64_t index, const uint8_t* data) = 0;
  // Writes pages first .. first + count - 1 from `count` pages of bytes back to back: one system call
  // where the store can (small writes cost the page cache several times what large ones do per byte).
  virtual Status WritePages(uint64_t first, uint64_t count, const uint8_t* data) {
    for (uint64_t i = 0; i < count; ++i)
      MKTREE_RETURN_IF_ERROR(WritePage(first + i, data + i * page_bytes()));
    return Status::Ok();
  }
  virtual Status Sync() = 0;
  // The file (or "memory") the store lives in, for error messages.
  virtual const std::string& name() const = 0;
  // Page `index` in place when the store maps its file read-only (a cache miss then copies nothing), or
  // nullptr: read it with ReadPage. Valid as long as the store. REQUIRES index < page_count().
  virtual const uint8_t* MappedPage(uint64_t index) const {
    (void)index;
    return nullptr;
  }
};

}  // namespace mktree
