#include "engine/tree/subtree_builder.h"

#include <algorithm>
#include <limits>
#include <span>

#include "engine/tree/build_threads.h"
#include "engine/tree/page_budget.h"

namespace mktree::build {
namespace {

// The scratch arrays keep room for a node still to come of up to this many objects (RunSpawning): more
// would cost RAM for the whole left subtree and save few page faults.
constexpr uint32_t kRetainObjects = 1u << 16;

// Appends the `count` nodes of a SplitTree whose child indices count from tree[0] (its root) to *out, the
// indices moved to their new place; returns the new root index. One copy, then the rebase (cheaper than a
// push_back per node: SplitNodes outnumber the tree's nodes several times).
uint32_t AppendSplitTree(const SplitNode* tree, uint32_t count, BuildVector<SplitNode>* out) {
  const uint32_t base = static_cast<uint32_t>(out->size());
  out->insert(out->end(), tree, tree + count);
  RebaseSplitTree(out->data() + base, count, base);
  return base;
}

// Step 1's assignment: the first k objects of the chosen order go to Sn1 (side 0), the others to Sn2.
// (Arguments by value, not through a closure: byte stores may alias anything a loop would reload.)
void MarkSides(uint8_t* side, const uint32_t* chosen, size_t k, size_t n) {
  for (size_t i = 0; i < k; ++i) side[chosen[i]] = 0;
  for (size_t i = k; i < n; ++i) side[chosen[i]] = 1;
}

// A TaskSink for a builder that spawns nothing.
class NoSpawn final : public TaskSink {
 public:
  uint32_t Spawn(const Task&) override { return kNoIndex; }
  uint32_t LargestWaiting() const override { return 0; }
};

}  // namespace

void SubtreeBuilder::Run(const Task& root, SubtreeOut* out) {
  NoSpawn none;
  RunSpawning(root, out, std::numeric_limits<uint32_t>::max(), &none);
}

void SubtreeBuilder::RunSpawning(const Task& root, SubtreeOut* out, uint32_t min_spawn, TaskSink* sink) {
  std::vector<Task> stack{root};
  Task kids[2];
  while (!stack.empty()) {
    const Task t = stack.back();
    stack.pop_back();
    if (ProcessNode(t, out, kids)) {
      if (kids[1].hi - kids[1].lo >= min_spawn) {
        const uint32_t me = kids[1].parent;
        kids[1].parent = kNoIndex;
        out->nodes[me].child[1] = kFragmentRef | sink->Spawn(kids[1]);
      } else {
        stack.push_back(kids[1]);
      }
      stack.push_back(kids[0]);  // left next: it becomes node n+1 (DFS preorder)
    }
    // The scratch arrays were sized for the largest node so far; give the memory back once every node
    // still to come is under 2/3 of that, so that it does not add to the peak when the SplitTrees have
    // grown. (Not just the next node: pages given back and taken again are faulted in again. But only up
    // to kRetainObjects.)
    if (!stack.empty()) {
      uint32_t largest = sink->LargestWaiting();
      for (const Task& p : stack) largest = std::max(largest, p.hi - p.lo);
      ShrinkScratch(std::max(stack.back().hi - stack.back().lo, std::min(largest, kRetainObjects)));
    }
  }
}

bool SubtreeBuilder::ProcessNode(const Task& task, SubtreeOut* out, Task kids[2]) {
  Task t = task;
  const uint32_t n = t.hi - t.lo;
  const uint32_t me = static_cast<uint32_t>(out->nodes.size());
  if (t.parent != kNoIndex) out->nodes[t.parent].child[t.slot] = me;
  if (t.spilled) Unspill(&t);
  TreeNode node;
  node.box = NodeBox(t);
  node.depth = static_cast<uint8_t>(std::min<uint32_t>(t.depth, 255));
  if (IsLeaf(n, t.bytes)) {
    AppendLeaf(t, node, out);
    return false;
  }

  const CutRange cuts = BalancedCuts(n, t.depth, s_.params.balance_r);
  const Candidate best = chooser_.Choose(t, cuts);
  const int w = best.list / 2;
  node.axis = static_cast<uint8_t>(w);
  split_.clear();  // (reused: no allocation a node)
  const uint32_t n_items = AssignSides(t, best);
  if (best.a < best.b && s_.params.split_tree_node_budget > 0)
    PlaceSlabObjects(t, node.box, best, cuts, n_items);
  const Partition part = PartitionLists(t, w);

  // The stored planes are those of the final children (free objects may have narrowed the slab).
  node.a = part.a;
  node.b = part.b;
  uint32_t sm = 0;
  if (node.a < node.b) {
    sm = CountOverlap(n_items, w, node.a, node.b);
    if (!split_.empty())
      node.split_root =
          AppendSplitTree(split_.data(), static_cast<uint32_t>(split_.size()), &out->split_nodes);
  }
  out->nodes.push_back(node);
  out->overlap.push_back(sm);
  if (track_split_count_)
    out->split_count.push_back(node.split_root == kNoIndex ? 0 : static_cast<uint32_t>(split_.size()));
  kids[0] = Task{t.lo, t.lo + part.n1, t.depth + 1, me, 0, part.left_bytes, part.leaf_kids};
  kids[1] = Task{t.lo + part.n1, t.hi, t.depth + 1, me, 1, t.bytes - part.left_bytes, part.leaf_kids};
  kids[0].spilled = kids[1].spilled = t.spilled;
  return true;
}

// A spilled node small enough for RAM (or a leaf: list 0, its objects, and the lists' ends for its box
// unless its parent made it leaf_lists_only) has its lists loaded and is built in RAM from here on. A
// larger one gets the ends of its lists, which give its box and its spreads (NodeBox,
// SplitChooser::CompactAxes); its sweeps load the rest as they go. (The box from the lists' ends and the
// one from the objects may differ in the sign of a zero: each node takes it as the RAM build does.)
void SubtreeBuilder::Unspill(Task* t) {
  ListSpill& spill = *s_.spill;
  const bool leaf = IsLeaf(t->hi - t->lo, t->bytes);
  if (!leaf && t->hi - t->lo <= s_.ram_node_objects) {
    for (int l = 0; l < 6; ++l) spill.Load(l, t->lo, t->hi);
    t->spilled = false;
    return;
  }
  if (leaf) spill.Load(0, t->lo, t->hi);
  if (!t->leaf_lists_only)
    for (int l = leaf ? 1 : 0; l < 6; ++l) spill.Load(l, t->lo, t->lo + 1), spill.Load(l, t->hi - 1, t->hi);
  if (leaf) t->spilled = false;
}

// R(Sn): from the ends of the six sorted lists, or from the objects when only list 0 holds them in order.
Box3f SubtreeBuilder::NodeBox(const Task& t) const {
  Box3f box;
  if (t.leaf_lists_only) {
    for (uint32_t i = t.lo; i < t.hi; ++i) box.Extend(box_[s_.lists[0][i]]);
  } else {
    for (int w = 0; w < 3; ++w) {
      box.min[w] = box_[s_.lists[2 * w][t.lo]].min[w];
      box.max[w] = box_[s_.lists[2 * w + 1][t.hi - 1]].max[w];
    }
  }
  return box;
}

void SubtreeBuilder::AppendLeaf(const Task& t, TreeNode node, SubtreeOut* out) {
  const uint32_t me = static_cast<uint32_t>(out->nodes.size());
  node.leaf = static_cast<uint32_t>(out->leaves.size());
  LeafInfo leaf;
  leaf.box = node.box;
  leaf.node = me;
  leaf.object_count = t.hi - t.lo;
  leaf.payload_bytes = LeafPayloadBytes(t.bytes);
  leaf.page_count = static_cast<uint32_t>(PagesForLeaf(t.bytes, mem_page_));
  out->leaves.push_back(leaf);
  out->leaf_begin.push_back(t.lo);
  s_.done.LeafDone(t.lo, t.hi);
  out->nodes.push_back(node);
  out->overlap.push_back(0);
  if (track_split_count_) out->split_count.push_back(0);
}

// Sends the first best.k objects of the chosen order to Sn1 and the others to Sn2 (s_.side), and gathers
// the objects meeting the closed slab [a, b] (if any) as SplitTree items: they decide the SplitTree, and
// the free ones among them (the paper's In objects) may change side. Returns how many there are.
// When the split is by min_w (key 0), the gathering walks the chosen list itself, so an object's side is
// its position (no read of side[], and the sides may be marked meanwhile, on the root's second thread).
uint32_t SubtreeBuilder::AssignSides(const Task& t, const Candidate& best) {
  uint8_t* const side = s_.side.data();
  const uint32_t* const chosen = chooser_.Range(t, best.list);
  const size_t k = best.k, n = t.hi - t.lo;
  const bool key0 = best.list % 2 == 0;
  uint32_t n_items = 0;
  if (!(best.a < best.b)) {
    MarkSides(side, chosen, k, n);
  } else if (!key0) {
    MarkSides(side, chosen, k, n);
    n_items = GatherSlabItems<false>(t, best);  // (a spilled node: its by_min list replaces `chosen`)
  } else if (t.cooperative) {
    Together([=] { MarkSides(side, chosen, k, n); }, [&] { n_items = GatherSlabItems<true>(t, best); });
  } else {
    MarkSides(side, chosen, k, n);
    n_items = GatherSlabItems<true>(t, best);
  }
  chooser_.NodeDone(t);  // (its lists are read again by PartitionLists)
  return n_items;
}

// The classification of the paper's groups: an object meeting the slab that reaches below a (crosses pi0)
// is fixed to Sn1 (kLeft), one reaching above b (crosses pi1) to Sn2 (kRight), one inside it is free (In);
// the others (WW, BB) keep their side. Branch-free: every object up to the slab's far end is written, and
// kept (the count advanced) when it meets the slab, which is not predictable (in large nodes about half
// do). The arrays are sized for the whole node, but only the pages written are touched.
template <bool kKey0>
uint32_t SubtreeBuilder::GatherSlabItems(const Task& t, const Candidate& best) {
  const uint32_t n = t.hi - t.lo;
  items_.Fit(n);
  overlap_ids_.Fit(n);
  // (Locals: the item stores could alias what `this` refers to.)
  SplitItem* const items = items_.data();
  uint32_t* const ids = overlap_ids_.data();
  const int axis = best.list / 2;
  const uint32_t* const by_min = chooser_.Range(t, 2 * axis);  // [0]: position t.lo
  const Box3f* const box = box_.data();
  const uint32_t* const bytes = bytes_.data();
  const uint8_t* const sides = s_.side.data();
  const float a = best.a, b = best.b;
  const size_t size = n;  // (64-bit: no zero-extensions in the loop)
  const size_t prefetch_end = n >= kPrefetchObjects ? size - kPrefetch : 0;
  const size_t first_right = best.k;
  size_t count = 0;
  for (size_t i = 0; i < size; ++i) {
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
  return static_cast<uint32_t>(count);
}

// Builds the node's SplitTree over the overlap region Q = R(Sn) with a <= w <= b, which gives each free
// object its side (within the balance window of the cuts step 1 allows, and, for a split chosen to fill
// pages, within its page counts).
void SubtreeBuilder::PlaceSlabObjects(const Task& t, const Box3f& box, const Candidate& best, CutRange cuts,
                                      uint32_t n_items) {
  const int w = best.list / 2;
  SplitItem* const items = items_.data();
  const uint32_t* const ids = overlap_ids_.data();
  Box3f q = box;
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
  BuildSplitTree(q, std::span<SplitItem>(items, n_items), s_.params.split_tree_node_budget, &window, &split_,
                 s_.tuning.split_min_gain, &split_scratch_);
  uint8_t* const side = s_.side.data();
  for (uint32_t i = 0; i < n_items; ++i) side[ids[i]] = items[i].side;
}

// Stable in-place partition of the lists by side, keeping each half sorted by its key. List 0 goes first
// and also sums the left child's bytes: when both children are leaves, only list 0 (their objects) and
// the split axis' lists (the planes) are partitioned, as a leaf takes its box from its objects. A spilled
// node's lists are all cut (its children may be anything), each read into a window, partitioned there and
// written back. The planes of the final children are read off the split axis' two lists.
SubtreeBuilder::Partition SubtreeBuilder::PartitionLists(const Task& t, int w) {
  const uint32_t n = t.hi - t.lo;
  Partition part;
  auto one = [&](int l, int slot) {
    uint32_t* const buffer = chooser_.PartitionBuffer(slot, n);
    uint32_t* v = s_.lists[l].data() + t.lo;
    if (t.spilled) {
      v = chooser_.Window(slot, n);
      s_.spill->Read(l, t.lo, t.hi, v);
    }
    uint32_t n1 = 0;
    if (l == 0)
      n1 = part.n1 = PartitionList<true>(v, n, buffer, &part.left_bytes);
    else
      n1 = PartitionList<false>(v, n, buffer, nullptr);
    if (l == 2 * w) part.a = box_[v[n1]].min[w];
    if (l == 2 * w + 1) part.b = box_[v[n1 - 1]].max[w];
    if (t.spilled) s_.spill->Write(l, t.lo, t.hi, v);
  };
  auto lists_0_to_2 = [&] {
    one(0, 0);
    part.leaf_kids = IsLeaf(part.n1, part.left_bytes) && IsLeaf(n - part.n1, t.bytes - part.left_bytes);
    for (int l = 1; l < 3; ++l)
      if (!part.leaf_kids || l / 2 == w || t.spilled) one(l, 0);
  };
  if (t.cooperative) {  // lists 3-5 on the other thread (partitioned even for leaf children: harmless)
    Together(lists_0_to_2, [&] {
      for (int l = 3; l < 6; ++l) one(l, 1);
    });
  } else {
    lists_0_to_2();
    for (int l = 3; l < 6; ++l)
      if (!part.leaf_kids || l / 2 == w || t.spilled) one(l, 0);
  }
  chooser_.NodeDone(t);
  return part;
}

// One list of PartitionLists: the n positions at v, through `right` (room for n); kSumBytes: *left_bytes
// gets the encoded bytes of Sn1. Returns |Sn1|. Branch-free: the sides of neighbours in key order are not
// predictable.
template <bool kSumBytes>
uint32_t SubtreeBuilder::PartitionList(uint32_t* v, size_t n, uint32_t* right, uint64_t* left_bytes) {
  // (Locals: the list stores could alias the byte sum.)
  const uint8_t* side = s_.side.data();
  const uint32_t* bytes = bytes_.data();
  // 64-bit positions and 1 - r: no zero-extensions in the loop.
  size_t wpos = 0, tpos = 0;
  uint64_t sum = 0;
  for (size_t i = 0; i < n; ++i) {
    const uint32_t idx = v[i];
    const size_t r = side[idx];
    v[wpos] = idx;
    right[tpos] = idx;
    wpos += 1 - r;
    tpos += r;
    if (kSumBytes) sum += bytes[idx] & (r - 1);  // r = 0: all bits
  }
  std::copy(right, right + tpos, v + wpos);
  if (kSumBytes) *left_bytes = sum;
  return static_cast<uint32_t>(wpos);
}

// |Sm| of the final children: the slab's objects with max_w > a and min_w < b. The items' boxes are
// clipped to the chosen [a, b] on w, which holds the final one (the children only lost or took free
// objects, which lie in it), so they meet the final slab as the objects do.
uint32_t SubtreeBuilder::CountOverlap(uint32_t n_items, int w, float a, float b) const {
  const SplitItem* const items = items_.data();
  uint32_t sm = 0;
  for (size_t i = 0; i < n_items; ++i) sm += items[i].box.max[w] > a && items[i].box.min[w] < b;
  return sm;
}

void SubtreeBuilder::ShrinkScratch(size_t n) {
  const size_t had = chooser_.ScratchObjects();
  if (had < n + n / 2 + (1u << 16)) return;
  const size_t freed = 6 * (had - n) * sizeof(float);  // about
  chooser_.ShrinkScratch(n);
  split_scratch_.Release();
  if (items_.capacity() > n) items_.Reset(n);
  if (overlap_ids_.capacity() > n) overlap_ids_.Reset(n);
  if (freed >= kTrimBytes) TrimHeap();  // trimming is a walk of the heap: only for large frees
}

void ReleaseBuildLists(BuildState* state) {
  for (int l = 1; l < 6; ++l) BuildVector<uint32_t>().swap(state->lists[l]);
  std::vector<uint8_t>().swap(state->side);
  if (state->records != nullptr) {
    BuildVector<Box3f>().swap(state->records->box);
    BuildVector<uint32_t>().swap(state->records->bytes);
  }
  TrimHeap();
}

}  // namespace mktree::build
