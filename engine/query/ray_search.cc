#include "engine/query/ray_search.h"

#include <cmath>
#include <limits>

#include "engine/core/guarded.h"
#include "engine/geometry/ray_cast.h"

namespace mktree {

namespace {

bool Finite(const Vec3d& p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); }

class RayMetric {
 public:
  RayMetric(const std::vector<SearchPart>& parts, const RayQuery& q) : q_(q) {
    for (const SearchPart& part : parts) {
      const Vec3d& o = part.tree().origin;
      rays_.emplace_back(Vec3d{q.origin.x - o.x, q.origin.y - o.y, q.origin.z - o.z}, q.direction);
    }
  }
  double Key(size_t part, const Box3d& b) const {
    double t;
    return RayBoxEnter(rays_[part], b, Bound(), &t) ? t : std::numeric_limits<double>::infinity();
  }
  double Rank(size_t part, const Box3d& b) const { return Key(part, b); }
  double KeyOfRank(double rank) const { return rank; }
  double Bound() const { return q_.all_hits ? q_.max_length : std::min(q_.max_length, first_); }
  void Found(double t) { first_ = std::min(first_, t); }
  Result<bool> Exact(size_t part, const Mesh& mesh, uint8_t, SearchFound* f) const {
    const RayHit3 h = FirstHit(mesh, rays_[part], Bound());
    if (!h.hit()) return false;
    f->key = h.t;
    f->point = h.point;
    f->normal = h.normal;
    return true;
  }

 private:
  const RayQuery& q_;
  std::vector<PreparedRay> rays_;
  double first_ = std::numeric_limits<double>::infinity();
};

}  // namespace

Status CheckRayQuery(const RayQuery& q) {
  if (!Finite(q.origin)) return Status::InvalidArgument("ray query: origin with a non-finite coordinate");
  if (!Finite(q.direction))
    return Status::InvalidArgument("ray query: direction with a non-finite coordinate");
  if (q.direction.x == 0 && q.direction.y == 0 && q.direction.z == 0)
    return Status::InvalidArgument("ray query: zero direction");
  const double len2 =
      q.direction.x * q.direction.x + q.direction.y * q.direction.y + q.direction.z * q.direction.z;
  if (!(len2 > 0) || !std::isfinite(len2))
    return Status::InvalidArgument("ray query: direction too short or too long to normalise");
  if (std::isnan(q.max_length) || q.max_length < 0)
    return Status::InvalidArgument("ray query: max length must be >= 0");
  return Status::Ok();
}

Result<bool> RunRaySearch(const std::vector<SearchPart>& parts, const RayQuery& q, const std::string& name,
                          const RayVisitor& visit, QueryStats* stats) {
  QueryStats local;
  QueryStats& s = stats ? *stats : local;
  s.Reset();
  MKTREE_RETURN_IF_ERROR(CheckRayQuery(q));
  return Guarded(name, [&]() -> Result<bool> {
    RayMetric metric(parts, q);
    BestFirstSearch<RayMetric> search(parts, &metric);
    SearchFound f;
    while (true) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, search.Next(&f, &s));
      if (!more) return true;
      const Vec3d& o = parts[f.part].tree().origin;
      RayHit hit;
      hit.id = f.id;
      hit.t = f.key;
      hit.point = {f.point.x + o.x, f.point.y + o.y, f.point.z + o.z};
      hit.normal = f.normal;
      if (!visit(hit)) return false;
      if (!q.all_hits) return true;
    }
  });
}

uint64_t RayPageFloor(const std::vector<SearchPart>& parts, const RayQuery& q, double t) {
  RayQuery all = q;
  all.all_hits = true;
  all.max_length = std::numeric_limits<double>::infinity();
  const RayMetric metric(parts, all);
  uint64_t pages = 0;
  for (size_t p = 0; p < parts.size(); ++p) {
    const MKTree& tree = parts[p].tree();
    for (uint32_t leaf = 0; leaf < tree.leaves.size(); ++leaf)
      if (LeafRegionKey(tree, leaf, metric, p) <= t) pages += tree.leaves[leaf].page_count;
  }
  return pages;
}

}  // namespace mktree
