// A fixed set of worker threads that run the iterations of a loop, started once per clash call so
// that thousands of small batches do not pay a thread start each.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

#include "mktree/status.h"

namespace mktree::clash {

class WorkPool {
 public:
  // `threads` counts the caller, which works too: threads - 1 workers are started.
  explicit WorkPool(unsigned threads);
  ~WorkPool();
  WorkPool(const WorkPool&) = delete;
  WorkPool& operator=(const WorkPool&) = delete;

  unsigned threads() const { return static_cast<unsigned>(workers_.size()) + 1; }
  // Runs f(i) for every i in [0, n), in any order and on any thread, and returns when all are done. The
  // first exception f throws is rethrown here (the remaining iterations are skipped).
  void For(size_t n, const std::function<void(size_t)>& f);
  // The same, while the calling thread first runs side() (work that must stay on it, such as handing
  // earlier results to a visitor) and then joins the loop. An exception from side() is rethrown once the
  // loop is done.
  void For(size_t n, const std::function<void(size_t)>& f, const std::function<void()>& side);

 private:
  void Work();
  void RunShare();

  std::vector<std::thread> workers_;
  std::mutex mu_;
  std::condition_variable start_, done_;
  uint64_t generation_ = 0;
  bool stop_ = false;
  const std::function<void(size_t)>* f_ = nullptr;
  size_t n_ = 0, next_ = 0, busy_ = 0, started_ = 0;
  std::exception_ptr error_;
};

// The first error of `errors` (one per iteration of a loop, in order), or Ok.
inline Status FirstError(const std::vector<Status>& errors) {
  for (const Status& e : errors)
    if (!e.ok()) return e;
  return Status::Ok();
}

}  // namespace mktree::clash
