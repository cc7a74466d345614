// mktree's public query API: open a store, ask it point and box queries, and read what each query cost.
//
// One query shape: a Query is a point or a box, and a mode. Visit is the one way a query runs; Run and
// RunBatch are thin layers over it, so all three give the same ids and the same statistics:
//   Visit(query, visit, &stats)           streams each answering id to `visit`, leaf by leaf, holding one
//                                         leaf's ids at a time however large the answer
//   Run(query, &result)                   the answer sorted, with its statistics
//   RunBatch(queries, threads, &results)  Run on many queries from many threads
//
//   auto db = mktree::Database::Open("ship.mkt", {.cache_pages = 4096});
//   if (!db.ok()) { ... db.status().ToString() ... }
//   mktree::QueryResult r;
//   mktree::Status st = (*db)->Run(mktree::Query::Box(box), &r);  // r.hits, r.stats
//   st = (*db)->Visit(mktree::Query::Box(box, mktree::QueryMode::kExact), [&](mktree::ObjectId id) { ... },
//                     /*stats=*/nullptr);
//
// Thread safety: a Database is safe to query from many threads at once (the page cache is shared and
// locked; each query has its own QueryStats). ClearCache must not run concurrently with queries if the
// caller wants per-query cold counts.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mktree/clash.h"
#include "mktree/geometry.h"
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
  // Capacity of the LRU page cache, in pages (0: every page lookup is a disk access).
  uint64_t cache_pages = 4096;
  // Verify each page's checksum when it is read from the store. A mismatch is an error, never an answer.
  bool verify_checksums = true;
  // Bypass the OS page cache (O_DIRECT, paged-file backend) for honest cold reads.
  bool direct_io = false;
};

// A query: the objects containing `point`, or meeting `box` (intervals closed), tested as `mode` says.
// REQUIRES (else InvalidArgument): finite coordinates; for a box, min <= max on every axis.
struct Query {
  enum class Kind { kPoint, kBox };
  Kind kind = Kind::kPoint;
  Vec3d point;  // kPoint
  Box3d box;    // kBox
  QueryMode mode = QueryMode::kAabb;

  static Query Point(const Vec3d& p, QueryMode mode = QueryMode::kAabb) {
    return {Kind::kPoint, p, {}, mode};
  }
  static Query Box(const Box3d& b, QueryMode mode = QueryMode::kAabb) { return {Kind::kBox, {}, b, mode}; }
};

struct QueryResult {
  std::vector<ObjectId> hits;  // sorted ids
  QueryStats stats;
};

// Receives the ids of a streamed answer (Database::Visit).
using ObjectVisitor = std::function<void(ObjectId)>;

class Database {
 public:
  virtual ~Database() = default;

  // Opens the store at `path` (HDF5 or paged file, detected from the file). Reads only the header and
  // the in-RAM structure; refuses truncated, foreign or corrupt files with an error naming the file.
  static Result<std::unique_ptr<Database>> Open(const std::string& path, const OpenOptions& options = {});

  // Runs `query`, calling `visit` once for each object of the answer: ids in the order their leaves are
  // read, not sorted, each once. `stats` (may be null) is reset and filled. `visit` runs on the calling
  // thread after its leaf's pages are released, so it may query this Database too. An exception thrown
  // by `visit` ends the query with an Internal error. On an error the ids visited so far are an incomplete
  // answer.
  virtual Status Visit(const Query& query, const ObjectVisitor& visit, QueryStats* stats) const = 0;

  // Runs `query`: `result->hits` is replaced by the sorted answer, `result->stats` by its statistics.
  Status Run(const Query& query, QueryResult* result) const;

  // Runs `queries` on `threads` threads (0: hardware concurrency); `(*results)[i]` answers `queries[i]`.
  // A failed query stops the batch: the error returned is the first failing query's in query order, with
  // its own code and message, the message prefixed by "query <i>: ". The results are then incomplete.
  Status RunBatch(const std::vector<Query>& queries, unsigned threads,
                  std::vector<QueryResult>* results) const;

  // Clash detection (mktree/clash.h, docs/clash.md). SelfClash: every pair of the store's objects that
  // clashes under `options`. Collide: every object that clashes with `mesh` (world coordinates) moved by
  // `transform` (none: as it is); its pairs have b = kCollideObject. Pairs go to `visit` on the calling
  // thread, in an order that does not depend on options.threads; `stats` (may be null) is reset and
  // filled. Pages are read through this Database's cache; the self-clash keeps decoded leaves in a window
  // of OpenOptions::cache_pages pages. On an error the pairs visited so far are an incomplete answer.
  virtual Status SelfClash(const ClashOptions& options, const ClashVisitor& visit,
                           ClashStats* stats) const = 0;
  virtual Status Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                         const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats) const = 0;

  // Empties the page cache (pages pinned by running queries stay until released).
  virtual void ClearCache() = 0;

  // The store's file, as given to Open.
  virtual const std::string& path() const = 0;
  virtual uint64_t object_count() const = 0;
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
