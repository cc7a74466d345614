// The streamed batch shared by every Database (RunBatchStreamed's contract, include/mktree/database.h):
// queries from a source run on worker threads and their results are delivered in the source's order,
// with at most `window` results held at once. Internal to engine/query.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "engine/core/guarded.h"
#include "mktree/database.h"

namespace mktree {

// `st` with `prefix` before its message, its code kept.
Status Prefixed(const Status& st, const std::string& prefix);

// The worker state of a batch that needs none.
struct NoWorker {};

// Runs `source`'s queries with `run(query, worker, &result)`, where `worker` is the calling worker's
// `std::unique_ptr<Worker>` from `make_worker()` (made on the worker's first query: a private page cache,
// or null), and hands the results to `deliver` in order. `threads` <= 1, or no thread starting, runs
// everything on the calling thread. `path` names the store in the errors of exceptions.
template <typename Worker, typename MakeWorker, typename Run>
Status RunOrderedBatch(const QuerySource& source, unsigned threads, uint64_t window, const std::string& path,
                       MakeWorker make_worker, Run run, const ResultVisitor& deliver) {
  auto failed = [](uint64_t i, const Status& st) {
    return Prefixed(st, "query " + std::to_string(i) + ": ");
  };

  // The calling thread reads the source into a ring of `window` slots and delivers them in order;
  // workers run the slots in order. Slot i % window is refilled only after result i is delivered.
  struct Slot {
    Query query;
    QueryResult result;
    Status status;
    bool done = false;
  };
  std::vector<Slot> slots(threads > 1 ? window : 0);
  std::mutex mu;
  std::condition_variable ready, done;
  uint64_t filled = 0, started = 0;  // under mu
  bool stop = false;                 // under mu
  auto work = [&]() noexcept {
    std::unique_ptr<Worker> own;
    bool made = false;
    std::unique_lock<std::mutex> lock(mu);
    while (true) {
      ready.wait(lock, [&] { return stop || started < filled; });
      if (stop) return;
      Slot& slot = slots[started++ % window];
      lock.unlock();
      Status st;
      try {
        if (!made) own = make_worker(), made = true;
        st = run(slot.query, own.get(), &slot.result);
      } catch (...) {
        st = StatusOfCurrentException(path);
      }
      lock.lock();
      slot.status = std::move(st);
      slot.done = true;
      done.notify_all();
    }
  };
  std::vector<std::thread> pool;
  struct Join {  // on every way out: stop the workers (a running query finishes first) and join them
    std::mutex& mu;
    bool& stop;
    std::condition_variable& ready;
    std::vector<std::thread>& pool;
    ~Join() {
      {
        std::lock_guard<std::mutex> lock(mu);
        stop = true;
      }
      ready.notify_all();
      for (auto& t : pool) t.join();
    }
  } join{mu, stop, ready, pool};
  if (threads > 1) {
    try {
      pool.reserve(threads);
      for (unsigned t = 0; t < threads; ++t) pool.emplace_back(work);
    } catch (...) {
      // A thread that cannot start leaves its share to the others.
    }
  }

  if (pool.empty()) {  // one thread: each query on the calling thread, delivered at once
    std::unique_ptr<Worker> own = make_worker();
    QueryResult r;
    Query q;
    for (uint64_t i = 0;; ++i) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, source(&q));
      if (!more) return Status::Ok();
      Status st = run(q, own.get(), &r);
      if (!st.ok()) return failed(i, st);
      MKTREE_RETURN_IF_ERROR(deliver(i, r));
    }
  }

  Status source_status;
  bool source_done = false;
  for (uint64_t delivered = 0;; ++delivered) {
    while (!source_done && filled < delivered + window) {
      Query q;
      Result<bool> more = source(&q);
      if (!more.ok() || !*more) {
        source_status = more.status();
        source_done = true;
        break;
      }
      {
        std::lock_guard<std::mutex> lock(mu);
        Slot& slot = slots[filled % window];
        slot.query = q;
        slot.done = false;
        ++filled;
      }
      ready.notify_one();
    }
    if (delivered == filled) return source_status;  // every query before the source's end or error
    Slot& slot = slots[delivered % window];
    {
      std::unique_lock<std::mutex> lock(mu);
      done.wait(lock, [&] { return slot.done; });
    }
    if (!slot.status.ok()) return failed(delivered, slot.status);
    MKTREE_RETURN_IF_ERROR(deliver(delivered, slot.result));
  }
}

}  // namespace mktree
