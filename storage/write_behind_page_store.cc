#include "storage/write_behind_page_store.h"

#include <algorithm>
#include <cstring>

namespace mktree {

WriteBehindPageStore::WriteBehindPageStore(PageStore* base, uint64_t batch_bytes)
    : base_(base),
      batch_pages_(static_cast<size_t>(
          std::max<uint64_t>(1, batch_bytes / std::max<uint64_t>(1, base->page_bytes())))),
      count_(base->page_count()) {}

WriteBehindPageStore::WriteBehindPageStore(PageStore* base, uint64_t first_page, uint64_t batch_bytes)
    : base_(base),
      first_page_(first_page),
      batch_pages_(static_cast<size_t>(
          std::max<uint64_t>(1, batch_bytes / std::max<uint64_t>(1, base->page_bytes())))),
      count_(0) {}

WriteBehindPageStore::~WriteBehindPageStore() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
    queue_.clear();
  }
  work_cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

Status WriteBehindPageStore::WriteBatch(const Batch& b) {
  const uint64_t page = base_->page_bytes();
  // Runs of consecutive pages (a build writes little else) in one call each.
  for (size_t i = 0, run = 1; i < b.index.size(); i += run) {
    run = 1;
    while (i + run < b.index.size() && b.index[i + run] == b.index[i] + run) ++run;
    MKTREE_RETURN_IF_ERROR(base_->WritePages(first_page_ + b.index[i], run, b.bytes.data() + i * page));
  }
  return Status::Ok();
}

void WriteBehindPageStore::Run() {
  std::unique_lock<std::mutex> lock(mu_);
  while (true) {
    work_cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    Batch b = std::move(queue_.front());
    queue_.pop_front();
    busy_ = true;
    const bool failed = !error_.ok();
    lock.unlock();
    Status st = failed ? Status::Ok() : WriteBatch(b);  // after a failure, nothing more reaches the base
    lock.lock();
    if (!st.ok() && error_.ok()) error_ = std::move(st);
    b.index.clear();
    spare_.push_back(std::move(b));
    busy_ = false;
    done_cv_.notify_all();
  }
}

void WriteBehindPageStore::Submit() {
  if (filling_.index.empty()) return;
  std::unique_lock<std::mutex> lock(mu_);
  if (!thread_.joinable()) thread_ = std::thread([this] { Run(); });
  done_cv_.wait(lock, [this] { return queue_.size() < kQueuedBatches; });
  queue_.push_back(std::move(filling_));
  filling_ = Batch();
  if (!spare_.empty()) {
    filling_ = std::move(spare_.back());
    spare_.pop_back();
  }
  work_cv_.notify_one();
}

Status WriteBehindPageStore::WritePage(uint64_t index, const uint8_t* data) {
  if (index > count_)
    return Status::InvalidArgument(name() + ": page " + std::to_string(first_page_ + index) +
                                   " written out of order");
  if (index >= limit_)
    return Status::InvalidArgument(name() + ": page " + std::to_string(first_page_ + index) +
                                   " written past the " + std::to_string(limit_) + " pages of its stream");
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!error_.ok()) return error_;
  }
  const uint64_t page = base_->page_bytes();
  if (filling_.bytes.size() < batch_pages_ * page) filling_.bytes.resize(batch_pages_ * page);
  std::memcpy(filling_.bytes.data() + filling_.index.size() * page, data, page);
  filling_.index.push_back(index);
  if (index == count_) ++count_;
  if (filling_.index.size() == batch_pages_) Submit();
  return Status::Ok();
}

Status WriteBehindPageStore::Flush() {
  if (!thread_.joinable()) {
    // Nothing went to the thread: a small store is written here, without starting one.
    Status st = WriteBatch(filling_);
    filling_.index.clear();
    if (!st.ok() && error_.ok()) error_ = st;
    return error_;
  }
  Submit();
  std::unique_lock<std::mutex> lock(mu_);
  done_cv_.wait(lock, [this] { return queue_.empty() && !busy_; });
  return error_;
}

Status WriteBehindPageStore::ReadPage(uint64_t index, uint8_t* out) const {
  MKTREE_RETURN_IF_ERROR(const_cast<WriteBehindPageStore*>(this)->Flush());
  return base_->ReadPage(first_page_ + index, out);
}

Status WriteBehindPageStore::Sync() {
  MKTREE_RETURN_IF_ERROR(Flush());
  return base_->Sync();
}

}  // namespace mktree
