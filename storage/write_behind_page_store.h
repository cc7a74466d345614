// WriteBehindPageStore: a builder's pages written on a thread of their own, so that encoding the next pages
// overlaps the system calls (and HDF5's chunk bookkeeping) of the last ones.
//
// WritePage copies the page into a batch; full batches go to one writer thread, which hands them to the
// base store in the order they were written, each run of consecutive pages as one WritePages call. At most
// kQueuedBatches full batches wait, so the memory held is bounded (about 1 MiB). A failed write is sticky:
// the next WritePage, Flush or Sync returns it, and nothing after it reaches the base. Flush waits until
// the base has every page; Sync is Flush and the base's Sync.
//
// Thread safety: used by one thread, as a PageStore writer is; the writer thread is its own.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "storage/page_store.h"

namespace mktree {

class WriteBehindPageStore : public PageStore {
 public:
  // `base` must outlive this store. Batches hold about `batch_bytes` (at least one page).
  explicit WriteBehindPageStore(PageStore* base, uint64_t batch_bytes = kDefaultBatchBytes);
  // Pages 0, 1, 2, ... of this store are the base's pages first_page, first_page + 1, ...: a second
  // stream of pages into the same base, written while another stream writes the pages before first_page
  // (file stores only: page_store.h). Starts empty; never reads the base's count.
  WriteBehindPageStore(PageStore* base, uint64_t first_page, uint64_t batch_bytes);
  // Writes of 256 KiB cost the page cache no more per byte than larger ones; small ones cost several times
  // more (bench/README.md).
  static constexpr uint64_t kDefaultBatchBytes = uint64_t{256} << 10;
  // Stops the writer thread; pages not yet written are dropped (the caller flushes what it keeps).
  ~WriteBehindPageStore() override;
  WriteBehindPageStore(const WriteBehindPageStore&) = delete;
  WriteBehindPageStore& operator=(const WriteBehindPageStore&) = delete;

  uint64_t page_bytes() const override { return base_->page_bytes(); }
  // Pages written so far, including those the base has not been given yet.
  uint64_t page_count() const override { return count_; }
  // Flushes first (reads see every page written).
  Status ReadPage(uint64_t index, uint8_t* out) const override;
  // REQUIRES (else InvalidArgument, at once): index <= page_count() and index < the limit.
  Status WritePage(uint64_t index, const uint8_t* data) override;
  // Pages from `limit` on are refused from now on (another stream writes them).
  void SetLimit(uint64_t limit) { limit_ = limit; }
  Status Sync() override;
  const std::string& name() const override { return base_->name(); }

  // Waits until the base holds every page written; the first write error, if any.
  Status Flush();

 private:
  struct Batch {
    std::vector<uint64_t> index;
    std::vector<uint8_t> bytes;
  };
  static constexpr size_t kQueuedBatches = 2;

  void Submit();  // hands the filling batch to the writer thread
  void Run();     // the writer thread
  Status WriteBatch(const Batch& b);

  PageStore* const base_;
  const uint64_t first_page_ = 0;  // the base's index of page 0
  const size_t batch_pages_;
  uint64_t count_ = 0;
  uint64_t limit_ = UINT64_MAX;
  Batch filling_;

  std::mutex mu_;
  std::condition_variable work_cv_, done_cv_;
  std::deque<Batch> queue_;   // full batches, oldest first
  std::vector<Batch> spare_;  // written batches, their buffers reused
  bool busy_ = false;         // the writer thread holds a batch
  bool stop_ = false;
  Status error_;        // the first failed write
  std::thread thread_;  // started with the first full batch
};

}  // namespace mktree
