#include "engine/tree/parallel_build.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <exception>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

#include "engine/tree/build_threads.h"
#include "engine/tree/subtree_builder.h"

namespace mktree::build {
namespace {

using Fragments = std::vector<std::unique_ptr<SubtreeOut>>;

// The shared queue of subtree tasks, each with the fragment it is built into (fragment 0: the root's).
class TaskPool final : public TaskSink {
 public:
  explicit TaskPool(const Task& root) {
    frags_.push_back(std::make_unique<SubtreeOut>());
    queue_.push_back({root, 0});
  }

  uint32_t Spawn(const Task& t) override {
    std::lock_guard<std::mutex> lock(mu_);
    const uint32_t id = static_cast<uint32_t>(frags_.size());
    frags_.push_back(std::make_unique<SubtreeOut>());
    queue_.push_back({t, id});
    QueueChanged();
    cv_.notify_one();
    return id;
  }

  uint32_t LargestWaiting() const override { return queued_largest_.load(std::memory_order_relaxed); }

  // One worker: builds tasks (their right children of at least `min_spawn` objects spawned) until the
  // queue is empty and no worker is busy.
  void Work(BuildState* state, uint32_t min_spawn) {
    SubtreeBuilder builder(state, /*track_split_count=*/true);
    std::unique_lock<std::mutex> lock(mu_);
    for (;;) {
      cv_.wait(lock, [&] { return !queue_.empty() || busy_ == 0; });
      if (failed_) queue_.clear();
      if (queue_.empty()) break;              // and nobody busy (or a task failed): done
      const auto [task, id] = queue_.back();  // newest first: depth-first, smaller scratch
      queue_.pop_back();
      QueueChanged();
      SubtreeOut* frag = frags_[id].get();
      ++busy_;
      lock.unlock();
      std::exception_ptr failed;
      try {
        builder.RunSpawning(task, frag, min_spawn, this);
        frag->ShrinkToFit();  // fragments live until stitched: no growth slack in the peak
      } catch (...) {
        failed = std::current_exception();
      }
      lock.lock();
      if (failed) {  // (a spill file's error) the first is kept; nothing more is built
        if (!failed_) failed_ = failed;
      }
      if (failed_) queue_.clear();
      --busy_;
      if (busy_ == 0 && queue_.empty()) cv_.notify_all();
    }
  }

  // Once every worker is done.
  const Fragments& fragments() const { return frags_; }
  // Once every worker is done: the first exception a task threw, if any.
  std::exception_ptr failed() const { return failed_; }

 private:
  void QueueChanged() {  // (under mu_)
    uint32_t largest = 0;
    for (const auto& q : queue_) largest = std::max(largest, q.first.hi - q.first.lo);
    queued_largest_.store(largest, std::memory_order_relaxed);
  }

  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::pair<Task, uint32_t>> queue_;  // (task, fragment id)
  std::atomic<uint32_t> queued_largest_{0};      // (kept under mu_, read without it)
  Fragments frags_;
  int busy_ = 0;
  std::exception_ptr failed_;
};

// A SplitTree placed by the stitch's walk: `count` nodes at `from` (index `at` in its fragment) go to
// index `base` of the tree's SplitNodes.
struct SplitCopy {
  const SplitNode* from;
  uint32_t count, at, base;
};

// The stitch's walk: the fragments' nodes and leaves into `out` in DFS preorder, renumbered; the
// SplitTrees only placed (into *copies), ending at *split_end.
void StitchNodes(const Fragments& frags, SubtreeOut* out, std::vector<SplitCopy>* copies,
                 uint32_t* split_end) {
  struct Ref {
    uint32_t frag, node, parent;
    int slot;
  };
  std::vector<Ref> stack{{0, 0, kNoIndex, 0}};
  while (!stack.empty()) {
    const Ref r = stack.back();
    stack.pop_back();
    const SubtreeOut& f = *frags[r.frag];
    TreeNode nd = f.nodes[r.node];
    const uint32_t g = static_cast<uint32_t>(out->nodes.size());
    if (r.parent != kNoIndex) out->nodes[r.parent].child[r.slot] = g;
    if (nd.is_leaf()) {
      LeafInfo lf = f.leaves[nd.leaf];
      out->leaf_begin.push_back(f.leaf_begin[nd.leaf]);
      nd.leaf = static_cast<uint32_t>(out->leaves.size());
      lf.node = g;
      out->leaves.push_back(lf);
    } else {
      if (nd.split_root != kNoIndex) {
        const uint32_t count = f.split_count[r.node];
        copies->push_back({f.split_nodes.data() + nd.split_root, count, nd.split_root, *split_end});
        nd.split_root = *split_end;
        *split_end += count;
      }
      const uint32_t right = nd.child[1];
      stack.push_back(right & kFragmentRef ? Ref{right & ~kFragmentRef, 0, g, 1} : Ref{r.frag, right, g, 1});
      stack.push_back(Ref{r.frag, nd.child[0], g, 0});
    }
    out->nodes.push_back(nd);
    out->overlap.push_back(f.overlap[r.node]);
  }
}

// Stitch in DFS preorder. The SplitTrees (most of the bytes) are only placed by the walk and copied after
// it, on two threads; the other thread sizes their array meanwhile.
void Stitch(const Fragments& frags, SubtreeOut* out) {
  size_t nodes = 0, splits = 0, leaves = 0;
  for (const auto& f : frags)
    nodes += f->nodes.size(), splits += f->split_nodes.size(), leaves += f->leaves.size();
  std::thread sizing([&] { out->split_nodes.resize(splits); });
  std::vector<SplitCopy> copies;
  uint32_t split_end = 0;
  out->nodes.reserve(nodes);
  out->leaves.reserve(leaves);
  out->leaf_begin.reserve(leaves + 1);
  out->overlap.reserve(nodes);
  StitchNodes(frags, out, &copies, &split_end);
  sizing.join();
  // The copies in two runs of about equal SplitNode counts.
  auto copy = [&](size_t lo, size_t hi) {
    for (size_t i = lo; i < hi; ++i) {
      const SplitCopy& c = copies[i];
      SplitNode* to = out->split_nodes.data() + c.base;
      std::copy(c.from, c.from + c.count, to);
      RebaseSplitTree(to, c.count, c.base - c.at);
    }
  };
  const size_t middle = std::partition_point(copies.begin(), copies.end(),
                                             [&](const SplitCopy& c) { return c.base < split_end / 2; }) -
                        copies.begin();
  Together([&] { copy(middle, copies.size()); }, [&] { copy(0, middle); });
}

}  // namespace

double BuildParallel(BuildState* state, const Task& root, int threads, SubtreeOut* out) {
  const uint32_t n = root.hi - root.lo;
  // Tasks of at least this many objects are shared; smaller ones are not worth a fragment.
  const uint32_t min_spawn = state->tuning.parallel_task_objects > 0 ? state->tuning.parallel_task_objects
                                                                     : std::max<uint32_t>(4096, n / 256);
  TaskPool pool(root);
  std::vector<std::thread> workers;
  for (int i = 1; i < threads; ++i) workers.emplace_back([&] { pool.Work(state, min_spawn); });
  pool.Work(state, min_spawn);
  for (std::thread& th : workers) th.join();
  if (pool.failed()) std::rethrow_exception(pool.failed());
  ReleaseBuildLists(state);  // before stitching, which holds the fragments and the tree at once

  const auto stitch_start = std::chrono::steady_clock::now();
  Stitch(pool.fragments(), out);
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - stitch_start).count();
}

}  // namespace mktree::build
