// BuildTuning: the knobs of an MKtree build (BuildMKTree, mktree_builder.h) that change the tree's quality,
// its threads or its memory but not its contract, and SplitPolicy, how a node chooses its split. Not
// persisted in the store. A plain struct: copy it freely; the FileOps it points to, if any, must outlive
// the build.
#pragma once

#include <cstdint>
#include <string>

#include "storage/file_ops.h"

namespace mktree {

// How an internal node chooses among the SOA candidates (the 6 sort orders x the balanced cut positions k).
enum class SplitPolicy : uint8_t {
  // The reference SOA (docs/design.md §3.5): fewest |Sm|, then the thinner slab, then balance. With
  // BuildTuning::fill_aware off this is the SOA exactly; on, page waste ranks first near the leaves.
  kSoa,
  // The SOA over compact candidates: only axes along which the node's objects spread at least
  // compact_axis_ratio x their longest spread are tried, and ties on |Sm| (near the leaves: on page waste)
  // go to the smaller N1 x margin(R(Sn1)) + N2 x margin(R(Sn2)) (margin = ex + ey + ez, the R*-tree's),
  // then to the thinner slab and balance. Why: the SOA alone cuts a node along a thin axis whenever that
  // crosses the fewest objects, and its many ties (|Sm| = 0 is common) go to the thinner slab, not to the
  // tighter children; leaves become thin slabs that a box query meets many of. (What it measured, and the
  // variants tried and dropped: bench/README.md, tree_build_bench.)
  kCompact,
};

// Knobs that change the tree's quality but not its contract; defaults are what the benchmarks measured best.
struct BuildTuning {
  SplitPolicy split_policy = SplitPolicy::kCompact;
  // kCompact: candidate axes spread at least this share of the longest (the longest always stays).
  double compact_axis_ratio = 0.3;
  // Near the leaves (a node of at most `fill_aware_pages` pages of data), rank the SOA candidates whose
  // |Sm| is within `fill_sm_slack` + `fill_sm_slack_rel` x minimum first by page waste
  // (ceil(D1/C) + ceil(D2/C) - ceil(D/C)), then by |Sm| (kCompact: by margin, then |Sm|), slab and balance,
  // and keep the page counts when free objects change side. Off: plain SOA (|Sm|, slab, balance). Why:
  // the plain SOA leaves pages far from full, and fewer, fuller leaves cost fewer page reads.
  bool fill_aware = true;
  uint32_t fill_aware_pages = 8;
  uint32_t fill_sm_slack = 1u << 30;
  double fill_sm_slack_rel = 0;
  // A SplitTree cut is made only when it saves at least this share of the routing cost of a point spread
  // over the overlap region Q (see split_tree_builder.h): it keeps SplitTrees to the cuts that matter (the
  // leaf filter, not the SplitTrees, keeps a point query near one leaf).
  double split_min_gain = 0.1;
  // Threads used (0: one per hardware thread): with 2 or more, the key sorts run on two threads and
  // subtrees are built concurrently from a shared task queue (the right child of every node of at least
  // `parallel_task_objects` objects becomes a task; 0: max(4096, N/256)), each into its own fragment, and
  // the fragments are stitched in DFS order: the same tree as 1 thread (bench/tree_build_bench: tanker_1m
  // on 1 thread, tanker_1m_2t on 2).
  int threads = 0;
  uint32_t parallel_task_objects = 0;
  // With 2 threads or more, a root of at least this many objects shares its key sweeps and list partitions
  // with a second thread (the others have nothing to do until it is split).
  uint32_t cooperative_root_objects = 1u << 17;
  // Memory (the build's peak RSS; bench/README.md, tree_build_bench): a node of more than
  // `ram_node_objects` objects keeps its six key lists (24 bytes an object) in a spill file in `spill_dir`
  // between its sweeps, which load one list (two on a cooperative root) at a time; smaller nodes are built
  // in RAM as before. The tree is the same whatever the budget. 0: N / 8 for N of at least 2^18 objects,
  // else no spill (kNoIndex: never). Contract: the peak is then at most about 60 bytes an object plus the
  // process's fixed part (the records 28, side flags 1, the root's sweeps about 16 of which 4 for the list
  // loaded, the lists of the nodes in RAM at most 3 a thread, and the tree as it grows; the ids and the
  // built part of list 0 wait in the file), and the file holds 32 bytes an object until the build
  // returns. It has no name (list_spill.h), so nothing is left behind.
  // "": $TMPDIR, else /tmp (BuildStore passes the directory of its own spill files).
  uint32_t ram_node_objects = 0;
  std::string spill_dir;
  // The spill file's writes and reads (storage/file_ops.h); null: POSIX. Tests inject faults through it.
  FileOps* spill_file_ops = nullptr;
};

}  // namespace mktree
