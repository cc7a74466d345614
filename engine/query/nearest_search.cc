#include "engine/query/nearest_search.h"

#include <cmath>
#include <functional>
#include <optional>
#include <queue>
#include <utility>

#include "engine/core/guarded.h"
#include "engine/geometry/closest_point.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/store_format/object_codec.h"

namespace mktree {

namespace {

bool Finite(const Vec3d& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

// Lower bounds must stay lower bounds after the square root's rounding.
double Shrunk(double d2) { return std::sqrt(d2) * (1 - 1e-12); }

// The edge check ingest stored with an object, computed when the store is older.
EdgeCheck StoredEdges(uint8_t shape_flags, const Mesh& mesh) {
  if (!(shape_flags & kShapeKnown)) return CheckEdges(mesh);
  EdgeCheck e;
  e.even = (shape_flags & kShapeEvenEdges) != 0;
  e.closed = (shape_flags & kShapeClosed) != 0;
  return e;
}

Mesh BoxSolid(const Box3d& b) {
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.vertices.push_back((i & 1) ? b.max[0] : b.min[0]);
    m.vertices.push_back((i & 2) ? b.max[1] : b.min[1]);
    m.vertices.push_back((i & 4) ? b.max[2] : b.min[2]);
  }
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
  return m;
}

// The query in one part's store frame.
struct PartProbe {
  Vec3d point;
  Box3d box;  // the query box, or the query mesh's bounds
  Mesh mesh;  // box and mesh queries
  std::unique_ptr<ClashShape> shape;
};

class NearestMetric {
 public:
  NearestMetric(const std::vector<SearchPart>& parts, const DistanceQuery& q) : q_(q) {
    for (const SearchPart& part : parts) {
      const Vec3d& o = part.tree().origin;
      PartProbe probe;
      probe.point = {q.point.x - o.x, q.point.y - o.y, q.point.z - o.z};
      if (q.kind != DistanceQuery::Kind::kPoint) {
        probe.mesh = q.kind == DistanceQuery::Kind::kBox ? BoxSolid(q.box) : q.mesh;
        for (size_t v = 0; v < probe.mesh.vertices.size(); ++v) probe.mesh.vertices[v] -= o[v % 3];
        probe.box = probe.mesh.Bounds();
      }
      probes_.push_back(std::move(probe));
    }
    // Shapes point at their meshes: made once the probes no longer move.
    for (PartProbe& p : probes_)
      if (q.kind != DistanceQuery::Kind::kPoint) p.shape = std::make_unique<ClashShape>(p.mesh);
  }

  double Rank(size_t part, const Box3d& b) const {
    const PartProbe& p = probes_[part];
    return q_.kind == DistanceQuery::Kind::kPoint ? BoxPointDistanceSquared(b, p.point)
                                                  : BoxDistanceSquared(b, p.box);
  }
  double KeyOfRank(double rank) const { return Shrunk(rank); }
  double Key(size_t part, const Box3d& b) const { return KeyOfRank(Rank(part, b)); }
  double Bound() const {
    return kth_.size() == q_.k ? std::min(kth_.top(), q_.max_distance) : q_.max_distance;
  }
  void Found(double key) {
    if (q_.k == DistanceQuery::kAll) return;
    kth_.push(key);
    if (kth_.size() > q_.k) kth_.pop();
  }

  Result<bool> Exact(size_t part, const Mesh& mesh, uint8_t shape_flags, SearchFound* f) const {
    const PartProbe& p = probes_[part];
    const double bound = Bound();
    const EdgeCheck edges = StoredEdges(shape_flags, mesh);
    if (q_.kind == DistanceQuery::Kind::kPoint) {
      if (edges.closed && mesh.Bounds().Contains(p.point)) {
        SolidClassifierOptions o;
        o.edges = edges;
        if (SolidClassifier(mesh, o).Contains(p.point)) {
          f->key = 0;
          f->point = p.point;
          return true;
        }
      }
      const SurfacePoint sp = ClosestOnSurface(mesh, p.point, bound * bound * (1 + 1e-12));
      f->key = std::sqrt(sp.distance_squared);
      f->point = sp.point;
      return f->key <= bound;
    }
    const ClashShape object(mesh, edges);
    const double limit = std::isinf(bound) ? bound : std::nextafter(bound * (1 + 1e-12), INFINITY);
    const Separation s = Separate(object, *p.shape, limit, nullptr);
    f->key = s.meeting == Meeting::kApart ? s.distance : 0.0;
    f->point = s.point_a;
    return f->key <= bound;
  }

 private:
  const DistanceQuery& q_;
  std::vector<PartProbe> probes_;
  std::priority_queue<double> kth_;  // the k smallest exact distances found (k given)
};

class NearestSearch final : public NearestCursor {
 public:
  NearestSearch(std::vector<SearchPart> parts, const DistanceQuery& q, std::string name)
      : name_(std::move(name)),
        q_(q),
        metric_(parts, q_),
        search_(parts, &metric_),
        parts_(std::move(parts)) {}

  Result<bool> Next(NearestHit* hit) override {
    if (!failed_.ok()) return failed_;
    if (stats_.hits >= q_.k) return false;
    Result<bool> r = Guarded(name_, [&]() -> Result<bool> {
      SearchFound f;
      MKTREE_ASSIGN_OR_RETURN(const bool more, search_.Next(&f, &stats_));
      if (!more) return false;
      const Vec3d& o = parts_[f.part].tree().origin;
      hit->id = f.id;
      hit->distance = f.key;
      hit->point = {f.point.x + o.x, f.point.y + o.y, f.point.z + o.z};
      return true;
    });
    if (!r.ok()) failed_ = r.status();
    return r;
  }
  const QueryStats& stats() const override { return stats_; }

 private:
  std::string name_;
  DistanceQuery q_;  // the metric points at it
  NearestMetric metric_;
  BestFirstSearch<NearestMetric> search_;
  std::vector<SearchPart> parts_;
  QueryStats stats_;
  Status failed_ = Status::Ok();
};

}  // namespace

Result<const Mesh*> PinnedObjectMesh(const LeafSource& source, PinnedLeaf& pinned, size_t i, Mesh* scratch) {
  const DecodedLeaf& d = *pinned.decoded;
  if (const Mesh* m = d.mesh(i)) return m;
  MKTREE_RETURN_IF_ERROR(source.ParsePinned(&pinned));
  MKTREE_RETURN_IF_ERROR(source.DecodeMesh(pinned.view.entry(i), scratch));
  if (const Mesh* m = d.CacheMesh(i, std::move(*scratch))) return m;
  return scratch;  // over the leaf's mesh budget: CacheMesh left it as it was
}

Status CheckDistanceQuery(const DistanceQuery& q) {
  const std::string what = q.kind == DistanceQuery::Kind::kPoint ? "nearest query"
                           : q.kind == DistanceQuery::Kind::kBox ? "nearest query (box)"
                                                                 : "nearest query (mesh)";
  if (q.k == 0) return Status::InvalidArgument(what + ": k must be at least 1");
  if (std::isnan(q.max_distance) || q.max_distance < 0)
    return Status::InvalidArgument(what + ": max distance must be >= 0");
  switch (q.kind) {
    case DistanceQuery::Kind::kPoint:
      if (!Finite(q.point)) return Status::InvalidArgument(what + ": point with a non-finite coordinate");
      break;
    case DistanceQuery::Kind::kBox:
      for (int i = 0; i < 3; ++i) {
        if (!std::isfinite(q.box.min[i]) || !std::isfinite(q.box.max[i]))
          return Status::InvalidArgument(what + ": box with a non-finite coordinate");
        if (q.box.min[i] > q.box.max[i]) return Status::InvalidArgument(what + ": box with min > max");
      }
      break;
    case DistanceQuery::Kind::kMesh: {
      if (q.mesh.triangle_count() == 0) return Status::InvalidArgument(what + ": mesh without triangles");
      const Status st = ValidateClashMesh(q.mesh);
      if (!st.ok()) return Status::InvalidArgument(what + ": " + st.message());
      break;
    }
  }
  return Status::Ok();
}

Result<std::unique_ptr<NearestCursor>> OpenNearestSearch(std::vector<SearchPart> parts,
                                                         const DistanceQuery& q, const std::string& name) {
  MKTREE_RETURN_IF_ERROR(CheckDistanceQuery(q));
  return Guarded(name, [&]() -> Result<std::unique_ptr<NearestCursor>> {
    return std::unique_ptr<NearestCursor>(std::make_unique<NearestSearch>(std::move(parts), q, name));
  });
}

uint64_t NearestPageFloor(const std::vector<SearchPart>& parts, const DistanceQuery& q, double distance) {
  DistanceQuery unbounded = q;
  unbounded.k = DistanceQuery::kAll;
  unbounded.max_distance = std::numeric_limits<double>::infinity();
  const NearestMetric metric(parts, unbounded);
  uint64_t pages = 0;
  for (size_t p = 0; p < parts.size(); ++p) {
    const MKTree& t = parts[p].tree();
    for (uint32_t leaf = 0; leaf < t.leaves.size(); ++leaf)
      if (LeafRegionKey(t, leaf, metric, p) <= distance) pages += t.leaves[leaf].page_count;
  }
  return pages;
}

}  // namespace mktree
