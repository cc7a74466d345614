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
#include "engine/tree/split_choice.h"
#include "engine/tree/page_budget.h"
#include "engine/tree/split_tree_builder.h"

namespace mktree {
namespace {

using namespace build;

// The scratch arrays keep room for a node still to come of up to this many objects (RunSpawning). At 1M,
// 2 threads: 2^16 keeps most of the faults saved (57k a build, against 56k unbounded and 63k without) at
// the old peak; 2^18 and more keep room the peak pays for (97 B/obj).
constexpr uint32_t kRetainObjects = 1u << 16;

// Appends the `count` nodes of a SplitTree whose child indices count from tree[0] (its root) to *out, the
// indices moved to their new place; returns the new root index. One copy, then the rebase (a 1M-object
// tree has 865k SplitNodes: a push_back each costs more).
uint32_t AppendSplitTree(const SplitNode* tree, uint32_t count, std::vector<SplitNode>* out) {
  const uint32_t base = static_cast<uint32_t>(out->size());
  out->insert(out->end(), tree, tree + count);
  RebaseSplitTree(out->data() + base, count, base);
  return base;
}

class SubtreeBuilder {
 public:
  explicit SubtreeBuilder(BuildState* s, bool track_split_count = false)
      : s_(*s), box_(s->box), bytes_(s->bytes), mem_page_(s->params.mem_page()), track_split_count_(track_split_count),
        chooser_(*s) {}

  // Like Run, but the right child of a node with at least `min_spawn` objects becomes a task of its own
  // (spawn(task) returns its fragment id), referenced as kFragmentRef | id in child[1]. `queued_largest`:
  // the objects of the largest task waiting in the queue (this builder may take it next).
  template <typename Spawn>
  void RunSpawning(const Task& root, SubtreeOut* out, uint32_t min_spawn, Spawn&& spawn,
                   const std::atomic<uint32_t>* queued_largest = nullptr) {
    std::vector<Task> stack{root};
    Task kids[2];
    while (!stack.empty()) {
      const Task t = stack.back();
      stack.pop_back();
      if (ProcessNode(t, out, kids)) {
        if (kids[1].hi - kids[1].lo >= min_spawn) {
          const uint32_t me = kids[1].parent;
          kids[1].parent = kNoIndex;
          out->nodes[me].child[1] = kFragmentRef | spawn(kids[1]);
        } else {
          stack.push_back(kids[1]);
        }
        stack.push_back(kids[0]);  // left next: it becomes node n+1 (DFS preorder)
      }
      // The scratch arrays were sized for the largest node so far; give the memory back once every node
      // still to come is under 2/3 of that, so that it does not add to the peak when the SplitTrees have
      // grown. (Not just the next node: pages given back and taken again are faulted in again. But only up
      // to kRetainObjects: keeping more costs RAM for the whole left subtree and saves few faults.)
      if (!stack.empty()) {
        uint32_t largest = queued_largest != nullptr ? queued_largest->load(std::memory_order_relaxed) : 0;
        for (const Task& p : stack) largest = std::max(largest, p.hi - p.lo);
        ShrinkScratch(std::max(stack.back().hi - stack.back().lo, std::min(largest, kRetainObjects)));
      }
    }
  }

  // Builds the whole subtree of `root` into `out`: RunSpawning with a threshold no subtree reaches.
  void Run(const Task& root, SubtreeOut* out) {
    RunSpawning(root, out, std::numeric_limits<uint32_t>::max(), [](const Task&) -> uint32_t { return kNoIndex; });
  }

  // Appends the node of `t` to `out`; returns true with its two child tasks when it is internal.
  bool ProcessNode(const Task& t, SubtreeOut* out, Task kids[2]) {
    const uint32_t n = t.hi - t.lo;
    const uint32_t me = static_cast<uint32_t>(out->nodes.size());
    if (t.parent != kNoIndex) out->nodes[t.parent].child[t.slot] = me;
    TreeNode node;
    if (t.leaf_lists_only) {
      for (uint32_t i = t.lo; i < t.hi; ++i) node.box.Extend(box_[s_.lists[0][i]]);
    } else {
      for (int w = 0; w < 3; ++w) {
        node.box.min[w] = box_[s_.lists[2 * w][t.lo]].min[w];
        node.box.max[w] = box_[s_.lists[2 * w + 1][t.hi - 1]].max[w];
      }
    }
    node.depth = static_cast<uint8_t>(std::min<uint32_t>(t.depth, 255));
    if (IsLeaf(n, t.bytes)) {
      node.leaf = static_cast<uint32_t>(out->leaves.size());
      LeafInfo leaf;
      leaf.box = node.box;
      leaf.node = me;
      leaf.object_count = n;
      leaf.payload_bytes = LeafPayloadBytes(t.bytes);
      leaf.page_count = static_cast<uint32_t>(PagesForLeaf(t.bytes, mem_page_));
      out->leaves.push_back(leaf);
      out->leaf_begin.push_back(t.lo);
      out->nodes.push_back(node);
      out->overlap.push_back(0);
      if (track_split_count_) out->split_count.push_back(0);
      return false;
    }

    const CutRange cuts = BalancedCuts(n, t.depth, s_.params.balance_r);
    const Candidate best = chooser_.Choose(t, cuts);
    const int w = best.list / 2;
    node.axis = static_cast<uint8_t>(w);

    const uint32_t* chosen = s_.lists[best.list].data() + t.lo;
    uint8_t* const side = s_.side.data();  // local: a byte store may alias any pointer the loop would reload
    auto mark_sides = [side, chosen, k = size_t{best.k}, n = size_t{n}] {  // by value: byte stores alias all
      for (size_t i = 0; i < k; ++i) side[chosen[i]] = 0;
      for (size_t i = k; i < n; ++i) side[chosen[i]] = 1;
    };

    // Objects meeting the closed slab: they decide the SplitTree, and the free ones among them may move.
    // When the split is by min_w (key 0), the loop below walks the chosen list itself, so an object's side
    // is its position (no read of side[], and the sides may be marked meanwhile).
    const bool key0 = best.list % 2 == 0;
    std::vector<SplitNode>& split = split_;  // (reused: no allocation a node)
    split.clear();
    uint32_t n_items = 0;
    auto gather_items = [&]<bool kKey0>() {
      // Branch-free: every object up to the slab's far end is written, and kept (the count advanced) when
      // it meets the slab, which is not predictable (in large nodes about half do). The arrays are sized
      // for the whole node, but only the pages written are touched. (Locals: the item stores could alias
      // what the closure refers to.)
      items_.Fit(n);
      overlap_ids_.Fit(n);
      SplitItem* const items = items_.data();
      uint32_t* const ids = overlap_ids_.data();
      const uint32_t* const by_min = s_.lists[2 * w].data();
      const Box3f* const box = box_.data();
      const uint32_t* const bytes = bytes_.data();
      const uint8_t* const sides = side;
      const float a = best.a, b = best.b;
      const int axis = w;
      const size_t lo = t.lo, hi = t.hi;  // (64-bit: no zero-extensions in the loop)
      const size_t prefetch_end = n >= kPrefetchObjects ? hi - kPrefetch : lo;
      const size_t first_right = lo + best.k;
      size_t count = 0;
      for (size_t i = lo; i < hi; ++i) {
        if (i < prefetch_end) {  // (box, bytes and side are each a random read in a large node)
          const uint32_t ahead = by_min[i + kPrefetch];
          __builtin_prefetch(&box[ahead]);
          __builtin_prefetch(&bytes[ahead]);
          if (!kKey0) __builtin_prefetch(&sides[ahead]);
        }
        const uint32_t idx = by_min[i];
        const Box3f& bx = box[idx];
        if (bx.min[axis] > b) break;  // sorted by min_w
        SplitItem& it = items[count];
        it.box = bx;
        it.box.min[axis] = std::max(bx.min[axis], a);
        it.box.max[axis] = std::min(bx.max[axis], b);
        it.default_side = kKey0 ? i >= first_right : sides[idx];
        it.bytes = bytes[idx];
        it.side = bx.min[axis] < a ? SplitItem::kLeft : (bx.max[axis] > b ? SplitItem::kRight : SplitItem::kFree);
        ids[count] = idx;
        count += bx.max[axis] >= a;
      }
      n_items = static_cast<uint32_t>(count);
    };
    if (!(best.a < best.b)) {
      mark_sides();
    } else if (!key0) {
      mark_sides();
      gather_items.template operator()<false>();
    } else if (t.cooperative) {
      Together(mark_sides, [&] { gather_items.template operator()<true>(); });
    } else {
      mark_sides();
      gather_items.template operator()<true>();
    }
    if (best.a < best.b) {
      SplitItem* const items = items_.data();
      const uint32_t* const ids = overlap_ids_.data();
      if (s_.params.split_tree_node_budget > 0) {
        Box3f q = node.box;
        q.min[w] = best.a;
        q.max[w] = best.b;
        BalanceWindow window;
        window.left = best.k;
        window.min_left = cuts.k_lo;
        window.max_left = cuts.k_hi;
        window.left_bytes = best.left_bytes;
        window.total_bytes = t.bytes;
        if (best.fill_aware) {  // keep the page counts the split was chosen for
          const uint64_t cap = PagePayloadCapacity(mem_page_);
          window.max_left_bytes = Pages(best.left_bytes) * cap - kLeafHeaderBytes;
          window.max_right_bytes = Pages(t.bytes - best.left_bytes) * cap - kLeafHeaderBytes;
        }
        BuildSplitTree(q, std::span<SplitItem>(items, n_items), s_.params.split_tree_node_budget, &window, &split,
                       s_.tuning.split_min_gain, &split_scratch_);
        for (uint32_t i = 0; i < n_items; ++i) side[ids[i]] = items[i].side;
      }
    }

    // Stable in-place partition of the lists by side, keeping each half sorted by its key. Branch-free:
    // the sides of neighbours in key order are not predictable. List 0 goes first and also sums the left
    // child's bytes: when both children are leaves, only list 0 (their objects) and the split axis' lists
    // (the planes below) are partitioned, as a leaf takes its box from its objects.
    tmp_.Fit(n);
    uint64_t left_bytes = 0;
    auto partition = [&]<bool kSumBytes>(int l, uint32_t* right) {
      // (Locals: the list stores could alias the task's bounds and the byte sum.)
      uint32_t* v = s_.lists[l].data();
      const uint8_t* side = s_.side.data();
      const uint32_t* bytes = bytes_.data();
      // 64-bit positions and 1 - r: no zero-extensions in the loop.
      const size_t lo = t.lo, hi = t.hi;
      size_t wpos = lo, tpos = 0;
      uint64_t sum = 0;
      for (size_t i = lo; i < hi; ++i) {
        const uint32_t idx = v[i];
        const size_t r = side[idx];
        v[wpos] = idx;
        right[tpos] = idx;
        wpos += 1 - r;
        tpos += r;
        if (kSumBytes) sum += bytes[idx] & (r - 1);  // r = 0: all bits
      }
      std::copy(right, right + tpos, v + wpos);
      if (kSumBytes) left_bytes = sum;
      return static_cast<uint32_t>(wpos - lo);
    };
    uint32_t n1 = 0;
    bool leaf_kids = false;
    auto lists_0_to_2 = [&] {
      n1 = partition.template operator()<true>(0, tmp_.data());
      leaf_kids = IsLeaf(n1, left_bytes) && IsLeaf(n - n1, t.bytes - left_bytes);
      for (int l = 1; l < 3; ++l)
        if (!leaf_kids || l / 2 == w) partition.template operator()<false>(l, tmp_.data());
    };
    if (t.cooperative) {  // lists 3-5 on the other thread (partitioned even for leaf children: harmless)
      Scratch<uint32_t> other_tmp;
      other_tmp.Reset(n);
      Together(lists_0_to_2, [&] {
        for (int l = 3; l < 6; ++l) partition.template operator()<false>(l, other_tmp.data());
      });
    } else {
      lists_0_to_2();
      for (int l = 3; l < 6; ++l)
        if (!leaf_kids || l / 2 == w) partition.template operator()<false>(l, tmp_.data());
    }
    // The stored planes are those of the final children (free objects may have narrowed the slab).
    node.a = box_[s_.lists[2 * w][t.lo + n1]].min[w];
    node.b = box_[s_.lists[2 * w + 1][t.lo + n1 - 1]].max[w];
    uint32_t sm = 0;
    if (node.a < node.b) {
      // The items' boxes are clipped to [best.a, best.b] on w, which holds [node.a, node.b] (the children
      // only lost or took free objects, which lie in it), so they meet the final slab as the objects do.
      const SplitItem* const items = items_.data();
      for (size_t i = 0; i < n_items; ++i) sm += items[i].box.max[w] > node.a && items[i].box.min[w] < node.b;
      if (!split.empty())
        node.split_root = AppendSplitTree(split.data(), static_cast<uint32_t>(split.size()), &out->split_nodes);
    }
    out->nodes.push_back(node);
    out->overlap.push_back(sm);
    if (track_split_count_)
      out->split_count.push_back(node.split_root == kNoIndex ? 0 : static_cast<uint32_t>(split.size()));
    kids[0] = Task{t.lo, t.lo + n1, t.depth + 1, me, 0, left_bytes, leaf_kids};
    kids[1] = Task{t.lo + n1, t.hi, t.depth + 1, me, 1, t.bytes - left_bytes, leaf_kids};
    return true;
  }

 private:
  bool IsLeaf(uint32_t count, uint64_t bytes) const { return build::IsLeaf(count, bytes, mem_page_); }

  void ShrinkScratch(size_t n) {
    if (tmp_.capacity() < n + n / 2 + (1u << 16)) return;
    const size_t freed = 7 * (tmp_.capacity() - n) * sizeof(float);  // about
    chooser_.ShrinkScratch(n);
    tmp_.Reset(n);
    split_scratch_.Release();
    if (items_.capacity() > n) items_.Reset(n);
    if (overlap_ids_.capacity() > n) overlap_ids_.Reset(n);
    if (freed >= kTrimBytes) TrimHeap();  // trimming is a walk of the heap: only for large frees
  }

  uint64_t Pages(uint64_t bytes) const { return PagesForLeaf(bytes, mem_page_); }

  BuildState& s_;
  const BuildVector<Box3f>& box_;
  const BuildVector<uint32_t>& bytes_;
  const uint64_t mem_page_;
  const bool track_split_count_;
  SplitChooser chooser_;
  Scratch<uint32_t> tmp_;
  Scratch<SplitItem> items_;  // the slab's objects (SplitTree items), at overlap_ids_ in the records
  std::vector<SplitNode> split_;  // the node's SplitTree
  SplitTreeScratch split_scratch_;
  Scratch<uint32_t> overlap_ids_;
};

// Frees what only the splits needed: lists 1-5 and the side flags (list 0 gives the leaves' objects).
void ReleaseBuildLists(BuildState* shared) {
  for (int l = 1; l < 6; ++l) BuildVector<uint32_t>().swap(shared->lists[l]);
  std::vector<uint8_t>().swap(shared->side);
  TrimHeap();
}

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
      builder.RunSpawning(task, frag, min_spawn, spawn, &queued_largest);
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
