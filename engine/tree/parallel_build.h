// The multi-thread MKtree build (BuildMKTree with BuildTuning::threads >= 2, mktree_builder.h): workers
// take subtree tasks from a shared queue; each task is built depth-first into its own fragment (a
// SubtreeOut), handing the right child of every large node back to the queue. The fragments are then
// stitched in DFS preorder (nodes, SplitTree nodes and leaves renumbered), which gives exactly the tree
// that one thread builds: every node's split depends only on its own objects. Internal to engine/tree.
#pragma once

#include "engine/tree/build_state.h"

namespace mktree::build {

// Builds the tree of `root` on `threads` threads into `out` (whose vectors are sized exactly), and frees
// the lists but list 0 (ReleaseBuildLists) before the stitch. Returns the stitch's wall seconds.
double BuildParallel(BuildState* state, const Task& root, int threads, SubtreeOut* out);

}  // namespace mktree::build
