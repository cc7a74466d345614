// Database: what every implementation shares. The ways a query runs (Visit, Any, VisitSpans, Run, the
// batches) are layers over VisitUntil and RunBatchStreamed, which each implementation provides.
#include "mktree/database.h"

#include <algorithm>
#include <span>
#include <thread>
#include <utility>

#include "engine/core/guarded.h"
#include "engine/query/ordered_batch.h"
#include "engine/query/sorted_ids.h"

namespace mktree {

Status Prefixed(const Status& st, const std::string& prefix) {
  std::string m = prefix + st.message();
  switch (st.code()) {
    case Status::Code::kOk:
      return st;
    case Status::Code::kInvalidArgument:
      return Status::InvalidArgument(std::move(m));
    case Status::Code::kNotFound:
      return Status::NotFound(std::move(m));
    case Status::Code::kCorruption:
      return Status::Corruption(std::move(m));
    case Status::Code::kIOError:
      return Status::IOError(std::move(m));
    case Status::Code::kUnsupported:
      return Status::Unsupported(std::move(m));
    case Status::Code::kInternal:
      break;
  }
  return Status::Internal(std::move(m));
}

Result<bool> Database::VisitUntilPerShard(const Query& query, const StoppableVisitor& visit,
                                          QueryStats* stats, std::vector<ShardQueryStats>* per_shard) const {
  if (per_shard) per_shard->clear();
  return VisitUntil(query, visit, stats);
}

Status Database::Visit(const Query& query, const ObjectVisitor& visit, QueryStats* stats) const {
  return VisitUntil(
             query,
             [&visit](ObjectId id) {
               visit(id);
               return true;
             },
             stats)
      .status();
}

Result<bool> Database::Any(const Query& query, QueryStats* stats) const {
  Query q = query;
  q.limit = 0;  // leaves are scanned up to their first answer, which only tells that the answer goes on
  MKTREE_ASSIGN_OR_RETURN(const bool complete, VisitUntil(
                                                   q, [](ObjectId) { return true; }, stats));
  return !complete;
}

Status Database::VisitSpans(const Query& query, const SpanVisitor& visit, QueryStats* stats) const {
  return VisitUntil(
             query,
             [&visit](ObjectId id) {
               visit(std::span<const ObjectId>(&id, 1));
               return true;
             },
             stats)
      .status();
}

Status Database::Run(const Query& query, QueryResult* result) const {
  std::vector<ObjectId>& hits = result->hits;
  hits.clear();
  result->truncated = false;
  bool complete = true;
  if (query.limit == Query::kNoLimit) {  // a span at a time: no call per id
    MKTREE_RETURN_IF_ERROR(VisitSpans(
        query, [&hits](std::span<const ObjectId> ids) { hits.insert(hits.end(), ids.begin(), ids.end()); },
        &result->stats));
  } else {
    auto collect = [&hits](ObjectId id) {
      hits.push_back(id);
      return true;
    };
    MKTREE_ASSIGN_OR_RETURN(complete, VisitUntil(query, collect, &result->stats));
  }
  result->truncated = !complete;
  return Guarded(path(), [&] {
    SortIds(&hits);
    return CheckNoRepeatedIds(hits, path());
  });
}

Result<std::unique_ptr<NearestCursor>> Database::OpenNearest(const DistanceQuery&) const {
  return Status::Unsupported(path() + ": nearest queries are not supported by this database");
}

Result<bool> Database::VisitRay(const RayQuery&, const RayVisitor&, QueryStats* stats) const {
  if (stats) stats->Reset();
  return Status::Unsupported(path() + ": ray queries are not supported by this database");
}

Result<bool> Database::VisitNearest(const DistanceQuery& query, const NearestVisitor& visit,
                                    QueryStats* stats) const {
  if (stats) stats->Reset();
  MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<NearestCursor> cursor, OpenNearest(query));
  NearestHit hit;
  bool complete = true;
  while (true) {
    Result<bool> more = cursor->Next(&hit);
    if (stats) *stats = cursor->stats();
    if (!more.ok()) return more.status();
    if (!*more) break;
    if (!visit(hit)) {
      complete = false;
      break;
    }
  }
  return complete;
}

Status Database::Nearest(const DistanceQuery& query, std::vector<NearestHit>* hits, QueryStats* stats) const {
  hits->clear();
  return VisitNearest(
             query,
             [hits](const NearestHit& h) {
               hits->push_back(h);
               return true;
             },
             stats)
      .status();
}

Status Database::Ray(const RayQuery& query, std::vector<RayHit>* hits, QueryStats* stats) const {
  hits->clear();
  return VisitRay(
             query,
             [hits](const RayHit& h) {
               hits->push_back(h);
               return true;
             },
             stats)
      .status();
}

Status Database::RunBatchStreamed(const std::vector<Query>& queries, const BatchOptions& options,
                                  const ResultVisitor& deliver) const {
  BatchOptions o = options;
  if (o.threads == 0) o.threads = std::max(1u, std::thread::hardware_concurrency());
  o.threads = static_cast<unsigned>(std::min<size_t>(o.threads, std::max<size_t>(1, queries.size())));
  size_t next = 0;
  auto source = [&](Query* q) -> Result<bool> {
    if (next == queries.size()) return false;
    *q = queries[next++];
    return true;
  };
  return RunBatchStreamed(source, o, deliver);
}

Status Database::RunBatch(const std::vector<Query>& queries, unsigned threads,
                          std::vector<QueryResult>* results) const {
  MKTREE_RETURN_IF_ERROR(Guarded(path(), [&] {
    results->assign(queries.size(), QueryResult{});
    return Status::Ok();
  }));
  BatchOptions o;
  o.threads = threads;
  return RunBatchStreamed(queries, o, [results](uint64_t i, const QueryResult& r) {
    (*results)[i] = r;
    return Status::Ok();
  });
}

}  // namespace mktree
