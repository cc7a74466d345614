// What the subtree builders of one MKtree build (BuildMKTree, mktree_builder.h) share, take and produce:
// the records and the six key lists (BuildState), a node still to build (Task), and a built subtree
// (SubtreeOut). Internal to engine/tree.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <vector>

#include "engine/tree/build_layout.h"
#include "engine/tree/build_memory.h"
#include "engine/tree/build_tuning.h"
#include "engine/tree/list_spill.h"
#include "engine/tree/mktree.h"
#include "mktree/geometry.h"

namespace mktree::build {

// Gives back the pages of lists 1-5 over positions whose leaves are all built: nothing reads them again,
// and in DFS order the built leaves' positions fill whole chunks long before the build ends, when the tree
// it has built adds to the peak. List 0 gives the leaves' objects at the end: with a spill file its
// chunks go there first (Finish reads them back once the records are freed). Thread-safe.
class DoneRanges {
 public:
  static constexpr uint32_t kChunk = 1u << 14;  // positions: 64 KiB of each list
  // Only for lists mapped on their own (BuildAllocator): n * 4 bytes of at least kMapBytes. `spill`:
  // null, or the open spill file of these lists (list_spill.h).
  void Init(uint32_t n, std::array<BuildVector<uint32_t>, 6>* lists, ListSpill* spill);
  // The leaf over positions [lo, hi) is built.
  void LeafDone(uint32_t lo, uint32_t hi);
  // Where the spill file keeps list 0's built chunks (after the lists and the ids, so that the first
  // chunk's write extends the file: SpillFailuresAreErrorsAndLeaveNothing fails it there).
  static constexpr int kDoneList0 = 7;
  // List 0 is in stretch kDoneList0 of the spill file, not in RAM (once every leaf is built).
  bool list0_spilled() const { return done_ != nullptr && spill_ != nullptr; }

 private:
  std::array<BuildVector<uint32_t>, 6>* lists_ = nullptr;
  ListSpill* spill_ = nullptr;
  uint32_t n_ = 0;
  std::unique_ptr<std::atomic<uint32_t>[]> done_;  // per chunk: positions built
};

struct BuildState {
  const BuildVector<Box3f>& box;
  const BuildVector<uint32_t>& bytes;
  BuildParams params;
  BuildTuning tuning;
  // lists[2*w + key]: the objects of every node, each node's range sorted by min_w (key 0) / max_w (key 1).
  std::array<BuildVector<uint32_t>, 6> lists;
  std::vector<uint8_t> side;  // per object: 0 = Sn1, 1 = Sn2 at the node being split
  DoneRanges done;
  // Nodes of more objects keep their lists in `spill` (list_spill.h) between their sweeps; null: none do.
  uint32_t ram_node_objects = kNoIndex;
  ListSpill* spill = nullptr;
  // What box and bytes refer to, freed with the lists (ReleaseBuildLists): the stitch and Finish need
  // neither.
  BuildRecords* records = nullptr;
};

// A node to build: its objects are lists[l][lo, hi) of every list l.
struct Task {
  uint32_t lo = 0, hi = 0;
  uint32_t depth = 0;
  uint32_t parent = kNoIndex;  // local node index of the parent, kNoIndex for a subtree root
  int slot = 0;
  uint64_t bytes = 0;            // sum of encoded_bytes of the objects
  bool leaf_lists_only = false;  // a leaf whose range is sorted in list 0 (and the split axis' lists) only
  bool cooperative = false;      // the root of a multi-thread build: it takes an idle thread along (Together)
  bool spilled = false;          // its lists are in BuildState::spill, not in RAM
};

// What one builder produces for a subtree; indices are local to it until merged. Aligned to cache lines:
// two threads' fragments, allocated side by side, would otherwise share one, and every node pushed
// writes a vector's end pointer. On the build's allocator: as the arrays grow, the buffers they leave
// go back to the system at once (from the heap they stayed resident, holes the lists did not fit in),
// and the tree is copied out at its exact size once the lists are gone (BuildMKTree's Finish).
struct alignas(64) SubtreeOut {
  BuildVector<TreeNode> nodes;
  BuildVector<SplitNode> split_nodes;
  BuildVector<LeafInfo> leaves;
  BuildVector<uint64_t> leaf_begin;   // position of the leaf's first object in the lists
  BuildVector<uint32_t> overlap;      // |Sm| per node
  BuildVector<uint32_t> split_count;  // SplitTree nodes per node (filled only by the multi-thread build)

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
inline constexpr uint32_t kFragmentRef = 0x80000000u;

// Adds delta (modulo 2^32, like the indices) to the child indices of the `count` SplitNodes at `nodes`
// (cells keep their kNoIndex children), branch-free.
inline void RebaseSplitTree(SplitNode* nodes, uint32_t count, uint32_t delta) {
  for (SplitNode *sn = nodes, *end = sn + count; sn < end; ++sn) {
    const uint32_t d = sn->is_cell() ? 0 : delta;
    sn->child[0] += d;
    sn->child[1] += d;
  }
}

}  // namespace mktree::build
