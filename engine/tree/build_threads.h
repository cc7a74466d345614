// The two ways the MKtree build (mktree_builder.h) puts a second thread to work outside its task queue
// (parallel_build.h): a loop over the objects in two halves, and two jobs side by side. Internal to
// engine/tree.
#pragma once

#include <cstddef>
#include <exception>
#include <thread>
#include <utility>

namespace mktree::build {

// fn(lo, hi) over [0, n) in two halves, the first on a thread of its own when there are threads to spare
// and enough objects to pay for one.
template <typename Fn>
void RunOnHalves(size_t n, int threads, Fn&& fn) {
  if (threads < 2 || n < (size_t{1} << 16)) {
    fn(size_t{0}, n);
    return;
  }
  std::thread first([&] { fn(size_t{0}, n / 2); });
  fn(n / 2, n);
  first.join();
}

// Runs a() here and b() on a thread of its own, and waits for both: for the parts of a multi-thread build
// during which the other threads have nothing to do (the root, the stitch). An exception of either (a
// spill file's error) is thrown here once both are done.
template <typename A, typename B>
void Together(A&& a, B&& b) {
  std::exception_ptr failed;
  std::thread other([&] {
    try {
      b();
    } catch (...) {
      failed = std::current_exception();
    }
  });
  try {
    a();
  } catch (...) {
    other.join();
    throw;
  }
  other.join();
  if (failed) std::rethrow_exception(failed);
}

}  // namespace mktree::build
