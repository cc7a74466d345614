// Node processing of the MKtree build (BuildMKTree, mktree_builder.h): a SubtreeBuilder takes a node's
// objects (a Task), makes it a leaf when InPage, or else splits it as the SOA chooses (split_choice.h),
// sends each object to Sn1 or Sn2, lets the SplitTree (split_tree_builder.h) place the objects inside the
// slab, partitions the six key lists between the two children, and goes on depth-first. Internal to
// engine/tree.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/tree/build_memory.h"
#include "engine/tree/build_state.h"
#include "engine/tree/split_choice.h"
#include "engine/tree/split_tree_builder.h"

namespace mktree::build {

// Where RunSpawning sends the subtrees it does not build itself (the multi-thread build's task queue,
// parallel_build.cc). Thread-safe: several builders share one.
class TaskSink {
 public:
  virtual ~TaskSink() = default;
  // Queues `t` (a subtree root: parent kNoIndex) to be built into a fragment of its own; returns the
  // fragment's id.
  virtual uint32_t Spawn(const Task& t) = 0;
  // The objects of the largest task waiting in the queue (the builder may take it next).
  virtual uint32_t LargestWaiting() const = 0;
};

// Builds subtrees one after another (one per thread: it keeps the per-node scratch).
class SubtreeBuilder {
 public:
  // track_split_count: fill SubtreeOut::split_count (the multi-thread build's stitch needs it).
  explicit SubtreeBuilder(BuildState* s, bool track_split_count = false)
      : s_(*s),
        box_(s->box),
        bytes_(s->bytes),
        mem_page_(s->params.mem_page()),
        track_split_count_(track_split_count),
        chooser_(*s) {}

  // Builds the whole subtree of `root` into `out`, in DFS preorder.
  void Run(const Task& root, SubtreeOut* out);

  // Like Run, but the right child of a node with at least `min_spawn` objects is sent to `sink`, and
  // referenced as kFragmentRef | (its fragment id) in child[1].
  void RunSpawning(const Task& root, SubtreeOut* out, uint32_t min_spawn, TaskSink* sink);

 private:
  // What partitioning the lists between the two children found.
  struct Partition {
    uint32_t n1 = 0;          // objects of Sn1
    uint64_t left_bytes = 0;  // their encoded bytes
    bool leaf_kids = false;   // both children are leaves (only list 0 and the split axis' lists were cut)
    float a = 0, b = 0;       // the planes of the final children
  };

  bool IsLeaf(uint32_t count, uint64_t bytes) const { return build::IsLeaf(count, bytes, mem_page_); }
  uint64_t Pages(uint64_t bytes) const { return PagesForLeaf(bytes, mem_page_); }

  // Appends the node of `t` to `out`; returns true with its two child tasks when it is internal.
  bool ProcessNode(const Task& task, SubtreeOut* out, Task kids[2]);
  void Unspill(Task* t);
  Box3f NodeBox(const Task& t) const;
  void AppendLeaf(const Task& t, TreeNode node, SubtreeOut* out);
  uint32_t AssignSides(const Task& t, const Candidate& best);
  template <bool kKey0>
  uint32_t GatherSlabItems(const Task& t, const Candidate& best);
  void PlaceSlabObjects(const Task& t, const Box3f& box, const Candidate& best, CutRange cuts,
                        uint32_t n_items);
  Partition PartitionLists(const Task& t, int w);
  template <bool kSumBytes>
  uint32_t PartitionList(uint32_t* v, size_t n, uint32_t* right, uint64_t* left_bytes);
  uint32_t CountOverlap(uint32_t n_items, int w, float a, float b) const;
  void ShrinkScratch(size_t n);

  BuildState& s_;
  const BuildVector<Box3f>& box_;
  const BuildVector<uint32_t>& bytes_;
  const uint64_t mem_page_;
  const bool track_split_count_;
  SplitChooser chooser_;
  Scratch<SplitItem> items_;      // the slab's objects (SplitTree items), at overlap_ids_ in the records
  std::vector<SplitNode> split_;  // the node's SplitTree
  SplitTreeScratch split_scratch_;
  Scratch<uint32_t> overlap_ids_;
};

// Frees what only the splits needed: lists 1-5, the side flags and the records (list 0 gives the leaves'
// objects).
void ReleaseBuildLists(BuildState* state);

}  // namespace mktree::build
