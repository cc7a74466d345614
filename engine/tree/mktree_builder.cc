#include "engine/tree/mktree_builder.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <thread>
#include <type_traits>

#include "engine/tree/box_lanes.h"
#include "engine/tree/build_layout.h"
#include "engine/tree/build_memory.h"
#include "engine/tree/build_state.h"
#include "engine/tree/build_threads.h"
#include "engine/tree/build_validation.h"
#include "engine/tree/page_budget.h"
#include "engine/tree/subtree_builder.h"

namespace mktree {
namespace {

using namespace build;

// Multi-thread build: workers take subtree tasks from a shared queue; each task is built depth-first into
// its own fragment, handing the right child of every large node back to the queue. The fragments are then
// stitched in DFS preorder (nodes, SplitTree nodes and leaves renumbered), which gives exactly the tree
// that one thread builds: every node's split depends only on its own objects.
void BuildParallel(BuildState* shared, const Task& root, int threads, SubtreeOut* out, double* stitch_seconds) {
  const uint32_t n = root.hi - root.lo;
  // Tasks of at least this many objects are shared; smaller ones are not worth a fragment.
  const uint32_t min_spawn = shared->tuning.parallel_task_objects > 0 ? shared->tuning.parallel_task_objects
                                                                      : std::max<uint32_t>(4096, n / 256);
  std::mutex mu;
  std::condition_variable cv;
  std::deque<std::pair<Task, uint32_t>> queue;
  std::atomic<uint32_t> queued_largest{0};  // (kept under mu, read without it)
  auto queue_changed = [&] {
    uint32_t largest = 0;
    for (const auto& q : queue) largest = std::max(largest, q.first.hi - q.first.lo);
    queued_largest.store(largest, std::memory_order_relaxed);
  };
  std::vector<std::unique_ptr<SubtreeOut>> frags;
  int busy = 0;
  frags.push_back(std::make_unique<SubtreeOut>());
  queue.push_back({root, 0});
  auto spawn = [&](const Task& t) {
    std::lock_guard<std::mutex> lock(mu);
    const uint32_t id = static_cast<uint32_t>(frags.size());
    frags.push_back(std::make_unique<SubtreeOut>());
    queue.push_back({t, id});
    queue_changed();
    cv.notify_one();
    return id;
  };
  class QueueSink final : public TaskSink {
   public:
    QueueSink(std::function<uint32_t(const Task&)> spawn, const std::atomic<uint32_t>* largest)
        : spawn_(std::move(spawn)), largest_(largest) {}
    uint32_t Spawn(const Task& t) override { return spawn_(t); }
    uint32_t LargestWaiting() const override { return largest_->load(std::memory_order_relaxed); }

   private:
    std::function<uint32_t(const Task&)> spawn_;
    const std::atomic<uint32_t>* largest_;
  } sink(spawn, &queued_largest);
  auto worker = [&] {
    SubtreeBuilder builder(shared, /*track_split_count=*/true);
    std::unique_lock<std::mutex> lock(mu);
    for (;;) {
      cv.wait(lock, [&] { return !queue.empty() || busy == 0; });
      if (queue.empty()) break;  // and nobody busy: done
      const auto [task, id] = queue.back();  // newest first: depth-first, smaller scratch
      queue.pop_back();
      queue_changed();
      SubtreeOut* frag = frags[id].get();
      ++busy;
      lock.unlock();
      builder.RunSpawning(task, frag, min_spawn, &sink);
      frag->ShrinkToFit();  // fragments live until stitched: no growth slack in the peak
      lock.lock();
      --busy;
      if (busy == 0 && queue.empty()) cv.notify_all();
    }
  };
  std::vector<std::thread> pool;
  for (int i = 1; i < threads; ++i) pool.emplace_back(worker);
  worker();
  for (std::thread& th : pool) th.join();
  ReleaseBuildLists(shared);  // before stitching, which holds the fragments and the tree at once

  // Stitch in DFS preorder. The SplitTrees (most of the bytes) are only placed by the walk and copied
  // after it, on two threads; the other thread sizes their array meanwhile.
  const auto stitch_start = std::chrono::steady_clock::now();
  size_t nodes = 0, splits = 0, leaves = 0;
  for (const auto& f : frags) nodes += f->nodes.size(), splits += f->split_nodes.size(), leaves += f->leaves.size();
  std::thread sizing([&] { out->split_nodes.resize(splits); });
  struct SplitCopy {
    const SplitNode* from;
    uint32_t count, at, base;
  };
  std::vector<SplitCopy> split_copies;
  uint32_t split_end = 0;
  out->nodes.reserve(nodes);
  out->leaves.reserve(leaves);
  out->leaf_begin.reserve(leaves + 1);
  out->overlap.reserve(nodes);
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
        split_copies.push_back({f.split_nodes.data() + nd.split_root, count, nd.split_root, split_end});
        nd.split_root = split_end;
        split_end += count;
      }
      const uint32_t right = nd.child[1];
      stack.push_back(right & kFragmentRef ? Ref{right & ~kFragmentRef, 0, g, 1} : Ref{r.frag, right, g, 1});
      stack.push_back(Ref{r.frag, nd.child[0], g, 0});
    }
    out->nodes.push_back(nd);
    out->overlap.push_back(f.overlap[r.node]);
  }
  sizing.join();
  // The copies in two runs of about equal SplitNode counts.
  auto copy = [&](size_t lo, size_t hi) {
    for (size_t i = lo; i < hi; ++i) {
      const SplitCopy& c = split_copies[i];
      SplitNode* to = out->split_nodes.data() + c.base;
      std::copy(c.from, c.from + c.count, to);
      RebaseSplitTree(to, c.count, c.base - c.at);
    }
  };
  const size_t middle = std::partition_point(split_copies.begin(), split_copies.end(),
                                             [&](const SplitCopy& c) { return c.base < split_end / 2; }) -
                        split_copies.begin();
  Together([&] { copy(middle, split_copies.size()); }, [&] { copy(0, middle); });
  *stitch_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - stitch_start).count();
}

}  // namespace

Result<BuildResult> BuildMKTree(std::vector<ObjectRecord> records, const BuildParams& params,
                                const BuildTuning& tuning) {
  using Clock = std::chrono::steady_clock;
  Clock::time_point mark = Clock::now();
  auto lap = [&mark](double* phase) {
    const Clock::time_point now = Clock::now();
    *phase = std::chrono::duration<double>(now - mark).count();
    mark = now;
  };
  const int threads =
      tuning.threads > 0 ? tuning.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  Box3f bounds;
  ObjectId max_id = 0;
  MKTREE_RETURN_IF_ERROR(Validate(records, params, threads, &bounds, &max_id));
  BuildResult result;
  result.tree.params = params;
  result.leaf_offsets.push_back(0);
  const uint32_t n = static_cast<uint32_t>(records.size());
  if (n == 0) {
    result.stats = ComputeTreeStats(result.tree, 0, {});
    return result;
  }

  BuildVector<ObjectId> ids;
  BuildRecords rec;
  BuildState shared{rec.box, rec.bytes, params, tuning, {}, {}};
  {
    BuildVector<uint32_t> input_position;
    rec = SpatialLayout(std::move(records), bounds, &ids, &input_position, threads);
    MKTREE_RETURN_IF_ERROR(CheckUniqueIds(ids, input_position, max_id));
  }
  lap(&result.timings.layout);
  SortKeyOrders(rec.box, threads, &shared.lists);
  TrimHeap();
  lap(&result.timings.sorts);
  shared.side.assign(n, 0);
  uint64_t total_bytes = 0;
  for (uint32_t b : rec.bytes) total_bytes += b;

  SubtreeOut out;
  Task root{0, n, 0, kNoIndex, 0, total_bytes};
  if (threads >= 2) {
    root.cooperative = n >= tuning.cooperative_root_objects;
    BuildParallel(&shared, root, threads, &out, &result.timings.stitch);
  } else {
    SubtreeBuilder(&shared).Run(root, &out);
    // The tree stays in RAM for the store's lifetime: no growth slack (the 2-thread stitch sizes it
    // exactly). Copied once the lists are gone, so under the build's peak.
    ReleaseBuildLists(&shared);
    out.ShrinkToFit();
  }

  lap(&result.timings.nodes);
  // Pages in leaf order.
  uint64_t page = 0;
  for (LeafInfo& lf : out.leaves) {
    lf.first_page = page;
    page += lf.page_count;
  }
  result.leaf_offsets = std::move(out.leaf_begin);
  result.leaf_offsets.push_back(n);
  result.tree.nodes = std::move(out.nodes);
  result.tree.split_nodes = std::move(out.split_nodes);
  result.tree.leaves = std::move(out.leaves);
  // The leaves' ranges of any list hold their objects: list 0, as ids, becomes leaf_objects.
  result.leaf_objects.resize(n);
  const uint32_t* leaf_order = shared.lists[0].data();
  RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    for (size_t i = lo; i < hi; ++i) result.leaf_objects[i] = ids[leaf_order[i]];
  });
  BuildVector<uint32_t>().swap(shared.lists[0]);
  result.stats = ComputeTreeStats(result.tree, n, out.overlap, threads);
  lap(&result.timings.finish);
  return result;
}

}  // namespace mktree
