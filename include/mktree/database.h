// mktree's public query API: open a store, ask it point and box queries, and read what each query cost.
//
// One query shape: a Query is a point or a box, a mode and an optional limit. VisitUntil is the one way a
// query runs; the others are thin layers over it, so all give the same ids and the same statistics:
//   VisitUntil(query, visit, &stats)      streams each answering id to `visit`, leaf by leaf, holding one
//                                         leaf's ids at a time however large the answer; `visit` returns
//                                         false to stop (no further page is read)
//   Visit(query, visit, &stats)           the same with a visitor that never stops
//   VisitSpans(query, visit, &stats)      the same, the ids handed over a span at a time (one or more
//                                         leaves' ids per call, no call per id); no limit: a whole answer
//   Any(query, &stats)                    whether anything answers; reads pages up to the first hit only
//   Run(query, &result)                   the answer sorted, with its statistics
//   RunBatchStreamed(source, options, deliver)
//                                         many queries on many threads; each result goes to `deliver` on
//                                         the calling thread in query order, at most a window of results
//                                         held at once, however many queries
//   RunBatch(queries, threads, &results)  RunBatchStreamed into a vector
//
// Query::limit caps an answer at its first `limit` ids in visiting order (leaf by leaf, as VisitUntil
// delivers them): a limited query stops reading pages as soon as it knows the answer has more (the id
// after the limit), and says so (QueryResult::truncated, VisitUntil's result). Run sorts those ids; it
// does not find the `limit` smallest ids of the whole answer, which would need the whole answer read.
//
//   auto db = mktree::Database::Open("ship.mkt", {.cache_pages = 4096});
//   if (!db.ok()) { ... db.status().ToString() ... }
//   mktree::QueryResult r;
//   mktree::Status st = (*db)->Run(mktree::Query::Box(box), &r);  // r.hits, r.stats
//   st = (*db)->Visit(mktree::Query::Box(box, mktree::QueryMode::kExact), [&](mktree::ObjectId id) { ... },
//                     /*stats=*/nullptr);
//   mktree::Result<bool> any = (*db)->Any(mktree::Query::Box(box), nullptr);  // reads up to the first hit
//   st = (*db)->RunBatchStreamed(queries, {.threads = 4}, [&](uint64_t i, const mktree::QueryResult& r) {
//     ...;  // r answers queries[i]; results come in order of i
//     return mktree::Status::Ok();
//   });
//
// Thread safety: a Database is safe to query from many threads at once (the page cache is shared and
// locked; each query has its own QueryStats). ClearCache must not run concurrently with queries if the
// caller wants per-query cold counts (RunBatchStreamed with BatchOptions::cold gives them on any number of
// threads).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mktree/clash.h"
#include "mktree/geometry.h"
#include "mktree/nearest.h"
#include "mktree/query_stats.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

enum class QueryMode {
  kAabb,   // an object answers when its stored AABB (float32 in the store's frame, rounded outward) meets
           // the query
  kExact,  // an object answers when its closed solid meets the query; see engine/geometry for meshes
           // that are not closed (open surfaces)
};

struct OpenOptions {
  // Capacity of the LRU page cache, in pages (0: every page lookup is a disk access). The budget stays in
  // pages: each cached leaf also keeps its decoded form (ids and float32 boxes as arrays, about 37 bytes
  // per object, fewer than its entries take in the page) for as long as its pages stay cached, so that a
  // warm query never parses entries; exact mode adds the meshes it decoded, at most the leaf's page bytes.
  // Memory is thus at most about twice cache_pages pages. Page counts (QueryStats) are unchanged by it.
  uint64_t cache_pages = 4096;
  // Verify each page's checksum when it is read from the store. A mismatch is an error, never an answer.
  bool verify_checksums = true;
  // Bypass the OS page cache (O_DIRECT, paged-file backend) for honest cold reads.
  bool direct_io = false;
  // The revision to answer (mktree/changes.h): unset, the newest; an older one while the store keeps it
  // (NotFound naming the store and the revision when it is not kept).
  std::optional<uint64_t> revision = std::nullopt;
};

// A query: the objects containing `point`, or meeting `box` (intervals closed), tested as `mode` says.
// REQUIRES (else InvalidArgument): finite coordinates; for a box, min <= max on every axis.
struct Query {
  enum class Kind { kPoint, kBox };
  Kind kind = Kind::kPoint;
  Vec3d point;  // kPoint
  Box3d box;    // kBox
  QueryMode mode = QueryMode::kAabb;
  // At most this many ids (the first in visiting order). 0 answers no id but still says, by truncated,
  // whether anything answers.
  uint64_t limit = kNoLimit;

  static constexpr uint64_t kNoLimit = UINT64_MAX;

  static Query Point(const Vec3d& p, QueryMode mode = QueryMode::kAabb) {
    return {Kind::kPoint, p, {}, mode};
  }
  static Query Box(const Box3d& b, QueryMode mode = QueryMode::kAabb) { return {Kind::kBox, {}, b, mode}; }
  // The other query shapes (mktree/nearest.h), run by Database::Nearest and Database::Ray.
  static DistanceQuery Nearest(const Vec3d& p, uint64_t k,
                               double max_distance = std::numeric_limits<double>::infinity()) {
    return DistanceQuery::Nearest(p, k, max_distance);
  }
  static RayQuery Ray(const Vec3d& origin, const Vec3d& direction,
                      double max_length = std::numeric_limits<double>::infinity(), bool all_hits = false) {
    return {origin, direction, max_length, all_hits};
  }
};

struct QueryResult {
  std::vector<ObjectId> hits;  // sorted ids (empty when the batch was asked for counts only)
  QueryStats stats;            // stats.hits: the number of ids of the answer (as limited)
  bool truncated = false;      // the query's limit cut the answer: it has more ids than `hits`
};

// What a store keeps of one object besides its geometry (Database::Object).
struct ObjectRecord {
  ObjectId id = 0;
  std::string name;    // any bytes, as the input gave them
  std::string source;  // the input file it came from (empty for generated objects)
  std::vector<ObjectAttribute> attributes;
  Box3d box;  // world coordinates: the stored float32 box (rounded outward in the store's frame) plus origin
};

// One shard's part of a query over a sharded store (Database::VisitUntilPerShard, docs/shards.md).
struct ShardQueryStats {
  uint32_t shard = 0;  // its index in the manifest
  QueryStats stats;    // what the query cost in that shard's store
};

// Receives the ids of a streamed answer (Database::Visit).
using ObjectVisitor = std::function<void(ObjectId)>;
// The same, for VisitUntil: returns false to stop the query.
using StoppableVisitor = std::function<bool(ObjectId)>;
// Receives a streamed answer a span of ids at a time (Database::VisitSpans); the span is valid only
// during the call.
using SpanVisitor = std::function<void(std::span<const ObjectId> ids)>;

// The queries of a streamed batch, one a call: fills `*next` and returns true, or returns false at the
// end. An error stops the batch and is returned as it is (name the file and line in it).
using QuerySource = std::function<Result<bool>(Query* next)>;
// Receives one result of a streamed batch: its query's index (from 0, in the source's order) and the
// result, valid only during the call. A non-OK Status stops the batch and is returned as it is.
using ResultVisitor = std::function<Status(uint64_t index, const QueryResult& result)>;

struct BatchOptions {
  // Threads running queries (0: hardware concurrency). 1 runs them on the calling thread.
  unsigned threads = 0;
  // Results held at most (finished but not yet delivered, plus running); 0: 4 per thread, so that the
  // other threads keep working while one query takes up to about four times as long as the rest. Memory
  // is this many answers, whatever the number of queries.
  uint64_t window = 0;
  // Each query runs on an empty private cache of OpenOptions::cache_pages pages, as after ClearCache: the
  // same per-query counts on any number of threads. Otherwise queries share the Database's cache, and
  // with several threads the cache-dependent counts (pages_read, cache_hits, bytes_read) depend on timing.
  bool cold = false;
  // Whether results carry their ids; without, only the statistics (stats.hits counts) and truncated: an
  // answer of millions of ids is counted, never held.
  bool ids = true;
};

class Database {
 public:
  virtual ~Database() = default;

  // Opens the store at `path` (HDF5 or paged file, detected from the file). Reads only the header and
  // the in-RAM structure; refuses truncated, foreign or corrupt files with an error naming the file.
  // A store that has taken changes (mktree/changes.h) answers options.revision, by default its newest,
  // holding it (the writer does not retire it) until the Database is destroyed.
  // `path` may also be a sharded store's manifest (docs/shards.md, BuildOptions::shards): every shard
  // store and id file is opened and checked at once (a missing, damaged or foreign one is an error naming
  // it), each shard with a cache of ceil(cache_pages / shards) pages. The Database then answers every
  // query, batch, Object and ObjectGeometry as the unsharded store of the same scene: the same ids (a
  // streamed answer visits them shard by shard, so in another order; Run and batches sort them), names,
  // boxes and meshes; SelfClash and Collide find the same pairs (docs/shards.md, "Clash").
  static Result<std::unique_ptr<Database>> Open(const std::string& path, const OpenOptions& options = {});

  // Runs `query`, calling `visit` once for each object of the answer: ids in the order their leaves are
  // read, not sorted, each once, at most query.limit of them. Returns true when the whole answer was
  // visited; false when `visit` returned false (no later leaf is read) or the limit cut an answer that has
  // more ids. `stats` (may be null) is reset and filled with what was done: hits counts the ids visited.
  // `visit` runs on the calling thread after its leaf's pages are released, so it may query this Database
  // too. An exception thrown by `visit` ends the query with an Internal error. On an error the ids
  // visited so far are an incomplete answer.
  virtual Result<bool> VisitUntil(const Query& query, const StoppableVisitor& visit,
                                  QueryStats* stats) const = 0;
  // VisitUntil, with each shard's statistics: `*per_shard` (may be null) is replaced by one entry per
  // shard that the top levels routed the query to and that it reached before it stopped, in shard order;
  // `stats` is their sum, plus the top levels' nodes in internal_nodes_visited. An ordinary store has no
  // shards: per_shard is emptied.
  virtual Result<bool> VisitUntilPerShard(const Query& query, const StoppableVisitor& visit,
                                          QueryStats* stats, std::vector<ShardQueryStats>* per_shard) const;
  // Shards of a sharded store; 0 for an ordinary store.
  virtual uint32_t shard_count() const { return 0; }
  // The revision this Database answers (mktree/changes.h): the one it opened, for as long as it is open;
  // 0 for a store that has taken no change.
  virtual uint64_t revision() const { return 0; }
  // Above every id of this revision: object_count() for a store that has taken no change; with changes,
  // ids removed or never given lie below it too (Object and ObjectGeometry refuse them).
  virtual uint64_t id_limit() const { return object_count(); }
  // VisitUntil with a visitor that never stops.
  Status Visit(const Query& query, const ObjectVisitor& visit, QueryStats* stats) const;
  // Visit, the ids handed to `visit` a span at a time: the same ids in the same order and the same
  // statistics, one call per leaf or per several leaves (warm AABB queries without a limit read the
  // cached leaves a few at a time, all released before their ids are visited, so `visit` may query this
  // Database too). The fast way to collect a large answer.
  virtual Status VisitSpans(const Query& query, const SpanVisitor& visit, QueryStats* stats) const;
  // Whether any object answers `query` (its limit is ignored): the query with limit 0, which reads the
  // leaves up to the first one holding an answer and tests its objects up to that answer. No id is
  // visited, so stats->hits is 0.
  Result<bool> Any(const Query& query, QueryStats* stats) const;

  // Runs `query`: `result->hits` is replaced by the sorted answer, `result->stats` by its statistics,
  // `result->truncated` says whether query.limit cut the answer.
  Status Run(const Query& query, QueryResult* result) const;

  // Runs the queries of `source` on options.threads threads and hands each result to `deliver` on the
  // calling thread, in query order, as soon as it and every earlier one are complete; at most
  // options.window results are held at once. `source` is called on the calling thread too. A failed
  // query stops the batch: the error returned is the first failing query's in query order, with its own
  // code and message, the message prefixed by "query <i>: "; every result before it has been delivered
  // and stays valid, none after it is.
  virtual Status RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                                  const ResultVisitor& deliver) const = 0;
  // The same over a vector of queries.
  Status RunBatchStreamed(const std::vector<Query>& queries, const BatchOptions& options,
                          const ResultVisitor& deliver) const;

  // Runs `queries` on `threads` threads (0: hardware concurrency); `(*results)[i]` answers `queries[i]`.
  // Errors as RunBatchStreamed's; the results are then incomplete.
  Status RunBatch(const std::vector<Query>& queries, unsigned threads,
                  std::vector<QueryResult>* results) const;

  // Clash detection (mktree/clash.h, docs/clash.md). SelfClash: every pair of the store's objects that
  // clashes under `options`. Collide: every object that clashes with `mesh` (world coordinates) moved by
  // `transform` (none: as it is); its pairs have b = kCollideObject. Pairs go to `visit` on the calling
  // thread, in an order that does not depend on options.threads; `stats` (may be null) is reset and
  // filled. Pages are read through this Database's cache; the self-clash keeps decoded leaves in a window
  // of ClashOptions::window_bytes. On an error the pairs visited so far are an incomplete answer.
  virtual Status SelfClash(const ClashOptions& options, const ClashVisitor& visit,
                           ClashStats* stats) const = 0;
  virtual Status Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                         const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats) const = 0;

  // Nearest and within-distance queries (mktree/nearest.h, docs/nearest_and_ray.md): an incremental
  // best-first search over the tree, the leaf filter and the objects' boxes, exact distances last.
  // OpenNearest checks the query and returns its cursor (nothing read yet); VisitNearest hands the answers
  // to `visit` nearest first until it returns false (returns whether the answer was visited to its end);
  // Nearest collects them. `stats` (may be null) is reset and filled. Sharded stores and revisions answer
  // as one store: one search over all their parts' trees, nearest part first.
  virtual Result<std::unique_ptr<NearestCursor>> OpenNearest(const DistanceQuery& query) const;
  Result<bool> VisitNearest(const DistanceQuery& query, const NearestVisitor& visit, QueryStats* stats) const;
  Status Nearest(const DistanceQuery& query, std::vector<NearestHit>* hits, QueryStats* stats) const;
  // Ray queries: the tree walked front to back along the ray, the first hit's search ending at it.
  // VisitRay hands the hits in order to `visit` until it returns false; Ray collects them (empty: nothing
  // hit). `stats` (may be null) is reset and filled.
  virtual Result<bool> VisitRay(const RayQuery& query, const RayVisitor& visit, QueryStats* stats) const;
  Status Ray(const RayQuery& query, std::vector<RayHit>* hits, QueryStats* stats) const;

  // Empties the page cache (pages pinned by running queries stay until released).
  virtual void ClearCache() = 0;

  // The store's file, as given to Open.
  virtual const std::string& path() const = 0;
  virtual uint64_t object_count() const = 0;  // live objects
  // One object's record: name, source file, attributes and box. Records live in pages of the store, read
  // through the page cache like leaves: `stats` (may be null) is reset and counts the pages touched and
  // read. InvalidArgument for an id >= id_limit() or not live at this revision; Corruption naming the store
  // and the page if its record page is damaged.
  virtual Result<ObjectRecord> Object(ObjectId id, QueryStats* stats = nullptr) const = 0;
  // One object's triangles in world coordinates (the stored vertices, float32 in the object's frame, plus
  // the store's origin in double), read from its leaf through the page cache. Errors as Object's.
  virtual Result<Mesh> ObjectGeometry(ObjectId id, QueryStats* stats = nullptr) const = 0;
  // Object(id)'s name (one record page read).
  virtual Result<std::string> ObjectName(ObjectId id) const = 0;
  // Scene bounds in world coordinates (the root's box, which is rounded outward to float32 in the store's
  // frame); empty for an empty store.
  virtual Box3d bounds() const = 0;
  // Mean objects per leaf page (B of the I/O floor ceil(T / B), docs/design.md §8.3).
  virtual double objects_per_page() const = 0;
  // The builder's statistics as JSON (what `mktree info --json` prints under "tree").
  virtual const std::string& stats_json() const = 0;
};

}  // namespace mktree
