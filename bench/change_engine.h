// The interface every engine of changes_bench implements (SQLite R*Tree, libspatialindex, Boost.Geometry's
// rtree and mktree's ChangeWriter), so that the driver
// loads, changes and checks them all the same way.
//
// Protocol, per engine: Load() builds the engine's index of the tanker's N objects (timed, reported, not
// part of the commit latency); then for each batch of the script, Stage() prepares what the engine is
// handed (untimed: e.g. mktree's moved meshes) and Commit() applies it and makes it durable as far as the
// engine can (timed); at the end Query() answers AABB box queries, which the driver checks against the
// script's live set.
//
// Thread safety: none; the driver uses one engine from one thread.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "bench/change_workload.h"
#include "mktree/status.h"

namespace mktree::bench {

class ChangeEngine {
 public:
  virtual ~ChangeEngine() = default;
  virtual std::string name() const = 0;
  // One line for the printed header: what the engine stores and what a commit does to make it durable.
  virtual std::string description() const = 0;
  virtual Status Load(const ChangeWorkload& workload) = 0;
  virtual Status Stage(const ChangeBatchScript& batch) = 0;
  virtual Status Commit() = 0;
  // The ids of the live objects whose box meets `box`, sorted.
  virtual Status Query(const Box3f& box, std::vector<ObjectId>* ids) = 0;
  // What the run showed beyond latencies (e.g. compactions), one line, printed after the engine's rows.
  virtual std::string summary() const { return ""; }
};

// `dir` takes the engine's files, removed by the destructor.
enum class SqliteSync { kFull, kNormal };
std::unique_ptr<ChangeEngine> MakeSqliteChangeEngine(const std::string& dir, SqliteSync sync);
std::unique_ptr<ChangeEngine> MakeSpatialIndexChangeEngine(const std::string& dir);
std::unique_ptr<ChangeEngine> MakeBoostChangeEngine();
// bench/changes_bench_mktree.cc. `compact_threshold` is ChangeOptions::compact_threshold (0: no automatic
// compaction during the script).
std::unique_ptr<ChangeEngine> MakeMktreeChangeEngine(const std::string& dir, double compact_threshold);

}  // namespace mktree::bench
