// StoreDatabase: routes a query through the store's in-RAM MKtree and SplitTrees to the leaves it must
// read, reads those leaves through the store's LeafSource, and tests each object of those leaves.
#include "engine/query/store_database.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <span>
#include <thread>
#include <utility>
#include <vector>

#if defined(__SSE2__)
#include <immintrin.h>
#endif

#include "engine/clash/clash_engine.h"
#include "engine/core/guarded.h"
#include "engine/geometry/exact_geometry.h"
#include "engine/query/nearest_search.h"
#include "engine/query/ordered_batch.h"
#include "engine/query/ray_search.h"
#include "engine/query/sorted_ids.h"
#include "engine/store_format/leaf_reader.h"
#include "engine/store_format/object_codec.h"
#include "engine/store_format/record_codec.h"

namespace mktree {

namespace {

// The classifier for an entry's mesh, with the edge check ingest stored (computed here for old entries).
SolidClassifier Classifier(uint8_t shape_flags, const Mesh& mesh) {
  SolidClassifierOptions o;
  if (shape_flags & kShapeKnown) {
    EdgeCheck edges;
    edges.even = (shape_flags & kShapeEvenEdges) != 0;
    edges.closed = (shape_flags & kShapeClosed) != 0;
    o.edges = edges;
  }
  return SolidClassifier(mesh, o);
}

// The largest float <= x and the smallest float >= x, for any finite x (beyond float's range: +-FLT_MAX
// or +-inf).
float FloatBelow(double x) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (x > kMax) return std::numeric_limits<float>::max();
  if (x < -kMax) return -std::numeric_limits<float>::infinity();
  return RoundDownToFloat(x);
}
float FloatAbove(double x) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (x < -kMax) return std::numeric_limits<float>::lowest();
  if (x > kMax) return std::numeric_limits<float>::infinity();
  return RoundUpToFloat(x);
}

// A query box (store frame, double) as float bounds that give the same answers on float32 entry boxes:
// for a float f, f > x exactly when f > FloatBelow(x), and f < x when f < FloatAbove(x). An entry meets the
// box unless query max < entry min or query min > entry max on some axis (Box3f::Intersects, and
// Box3f::Contains for a point box), written as negations so that a NaN coordinate compares as it did.
struct FloatQuery {
  float lo[3], hi[3];  // FloatAbove(min), FloatBelow(max)
  explicit FloatQuery(const Box3d& b) {
    for (int i = 0; i < 3; ++i) {
      lo[i] = FloatAbove(b.min[i]);
      hi[i] = FloatBelow(b.max[i]);
    }
  }
  // Whether every box within `b` meets the query: b lies inside it (false for a NaN bound).
  bool Contains(const Box3f& b) const {
    for (int a = 0; a < 3; ++a)
      if (!(lo[a] <= b.min[a] && b.max[a] <= hi[a])) return false;
    return true;
  }
  bool Meets(const DecodedLeaf& d, size_t i) const {
    for (int a = 0; a < 3; ++a)
      if (hi[a] < d.plane(a)[i] || lo[a] > d.plane(3 + a)[i]) return false;
    return true;
  }
};

// Writes the ids of the leaf's objects whose boxes meet `q` to out[0..], in leaf order; returns how many.
// REQUIRES: room for d.padded_size() ids.
size_t ScanBoxes(const DecodedLeaf& d, const FloatQuery& q, ObjectId* out) {
  const size_t padded = d.padded_size();
  const ObjectId* ids = d.ids();
  size_t n = 0;
#if defined(__SSE2__)
  const __m128 lo0 = _mm_set1_ps(q.lo[0]), lo1 = _mm_set1_ps(q.lo[1]), lo2 = _mm_set1_ps(q.lo[2]);
  const __m128 hi0 = _mm_set1_ps(q.hi[0]), hi1 = _mm_set1_ps(q.hi[1]), hi2 = _mm_set1_ps(q.hi[2]);
  const float *mn0 = d.plane(0), *mn1 = d.plane(1), *mn2 = d.plane(2);
  const float *mx0 = d.plane(3), *mx1 = d.plane(4), *mx2 = d.plane(5);
  for (size_t i = 0; i < padded; i += 4) {
    // cmpnlt(a, b) = !(a < b), cmpngt(a, b) = !(a > b): the scalar test's negations, NaN included.
    __m128 m =
        _mm_and_ps(_mm_cmpnlt_ps(hi0, _mm_loadu_ps(mn0 + i)), _mm_cmpngt_ps(lo0, _mm_loadu_ps(mx0 + i)));
    m = _mm_and_ps(m, _mm_cmpnlt_ps(hi1, _mm_loadu_ps(mn1 + i)));
    m = _mm_and_ps(m, _mm_cmpngt_ps(lo1, _mm_loadu_ps(mx1 + i)));
    m = _mm_and_ps(m, _mm_cmpnlt_ps(hi2, _mm_loadu_ps(mn2 + i)));
    m = _mm_and_ps(m, _mm_cmpngt_ps(lo2, _mm_loadu_ps(mx2 + i)));
    for (unsigned bits = static_cast<unsigned>(_mm_movemask_ps(m)); bits != 0; bits &= bits - 1)
      out[n++] = ids[i + static_cast<unsigned>(__builtin_ctz(bits))];
  }
#else
  for (size_t i = 0; i < padded; ++i) {
    out[n] = ids[i < d.size() ? i : 0];
    n += q.Meets(d, i);
  }
#endif
  return n;
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

// One store's query path over its LeafSource: the routing, the leaf scans and the warm window.
class LeafQuery {
 public:
  explicit LeafQuery(const LeafSource& leaves) : leaves_(leaves), reader_(&leaves.reader()) {}

 private:
  // The store frame (MKTree::origin). Subtraction rounds monotonically, and object boxes were moved into the
  // frame by the same subtraction at ingest, so a point on a box's face stays on it.
  Vec3d ToStoreFrame(const Vec3d& p) const {
    const Vec3d& o = reader_->tree().origin;
    return {p.x - o.x, p.y - o.y, p.z - o.z};
  }

  // Appends to `found` the ids of the decoded leaf whose boxes meet `fq` (AABB mode, no cap). A leaf whose
  // box lies inside the query gives all its ids untested: CheckLeafEntries found each box within the
  // leaf's, so each meets the query unless it is empty or NaN (boxes_ordered).
  void ScanAabb(const DecodedLeaf& d, const LeafInfo& info, const FloatQuery& fq, QueryStats* s,
                std::vector<ObjectId>* found) const {
    const size_t n = d.size();
    s->candidates_tested += n;
    const size_t at = found->size();
    if (d.boxes_ordered() && fq.Contains(info.box)) {
      found->insert(found->end(), d.ids(), d.ids() + n);
      return;
    }
    found->resize(at + d.padded_size());
    found->resize(at + ScanBoxes(d, fq, found->data() + at));
  }

  // Reads the leaf (its DecodedLeaf: LeafSource::ReadDecoded) and appends to `found` the objects that
  // answer, up to `cap` of them (the rest of the leaf is not tested). AABB mode tests the boxes only; exact
  // mode tests the solid of each object whose box meets the query, with `meets_solid`.
  template <typename MeetsSolid>
  Status ScanLeaf(uint32_t leaf, QueryStats* s, const FloatQuery& fq, QueryMode mode,
                  MeetsSolid&& meets_solid, uint64_t cap, std::vector<ObjectId>* found) const {
    const MKTree& tree = reader_->tree();
    // One PinnedLeaf per thread, reused leaf after leaf so that a scan allocates nothing; it holds pins
    // only during the scan.
    thread_local PinnedLeaf pinned;
    struct Unpin {
      PinnedLeaf& leaf;
      ~Unpin() { leaf.Release(); }
    } unpin{pinned};
    MKTREE_RETURN_IF_ERROR(leaves_.ReadDecoded(leaf, s, &pinned));
    const DecodedLeaf& d = *pinned.decoded;
    const size_t n = d.size();
    if (mode == QueryMode::kAabb && found->size() + n <= cap) {  // no cap within this leaf
      ScanAabb(d, tree.leaves[leaf], fq, s, found);
      return Status::Ok();
    }
    for (size_t i = 0; i < n; ++i) {
      if (found->size() >= cap) break;
      ++s->candidates_tested;
      if (!fq.Meets(d, i)) continue;
      if (mode == QueryMode::kExact) {
        MKTREE_ASSIGN_OR_RETURN(const bool answers, MeetsExactly(d, i, pinned, meets_solid));
        if (!answers) continue;
      }
      found->push_back(d.ids()[i]);
    }
    return Status::Ok();
  }

  // The warm path of an AABB query without a limit whose ids go to a sink that never stops: from leaf
  // *next on, the leaves LeafSource::VisitCachedDecoded passes (all pages cached and verified, the
  // DecodedLeaf current: scanned under one lock of the cache without pinning them, the counts and the LRU
  // order those of reading them one at a time), the next leaves' arrays prefetched. Else one leaf whose
  // pages are all cached (ReadCachedDecoded: not decoded yet, or decoded from older copies). Appends their
  // answers to `found`, counts *leaves_with_hits and advances *next past the leaves read. Reads nothing
  // (and returns OK) when the first leaf is not cached.
  Status ScanCachedWindow(const std::vector<uint32_t>& leaves, size_t* next, const FloatQuery& fq,
                          QueryStats* s, std::vector<ObjectId>* found, uint64_t* leaves_with_hits) const {
    const MKTree& tree = reader_->tree();
    auto scan = [&](std::span<const DecodedLeaf* const> decoded) {
      const size_t n = decoded.size();
      // A leaf inside the query needs its ids only.
      auto prefetch = [&](size_t k) {
        decoded[k]->Prefetch(
            !(decoded[k]->boxes_ordered() && fq.Contains(tree.leaves[leaves[*next + k]].box)));
      };
      for (size_t k = 0; k < n && k < 2; ++k) prefetch(k);
      for (size_t k = 0; k < n; ++k) {
        if (k + 2 < n) prefetch(k + 2);
        const size_t before = found->size();
        ScanAabb(*decoded[k], tree.leaves[leaves[*next + k]], fq, s, found);
        *leaves_with_hits += found->size() > before;
      }
      *next += n;
    };
    if (leaves_.VisitCachedDecoded(std::span<const uint32_t>(leaves).subspan(*next), s, scan) > 0)
      return Status::Ok();
    thread_local PinnedLeaf one;
    struct Release {
      ~Release() { one.Release(); }
    } release;
    Result<bool> cached = leaves_.ReadCachedDecoded(leaves[*next], s, &one);
    if (!cached.ok()) {
      ++*next;  // read, and refused
      return cached.status();
    }
    if (!*cached) return Status::Ok();
    scan(std::span<const DecodedLeaf* const>(&one.decoded, 1));
    return Status::Ok();
  }

  // Object i of the pinned leaf tested against its solid: its mesh from the DecodedLeaf, else decoded
  // from the entry (and cached there, within its budget).
  template <typename MeetsSolid>
  Result<bool> MeetsExactly(const DecodedLeaf& d, size_t i, PinnedLeaf& pinned,
                            MeetsSolid&& meets_solid) const {
    const Mesh* mesh = d.mesh(i);
    Mesh local;
    if (!mesh) {
      MKTREE_RETURN_IF_ERROR(leaves_.ParsePinned(&pinned));
      MKTREE_RETURN_IF_ERROR(leaves_.DecodeMesh(pinned.view.entry(i), &local));
      mesh = d.CacheMesh(i, std::move(local));
      if (!mesh) mesh = &local;  // over the leaf's budget: CacheMesh left `local` as it was
    }
    return meets_solid(Classifier(d.shape_flags(i), *mesh));
  }

 public:
  // One query; the ids go to `sink` (sink(ids, n, s) counts them in s->hits and returns
  // false to stop). Returns whether the whole answer was visited. kCanStop: whether the sink may stop;
  // one that never does lets AABB queries without a limit read cached leaves a window at a time.
  template <bool kCanStop, typename Sink>
  Result<bool> Run(const Query& q, Sink&& sink, QueryStats* stats) const {
    QueryStats local;
    QueryStats& s = stats ? *stats : local;
    s.Reset();
    MKTREE_RETURN_IF_ERROR(CheckQuery(q));
    const MKTree& tree = reader_->tree();
    return Guarded(reader_->path(), [&]() -> Result<bool> {
      if (q.kind == Query::Kind::kPoint) {
        const Vec3d p = ToStoreFrame(q.point);
        Box3d at;
        at.min = at.max = {p.x, p.y, p.z};
        return Answer<kCanStop>([&](std::vector<uint32_t>* leaves) { tree.RoutePoint(p, leaves, &s); }, q, at,
                                [&](const SolidClassifier& solid) { return solid.Contains(p); }, sink, &s);
      }
      Box3d box;
      for (int i = 0; i < 3; ++i) {
        box.min[i] = q.box.min[i] - tree.origin[i];
        box.max[i] = q.box.max[i] - tree.origin[i];
      }
      return Answer<kCanStop>([&](std::vector<uint32_t>* leaves) { tree.RouteBox(box, leaves, &s); }, q, box,
                              [&](const SolidClassifier& solid) { return solid.MeetsBox(box); }, sink, &s);
    });
  }

 private:
  // One query: `route` lists the leaves to read; `box` (the query in the store frame, a point's box for a
  // point) tests an entry's box (AABB mode, and the first test of exact mode); `meets_solid` tests the
  // object's solid (exact mode). Each leaf's answers go to `sink` once the leaf is released. Under a limit,
  // leaves are scanned for one id more than the limit leaves room for, which tells whether the answer goes on
  // without reading further.
  template <bool kCanStop, typename Route, typename MeetsSolid, typename Sink>
  Result<bool> Answer(Route&& route, const Query& q, const Box3d& box, MeetsSolid&& meets_solid, Sink&& sink,
                      QueryStats* s) const {
    thread_local std::vector<uint32_t> t_leaves;
    std::vector<uint32_t> leaves = std::exchange(t_leaves, {});
    std::vector<ObjectId> found = std::exchange(t_spare_ids, {});
    struct Restore {  // the buffers go back on every path, errors included
      std::vector<uint32_t>& leaves;
      std::vector<ObjectId>& found;
      ~Restore() {
        t_leaves = std::move(leaves);
        t_spare_ids = std::move(found);
      }
    } restore{leaves, found};
    leaves.clear();
    route(&leaves);
    if (leaves.empty()) return true;  // most points, in a scene of free space
    const FloatQuery fq(box);
    // The routing counted every leaf it let through as visited; a query that stops early reads fewer.
    struct Unvisited {
      QueryStats* s;
      size_t unread;
      ~Unvisited() { s->leaves_visited -= std::min<uint64_t>(s->leaves_visited, unread); }
    } unvisited{s, leaves.size()};
    if (!kCanStop && q.mode == QueryMode::kAabb && q.limit == Query::kNoLimit) {
      size_t next = 0;
      while (next < leaves.size()) {
        found.clear();
        const size_t from = next;
        Status st = ScanCachedWindow(leaves, &next, fq, s, &found, &s->leaves_with_hits);
        unvisited.unread -= next - from;
        if (next == from) {  // not cached: read as always
          --unvisited.unread;
          MKTREE_RETURN_IF_ERROR(
              ScanLeaf(leaves[next++], s, fq, q.mode, meets_solid, Query::kNoLimit, &found));
          s->leaves_with_hits += !found.empty();
        }
        if (!found.empty()) sink(found.data(), found.size(), s);
        MKTREE_RETURN_IF_ERROR(st);
      }
      return true;
    }
    uint64_t room = q.limit;  // ids the limit still allows
    for (uint32_t leaf : leaves) {
      --unvisited.unread;
      found.clear();
      const uint64_t cap = room == Query::kNoLimit ? room : room + 1;
      MKTREE_RETURN_IF_ERROR(ScanLeaf(leaf, s, fq, q.mode, meets_solid, cap, &found));
      const size_t take = static_cast<size_t>(std::min<uint64_t>(found.size(), room));
      s->leaves_with_hits += take > 0;
      if (take > 0 && !sink(found.data(), take, s)) return false;
      if (found.size() > take) return false;  // an id past the limit: the answer goes on
      if (room != Query::kNoLimit) room -= take;
    }
    return true;
  }

  const LeafSource leaves_;  // a copy: a cold batch's query reads through a source of its own cache
  const StoreReader* reader_;
};

}  // namespace

StoreDatabase::StoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options)
    : reader_(std::move(reader)),
      options_(options),
      cache_(&reader_->pages(), options.cache_pages),
      leaves_(*reader_, cache_, options.verify_checksums) {}

Result<bool> StoreDatabase::VisitUntil(const Query& q, const StoppableVisitor& visit,
                                       QueryStats* stats) const {
  return LeafQuery(leaves_).Run</*kCanStop=*/true>(
      q,
      [&visit](const ObjectId* ids, size_t n, QueryStats* s) {
        for (size_t k = 0; k < n; ++k) {
          ++s->hits;
          if (!visit(ids[k])) return false;
        }
        return true;
      },
      stats);
}

Status StoreDatabase::VisitSpans(const Query& q, const SpanVisitor& visit, QueryStats* stats) const {
  return LeafQuery(leaves_)
      .Run</*kCanStop=*/false>(
          q,
          [&visit](const ObjectId* ids, size_t n, QueryStats* s) {
            s->hits += n;
            visit(std::span<const ObjectId>(ids, n));
            return true;
          },
          stats)
      .status();
}

Result<std::unique_ptr<NearestCursor>> StoreDatabase::OpenNearest(const DistanceQuery& query) const {
  return OpenNearestSearch({SearchPart{this}}, query, path());
}

Result<bool> StoreDatabase::VisitRay(const RayQuery& query, const RayVisitor& visit,
                                     QueryStats* stats) const {
  return RunRaySearch({SearchPart{this}}, query, path(), visit, stats);
}

Status StoreDatabase::SelfClash(const ClashOptions& options, const ClashVisitor& visit,
                                ClashStats* stats) const {
  return Guarded(path(), [&] { return RunSelfClash(leaves_, options, visit, stats); });
}

Status StoreDatabase::Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                              const ClashOptions& options, const ClashVisitor& visit,
                              ClashStats* stats) const {
  return Guarded(path(), [&] { return RunCollide(leaves_, mesh, transform, options, visit, stats); });
}

Result<std::string> StoreDatabase::ObjectName(ObjectId id) const {
  return Guarded(path(), [&]() -> Result<std::string> {
    MKTREE_ASSIGN_OR_RETURN(StoredRecord r,
                            reader_->ReadRecord(id, &cache_, options_.verify_checksums, nullptr));
    return std::move(r.name);
  });
}

Result<ObjectRecord> StoreDatabase::Object(ObjectId id, QueryStats* stats) const {
  return Guarded(path(), [&]() -> Result<ObjectRecord> {
    QueryStats local;
    QueryStats& s = stats ? *stats : local;
    s = QueryStats();
    MKTREE_ASSIGN_OR_RETURN(StoredRecord r, reader_->ReadRecord(id, &cache_, options_.verify_checksums, &s));
    ObjectRecord out;
    out.id = id;
    MKTREE_ASSIGN_OR_RETURN(out.source, reader_->SourceName(r));
    out.name = std::move(r.name);
    out.attributes = std::move(r.attributes);
    if (!r.box.empty()) {
      const Vec3d& o = reader_->tree().origin;
      for (int i = 0; i < 3; ++i) {
        out.box.min[i] = o[i] + r.box.min[i];
        out.box.max[i] = o[i] + r.box.max[i];
      }
    }
    return out;
  });
}

Result<Mesh> StoreDatabase::ObjectGeometry(ObjectId id, QueryStats* stats) const {
  return Guarded(path(), [&]() -> Result<Mesh> {
    QueryStats local;
    QueryStats& s = stats ? *stats : local;
    s = QueryStats();
    // The leaf is in the object's record: one counted record page, then the leaf's pages.
    MKTREE_ASSIGN_OR_RETURN(const uint32_t leaf,
                            reader_->ObjectLeaf(id, &cache_, options_.verify_checksums, &s));
    MKTREE_ASSIGN_OR_RETURN(PinnedLeaf pinned, leaves_.Read(leaf, &s));
    for (const ObjectEntryView& e : pinned.view.entries()) {
      if (e.id != id) continue;
      Mesh mesh;
      MKTREE_RETURN_IF_ERROR(leaves_.DecodeMesh(e, &mesh));
      const Vec3d& o = reader_->tree().origin;
      for (size_t v = 0; v < mesh.vertices.size(); ++v) mesh.vertices[v] += o[v % 3];
      return mesh;
    }
    // The leaf's entries passed CheckLeafEntries: the record names the wrong leaf.
    return Status::Corruption(path() + ": object " + std::to_string(id) + ": its record puts it in leaf " +
                              std::to_string(leaf) + ", which does not hold it");
  });
}

double StoreDatabase::objects_per_page() const {
  const MKTree& t = reader_->tree();
  uint64_t pages = 0;
  for (const LeafInfo& l : t.leaves) pages += l.page_count;
  return pages ? static_cast<double>(reader_->object_count()) / static_cast<double>(pages) : 0.0;
}

Status StoreDatabase::RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                                       const ResultVisitor& deliver) const {
  return Guarded(path(), [&]() -> Status {
    const unsigned threads =
        options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    const uint64_t window = options.window ? options.window : 4 * uint64_t{threads};
    // One query into `r`; cold queries through `own`, a private cache emptied first.
    auto run = [&](const Query& q, PageCache* own, QueryResult* r) -> Status {
      if (own) own->Clear();
      const LeafQuery query(own ? LeafSource(*reader_, *own, options_.verify_checksums) : leaves_);
      r->hits.clear();
      auto collect = [r](const ObjectId* ids, size_t n, QueryStats* s) {
        s->hits += n;
        r->hits.insert(r->hits.end(), ids, ids + n);
        return true;
      };
      auto count = [](const ObjectId*, size_t n, QueryStats* s) {
        s->hits += n;
        return true;
      };
      Result<bool> complete =
          options.ids ? query.Run<false>(q, collect, &r->stats) : query.Run<false>(q, count, &r->stats);
      if (!complete.ok()) return complete.status();
      r->truncated = !*complete;
      SortIds(&r->hits);
      return CheckNoRepeatedIds(r->hits, path());
    };
    auto own_cache = [&] {
      return options.cold ? std::make_unique<PageCache>(&reader_->pages(), options_.cache_pages) : nullptr;
    };
    return RunOrderedBatch<PageCache>(source, threads, window, path(), own_cache, run, deliver);
  });
}

std::unique_ptr<StoreDatabase> OpenStoreDatabase(std::unique_ptr<StoreReader> reader,
                                                 const OpenOptions& options) {
  return std::make_unique<StoreDatabase>(std::move(reader), options);
}

}  // namespace mktree
