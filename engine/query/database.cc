// Database: routes a query through the in-RAM MKtree and SplitTrees to the leaves it must read, reads
// those leaves' pages through the LRU cache, and tests each object of those leaves.
#include "mktree/database.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>
#include <type_traits>
#include <utility>

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

class StoreDatabase final : public Database {
 public:
  StoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options)
      : reader_(std::move(reader)),
        options_(options),
        cache_(&reader_->pages(), options.cache_pages) {}

  Status QueryPoint(const Vec3d& world, QueryMode mode, std::vector<ObjectId>* hits,
                    QueryStats* stats) const override {
    if (!Finite(world)) return Status::InvalidArgument("point query with a non-finite coordinate");
    const Vec3d p = ToStoreFrame(world);
    return Guarded(name(), [&] {
      return Answer(
          [&](std::vector<uint32_t>* leaves, QueryStats* s) { reader_->tree().RoutePoint(p, leaves, s); },
          mode, [&](const ObjectEntryView& e) { return e.box.Contains(p); },
          [&](const SolidClassifier& solid) { return solid.Contains(p); }, hits, stats);
    });
  }

  Status QueryBox(const Box3d& world, QueryMode mode, std::vector<ObjectId>* hits,
                  QueryStats* stats) const override {
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(world.min[i]) || !std::isfinite(world.max[i]))
        return Status::InvalidArgument("box query with a non-finite coordinate");
      if (world.min[i] > world.max[i]) return Status::InvalidArgument("box query with min > max");
    }
    Box3d box;
    for (int i = 0; i < 3; ++i) {
      box.min[i] = world.min[i] - reader_->tree().origin[i];
      box.max[i] = world.max[i] - reader_->tree().origin[i];
    }
    return Guarded(name(), [&] {
      return Answer(
          [&](std::vector<uint32_t>* leaves, QueryStats* s) { reader_->tree().RouteBox(box, leaves, s); },
          mode, [&](const ObjectEntryView& e) { return e.box.Intersects(box); },
          [&](const SolidClassifier& solid) { return solid.MeetsBox(box); }, hits, stats);
    });
  }

  Status Run(const Query& q, QueryMode mode, QueryResult* out) const override {
    return q.kind == Query::Kind::kPoint ? QueryPoint(q.point, mode, &out->hits, &out->stats)
                                         : QueryBox(q.box, mode, &out->hits, &out->stats);
  }

  Status RunBatch(const std::vector<Query>& queries, QueryMode mode, unsigned threads,
                  std::vector<QueryResult>* results) const override {
    return Guarded(name(), [&] {
      results->assign(queries.size(), QueryResult{});
      if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
      threads = static_cast<unsigned>(std::min<size_t>(threads, std::max<size_t>(1, queries.size())));
      std::atomic<size_t> next{0};
      std::atomic<bool> failed{false};
      std::vector<Status> errors(threads);
      // Run never throws, but naming a failed query allocates: what a worker throws is caught there (it
      // would otherwise end the process) and reported after the join.
      std::vector<char> threw(threads, 0);
      auto work = [&](unsigned t) noexcept {
        try {
          for (size_t i; !failed && (i = next.fetch_add(1)) < queries.size();) {
            Status st = Run(queries[i], mode, &(*results)[i]);
            if (!st.ok()) {
              errors[t] = Prefixed(st, "query " + std::to_string(i) + ": ");
              failed = true;
            }
          }
        } catch (...) {
          threw[t] = 1;
          failed = true;
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
      for (unsigned t = 0; t < threads; ++t) {
        if (threw[t]) return Status::Internal(name() + ": out of memory naming a failed query");
        if (!errors[t].ok()) return errors[t];
      }
      return Status::Ok();
    });
  }

  void ClearCache() override { cache_.Clear(); }
  uint64_t object_count() const override { return reader_->object_count(); }
  Result<std::string> ObjectName(ObjectId id) const override {
    return Guarded(name(), [&] { return reader_->ObjectName(id); });
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
  const std::string& name() const { return reader_->path(); }

  // Pins the leaf's pages, verifies and parses them, and tests every object; `test` says whether an
  // object answers: a bool, or a Result<bool> where the test can fail (exact geometry).
  template <typename Test>
  Status ScanLeaf(uint32_t leaf, QueryStats* s, Test&& test, std::vector<ObjectId>* hits) const {
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
    const size_t before = hits->size();
    for (const ObjectEntryView& e : pinned.view.entries()) {
      ++s->candidates_tested;
      if constexpr (std::is_same_v<std::invoke_result_t<Test&, const ObjectEntryView&>, bool>) {
        if (test(e)) hits->push_back(e.id);
      } else {
        auto answer = test(e);
        if (!answer.ok()) return answer.status();
        if (*answer) hits->push_back(e.id);
      }
    }
    s->leaves_with_hits += hits->size() > before;
    return Status::Ok();
  }

  // One query: `route` lists the leaves to read; `meets_aabb` tests an entry's box (AABB mode, and the
  // first test of exact mode); `meets_solid` tests the object's solid (exact mode).
  template <typename Route, typename MeetsAabb, typename MeetsSolid>
  Status Answer(Route&& route, QueryMode mode, MeetsAabb&& meets_aabb, MeetsSolid&& meets_solid,
                std::vector<ObjectId>* hits, QueryStats* stats) const {
    QueryStats local;
    QueryStats& s = stats ? *stats : local;
    s.Reset();
    hits->clear();
    std::vector<uint32_t> leaves;
    route(&leaves, &s);
    auto exact = [&](const ObjectEntryView& e) -> Result<bool> {
      if (!meets_aabb(e)) return false;
      Mesh mesh;
      MKTREE_RETURN_IF_ERROR(DecodeObjectMesh(e, &mesh));
      return meets_solid(Classifier(e, mesh));
    };
    for (uint32_t leaf : leaves)
      MKTREE_RETURN_IF_ERROR(mode == QueryMode::kAabb ? ScanLeaf(leaf, &s, meets_aabb, hits)
                                                      : ScanLeaf(leaf, &s, exact, hits));
    return Finish(hits, &s);
  }

  static Status Finish(std::vector<ObjectId>* hits, QueryStats* s) {
    SortIds(hits);
    s->hits = hits->size();
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

Result<std::unique_ptr<Database>> Database::Open(const std::string& path, const OpenOptions& options) {
  return Guarded(path, [&]() -> Result<std::unique_ptr<Database>> {
    ReadOptions ro;
    ro.direct_io = options.direct_io;
    auto reader = StoreReader::Open(path, ro);
    if (!reader.ok()) return reader.status();
    return OpenStoreDatabase(std::move(*reader), options);
  });
}

}  // namespace mktree
