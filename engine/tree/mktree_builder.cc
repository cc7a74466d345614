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

#ifdef __GLIBC__
#include <malloc.h>
#endif
#ifdef __linux__
#include <sys/mman.h>
#endif

#include "engine/tree/box_lanes.h"
#include "engine/tree/page_budget.h"
#include "engine/tree/split_tree_builder.h"

namespace mktree {
namespace {

constexpr uint32_t kDepthGuard = 100;
constexpr size_t kTrimBytes = size_t{8} << 20;
constexpr double kGuardBalance = 0.25;
// How far ahead record reads in key order are prefetched, in nodes of at least kPrefetchObjects (smaller
// ones are in cache). Measured at 1M (1 thread, key sweeps of the nodes of 2^13 objects and more, three
// runs each): 16 ahead 119-146 ms, 32 114-120, 48 116-131, 64 91-148, 96 112-121.
constexpr uint32_t kPrefetch = 48;
constexpr uint32_t kPrefetchObjects = 8192;
// The scratch arrays keep room for a node still to come of up to this many objects (RunSpawning). At 1M,
// 2 threads: 2^16 keeps most of the faults saved (57k a build, against 56k unbounded and 63k without) at
// the old peak; 2^18 and more keep room the peak pays for (97 B/obj).
constexpr uint32_t kRetainObjects = 1u << 16;
// Cuts per block of the pruned candidate scan (ScanKeys).
constexpr uint32_t kPruneBlock = 64;

// Float -> uint32 whose unsigned order is the float order (for the radix sort).
inline uint32_t SortableBits(float f) {
  const uint32_t u = std::bit_cast<uint32_t>(f);
  return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

// The allocator of the build's large arrays.
// - No zero-fill: resize() constructs nothing (every element is written before it is read), so the page
//   faults happen in the loops that fill the arrays (on two threads for the layout), not in a serial memset.
//   Not even Box3f's member initializers run: they wrote the 24 bytes an object of the layout's box array
//   on one thread (1M tanker: 6k page faults, 12 ms, before the two-thread copy that overwrites them).
// - Arrays of 1 MiB or more are mapped on their own, so freeing one gives its memory back at once (not to
//   a heap whose holes the next allocations may not fit): 1M tanker, 1 thread, peak 93.3 -> 91.4 B/object.
// (Transparent huge pages for them were tried: the sorts' TLB misses drop, but on this VM a 2 MiB page
// costs more to fault in than 512 small ones: 10M layout 0.39 -> 0.93 s, sorts 0.52 -> 1.0 s. A 2 MiB
// page new to the process costs ~6 ms, one it freed moments before ~0.25 ms, 512 small ones ~1 ms; and
// random reads over a 24 MiB array take as long with huge pages: the key sweeps are not bound by the TLB.)
template <typename T>
struct BuildAllocator {
  using value_type = T;
  static constexpr size_t kMapBytes = size_t{1} << 20;  // smaller arrays come from malloc
  BuildAllocator() = default;
  template <typename U>
  BuildAllocator(const BuildAllocator<U>&) noexcept {}
  T* allocate(size_t n) {
#ifdef __linux__
    if (n * sizeof(T) >= kMapBytes) {
      void* p = mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      return static_cast<T*>(p);
    }
#endif
    void* p = std::malloc(std::max<size_t>(n * sizeof(T), 1));
    if (p == nullptr) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
#ifdef __linux__
    if (n * sizeof(T) >= kMapBytes) {
      munmap(p, n * sizeof(T));
      return;
    }
#endif
    std::free(p);
  }
  template <typename U>
  void construct(U*) noexcept {
    // Implicit-lifetime element types only (as for Scratch): the storage's objects exist once written.
    static_assert(std::is_trivially_copyable_v<U> && std::is_trivially_destructible_v<U>);
  }
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
  template <typename U>
  bool operator==(const BuildAllocator<U>&) const noexcept {
    return true;
  }
};
template <typename T>
using BuildVector = std::vector<T, BuildAllocator<T>>;

// LSD radix sort of (key << 32 | payload) pairs by the key, stable, writing the payloads in that order to
// *out (resized; b is scratch): 3 passes of 11/11/10 bits, far faster than an indirect comparison sort at
// 10M. `count` holds the three digits' counts (kRadixBuckets each), counted as *a was written; the last pass
// writes the payloads directly.
constexpr size_t kRadixBuckets = size_t{1} << 11;
void RadixSortPayloads(BuildVector<uint64_t>* a, BuildVector<uint64_t>* b, uint32_t* count,
                       BuildVector<uint32_t>* out) {
  const size_t n = a->size();
  b->resize(n);
  out->resize(n);
  constexpr int kShift[3] = {32, 43, 54};
  for (int pass = 0; pass < 3; ++pass) {
    uint32_t* c = count + pass * kRadixBuckets;
    uint32_t sum = 0;  // (fewer than 2^32 objects: BuildMKTree's REQUIRES)
    for (size_t i = 0; i < kRadixBuckets; ++i) {
      const uint32_t here = c[i];
      c[i] = sum;
      sum += here;
    }
    const int shift = kShift[pass];
    if (pass < 2) {
      for (uint64_t v : *a) (*b)[c[(v >> shift) & 0x7ff]++] = v;
      a->swap(*b);
    } else {
      for (uint64_t v : *a) (*out)[c[(v >> shift) & 0x7ff]++] = static_cast<uint32_t>(v);
    }
  }
}

// What the builder reads of an object, 28 bytes instead of ObjectRecord's 40, in two arrays: the boxes,
// and the encoded sizes (read alone when a node sums its bytes, 16 to a cache line). The ids are kept
// apart, for the end only.
struct BuildRecords {
  BuildVector<Box3f> box;
  BuildVector<uint32_t> bytes;
};

// Object indices sorted by one key (axis, min or max), stable: ties in layout order (which the input
// decides, as it decides the layout), so the boxes are read in order, not gathered. The radix digits are
// counted as the keys are written.
void SortByKey(const BuildVector<Box3f>& box, int axis, bool use_max, BuildVector<uint64_t>* a,
               BuildVector<uint64_t>* b, BuildVector<uint32_t>* out) {
  const size_t n = box.size();
  a->resize(n);
  // The top digit (sign, exponent) takes few values: neighbours' counts go to four copies (the last
  // three after the three digits' blocks), or each increment would wait for the last one.
  constexpr size_t kTop = kRadixBuckets / 2;
  std::vector<uint32_t> count(3 * kRadixBuckets + 3 * kTop, 0);
  uint32_t* const low = count.data();
  uint32_t* const mid = low + kRadixBuckets;
  uint32_t* const top = mid + kRadixBuckets;
  auto top_copy = [&](size_t copy) { return copy == 0 ? top : top + kRadixBuckets + (copy - 1) * kTop; };
  uint64_t* const keys = a->data();
  auto add = [&](size_t i, size_t copy) {
    const float k = use_max ? box[i].max[axis] : box[i].min[axis];
    const uint32_t bits = SortableBits(k);
    keys[i] = (uint64_t{bits} << 32) | i;
    ++low[bits & 0x7ff];
    ++mid[(bits >> 11) & 0x7ff];
    ++top_copy(copy)[bits >> 22];
  };
  size_t i = 0;
  for (; i + 4 <= n; i += 4) add(i, 0), add(i + 1, 1), add(i + 2, 2), add(i + 3, 3);
  for (; i < n; ++i) add(i, 0);
  for (size_t copy = 1; copy < 4; ++copy)
    for (size_t d = 0; d < kTop; ++d) top[d] += top_copy(copy)[d];
  RadixSortPayloads(a, b, count.data(), out);
}

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

// Spreads the low 10 bits of v to every third bit (Morton code helper).
inline uint32_t Spread3(uint32_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x030000ff;
  v = (v | (v << 8)) & 0x0300f00f;
  v = (v | (v << 4)) & 0x030c30c3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

// The builder's records, grouped by the Morton cell of their box centres (16 cells an axis), in input order
// within a cell, so that a node's objects lie close together in RAM: the split sweeps and the list
// partitions read records in key order, which in input order misses the cache all the way down the tree.
// Cells this coarse cost one counting pass, and keep what locality the input order has. `all`: the union
// of the boxes. Frees `records`; *ids: the object ids in the same layout; *input_position: the input
// position of the object at each layout position.
BuildRecords SpatialLayout(std::vector<ObjectRecord> records, const Box3f& all, BuildVector<ObjectId>* ids,
                          BuildVector<uint32_t>* input_position, int threads) {
  const size_t n = records.size();
  constexpr uint32_t kCellsPerAxis = 16;
  constexpr size_t kCells = kCellsPerAxis * kCellsPerAxis * kCellsPerAxis;
  BuildVector<uint16_t> cell(n);
  // A counting sort by cell on the two halves: each counts its own objects, and a cell's objects from the
  // first half go before those from the second (input order within a cell).
  std::vector<size_t> count(2 * kCells, 0);
  double scale[3];  // cells per metre (a multiply per axis, not a division: the cells only group)
  for (int w = 0; w < 3; ++w) {
    const double ext = double{all.max[w]} - all.min[w];
    scale[w] = ext > 0 ? kCellsPerAxis / ext : 0;
  }
  RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    size_t* const counts = count.data() + (lo == 0 ? 0 : kCells);
    for (size_t i = lo; i < hi; ++i) {
      const Box3f& bx = records[i].box;
      uint32_t code = 0;
      for (int w = 0; w < 3; ++w) {
        const double c = 0.5 * (double{bx.min[w]} + bx.max[w]) - all.min[w];
        constexpr double kTop = kCellsPerAxis - 1;
        code |= Spread3(static_cast<uint32_t>(std::clamp(c * scale[w], 0.0, kTop))) << w;
      }
      cell[i] = static_cast<uint16_t>(code);
      ++counts[code];
    }
  });
  size_t start = 0;  // count[half * kCells + c] becomes where that half's objects of cell c go
  for (size_t c = 0; c < kCells; ++c) {
    for (size_t half : {size_t{0}, kCells}) {
      const size_t here = count[half + c];
      count[half + c] = start;
      start += here;
    }
  }
  BuildVector<uint32_t> order(n);  // layout position -> input position (record index)
  RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    size_t* const next = count.data() + (lo == 0 ? 0 : kCells);
    for (size_t i = lo; i < hi; ++i) order[next[cell[i]]++] = static_cast<uint32_t>(i);
  });
  BuildVector<uint16_t>().swap(cell);
  BuildRecords rec;
  rec.box.resize(n);
  rec.bytes.resize(n);
  ids->resize(n);
  RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    for (size_t i = lo; i < hi; ++i) {
      if (i + kPrefetch < hi) __builtin_prefetch(&records[order[i + kPrefetch]]);  // (a random read each)
      const uint32_t from = order[i];
      rec.box[i] = records[from].box;
      rec.bytes[i] = records[from].encoded_bytes;
      (*ids)[i] = records[from].id;
    }
  });
  *input_position = std::move(order);
  return rec;
}

// Gives the heap's free pages back to the system: the builder frees large temporaries between phases,
// and glibc keeps freed heap memory (not only its top) resident otherwise.
void TrimHeap() {
#ifdef __GLIBC__
  malloc_trim(0);
#endif
}

// A per-node scratch array: it grows without zero-filling (every node writes what it reads), keeps its
// size from node to node, and is shrunk explicitly. From 1 MiB on it is mapped on its own and resized in
// place (mremap): the pages it keeps stay mapped, so shrinking it as the nodes get smaller faults nothing
// in again. (With free-and-allocate, the next larger node faulted them in again: with the retention in
// RunSpawning, 1M tanker, 63k -> 56k faults a 2-thread build, at about 1.6 us each on this VM.)
template <typename T>
class Scratch {
  // Implicit-lifetime element types only: the storage's objects exist once written.
  static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

 public:
  Scratch() = default;
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  ~Scratch() { Free(); }

  void Fit(size_t n) {
    if (n > capacity_) Reset(n);
  }
  // Capacity n (at least), contents not kept.
  void Reset(size_t n) {
    const size_t bytes = std::max<size_t>(n * sizeof(T), 1);
#ifdef __linux__
    if (mapped_ > 0 || bytes >= BuildAllocator<T>::kMapBytes) {  // once mapped, resized in place
      const size_t want = (bytes + kPage - 1) / kPage * kPage;
      void* p = mapped_ > 0 ? mremap(data_, mapped_, want, MREMAP_MAYMOVE)
                            : mmap(nullptr, want, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      if (mapped_ == 0) Free();
      data_ = static_cast<T*>(p);
      mapped_ = want;
      capacity_ = want / sizeof(T);
      return;
    }
#endif
    Free();
    data_ = static_cast<T*>(std::malloc(bytes));
    if (data_ == nullptr) throw std::bad_alloc();
    capacity_ = n;
  }
  size_t capacity() const { return capacity_; }
  T* data() { return data_; }
  T& operator[](size_t i) { return data_[i]; }
  const T& operator[](size_t i) const { return data_[i]; }

 private:
  static constexpr size_t kPage = 4096;  // mremap sizes are whole pages (rounding up only wastes address space)

  void Free() {
#ifdef __linux__
    if (mapped_ > 0) {
      munmap(data_, mapped_);
      data_ = nullptr;
      mapped_ = 0;
      capacity_ = 0;
      return;
    }
#endif
    std::free(data_);
    data_ = nullptr;
    capacity_ = 0;
  }

  T* data_ = nullptr;
  size_t capacity_ = 0;
  size_t mapped_ = 0;  // bytes mapped, 0 when data_ is from malloc
};

struct Shared {
  const BuildVector<Box3f>& box;
  const BuildVector<uint32_t>& bytes;
  BuildParams params;
  BuildTuning tuning;
  // lists[2*w + key]: the objects of every node, each node's range sorted by min_w (key 0) / max_w (key 1).
  std::array<BuildVector<uint32_t>, 6> lists;
  std::vector<uint8_t> side;  // per object: 0 = Sn1, 1 = Sn2 at the node being split
};

// What one builder produces for a subtree; indices are local to it until merged. Aligned to cache lines:
// two threads' fragments, allocated side by side, would otherwise share one, and every node pushed
// writes a vector's end pointer.
struct alignas(64) SubtreeOut {
  std::vector<TreeNode> nodes;
  std::vector<SplitNode> split_nodes;
  std::vector<LeafInfo> leaves;
  std::vector<uint64_t> leaf_begin;  // position of the leaf's first object in the lists
  std::vector<uint32_t> overlap;     // |Sm| per node
  std::vector<uint32_t> split_count;  // SplitTree nodes per node (filled only by the multi-thread build)

  void ShrinkToFit() {
    nodes.shrink_to_fit();
    split_nodes.shrink_to_fit();
    leaves.shrink_to_fit();
    leaf_begin.shrink_to_fit();
    overlap.shrink_to_fit();
    split_count.shrink_to_fit();
  }
};

// child[1] of a node whose right subtree was built as another fragment (multi-thread build).
constexpr uint32_t kFragmentRef = 0x80000000u;

struct Task {
  uint32_t lo = 0, hi = 0;
  uint32_t depth = 0;
  uint32_t parent = kNoIndex;  // local node index of the parent, kNoIndex for a subtree root
  int slot = 0;
  uint64_t bytes = 0;          // sum of encoded_bytes of the objects
  bool leaf_lists_only = false;  // a leaf whose range is sorted in list 0 (and the split axis' lists) only
  bool cooperative = false;  // the root of a multi-thread build: it takes an idle thread along (Together)
};

struct Candidate {
  int list = -1;  // 2*w + key
  uint32_t k = 0;
  float a = 0, b = 0;
  uint32_t sm = 0;
  uint32_t primary = 0;  // sm, or 0 when within the fill slack of the minimum
  uint32_t waste = 0;
  float margin = 0;  // kCompact: N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)); 0 under kSoa
  double slab = 0;
  uint32_t imbalance = 0;
  uint64_t left_bytes = 0;  // encoded bytes of Sn1 (known only when fill_aware)
  bool fill_aware = false;
  bool BetterThan(const Candidate& o) const {
    if (o.list < 0) return true;
    if (primary != o.primary) return primary < o.primary;
    if (waste != o.waste) return waste < o.waste;
    if (margin != o.margin) return margin < o.margin;
    if (sm != o.sm) return sm < o.sm;
    if (slab != o.slab) return slab < o.slab;
    return imbalance < o.imbalance;
  }
};

// Adds delta (modulo 2^32, like the indices) to the child indices of the `count` SplitNodes at `nodes`
// (cells keep their kNoIndex children), branch-free.
void RebaseSplitTree(SplitNode* nodes, uint32_t count, uint32_t delta) {
  for (SplitNode* sn = nodes, *end = sn + count; sn < end; ++sn) {
    const uint32_t d = sn->is_cell() ? 0 : delta;
    sn->child[0] += d;
    sn->child[1] += d;
  }
}

// Appends the `count` nodes of a SplitTree whose child indices count from tree[0] (its root) to *out, the
// indices moved to their new place; returns the new root index. One copy, then the rebase (a 1M-object
// tree has 865k SplitNodes: a push_back each costs more).
uint32_t AppendSplitTree(const SplitNode* tree, uint32_t count, std::vector<SplitNode>* out) {
  const uint32_t base = static_cast<uint32_t>(out->size());
  out->insert(out->end(), tree, tree + count);
  RebaseSplitTree(out->data() + base, count, base);
  return base;
}

// Runs a() here and b() on a thread of its own, and waits for both: for the parts of a multi-thread build
// during which the other threads have nothing to do (the root, the stitch).
template <typename A, typename B>
void Together(A&& a, B&& b) {
  std::thread other(std::forward<B>(b));
  a();
  other.join();
}

class SubtreeBuilder {
 public:
  explicit SubtreeBuilder(Shared* s, bool track_split_count = false)
      : s_(*s), box_(s->box), bytes_(s->bytes), mem_page_(s->params.mem_page()), track_split_count_(track_split_count) {}

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

    const double r = t.depth >= kDepthGuard ? std::max(s_.params.balance_r, kGuardBalance) : s_.params.balance_r;
    int64_t k_lo = std::max<int64_t>(1, static_cast<int64_t>(std::ceil(r * n - 1e-9)));
    int64_t k_hi = std::min<int64_t>(n - 1, static_cast<int64_t>(std::floor((1 - r) * n + 1e-9)));
    if (k_lo > k_hi) k_lo = k_hi = std::clamp<int64_t>(n / 2, 1, n - 1);  // r near 0.5 and tiny n
    const Candidate best = ChooseSplit(t, static_cast<uint32_t>(k_lo), static_cast<uint32_t>(k_hi));
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
        window.min_left = k_lo;
        window.max_left = k_hi;
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
  // InPage (docs/design.md §3.1): a node of `count` objects whose entries take `bytes` is a leaf.
  bool IsLeaf(uint32_t count, uint64_t bytes) const { return count == 1 || FitsInOnePage(bytes, mem_page_); }

  void ShrinkScratch(size_t n) {
    if (tmp_.capacity() < n + n / 2 + (1u << 16)) return;
    const size_t freed = 7 * (tmp_.capacity() - n) * sizeof(float);  // about
    for (auto* v : {&sorted_min_, &prefix_max_, &sorted_max_, &suffix_min_, &margin_pre_, &margin_suf_})
      if (v->capacity() > n + 1) v->Reset(n + 1);
    tmp_.Reset(n);
    split_scratch_.Release();
    if (items_.capacity() > n) items_.Reset(n);
    if (overlap_ids_.capacity() > n) overlap_ids_.Reset(n);
    if (freed >= kTrimBytes) TrimHeap();  // trimming is a walk of the heap: only for large frees
  }

  uint64_t Pages(uint64_t bytes) const { return PagesForLeaf(bytes, mem_page_); }

  // How the candidates of one node are ranked.
  struct Mode {
    bool fill_aware = false;
    bool compact = false;
    uint32_t sm_min = 0;  // the minimal |Sm| over the candidates (known when fill_aware)
  };

  Candidate ChooseSplit(const Task& t, uint32_t k_lo, uint32_t k_hi) {
    const BuildTuning& tu = s_.tuning;
    const uint64_t pages = Pages(t.bytes);
    Mode m;
    m.fill_aware = tu.fill_aware && pages <= tu.fill_aware_pages;
    m.compact = tu.split_policy == SplitPolicy::kCompact;
    bool axis_ok[3] = {true, true, true};
    if (m.compact) CompactAxes(t, axis_ok);
    Candidate best;
    // First pass: the minimal |Sm|, to know which candidates are within the slack (no need when the
    // slack admits every candidate, as by default).
    if (m.fill_aware && tu.fill_sm_slack < t.hi - t.lo) {
      uint32_t sm_min = std::numeric_limits<uint32_t>::max();
      Mode first;
      for (int w = 0; w < 3; ++w)
        if (axis_ok[w]) Sweep(t, w, k_lo, k_hi, first, &best, &sm_min);
      m.sm_min = sm_min;
      best = Candidate();
    }
    if (!m.compact) {
      for (int w = 0; w < 3; ++w)
        if (axis_ok[w]) Sweep(t, w, k_lo, k_hi, m, &best, nullptr);
      return best;
    }
    // Near the leaves every |Sm| is within the fill slack (by default): the key is the page waste, then
    // the margin, and nearly every list ties on the waste, so the margins are computed with it.
    const double slack = tu.fill_sm_slack + tu.fill_sm_slack_rel * m.sm_min;
    if (m.fill_aware && m.sm_min + slack >= t.hi - t.lo) {
      for (int w = 0; w < 3; ++w)
        if (axis_ok[w]) ScanWasteMargins(t, w, k_lo, k_hi, &best);
      return best;
    }
    // kCompact: the margin only breaks ties on (primary, waste). Per axis, while its keys are gathered:
    // per list, the best (primary, waste) and the range of k reaching it; margins are computed only for
    // the candidates that tie with the best so far, and not at all when one candidate alone is best. Same
    // choice as ranking every candidate with its margin: the others lose on (primary, waste) anyway, and
    // the tied ones are compared in the same order (list, then k).
    Mode plain = m;
    plain.compact = false;
    uint64_t top = std::numeric_limits<uint64_t>::max();
    bool lone = false;  // `best` is the only candidate reaching `top` so far; its margin is not computed
    for (int w = 0; w < 3; ++w) {
      if (!axis_ok[w]) continue;
      ListTies ties[2];
      GatherAxis(t, w, k_lo, k_hi);
      ScanKeys(t, w, k_lo, k_hi, plain, nullptr, nullptr, ties, nullptr, nullptr, top);
      uint64_t local = std::numeric_limits<uint64_t>::max();
      uint32_t count = 0;
      for (const ListTies& lt : ties)
        if (lt.count > 0) local = std::min(local, lt.key);
      for (const ListTies& lt : ties) count += lt.count > 0 && lt.key == local ? lt.count : 0;
      if (count == 0 || local > top) continue;
      if (local < top) {
        top = local;
        best = Candidate();
        lone = false;
        if (count == 1) {
          best = ties[0].count > 0 && ties[0].key == local ? ties[0].first : ties[1].first;
          lone = true;
          continue;
        }
      }
      if (lone) {
        best.margin = SplitMargin(t, best.list, best.k);
        lone = false;
      }
      ScanKeys(t, w, k_lo, k_hi, m, &best, nullptr, nullptr, &top, ties);
    }
    return best;
  }

  // kCompact near the leaves, when every |Sm| is within the fill slack (primary 0): the cuts of both keys
  // of axis w ranked by page waste, then margin, then as BetterThan says. Per list the least (waste,
  // margin) is found first, with no candidate built, and only the cuts reaching it are evaluated, in
  // order: the same choice as evaluating every cut, as BetterThan ranks those two first.
  void ScanWasteMargins(const Task& t, int w, uint32_t k_lo, uint32_t k_hi, Candidate* best) {
    const uint32_t n = t.hi - t.lo;
    const uint32_t* const bytes = bytes_.data();
    for (int key = 0; key < 2; ++key) {
      const int list = 2 * w + key;
      const BuildVector<uint32_t>& order = s_.lists[list];
      PrefixSuffixMargins(t, order, k_lo, k_hi);
      const uint32_t* const ord = order.data() + t.lo;
      uint64_t sum = 0;  // encoded bytes of the first k objects
      for (uint32_t i = 0; i + 1 < k_lo; ++i) sum += bytes[ord[i]];
      const uint64_t sum_begin = sum;
      const PageSplit pages_begin(sum, t.bytes, mem_page_);
      PageSplit pages = pages_begin;
      uint64_t least_waste = std::numeric_limits<uint64_t>::max();
      float least_margin = std::numeric_limits<float>::infinity();
      size_t least_k = 0, least_count = 0;
      uint64_t least_sum = 0;
      for (size_t k = k_lo; k <= k_hi; ++k) {  // (64-bit: no zero-extensions)
        sum += bytes[ord[k - 1]];
        const uint64_t waste = pages.Waste(sum);
        if (waste > least_waste) continue;
        const float margin = CutMargin(static_cast<uint32_t>(k), n);
        if (waste < least_waste || margin < least_margin) {
          least_waste = waste, least_margin = margin, least_k = k, least_sum = sum, least_count = 1;
        } else {
          least_count += margin == least_margin;
        }
      }
      if (least_count == 0 || (best->list >= 0 && (least_waste > best->waste ||
                                                    (least_waste == best->waste && least_margin > best->margin))))
        continue;
      // The cut's planes and |Sm| straight from the boxes: only about half of these lists get here (73k of
      // 154k at 1M), so the keys are not gathered for them (as GatherAxis and ScanKeys would find them).
      const Box3f* const box = box_.data();
      auto evaluate = [&](size_t k, uint64_t left) {
        float a = std::numeric_limits<float>::infinity(), b = -std::numeric_limits<float>::infinity();
        if (key == 0) {  // a: the k-th object's min_w, b: the max of max_w before it
          a = box[ord[k]].min[w];
          for (size_t i = 0; i < k; ++i) b = std::max(b, box[ord[i]].max[w]);
        } else {  // b: the (k-1)-th object's max_w, a: the min of min_w from the k-th on
          b = box[ord[k - 1]].max[w];
          for (size_t i = k; i < n; ++i) a = std::min(a, box[ord[i]].min[w]);
        }
        uint32_t sm = 0;  // #(min_w < b) - #(max_w <= a)
        if (a < b)
          for (size_t i = 0; i < n; ++i) sm += (box[ord[i]].min[w] < b) - (box[ord[i]].max[w] <= a);
        const uint32_t k32 = static_cast<uint32_t>(k);
        Candidate c = MakeCandidate(list, k32, n, a, b, sm, 0, static_cast<uint32_t>(least_waste), left, true);
        c.margin = least_margin;
        if (c.BetterThan(*best)) *best = c;
      };
      if (least_count == 1) {
        evaluate(least_k, least_sum);
        continue;
      }
      sum = sum_begin;  // several cuts reach it: again, in order
      pages = pages_begin;
      for (size_t k = k_lo; k <= k_hi; ++k) {
        sum += bytes[ord[k - 1]];
        if (pages.Waste(sum) == least_waste && CutMargin(static_cast<uint32_t>(k), n) == least_margin)
          evaluate(k, sum);
      }
    }
  }

  // Per sort list, the candidates with the list's best (primary, waste) (kCompact's first pass).
  struct ListTies {
    uint64_t key = 0;  // primary << 32 | waste
    uint32_t count = 0, k_min = 0, k_max = 0;
    Candidate first;
  };

  // kCompact: the axes along which the objects spread at least compact_axis_ratio x the longest spread.
  // Spread along w: the mean of the spreads of min_w and of max_w (the ends of the two sorted lists), so
  // one long object does not make an axis look long.
  void CompactAxes(const Task& t, bool axis_ok[3]) const {
    double spread[3], longest = 0;
    for (int w = 0; w < 3; ++w) {
      const BuildVector<uint32_t>& by_min = s_.lists[2 * w];
      const BuildVector<uint32_t>& by_max = s_.lists[2 * w + 1];
      spread[w] = 0.5 * ((double{box_[by_min[t.hi - 1]].min[w]} - box_[by_min[t.lo]].min[w]) +
                         (double{box_[by_max[t.hi - 1]].max[w]} - box_[by_max[t.lo]].max[w]));
      longest = std::max(longest, spread[w]);
    }
    // The longest axis always stays (whatever the ratio), so there is a candidate.
    for (int w = 0; w < 3; ++w)
      axis_ok[w] = spread[w] == longest || spread[w] >= s_.tuning.compact_axis_ratio * longest;
  }

  // N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) of one candidate, as ScanKeys computes it.
  float SplitMargin(const Task& t, int list, uint32_t k) const {
    const BuildVector<uint32_t>& order = s_.lists[list];
    LanesUnion lo, hi;
    for (uint32_t i = t.lo; i < t.lo + k; ++i) lo.Add(box_[order[i]]);
    for (uint32_t i = t.lo + k; i < t.hi; ++i) hi.Add(box_[order[i]]);
    const uint32_t n = t.hi - t.lo;
    return static_cast<float>(static_cast<double>(k) * lo.Margin() + static_cast<double>(n - k) * hi.Margin());
  }

  // Margin of the union of the boxes of order[lo .. lo+i] for i in [k_min-1, k_max-1] at
  // margin_pre_[i - (k_min-1)], and of order[lo+i .. hi) for i in [k_min, k_max] at margin_suf_[i - k_min]:
  // what the cuts k in [k_min, k_max] need. Each sweep runs in two stretches (without, then with a margin
  // stored) over the boxes as vectors.
  void PrefixSuffixMargins(const Task& t, const BuildVector<uint32_t>& order, uint32_t k_min32, uint32_t k_max32) {
    const size_t n = t.hi - t.lo, k_min = k_min32, k_max = k_max32;  // (64-bit: no zero-extensions)
    margin_base_ = k_min32;
    margin_pre_.Fit(k_max - k_min + 1);
    margin_suf_.Fit(k_max - k_min + 1);
    const uint32_t* ord = order.data() + t.lo;
    const Box3f* box = box_.data();
    float* const pre_out = margin_pre_.data();
    float* const suf_out = margin_suf_.data();
    // kFar: as in GatherRuns (large nodes tie on |Sm| = 0 over long runs of cuts, whose boxes are far apart).
    auto sweeps = [&]<bool kFar>() {
      LanesUnion pre;
      auto add_pre = [&](size_t j) {
        if (kFar && j + kPrefetch < n) __builtin_prefetch(&box[ord[j + kPrefetch]]);
        pre.Add(box[ord[j]]);
      };
      size_t i = 0;
      for (; i + 1 < k_min; ++i) add_pre(i);
      for (; i < k_max; ++i) add_pre(i), pre_out[i + 1 - k_min] = pre.Margin();
      LanesUnion suf;
      auto add_suf = [&](size_t j) {
        if (kFar && j >= kPrefetch) __builtin_prefetch(&box[ord[j - kPrefetch]]);
        suf.Add(box[ord[j]]);
      };
      i = n;
      while (i > k_max + 1) add_suf(--i);
      while (i > k_min) --i, add_suf(i), suf_out[i - k_min] = suf.Margin();
    };
    if (n >= kPrefetchObjects)
      sweeps.template operator()<true>();
    else
      sweeps.template operator()<false>();
  }

  // Gathers axis w and evaluates its candidates (kSoa, and kCompact's |Sm| first pass).
  void Sweep(const Task& t, int w, uint32_t k_lo, uint32_t k_hi, const Mode& m, Candidate* best,
             uint32_t* sm_min_out) {
    GatherAxis(t, w, k_lo, k_hi);
    const uint64_t bound = best->list >= 0 ? uint64_t{best->primary} << 32 | best->waste
                                           : std::numeric_limits<uint64_t>::max();
    ScanKeys(t, w, k_lo, k_hi, m, best, sm_min_out, nullptr, nullptr, nullptr, bound);
  }

  // The node's min_w in sorted order with the running max of max_w along it, and its max_w in sorted
  // order with the suffix min of min_w along it: all ScanKeys needs of axis w.
  void GatherAxis(const Task& t, int w, uint32_t k_lo, uint32_t k_hi) {
    const uint32_t n = t.hi - t.lo;
    // The running extremes are kept for the cuts k in [k_lo, k_hi] only: less scratch at the root.
    window_base_ = k_lo;
    sorted_min_.Fit(n + 1);
    prefix_max_.Fit(k_hi - k_lo + 1);
    sorted_max_.Fit(n + 1);
    suffix_min_.Fit(k_hi - k_lo + 1);
    sorted_min_[n] = sorted_max_[n] = std::numeric_limits<float>::infinity();
    if (n >= kPrefetchObjects)
      GatherRuns<true>(t, w, k_lo, k_hi);
    else
      GatherRuns<false>(t, w, k_lo, k_hi);
  }

  // GatherAxis' two sweeps, each in three stretches (before, in and after the cut window) so that the
  // window test is not made per object. kFar: the records are read in key order, scattered over RAM in
  // large nodes, so each is prefetched kPrefetch objects ahead.
  template <bool kFar>
  void GatherRuns(const Task& t, int w, uint32_t k_lo32, uint32_t k_hi32) {
    // (64-bit positions: no zero-extensions in the loops.)
    const size_t n = t.hi - t.lo, k_lo = k_lo32, k_hi = k_hi32;
    const Box3f* box = box_.data();
    const uint32_t* by_min = s_.lists[2 * w].data() + t.lo;
    const uint32_t* by_max = s_.lists[2 * w + 1].data() + t.lo;
    float* smin = sorted_min_.data();
    float* smax = sorted_max_.data();
    float* pmax = prefix_max_.data();  // [k - k_lo]: max of max_w over the first k objects
    float* smn = suffix_min_.data();   // [k - k_lo]: min of min_w over objects k..n-1
    auto sweep_up = [&] {
      float run = -std::numeric_limits<float>::infinity();
      auto up = [&](size_t i) {
        if (kFar && i + kPrefetch < n) __builtin_prefetch(&box[by_min[i + kPrefetch]]);
        const Box3f& bx = box[by_min[i]];
        smin[i] = bx.min[w];
        run = std::max(run, bx.max[w]);
      };
      size_t i = 0;
      for (; i + 1 < k_lo; ++i) up(i);
      for (; i < k_hi; ++i) up(i), pmax[i + 1 - k_lo] = run;
      for (; i < n; ++i) up(i);
    };
    auto sweep_down = [&] {
      float run = std::numeric_limits<float>::infinity();
      auto down = [&](size_t i) {
        if (kFar && i >= kPrefetch) __builtin_prefetch(&box[by_max[i - kPrefetch]]);
        const Box3f& bx = box[by_max[i]];
        smax[i] = bx.max[w];
        run = std::min(run, bx.min[w]);
      };
      size_t i = n;
      for (; i > k_hi + 1;) down(--i);
      for (; i > k_lo;) --i, down(i), smn[i - k_lo] = run;
      for (; i > 0;) down(--i);
    };
    if (t.cooperative) {
      Together(sweep_up, sweep_down);
    } else {
      sweep_up();
      sweep_down();
    }
  }

  // First index i >= from with arr[i] > x (upper) or arr[i] >= x (lower), by galloping forward: arr is
  // sorted and arr[n] = +inf stops it; the answer is known to be >= from.
  template <bool kUpper>
  static uint32_t Gallop(const float* arr, uint32_t n, uint32_t from, float x) {
    auto before = [x](float v) { return kUpper ? v <= x : v < x; };
    uint32_t lo = from, hi = from, step = 1;
    while (before(arr[hi])) {  // stops at the sentinel arr[n] at the latest
      lo = hi + 1;
      hi = std::min(n, hi + step);
      step <<= 1;
    }
    const float* r = kUpper ? std::upper_bound(arr + lo, arr + hi, x) : std::lower_bound(arr + lo, arr + hi, x);
    return static_cast<uint32_t>(r - arr);
  }

  // |Sm| of the cut with planes a, b over the sorted min_w / max_w arrays, the counts pa, pb galloping on
  // from where they are (cuts visited in increasing order): near the leaves, where only a few cuts need it.
  static uint32_t SmGalloping(const float* smin, const float* smax, uint32_t n, float a, float b, uint32_t& pa,
                              uint32_t& pb) {
    if (!(a < b)) return 0;
    pa = Gallop<true>(smax, n, pa, a);
    pb = Gallop<false>(smin, n, pb, b);
    return pb - pa;
  }

  // Page waste Pages(left) + Pages(total - left) - Pages(total) of cuts in increasing order of their left
  // bytes, without a division per cut: the page counts only step where the bytes cross a page.
  class PageSplit {
   public:
    PageSplit(uint64_t left, uint64_t total, uint64_t mem_page)
        : cap_(PagePayloadCapacity(mem_page)), left_pages_(PagesForLeaf(left, mem_page)),
          right_pages_(PagesForLeaf(total - left, mem_page)), total_pages_(PagesForLeaf(total, mem_page)) {
      // The left side takes another page once left > left_limit_; the right one gives one back once
      // left >= right_limit_ (never below one page).
      left_limit_ = left_pages_ * cap_ - kLeafHeaderBytes;
      right_limit_ = right_pages_ > 1 ? LeafPayloadBytes(total) - (right_pages_ - 1) * cap_
                                      : std::numeric_limits<uint64_t>::max();
    }
    uint64_t Waste(uint64_t left) {  // left never decreases from one call to the next
      while (left > left_limit_) ++left_pages_, left_limit_ += cap_;
      while (left >= right_limit_) {
        --right_pages_;
        right_limit_ = right_pages_ > 1 ? right_limit_ + cap_ : std::numeric_limits<uint64_t>::max();
      }
      return left_pages_ + right_pages_ - total_pages_;
    }

   private:
    uint64_t cap_, left_pages_, right_pages_, total_pages_, left_limit_, right_limit_;
  };

  // Evaluates the candidates of both keys of axis w (GatherAxis(t, w) done). In O(n): along either order,
  // a(k) and b(k) never decrease, so |Sm| = #(min_w < b) - #(max_w <= a) is counted with two cursors
  // moving forward over the sorted min_w and max_w arrays.
  // ties (kCompact, margins not computed): per key, the candidates of best (primary, waste).
  // only (kCompact): evaluate only the candidates whose (primary, waste) is *only, with their margins
  // computed over the k ranges of tied[key].
  // bound: a (primary, waste) key that the chosen candidate is known to reach; cuts that cannot reach it
  // may be skipped (kSoa: the best so far; kCompact: `top`).
  // Pruning (|Sm| ranks first): cut k's |Sm| is pb(k) - pa(k) (or 0), and both counts grow with k, so over
  // a block of cuts [p, q] |Sm| >= pb(p) - pa(q). Both are found at every block's ends by galloping; a
  // block whose bound exceeds the best key so far holds no candidate that wins or ties, and is skipped.
  void ScanKeys(const Task& t, int w, uint32_t k_lo, uint32_t k_hi, const Mode& m, Candidate* best,
                uint32_t* sm_min_out, ListTies* ties = nullptr, const uint64_t* only = nullptr,
                const ListTies* tied = nullptr, uint64_t bound = std::numeric_limits<uint64_t>::max()) {
    const bool fill_aware = m.fill_aware;
    const uint32_t n = t.hi - t.lo;
    const BuildVector<uint32_t>& by_min = s_.lists[2 * w];
    const BuildVector<uint32_t>& by_max = s_.lists[2 * w + 1];
    const double slack = s_.tuning.fill_sm_slack + s_.tuning.fill_sm_slack_rel * m.sm_min;
    const float* smin = sorted_min_.data();
    const float* smax = sorted_max_.data();
    // |Sm| ranks first (so a lower bound on it bounds the key) unless the fill slack zeroes it.
    const bool prunable = !fill_aware && sm_min_out == nullptr && only == nullptr;
    // Near the leaves with the default slack every |Sm| is within it: the key is the page waste alone.
    const bool sm_free = fill_aware && sm_min_out == nullptr && m.sm_min + slack >= n;

    // Per key, with the key a constant: the cut loop reads a(k) and b(k) without a select.
    auto scan_key = [&](auto key_constant) {
      constexpr int key = decltype(key_constant)::value;
      const BuildVector<uint32_t>& order = key == 0 ? by_min : by_max;
      if (only != nullptr) {
        if (tied[key].count == 0 || tied[key].key != *only) return;
        PrefixSuffixMargins(t, order, tied[key].k_min, tied[key].k_max);
      }
      // The second kCompact pass looks at the tied cuts only.
      const uint32_t k_first = only != nullptr ? tied[key].k_min : k_lo;
      const uint32_t k_last = only != nullptr ? tied[key].k_max : k_hi;
      const int list = 2 * w + key;
      // (Locals, not members or the task's fields, which the ties' counters could alias.)
      const float* const pmax = prefix_max_.data();
      const float* const smn = suffix_min_.data();
      const uint32_t base = window_base_;
      auto a_of = [smin, smn, base](uint32_t k) { return key == 0 ? smin[k] : smn[k - base]; };
      auto b_of = [smax, pmax, base](uint32_t k) { return key == 0 ? pmax[k - base] : smax[k - 1]; };
      const uint32_t* const ord = order.data() + t.lo;
      const uint32_t* const bytes = bytes_.data();
      uint64_t left_bytes = 0;  // encoded bytes of the first k objects
      if (fill_aware && only != nullptr)  // the first pass's candidate at k_first has them
        left_bytes = tied[key].first.left_bytes - bytes[ord[k_first - 1]];
      else if (fill_aware)
        for (uint32_t i = 0; i + 1 < k_first; ++i) left_bytes += bytes[ord[i]];

      PageSplit pages(left_bytes, t.bytes, mem_page_);

      // Cuts [k_begin, k_end]; pa, pb: the counts at k_begin when `placed`.
      auto eval = [&](uint32_t k_begin, uint32_t k_end, uint32_t pa, uint32_t pb, bool placed) {
        for (size_t k = k_begin; k <= k_end; ++k) {  // (64-bit: no zero-extensions)
          // Bytes only matter near the leaves (and are a random read per object, so not gathered above).
          uint64_t waste_key = 0;
          if (fill_aware) {
            left_bytes += bytes[ord[k - 1]];
            waste_key = pages.Waste(left_bytes);
          }
          // With the waste alone as the key (kSoa near the leaves), only a cut that may win or tie matters.
          if (sm_free && waste_key > bound) continue;
          const float a = a_of(k), b = b_of(k);  // the cut's planes
          uint32_t sm = 0;
          if (sm_free) {
            sm = SmGalloping(smin, smax, n, a, b, pa, pb);
          } else if (a < b) {
            if (!placed) {  // first use: a binary search instead of walking past the first ~k_lo objects
              pa = static_cast<uint32_t>(std::upper_bound(smax, smax + n, a) - smax);
              pb = static_cast<uint32_t>(std::lower_bound(smin, smin + n, b) - smin);
              placed = true;
            }
            // The cursors mostly move by 0-2 a step: two branch-free moves, then a loop that rarely runs
            // (+inf sentinels at [n] stop them).
            pa += smax[pa] <= a;
            pa += smax[pa] <= a;
            while (smax[pa] <= a) ++pa;
            pb += smin[pb] < b;
            pb += smin[pb] < b;
            while (smin[pb] < b) ++pb;
            sm = pb - pa;
          }
          if (sm_min_out != nullptr) {
            *sm_min_out = std::min(*sm_min_out, sm);
            continue;
          }
          uint32_t primary = sm, waste = 0;
          if (fill_aware) {
            if (sm <= m.sm_min + slack) primary = 0;
            waste = static_cast<uint32_t>(waste_key);
          }
          const uint64_t tie_key = uint64_t{primary} << 32 | waste;
          if (ties != nullptr) {  // a Candidate only for a new best: most cuts are not
            ListTies& lt = ties[key];
            if (lt.count == 0 || tie_key < lt.key) {
              lt.key = tie_key;
              lt.count = 1;
              lt.k_min = lt.k_max = k;
              lt.first = MakeCandidate(list, k, n, a, b, sm, primary, waste, left_bytes, fill_aware);
              bound = std::min(bound, tie_key);
            } else if (tie_key == lt.key) {
              ++lt.count;
              lt.k_max = k;
            }
            continue;
          }
          if (only != nullptr && tie_key != *only) continue;
          Candidate c = MakeCandidate(list, k, n, a, b, sm, primary, waste, left_bytes, fill_aware);
          if (only != nullptr) c.margin = CutMargin(k, n);
          if (c.BetterThan(*best)) {
            *best = c;
            bound = std::min(bound, tie_key);
          }
        }
      };

      const uint32_t cuts = k_last - k_first + 1;
      if (!prunable || cuts < 2 * kPruneBlock) {
        eval(k_first, k_last, 0, 0, false);
        return;
      }
      // Block ends p_j = k_first + j * kPruneBlock (j < blocks) and p_blocks = k_last; the counts there,
      // and the exact |Sm| of those cuts to tighten the bound before any block is scanned.
      const uint32_t blocks = (cuts + kPruneBlock - 1) / kPruneBlock;
      block_pa_.Fit(blocks + 1);
      block_pb_.Fit(blocks + 1);
      uint32_t pa = 0, pb = 0;
      for (uint32_t j = 0; j <= blocks; ++j) {
        const uint32_t p = j < blocks ? k_first + j * kPruneBlock : k_last;
        pa = Gallop<true>(smax, n, pa, a_of(p));
        pb = Gallop<false>(smin, n, pb, b_of(p));
        block_pa_[j] = pa;
        block_pb_[j] = pb;
        if (pb > pa) bound = std::min(bound, uint64_t{pb - pa} << 32);
        else bound = 0;  // a cut with |Sm| = 0: only such cuts can tie
      }
      for (uint32_t j = 0; j < blocks; ++j) {
        const uint32_t p = k_first + j * kPruneBlock;
        const uint32_t q = j + 1 < blocks ? p + kPruneBlock - 1 : k_last;
        const uint32_t lower = block_pb_[j] > block_pa_[j + 1] ? block_pb_[j] - block_pa_[j + 1] : 0;
        if ((uint64_t{lower} << 32) > bound) continue;
        eval(p, q, block_pa_[j], block_pb_[j], true);
      }
    };
    scan_key(std::integral_constant<int, 0>{});
    scan_key(std::integral_constant<int, 1>{});
  }

  // kCompact's margin pass: N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) of cut k (PrefixSuffixMargins done).
  float CutMargin(uint32_t k, uint32_t n) const {
    return static_cast<float>(static_cast<double>(k) * margin_pre_[k - margin_base_] +
                              static_cast<double>(n - k) * margin_suf_[k - margin_base_]);
  }

  static Candidate MakeCandidate(int list, uint32_t k, uint32_t n, float a, float b, uint32_t sm, uint32_t primary,
                                 uint32_t waste, uint64_t left_bytes, bool fill_aware) {
    Candidate c;
    c.list = list;
    c.k = k;
    c.a = a;
    c.b = b;
    c.sm = sm;
    c.primary = primary;
    c.waste = waste;
    c.slab = std::max(0.0, double{b} - double{a});
    c.imbalance = static_cast<uint32_t>(std::abs(2 * int64_t{k} - int64_t{n}));
    c.left_bytes = left_bytes;
    c.fill_aware = fill_aware;
    return c;
  }

  Shared& s_;
  const BuildVector<Box3f>& box_;
  const BuildVector<uint32_t>& bytes_;
  const uint64_t mem_page_;
  const bool track_split_count_;
  Scratch<float> sorted_min_, prefix_max_, sorted_max_, suffix_min_;
  uint32_t window_base_ = 0;  // prefix_max_ / suffix_min_ index of the cut k_lo
  Scratch<float> margin_pre_, margin_suf_;  // kCompact only
  Scratch<uint32_t> block_pa_, block_pb_;   // ScanKeys' counts at its block ends
  uint32_t margin_base_ = 0;  // margin_pre_ / margin_suf_ index of the cut k_min
  Scratch<uint32_t> tmp_;
  Scratch<SplitItem> items_;  // the slab's objects (SplitTree items), at overlap_ids_ in the records
  std::vector<SplitNode> split_;  // the node's SplitTree
  SplitTreeScratch split_scratch_;
  Scratch<uint32_t> overlap_ids_;
};

// Frees what only the splits needed: lists 1-5 and the side flags (list 0 gives the leaves' objects).
void ReleaseBuildLists(Shared* shared) {
  for (int l = 1; l < 6; ++l) BuildVector<uint32_t>().swap(shared->lists[l]);
  std::vector<uint8_t>().swap(shared->side);
  TrimHeap();
}

// Multi-thread build: workers take subtree tasks from a shared queue; each task is built depth-first into
// its own fragment, handing the right child of every large node back to the queue. The fragments are then
// stitched in DFS preorder (nodes, SplitTree nodes and leaves renumbered), which gives exactly the tree
// that one thread builds: every node's split depends only on its own objects.
void BuildParallel(Shared* shared, const Task& root, int threads, SubtreeOut* out, double* stitch_seconds) {
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

std::string Describe(const ObjectRecord& r) { return "object " + std::to_string(r.id); }

// The checks of BuildMKTree's REQUIRES but unique ids (CheckUniqueIds), the per-record ones on two halves;
// an error names the first bad record in input order. *bounds: the union of the boxes (the layout's).
Status Validate(const std::vector<ObjectRecord>& records, const BuildParams& params, int threads,
                Box3f* bounds, ObjectId* max_id) {
  if (!(params.balance_r >= 0 && params.balance_r < 0.5))
    return Status::InvalidArgument("balance ratio r = " + std::to_string(params.balance_r) +
                                   " outside [0, 0.5)");
  if (params.block_size == 0 || params.blocks_per_page == 0 ||
      params.mem_page() <= kPageHeaderBytes + kLeafHeaderBytes)
    return Status::InvalidArgument("page of " + std::to_string(params.mem_page()) +
                                   " bytes is not larger than its headers (" +
                                   std::to_string(kPageHeaderBytes + kLeafHeaderBytes) + " bytes)");
  if (records.size() >= kNoIndex) return Status::InvalidArgument("too many objects for 32-bit indices");
  struct Half {
    size_t bad = std::numeric_limits<size_t>::max();  // its first record with a bad box
    ObjectId max_id = 0;
    Box3f box;
  };
  Half half[2];
  RunOnHalves(records.size(), threads, [&](size_t lo, size_t hi) {
    // Kept here and stored once: the two halves' results share a cache line, and stores to it from both
    // threads in the loop made each half slower than the whole on one thread (1M: 7 ms against 3.8).
    Half h;
    for (size_t i = lo; i < hi; ++i) {
      const Box3f& b = records[i].box;
      // Finite with min <= max is -inf < min <= max < inf (NaN fails every comparison).
      constexpr float kInf = std::numeric_limits<float>::infinity();
      bool ok = true;
      for (int a = 0; a < 3; ++a) ok &= (b.min[a] > -kInf) & (b.min[a] <= b.max[a]) & (b.max[a] < kInf);
      if (!ok) {
        h.bad = i;
        break;
      }
      h.max_id = std::max(h.max_id, records[i].id);
      h.box.Extend(b);
    }
    half[lo == 0 ? 0 : 1] = h;
  });
  if (const size_t bad = std::min(half[0].bad, half[1].bad); bad < records.size()) {
    const ObjectRecord& r = records[bad];
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(r.box.min[i]) || !std::isfinite(r.box.max[i]))
        return Status::InvalidArgument(Describe(r) + ": bounding box is not finite");
      if (r.box.min[i] > r.box.max[i])
        return Status::InvalidArgument(Describe(r) + ": bounding box has min > max on axis " + std::to_string(i));
    }
  }
  *max_id = std::max(half[0].max_id, half[1].max_id);
  *bounds = half[0].box;
  bounds->Extend(half[1].box);
  return Status::Ok();
}

// Unique ids, checked on the laid-out ids (8 bytes an object, not the 40 of a record): a bitmap when ids
// are dense (the normal 0-based case), else a sorted copy. An error names the first object in input order
// whose id came before (input_position gives the input order; only then is it needed).
Status CheckUniqueIds(const BuildVector<ObjectId>& ids, const BuildVector<uint32_t>& input_position,
                      ObjectId max_id) {
  const size_t n = ids.size();
  if (uint64_t{max_id} > 64 * uint64_t{n}) {
    std::vector<ObjectId> sorted(ids.begin(), ids.end());
    std::sort(sorted.begin(), sorted.end());
    auto dup = std::adjacent_find(sorted.begin(), sorted.end());
    if (dup != sorted.end())
      return Status::InvalidArgument("object " + std::to_string(*dup) + ": duplicate object id");
    return Status::Ok();
  }
  std::vector<uint64_t> seen(max_id / 64 + 1, 0);
  auto seen_before = [&seen](ObjectId id) {  // marks id seen; whether it was already
    uint64_t& word = seen[id / 64];
    const uint64_t bit = uint64_t{1} << (id % 64);
    const bool was = (word & bit) != 0;
    word |= bit;
    return was;
  };
  bool found = false;
  for (const ObjectId id : ids) found |= seen_before(id);
  if (!found) return Status::Ok();
  std::fill(seen.begin(), seen.end(), 0);
  std::vector<uint32_t> at_input(n);  // input position -> layout position
  for (size_t i = 0; i < n; ++i) at_input[input_position[i]] = static_cast<uint32_t>(i);
  for (size_t p = 0; p < n; ++p) {
    const ObjectId id = ids[at_input[p]];
    if (seen_before(id)) return Status::InvalidArgument("object " + std::to_string(id) + ": duplicate object id");
  }
  return Status::Internal("a duplicate object id was not found again");
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
  Shared shared{rec.box, rec.bytes, params, tuning, {}, {}};
  {
    BuildVector<uint32_t> input_position;
    rec = SpatialLayout(std::move(records), bounds, &ids, &input_position, threads);
    MKTREE_RETURN_IF_ERROR(CheckUniqueIds(ids, input_position, max_id));
  }
  lap(&result.timings.layout);
  {
    // With two threads or more, the six sorts run on two (each thread with its own radix buffers).
    auto sort_lists = [&](int first, int step) {
      BuildVector<uint64_t> a, b;
      for (int l = first; l < 6; l += step) SortByKey(rec.box, l / 2, l % 2 == 1, &a, &b, &shared.lists[l]);
    };
    if (threads >= 2) {
      std::thread other(sort_lists, 1, 2);
      sort_lists(0, 2);
      other.join();
    } else {
      sort_lists(0, 1);
    }
  }
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
