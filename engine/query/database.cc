// Database: routes a query through the in-RAM MKtree and SplitTrees to the leaves it must read, reads
// those leaves' pages through the LRU cache, and tests each object of those leaves.
#include "mktree/database.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>
#include <type_traits>
#include <utility>

#include "engine/clash/clash_engine.h"
#include "engine/core/guarded.h"
#include "engine/geometry/exact_geometry.h"
#include "engine/query/store_database.h"
#include "engine/store/leaf_reader.h"
#include "engine/store/object_codec.h"
#include "engine/store/store_file.h"
#include "storage/page_cache.h"

namespace mktree {

namespace {

// The classifier for an entry's mesh, with the edge check ingest stored (computed here for old entries).
SolidClassifier Classifier(const ObjectEntryView& e, const Mesh& mesh) {
  SolidClassifierOptions o;
  if (e.shape_flags & kShapeKnown) {
    EdgeCheck edges;
    edges.even = (e.shape_flags & kShapeEvenEdges) != 0;
    edges.closed = (e.shape_flags & kShapeClosed) != 0;
    o.edges = edges;
  }
  return SolidClassifier(mesh, o);
}

// Sorts ids ascending. Large answers (an 8 m box in the tanker has ~1800) by radix, three passes of 11
// bits, which costs a fraction of std::sort's ~11 comparisons per id.
void SortIds(std::vector<ObjectId>* ids) {
  constexpr size_t kRadixFrom = 512;
  if (ids->size() < kRadixFrom) {
    std::sort(ids->begin(), ids->end());
    return;
  }
  thread_local std::vector<ObjectId> other;
  other.resize(ids->size());
  uint32_t counts[3][2048] = {};
  for (ObjectId id : *ids) {
    ++counts[0][id & 2047];
    ++counts[1][(id >> 11) & 2047];
    ++counts[2][id >> 22];
  }
  std::vector<ObjectId>* from = ids;
  std::vector<ObjectId>* to = &other;
  for (int pass = 0; pass < 3; ++pass) {
    uint32_t at = 0;
    for (uint32_t& c : counts[pass]) at += std::exchange(c, at);
    const int shift = 11 * pass;
    for (ObjectId id : *from) (*to)[counts[pass][(id >> shift) & 2047]++] = id;
    std::swap(from, to);
  }
  ids->swap(other);  // three passes: the sorted ids are in `other`
}

// `st` with `prefix` before its message, its code kept.
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

bool Finite(const Vec3d& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

Status CheckQuery(const Query& q) {
  if (q.kind == Query::Kind::kPoint) {
    if (!Finite(q.point)) return Status::InvalidArgument("point query with a non-finite coordinate");
    return Status::Ok();
  }
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(q.box.min[i]) || !std::isfinite(q.box.max[i]))
      return Status::InvalidArgument("box query with a non-finite coordinate");
    if (q.box.min[i] > q.box.max[i]) return Status::InvalidArgument("box query with min > max");
  }
  return Status::Ok();
}

// The ids one leaf answers, gathered before `visit` sees them. Each thread keeps one buffer and a query
// takes it for its duration, so that a query allocates nothing in the steady state and a query run from
// inside `visit` (which finds none to take) gets a buffer of its own.
thread_local std::vector<ObjectId> t_spare_ids;

class StoreDatabase final : public Database {
 public:
  StoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options)
      : reader_(std::move(reader)), options_(options), cache_(&reader_->pages(), options.cache_pages) {}

  Status Visit(const Query& q, const ObjectVisitor& visit, QueryStats* stats) const override {
    QueryStats local;
    QueryStats& s = stats ? *stats : local;
    s.Reset();
    MKTREE_RETURN_IF_ERROR(CheckQuery(q));
    const MKTree& tree = reader_->tree();
    return Guarded(path(), [&] {
      if (q.kind == Query::Kind::kPoint) {
        const Vec3d p = ToStoreFrame(q.point);
        return Answer([&](std::vector<uint32_t>* leaves) { tree.RoutePoint(p, leaves, &s); }, q.mode,
                      [&](const ObjectEntryView& e) { return e.box.Contains(p); },
                      [&](const SolidClassifier& solid) { return solid.Contains(p); }, visit, &s);
      }
      Box3d box;
      for (int i = 0; i < 3; ++i) {
        box.min[i] = q.box.min[i] - tree.origin[i];
        box.max[i] = q.box.max[i] - tree.origin[i];
      }
      return Answer([&](std::vector<uint32_t>* leaves) { tree.RouteBox(box, leaves, &s); }, q.mode,
                    [&](const ObjectEntryView& e) { return e.box.Intersects(box); },
                    [&](const SolidClassifier& solid) { return solid.MeetsBox(box); }, visit, &s);
    });
  }

  Status SelfClash(const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats) const override {
    return Guarded(path(), [&] { return RunSelfClash(ClashStoreView(), options, visit, stats); });
  }
  Status Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                 const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats) const override {
    return Guarded(path(),
                   [&] { return RunCollide(ClashStoreView(), mesh, transform, options, visit, stats); });
  }

  void ClearCache() override { cache_.Clear(); }
  const std::string& path() const override { return reader_->path(); }
  uint64_t object_count() const override { return reader_->object_count(); }
  Result<std::string> ObjectName(ObjectId id) const override {
    return Guarded(path(), [&] { return reader_->ObjectName(id); });
  }
  Box3d bounds() const override {
    const MKTree& t = reader_->tree();
    Box3d b;
    if (t.empty()) return b;
    for (int i = 0; i < 3; ++i) {
      b.min[i] = t.origin[i] + t.nodes[0].box.min[i];
      b.max[i] = t.origin[i] + t.nodes[0].box.max[i];
    }
    return b;
  }
  double objects_per_page() const override {
    const MKTree& t = reader_->tree();
    uint64_t pages = 0;
    for (const LeafInfo& l : t.leaves) pages += l.page_count;
    return pages ? static_cast<double>(reader_->object_count()) / static_cast<double>(pages) : 0.0;
  }
  const std::string& stats_json() const override { return reader_->stats_json(); }

 private:
  // The store frame (MKTree::origin). Subtraction rounds monotonically, and object boxes were moved into the
  // frame by the same subtraction at ingest, so a point on a box's face stays on it.
  Vec3d ToStoreFrame(const Vec3d& p) const {
    const Vec3d& o = reader_->tree().origin;
    return {p.x - o.x, p.y - o.y, p.z - o.z};
  }

  ClashStore ClashStoreView() const {
    return ClashStore{*reader_, cache_, options_.verify_checksums, options_.cache_pages};
  }

  // Pins the leaf's pages, verifies and parses them, and appends to `found` the objects that answer;
  // `test` says whether an object answers: a bool, or a Result<bool> where the test can fail (exact
  // geometry).
  template <typename Test>
  Status ScanLeaf(uint32_t leaf, QueryStats* s, Test&& test, std::vector<ObjectId>* found) const {
    const MKTree& tree = reader_->tree();
    // One PinnedLeaf per thread, reused leaf after leaf so that a scan allocates nothing; it holds pins
    // only during the scan.
    thread_local PinnedLeaf pinned;
    struct Unpin {
      PinnedLeaf& leaf;
      ~Unpin() { leaf.Release(); }
    } unpin{pinned};
    MKTREE_RETURN_IF_ERROR(ReadLeaf(cache_, reader_->pages().name(), leaf, tree.leaves[leaf],
                                    reader_->objects().leaf, tree.params.mem_page(),
                                    options_.verify_checksums, s, &pinned));
    for (const ObjectEntryView& e : pinned.view.entries()) {
      ++s->candidates_tested;
      if constexpr (std::is_same_v<std::invoke_result_t<Test&, const ObjectEntryView&>, bool>) {
        if (test(e)) found->push_back(e.id);
      } else {
        MKTREE_ASSIGN_OR_RETURN(const bool answers, test(e));
        if (answers) found->push_back(e.id);
      }
    }
    return Status::Ok();
  }

  // One query: `route` lists the leaves to read; `meets_aabb` tests an entry's box (AABB mode, and the
  // first test of exact mode); `meets_solid` tests the object's solid (exact mode). Each leaf's answers
  // go to `visit` once the leaf is released.
  template <typename Route, typename MeetsAabb, typename MeetsSolid>
  Status Answer(Route&& route, QueryMode mode, MeetsAabb&& meets_aabb, MeetsSolid&& meets_solid,
                const ObjectVisitor& visit, QueryStats* s) const {
    std::vector<uint32_t> leaves;
    route(&leaves);
    auto exact = [&](const ObjectEntryView& e) -> Result<bool> {
      if (!meets_aabb(e)) return false;
      Mesh mesh;
      MKTREE_RETURN_IF_ERROR(DecodeStoredMesh(path(), e, &mesh));
      return meets_solid(Classifier(e, mesh));
    };
    std::vector<ObjectId> found = std::exchange(t_spare_ids, {});
    for (uint32_t leaf : leaves) {
      found.clear();
      MKTREE_RETURN_IF_ERROR(mode == QueryMode::kAabb ? ScanLeaf(leaf, s, meets_aabb, &found)
                                                      : ScanLeaf(leaf, s, exact, &found));
      s->hits += found.size();
      s->leaves_with_hits += !found.empty();
      for (ObjectId id : found) visit(id);
    }
    t_spare_ids = std::move(found);
    return Status::Ok();
  }

  std::unique_ptr<StoreReader> reader_;
  OpenOptions options_;
  mutable PageCache cache_;
};

}  // namespace

std::unique_ptr<Database> OpenStoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options) {
  return std::make_unique<StoreDatabase>(std::move(reader), options);
}

Status Database::Run(const Query& query, QueryResult* result) const {
  std::vector<ObjectId>& hits = result->hits;
  hits.clear();
  auto collect = [&hits](ObjectId id) { hits.push_back(id); };
  MKTREE_RETURN_IF_ERROR(Visit(query, collect, &result->stats));
  return Guarded(path(), [&] {
    SortIds(&hits);
    return Status::Ok();
  });
}

Status Database::RunBatch(const std::vector<Query>& queries, unsigned threads,
                          std::vector<QueryResult>* results) const {
  return Guarded(path(), [&]() -> Status {
    results->assign(queries.size(), QueryResult{});
    if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
    threads = static_cast<unsigned>(std::min<size_t>(threads, std::max<size_t>(1, queries.size())));
    // Each worker keeps its first failure. Workers claim queries in order and stop claiming once one has
    // failed, so every query before a failed one has run: the failure of the lowest index is the batch's
    // first failing query, whatever the threads' timing.
    struct Failure {
      size_t query = SIZE_MAX;
      Status status;
    };
    std::vector<Failure> failures(threads);
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    auto work = [&](unsigned t) noexcept {  // Run returns every error as a Status, it never throws
      for (size_t i; !failed && (i = next.fetch_add(1)) < queries.size();) {
        Status st = Run(queries[i], &(*results)[i]);
        if (!st.ok()) {
          failures[t] = {i, std::move(st)};
          failed = true;
          return;
        }
      }
    };
    std::vector<std::thread> pool;
    try {
      pool.reserve(threads - 1);
      for (unsigned t = 1; t < threads; ++t) pool.emplace_back(work, t);
    } catch (...) {
      // A thread that cannot start (or its slot) leaves its share to the others.
    }
    work(0);
    for (auto& th : pool) th.join();
    Failure* first = nullptr;
    for (Failure& f : failures)
      if (f.query != SIZE_MAX && (!first || f.query < first->query)) first = &f;
    if (!first) return Status::Ok();
    try {
      return Prefixed(first->status, "query " + std::to_string(first->query) + ": ");
    } catch (...) {
      return std::move(first->status);  // no memory to name the query: its own Status as it is
    }
  });
}

Result<std::unique_ptr<Database>> Database::Open(const std::string& path, const OpenOptions& options) {
  return Guarded(path, [&]() -> Result<std::unique_ptr<Database>> {
    ReadOptions ro;
    ro.direct_io = options.direct_io;
    MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(path, ro));
    return OpenStoreDatabase(std::move(reader), options);
  });
}

}  // namespace mktree
