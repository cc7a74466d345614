// mktree's public query API: open a store, classify points, query boxes, and read what each query cost.
//
//   auto db = mktree::Database::Open("ship.mkt", {.cache_pages = 4096});
//   if (!db.ok()) { ... db.status().ToString() ... }
//   std::vector<mktree::ObjectId> hits;
//   mktree::QueryStats stats;
//   mktree::Status st = (*db)->QueryBox(box, mktree::QueryMode::kAabb, &hits, &stats);
//
// Thread safety: a Database is safe to query from many threads at once (the page cache is shared and
// locked; each query has its own QueryStats). ClearCache must not run concurrently with queries if the
// caller wants per-query cold counts.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

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

struct Query {
  enum class Kind { kPoint, kBox };
  Kind kind = Kind::kPoint;
  Vec3d point;
  Box3d box;
  static Query Point(const Vec3d& p) { return Query{Kind::kPoint, p, {}}; }
  static Query Box(const Box3d& b) { return Query{Kind::kBox, {}, b}; }
};

struct QueryResult {
  std::vector<ObjectId> hits;  // sorted ids
  QueryStats stats;
};

class Database {
 public:
  virtual ~Database() = default;

  // Opens the store at `path` (HDF5 or paged file, detected from the file). Reads only the header and
  // the in-RAM structure; refuses truncated, foreign or corrupt files with an error naming the file.
  static Result<std::unique_ptr<Database>> Open(const std::string& path, const OpenOptions& options = {});

  // Objects containing `p` (closed). REQUIRES: finite coordinates (else InvalidArgument).
  // `hits` is replaced by the sorted answer; `stats` (may be null) is reset and filled.
  virtual Status QueryPoint(const Vec3d& p, QueryMode mode, std::vector<ObjectId>* hits,
                            QueryStats* stats) const = 0;
  // Objects meeting `box` (closed). REQUIRES: finite coordinates and min <= max on every axis.
  virtual Status QueryBox(const Box3d& box, QueryMode mode, std::vector<ObjectId>* hits,
                          QueryStats* stats) const = 0;
  virtual Status Run(const Query& q, QueryMode mode, QueryResult* out) const = 0;
  // Runs `queries` on `threads` threads (0: hardware concurrency); results in query order. The first
  // error stops the batch and is returned.
  virtual Status RunBatch(const std::vector<Query>& queries, QueryMode mode, unsigned threads,
                          std::vector<QueryResult>* results) const = 0;

  // Empties the page cache (pages pinned by running queries stay until released).
  virtual void ClearCache() = 0;

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
