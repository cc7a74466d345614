#include "engine/query/part_queries.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <thread>

#include "engine/query/ordered_batch.h"

namespace mktree {

bool FiniteQuery(const Query& q) {
  if (q.kind == Query::Kind::kPoint)
    return std::isfinite(q.point.x) && std::isfinite(q.point.y) && std::isfinite(q.point.z);
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(q.box.min[i]) || !std::isfinite(q.box.max[i]) || q.box.min[i] > q.box.max[i])
      return false;
  return true;
}

Box3d UnionBox(Box3d a, const Box3d& b) {
  for (int i = 0; i < 3; ++i) {
    a.min[i] = std::min(a.min[i], b.min[i]);
    a.max[i] = std::max(a.max[i], b.max[i]);
  }
  return a;
}

Status RunOneOnStore(const StoreDatabase& db, const Query& q, const BatchOptions& options,
                     const std::function<void(const QueryResult&)>& got) {
  BatchOptions one;
  one.threads = 1;
  one.cold = options.cold;
  one.ids = options.ids;
  bool given = false;
  return db.RunBatchStreamed(
      [&](Query* next) -> Result<bool> {
        if (given) return false;
        given = true;
        *next = q;
        return true;
      },
      one,
      [&](uint64_t, const QueryResult& r) {
        got(r);
        return Status::Ok();
      });
}

Status RunQueriesOneByOne(const std::string& path, const QuerySource& source, const BatchOptions& options,
                          const ResultVisitor& deliver, const OneQuery& one) {
  const unsigned threads =
      options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  const uint64_t window = options.window ? options.window : 4 * uint64_t{threads};
  auto run = [&](const Query& q, const void*, QueryResult* r) -> Status {
    r->hits.clear();
    r->stats.Reset();
    r->truncated = false;
    if (!FiniteQuery(q)) return Status::InvalidArgument("query with a non-finite coordinate or min > max");
    return one(q, r);
  };
  auto no_worker = [] { return std::unique_ptr<NoWorker>(); };
  return RunOrderedBatch<NoWorker>(source, threads, window, path, no_worker, run, deliver);
}

}  // namespace mktree
