#include "engine/tree/mktree_builder.h"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <type_traits>
#include <utility>

#include "engine/tree/build_layout.h"
#include "engine/tree/build_memory.h"
#include "engine/tree/build_state.h"
#include "engine/tree/build_threads.h"
#include "engine/tree/build_validation.h"
#include "engine/tree/parallel_build.h"
#include "engine/tree/subtree_builder.h"

namespace mktree {
namespace {

// Below this many objects no node is spilled by default (BuildTuning::ram_node_objects).
constexpr uint32_t kSpillMinObjects = 1u << 18;
// Where the ids wait in the spill file during the nodes phase: the stretch after the six lists
// (list_spill.h).
constexpr int kSpilledIds = 6;

uint64_t PeakRss() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<uint64_t>(u.ru_maxrss) * 1024;  // (KiB on Linux)
}

using build::BuildRecords;
using build::BuildState;
using build::BuildVector;
using build::SubtreeOut;
using build::Task;

// The nodes of the tree of all n objects into *out, on one thread or on `threads`; frees the lists but
// list 0. Returns the wall seconds of the multi-thread build's stitch (0 on one thread).
double BuildNodes(BuildState* state, uint32_t n, uint64_t total_bytes, int threads, SubtreeOut* out) {
  Task root{0, n, 0, kNoIndex, 0, total_bytes};
  root.spilled = state->spill != nullptr;
  if (threads >= 2) {
    root.cooperative = n >= state->tuning.cooperative_root_objects;
    return build::BuildParallel(state, root, threads, out);
  }
  build::SubtreeBuilder(state).Run(root, out);
  build::ReleaseBuildLists(state);
  return 0;
}

// The built nodes into *result: pages in leaf order, the tree, each leaf's objects (the leaves' ranges of
// any list hold their objects: list 0, as ids), and the statistics. Frees list 0.
void Finish(SubtreeOut out, const BuildVector<ObjectId>& ids, BuildState* state, int threads,
            BuildResult* result) {
  const uint32_t n = static_cast<uint32_t>(ids.size());
  uint64_t page = 0;
  for (LeafInfo& lf : out.leaves) {
    lf.first_page = page;
    page += lf.page_count;
  }
  // The tree stays in RAM for the store's lifetime: copied at its exact size (no growth slack), once the
  // lists are gone, so under the build's peak.
  auto move_out = [](auto* from, auto* to, size_t extra = 0) {
    to->reserve(from->size() + extra);
    to->assign(from->begin(), from->end());
    std::remove_reference_t<decltype(*from)>().swap(*from);
  };
  result->leaf_offsets.clear();
  move_out(&out.leaf_begin, &result->leaf_offsets, 1);
  result->leaf_offsets.push_back(n);
  move_out(&out.nodes, &result->tree.nodes);
  move_out(&out.split_nodes, &result->tree.split_nodes);
  move_out(&out.leaves, &result->tree.leaves);
  result->leaf_objects.resize(n);
  const uint32_t* leaf_order = state->lists[0].data();
  build::RunOnHalves(n, threads, [&](size_t lo, size_t hi) {
    for (size_t i = lo; i < hi; ++i) result->leaf_objects[i] = ids[leaf_order[i]];
  });
  BuildVector<uint32_t>().swap(state->lists[0]);
  result->stats = ComputeTreeStats(result->tree, n, out.overlap, threads);
}

}  // namespace

Result<BuildResult> BuildMKTree(std::vector<BuildObject> records, const BuildParams& params,
                                const BuildTuning& tuning) {
  using Clock = std::chrono::steady_clock;
  Clock::time_point mark = Clock::now();
  auto lap = [&mark](double* phase, uint64_t* peak) {
    const Clock::time_point now = Clock::now();
    *phase = std::chrono::duration<double>(now - mark).count();
    mark = now;
    *peak = PeakRss();
  };
  const int threads = tuning.threads > 0
                          ? tuning.threads
                          : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  Box3f bounds;
  ObjectId max_id = 0;
  MKTREE_RETURN_IF_ERROR(build::Validate(records, params, threads, &bounds, &max_id));
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
  BuildState state{rec.box, rec.bytes, params, tuning, {}, {}, {}};
  state.records = &rec;
  MKTREE_RETURN_IF_ERROR(build::CheckUniqueIds(records, max_id));
  rec = build::SpatialLayout(std::move(records), bounds, &ids, threads);
  lap(&result.timings.layout, &result.timings.peak_layout);
  // Out of core (list_spill.h): the root's lists go to the spill file as they are sorted.
  const uint32_t ram_objects = tuning.ram_node_objects > 0 ? tuning.ram_node_objects
                               : n >= kSpillMinObjects     ? n / 8
                                                           : kNoIndex;
  build::ListSpill spill;
  if (n > ram_objects) {
    MKTREE_RETURN_IF_ERROR(spill.Open(tuning.spill_dir, n, &state.lists,
                                      tuning.spill_file_ops ? *tuning.spill_file_ops : DefaultFileOps()));
    state.spill = &spill;
    state.ram_node_objects = ram_objects;
  }
  SubtreeOut out;
  try {
    // The ids are read only by Finish: with a spill file they wait there (after the six lists).
    if (state.spill != nullptr) {
      spill.Write(kSpilledIds, 0, n, ids.data());
      BuildVector<ObjectId>().swap(ids);
    }
    build::SortKeyOrders(rec.box, &state.lists, [&](int l) {
      if (state.spill != nullptr) state.spill->Store(l, 0, n);
    });
    build::TrimHeap();
    lap(&result.timings.sorts, &result.timings.peak_sorts);
    state.side.assign(n, 0);
    state.done.Init(n, &state.lists, state.spill);
    uint64_t total_bytes = 0;
    for (uint32_t b : rec.bytes) total_bytes += b;

    result.timings.stitch = BuildNodes(&state, n, total_bytes, threads, &out);
    lap(&result.timings.nodes, &result.timings.peak_nodes);
    // Back for Finish, now that the records are freed (BuildNodes).
    if (state.spill != nullptr) {
      ids.resize(n);
      spill.Read(kSpilledIds, 0, n, ids.data());
    }
    if (state.done.list0_spilled()) spill.Read(build::DoneRanges::kDoneList0, 0, n, state.lists[0].data());
  } catch (const build::SpillError& e) {
    return Status::IOError(e.what());
  }
  Finish(std::move(out), ids, &state, threads, &result);
  lap(&result.timings.finish, &result.timings.peak_finish);
  return result;
}

}  // namespace mktree
