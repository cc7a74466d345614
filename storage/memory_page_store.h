// MemoryPageStore: pages in RAM (tests, and building stores in memory).
// FaultyPageStore: wraps another store and injects faults into reads (tests).
// Thread safety: as PageStore — concurrent ReadPage calls are safe; writes are single-threaded and never
// concurrent with reads. FaultyPageStore's fault settings must be made before concurrent reads start.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "storage/page_store.h"

namespace mktree {

class MemoryPageStore : public PageStore {
 public:
  explicit MemoryPageStore(uint64_t page_bytes, std::string name = "memory")
      : page_bytes_(page_bytes), name_(std::move(name)) {}
  uint64_t page_bytes() const override { return page_bytes_; }
  uint64_t page_count() const override { return count_; }
  Status ReadPage(uint64_t index, uint8_t* out) const override;
  // REQUIRES: index <= page_count() (append, or rewrite an existing page).
  Status WritePage(uint64_t index, const uint8_t* data) override;
  Status Sync() override { return Status::Ok(); }
  const std::string& name() const override { return name_; }
  // Direct access for tests that corrupt pages. REQUIRES: index < page_count().
  uint8_t* mutable_page(uint64_t index) { return data_.data() + index * page_bytes_; }

 private:
  uint64_t page_bytes_;
  uint64_t count_ = 0;
  std::string name_;
  std::vector<uint8_t> data_;
};

class FaultyPageStore : public PageStore {
 public:
  explicit FaultyPageStore(PageStore* base) : base_(base) {}
  // Owns its base (to stand in for a store's pages: StoreReader::WrapPages).
  explicit FaultyPageStore(std::unique_ptr<PageStore> base) : owned_(std::move(base)), base_(owned_.get()) {}
  // The k-th ReadPage call from now (1-based, counting all pages) fails with IOError; 0 disables.
  void FailNthRead(uint64_t k) { fail_at_ = k == 0 ? 0 : reads_.load() + k; }
  // Every read of `page` returns it with byte `offset` XORed with `mask` (a silent media error).
  void FlipByte(uint64_t page, uint64_t offset, uint8_t mask = 0x01) {
    flip_page_ = page;
    flip_offset_ = offset;
    flip_mask_ = mask;
  }
  // Every read of `page` delivers only its first `bytes` bytes and zeros after them, reporting success
  // (a short read the OS layer failed to notice).
  void ShortRead(uint64_t page, uint64_t bytes) {
    short_page_ = page;
    short_bytes_ = bytes;
  }
  void ClearFaults() {
    fail_at_ = 0;
    flip_page_ = short_page_ = UINT64_MAX;
  }
  uint64_t reads() const { return reads_.load(); }

  uint64_t page_bytes() const override { return base_->page_bytes(); }
  uint64_t page_count() const override { return base_->page_count(); }
  Status ReadPage(uint64_t index, uint8_t* out) const override;
  Status WritePage(uint64_t index, const uint8_t* data) override { return base_->WritePage(index, data); }
  Status Sync() override { return base_->Sync(); }
  const std::string& name() const override { return base_->name(); }

 private:
  std::unique_ptr<PageStore> owned_;
  PageStore* base_;
  mutable std::atomic<uint64_t> reads_{0};
  uint64_t fail_at_ = 0;
  uint64_t flip_page_ = UINT64_MAX, flip_offset_ = 0;
  uint8_t flip_mask_ = 1;
  uint64_t short_page_ = UINT64_MAX, short_bytes_ = 0;
};

}  // namespace mktree
