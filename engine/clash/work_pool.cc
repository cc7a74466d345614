#include "engine/clash/work_pool.h"

#include <utility>

namespace mktree::clash {

WorkPool::WorkPool(unsigned threads) {
  try {
    for (unsigned t = 1; t < threads; ++t) workers_.emplace_back([this] { Work(); });
  } catch (...) {
    // A thread that cannot start leaves its share to the others.
  }
  // Returns once every worker runs. A thread just started may wait on the caller's core for the kernel's
  // next load balancing (milliseconds here), the whole of a small collide; waiting lets it run.
  std::unique_lock<std::mutex> lock(mu_);
  done_.wait(lock, [&] { return started_ == workers_.size(); });
}

WorkPool::~WorkPool() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  start_.notify_all();
  for (auto& t : workers_) t.join();
}

void WorkPool::RunShare() {
  // Called with mu_ held; returns with it held.
  std::unique_lock<std::mutex> lock(mu_, std::adopt_lock);
  ++busy_;
  while (next_ < n_ && !error_) {
    const size_t i = next_++;
    lock.unlock();
    try {
      (*f_)(i);
    } catch (...) {
      lock.lock();
      if (!error_) error_ = std::current_exception();
      continue;
    }
    lock.lock();
  }
  if (--busy_ == 0) done_.notify_all();
  lock.release();
}

void WorkPool::Work() {
  std::unique_lock<std::mutex> lock(mu_);
  uint64_t seen = 0;  // the constructor's generation: a loop begun before this line runs is joined
  ++started_;
  done_.notify_all();
  for (;;) {
    start_.wait(lock, [&] { return stop_ || generation_ != seen; });
    if (stop_) return;
    seen = generation_;
    lock.release();  // RunShare adopts the held lock
    RunShare();
    lock = std::unique_lock<std::mutex>(mu_, std::adopt_lock);
  }
}

void WorkPool::For(size_t n, const std::function<void(size_t)>& f) { For(n, f, nullptr); }

namespace {

// Runs side (if any), keeping what it throws for after the loop.
std::exception_ptr RunSide(const std::function<void()>& side) {
  if (!side) return nullptr;
  try {
    side();
  } catch (...) {
    return std::current_exception();
  }
  return nullptr;
}

}  // namespace

void WorkPool::For(size_t n, const std::function<void(size_t)>& f, const std::function<void()>& side) {
  if (workers_.empty() || n <= 1) {
    const std::exception_ptr side_error = RunSide(side);
    for (size_t i = 0; i < n; ++i) f(i);
    if (side_error) std::rethrow_exception(side_error);
    return;
  }
  std::unique_lock<std::mutex> lock(mu_);
  f_ = &f;
  n_ = n;
  next_ = 0;
  error_ = nullptr;
  ++generation_;
  start_.notify_all();
  lock.unlock();
  const std::exception_ptr side_error = RunSide(side);
  lock.lock();
  lock.release();
  RunShare();
  lock = std::unique_lock<std::mutex>(mu_, std::adopt_lock);
  done_.wait(lock, [&] { return busy_ == 0 && (next_ >= n_ || error_); });
  f_ = nullptr;
  n_ = 0;
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
  if (side_error) std::rethrow_exception(side_error);
}

}  // namespace mktree::clash
