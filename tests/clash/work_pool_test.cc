// The clash engine's worker pool: every iteration once, the side work on the calling thread, errors.
#include "engine/clash/work_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <vector>

namespace mktree::clash {
namespace {

TEST(WorkPool, EveryIterationOnceWithSideWorkOnTheCallingThread) {
  for (unsigned threads : {1u, 2u, 4u}) {
    WorkPool pool(threads);
    for (size_t n : {size_t{0}, size_t{1}, size_t{7}, size_t{1000}}) {
      std::vector<std::atomic<int>> hits(n);
      std::thread::id side_thread;
      int sides = 0;
      pool.For(
          n, [&](size_t i) { hits[i].fetch_add(1); },
          [&] {
            side_thread = std::this_thread::get_id();
            ++sides;
          });
      EXPECT_EQ(sides, 1);
      EXPECT_EQ(side_thread, std::this_thread::get_id());
      for (size_t i = 0; i < n; ++i)
        EXPECT_EQ(hits[i].load(), 1) << threads << " threads, n " << n << ", i " << i;
    }
  }
}

// The first loop right after the pool is made runs on every thread: each iteration waits until all have
// begun, which only a worker that joins that loop lets happen. (A worker that started late used to take
// the loop in flight for done.)
TEST(WorkPool, WorkersJoinTheFirstLoop) {
  for (unsigned threads : {2u, 3u}) {
    WorkPool pool(threads);
    std::mutex mu;
    std::condition_variable all_in;
    size_t begun = 0;
    std::atomic<size_t> together{0};
    pool.For(threads, [&](size_t) {
      std::unique_lock<std::mutex> lock(mu);
      if (++begun == threads) all_in.notify_all();
      if (all_in.wait_for(lock, std::chrono::seconds(10), [&] { return begun == threads; })) together++;
    });
    EXPECT_EQ(together.load(), threads) << threads << " threads";
  }
}

TEST(WorkPool, ASideErrorComesBackAfterTheLoopIsDone) {
  for (unsigned threads : {1u, 2u}) {
    WorkPool pool(threads);
    std::atomic<size_t> done{0};
    EXPECT_THROW(pool.For(
                     500, [&](size_t) { done.fetch_add(1); }, [] { throw std::runtime_error("side"); }),
                 std::runtime_error);
    EXPECT_EQ(done.load(), 500u);  // nothing still runs against the caller's state
    // The pool is usable afterwards.
    std::atomic<size_t> again{0};
    pool.For(10, [&](size_t) { again.fetch_add(1); });
    EXPECT_EQ(again.load(), 10u);
  }
}

TEST(WorkPool, ALoopErrorIsRethrown) {
  WorkPool pool(2);
  EXPECT_THROW(pool.For(100,
                        [](size_t i) {
                          if (i == 37) throw std::runtime_error("37");
                        }),
               std::runtime_error);
}

}  // namespace
}  // namespace mktree::clash
