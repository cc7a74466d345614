// The Database over a sharded store (docs/shards.md): the manifest's top levels route each query to the
// shards whose stores' root boxes it meets; each shard is a StoreDatabase, whose local ids the shard's id
// file maps to global ones, and whose LeafSource a clash over all shards reads.
#include "engine/query/sharded_database.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <limits>
#include <mutex>
#include <queue>
#include <thread>

#include "engine/clash/clash_engine.h"
#include "engine/clash/pair_rules.h"
#include "engine/core/guarded.h"
#include "engine/query/nearest_search.h"
#include "engine/query/ordered_batch.h"
#include "engine/query/part_queries.h"
#include "engine/query/ray_search.h"
#include "engine/query/shard_open.h"
#include "engine/query/store_database.h"
#include "engine/shard/manifest.h"
#include "engine/store_format/store_file.h"

namespace mktree {

namespace {

class ShardedDatabase final : public Database {
 public:
  ShardedDatabase(std::string path, Manifest m, std::vector<std::unique_ptr<StoreDatabase>> shards,
                  std::vector<std::vector<ObjectId>> ids)
      : path_(std::move(path)), m_(std::move(m)), shards_(std::move(shards)), ids_(std::move(ids)) {
    // Each top node's box: the union of its shards' root boxes (children follow their parent in preorder).
    box_.resize(m_.top.nodes.size());
    for (size_t n = m_.top.nodes.size(); n-- > 0;) {
      const TopNode& t = m_.top.nodes[n];
      if (t.is_leaf()) {
        box_[n] = m_.shards[t.shard].box;
      } else {
        box_[n] = box_[t.child[0]];
        box_[n].Extend(box_[t.child[1]]);
      }
    }
    stats_json_ = "{\"shards\": [";
    double pages = 0;
    for (size_t s = 0; s < shards_.size(); ++s) {
      stats_json_ += (s ? ", " : "") + shards_[s]->stats_json();
      const double opp = shards_[s]->objects_per_page();
      if (opp > 0) pages += static_cast<double>(shards_[s]->object_count()) / opp;
      bounds_ = UnionBox(bounds_, shards_[s]->bounds());
    }
    stats_json_ += "]}";
    objects_per_page_ = pages > 0 ? static_cast<double>(m_.objects) / pages : 0;
  }

  uint32_t shard_count() const override { return static_cast<uint32_t>(shards_.size()); }

  Result<bool> VisitUntil(const Query& q, const StoppableVisitor& visit, QueryStats* stats) const override {
    return VisitUntilPerShard(q, visit, stats, nullptr);
  }

  Result<bool> VisitUntilPerShard(const Query& q, const StoppableVisitor& visit, QueryStats* stats,
                                  std::vector<ShardQueryStats>* per_shard) const override {
    QueryStats total;
    if (per_shard) per_shard->clear();
    if (!FiniteQuery(q))
      return Status::InvalidArgument(q.kind == Query::Kind::kPoint
                                         ? "point query with a non-finite coordinate"
                                         : "box query with a non-finite coordinate "
                                           "or min > max");
    uint64_t remaining = q.limit;
    bool complete = true;
    for (uint32_t s : Route(q, &total)) {
      Query sq = q;
      sq.limit = remaining;
      uint64_t visited = 0;
      QueryStats st;
      const std::vector<ObjectId>& ids = ids_[s];
      MKTREE_ASSIGN_OR_RETURN(const bool whole, shards_[s]->VisitUntil(
                                                    sq,
                                                    [&](ObjectId local) {
                                                      ++visited;
                                                      return visit(ids[local]);
                                                    },
                                                    &st));
      total += st;
      if (per_shard) per_shard->push_back({s, st});
      if (!whole) {
        complete = false;
        break;
      }
      if (remaining != Query::kNoLimit) remaining -= visited;
    }
    if (stats) *stats = total;
    return complete;
  }

  Status RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                          const ResultVisitor& deliver) const override;

  // One best-first search over every shard's tree: the nearest shard is searched first, and a shard's
  // leaves are read only when nearer than the answers still to come.
  Result<std::unique_ptr<NearestCursor>> OpenNearest(const DistanceQuery& q) const override {
    return OpenNearestSearch(SearchParts(), q, path_);
  }
  Result<bool> VisitRay(const RayQuery& q, const RayVisitor& visit, QueryStats* stats) const override {
    return RunRaySearch(SearchParts(), q, path_, visit, stats);
  }
  std::vector<SearchPart> SearchParts() const {
    std::vector<SearchPart> out;
    for (size_t s = 0; s < shards_.size(); ++s) out.push_back({shards_[s].get(), &ids_[s], nullptr});
    return out;
  }

  // One sweep over all the shards' leaves (docs/shards.md, "Clash"): the pairs inside each shard and,
  // for shards i < j whose root boxes grown by C meet, the pairs of a leaf of i and a leaf of j.
  Status SelfClash(const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) const override {
    return Guarded(path_, [&] { return RunMultiClash(ClashParts(), nullptr, o, visit, stats); });
  }
  Status Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform, const ClashOptions& o,
                 const ClashVisitor& visit, ClashStats* stats) const override;
  std::vector<ClashPart> ClashParts() const {
    std::vector<ClashPart> parts;
    for (size_t s = 0; s < shards_.size(); ++s) parts.push_back(ClashPart{&shards_[s]->leaves(), &ids_[s]});
    return parts;
  }
  // The same sweep within `scope` (its focus and partner sets: global ids).
  Status ScopedClash(const MultiClashScope& scope, const ClashOptions& o, const ClashVisitor& visit,
                     ClashStats* stats) const {
    return Guarded(path_, [&] { return RunMultiClash(ClashParts(), scope, o, visit, stats); });
  }
  void ClearCache() override {
    for (auto& s : shards_) s->ClearCache();
  }
  const std::string& path() const override { return path_; }
  uint64_t object_count() const override { return m_.objects; }
  Result<ObjectRecord> Object(ObjectId id, QueryStats* stats) const override {
    MKTREE_ASSIGN_OR_RETURN(const auto at, Locate(id));
    MKTREE_ASSIGN_OR_RETURN(ObjectRecord r, shards_[at.first]->Object(at.second, stats));
    r.id = id;
    return r;
  }
  Result<Mesh> ObjectGeometry(ObjectId id, QueryStats* stats) const override {
    MKTREE_ASSIGN_OR_RETURN(const auto at, Locate(id));
    return shards_[at.first]->ObjectGeometry(at.second, stats);
  }
  Result<std::string> ObjectName(ObjectId id) const override {
    MKTREE_ASSIGN_OR_RETURN(const auto at, Locate(id));
    return shards_[at.first]->ObjectName(at.second);
  }
  Box3d bounds() const override { return bounds_; }
  double objects_per_page() const override { return objects_per_page_; }
  const std::string& stats_json() const override { return stats_json_; }

 private:
  // The shards whose root boxes the query meets, in shard order, in the store frame (the same
  // subtraction as the shards' own routing, so a point on a face stays on it).
  std::vector<uint32_t> Route(const Query& q, QueryStats* stats) const {
    const Vec3d& o = m_.origin;
    Box3d b;
    if (q.kind == Query::Kind::kPoint) {
      const Vec3d p{q.point.x - o.x, q.point.y - o.y, q.point.z - o.z};
      for (int i = 0; i < 3; ++i) b.min[i] = b.max[i] = p[i];
    } else {
      for (int i = 0; i < 3; ++i) {
        b.min[i] = q.box.min[i] - o[i];
        b.max[i] = q.box.max[i] - o[i];
      }
    }
    return WalkTop([&](uint32_t n) { return box_[n].Intersects(b); }, stats);
  }

  // The shards (in shard order) of the top-level leaves reached through the nodes `meets` accepts; counts
  // the internal nodes passed in stats when given.
  template <typename Meets>
  std::vector<uint32_t> WalkTop(const Meets& meets, QueryStats* stats) const {
    std::vector<uint32_t> out;
    uint32_t stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const uint32_t n = stack[--top];
      if (!meets(n)) continue;
      const TopNode& t = m_.top.nodes[n];
      if (t.is_leaf()) {
        out.push_back(t.shard);
        continue;
      }
      if (stats) ++stats->internal_nodes_visited;
      stack[top++] = t.child[1];
      stack[top++] = t.child[0];
    }
    return out;
  }

  // The shards whose root boxes meet `b` (store frame) grown by c, in shard order.
  std::vector<uint32_t> RouteGrown(const Box3d& b, double c) const {
    return WalkTop([&](uint32_t n) { return clash::GrownMeet(clash::ToBox3d(box_[n]), b, c); }, nullptr);
  }

  // The shard holding global id `id` and its id there.
  Result<std::pair<uint32_t, ObjectId>> Locate(ObjectId id) const {
    if (id >= m_.objects)
      return Status::InvalidArgument(path_ + ": no object " + std::to_string(id) + " (the store has " +
                                     std::to_string(m_.objects) + ")");
    for (uint32_t s = 0; s < ids_.size(); ++s)
      if (auto local = LocalIdOf(ids_[s], id)) return std::pair{s, *local};
    return Status::Internal(path_ + ": object " + std::to_string(id) + " is in no shard");
  }

  std::string path_;
  Manifest m_;
  std::vector<std::unique_ptr<StoreDatabase>> shards_;
  std::vector<std::vector<ObjectId>> ids_;  // per shard: global id of each local id, increasing
  std::vector<Box3f> box_;                  // per top node
  Box3d bounds_;
  std::string stats_json_;
  double objects_per_page_ = 0;
};

// Each shard the mesh's box grown by C reaches runs its own Collide (the engine's, on its store) with
// the cap lifted and the exclusion seeing global ids; the pairs come back in shard order, each shard's in
// its leaf order, with global ids, and the cap is applied here. store_pages counts every shard's pages.
Status ShardedDatabase::Collide(const Mesh& mesh, const std::optional<RigidTransform>& transform,
                                const ClashOptions& o, const ClashVisitor& visit, ClashStats* stats) const {
  return Guarded(path_, [&]() -> Status {
    const auto start = std::chrono::steady_clock::now();
    ClashStats local;
    ClashStats& total = stats ? *stats : local;
    total = ClashStats();
    MKTREE_RETURN_IF_ERROR(clash::CheckOptions(o));
    MKTREE_RETURN_IF_ERROR(CheckCollideMesh(mesh, transform));
    // The mesh's box in the store frame, as RunCollide computes it.
    Box3d box;
    for (size_t v = 0; v < mesh.vertex_count(); ++v) {
      Vec3d p{mesh.vertices[3 * v], mesh.vertices[3 * v + 1], mesh.vertices[3 * v + 2]};
      if (transform) p = transform->Apply(p);
      for (int i = 0; i < 3; ++i) {
        const double x = p[i] - m_.origin[i];
        if (!std::isfinite(x))
          return Status::InvalidArgument("collide: the moved object has a non-finite vertex");
        box.min[i] = v ? std::min(box.min[i], x) : x;
        box.max[i] = v ? std::max(box.max[i], x) : x;
      }
    }
    const std::vector<uint32_t> route = RouteGrown(box, o.clearance);
    for (size_t s = 0; s < shards_.size(); ++s) {
      ClashStats st;
      if (std::find(route.begin(), route.end(), s) == route.end()) {
        // Unreached: none of its pages is read, but its pages are the store's.
        for (const LeafInfo& l : shards_[s]->reader().tree().leaves) st.store_pages += l.page_count;
        AddClashStats(&total, st);
        continue;
      }
      const std::vector<ObjectId>& ids = ids_[s];
      ClashOptions so = o;
      so.max_pairs = std::numeric_limits<uint64_t>::max();
      if (o.exclude) so.exclude = [&](ObjectId a, ObjectId b) { return o.exclude(ids[a], b); };
      PartPairCap cap(total, o.max_pairs);
      MKTREE_RETURN_IF_ERROR(shards_[s]->Collide(
          mesh, transform, so,
          [&](const ClashPair& p) {
            if (!cap.Take()) return;
            ClashPair g = p;
            g.a = ids[p.a];
            if (visit) visit(g);
          },
          &st));
      cap.Fill(&st);
      AddClashStats(&total, st);
    }
    total.total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return Status::Ok();
  });
}

Status ShardedDatabase::RunBatchStreamed(const QuerySource& source, const BatchOptions& options,
                                         const ResultVisitor& deliver) const {
  return Guarded(path_, [&]() -> Status {
    // One query: each routed shard runs it as a batch of one (cold: on its own empty cache), ids mapped.
    return RunQueriesOneByOne(path_, source, options, deliver, [&](const Query& q, QueryResult* r) -> Status {
      uint64_t remaining = q.limit;
      for (uint32_t s : Route(q, &r->stats)) {
        Query sq = q;
        sq.limit = remaining;
        uint64_t got = 0;
        MKTREE_RETURN_IF_ERROR(RunOneOnStore(*shards_[s], sq, options, [&](const QueryResult& sr) {
          for (ObjectId local : sr.hits) r->hits.push_back(ids_[s][local]);
          r->stats += sr.stats;
          got = sr.stats.hits;
          r->truncated = sr.truncated;
        }));
        if (r->truncated) break;
        if (remaining != Query::kNoLimit) remaining -= got;
      }
      std::sort(r->hits.begin(), r->hits.end());
      return Status::Ok();
    });
  });
}

}  // namespace

std::vector<ClashPart> ShardedClashParts(const Database& db) {
  const auto* s = dynamic_cast<const ShardedDatabase*>(&db);
  return s ? s->ClashParts() : std::vector<ClashPart>();
}

Status ShardedScopedClash(const Database& db, const MultiClashScope& scope, const ClashOptions& options,
                          const ClashVisitor& visit, ClashStats* stats) {
  const auto* s = dynamic_cast<const ShardedDatabase*>(&db);
  if (!s) return Status::Unsupported(db.path() + ": not a sharded store");
  return s->ScopedClash(scope, options, visit, stats);
}

Result<std::unique_ptr<Database>> OpenShardedDatabase(const std::string& manifest_path,
                                                      const OpenOptions& options) {
  MKTREE_ASSIGN_OR_RETURN(Manifest m, ReadManifest(manifest_path));
  const uint32_t k = m.top.shard_count;
  OpenOptions shard_options = options;
  shard_options.cache_pages = (options.cache_pages + k - 1) / k;
  std::vector<std::unique_ptr<StoreDatabase>> shards;
  std::vector<std::vector<ObjectId>> ids;
  for (uint32_t s = 0; s < k; ++s) {
    MKTREE_ASSIGN_OR_RETURN(ManifestShard shard, OpenManifestShard(manifest_path, m, s, shard_options));
    shards.push_back(std::move(shard.db));
    ids.push_back(std::move(shard.ids));
  }
  // Every global id in exactly one shard: the shards' increasing ids, merged (a heap of the shards' next
  // ids), are 0, 1, 2, ...
  {
    using Head = std::pair<ObjectId, uint32_t>;
    std::priority_queue<Head, std::vector<Head>, std::greater<Head>> heads;
    std::vector<size_t> at(k, 0);
    for (uint32_t s = 0; s < k; ++s)
      if (!ids[s].empty()) heads.push({ids[s][0], s});
    for (uint64_t want = 0; want < m.objects; ++want) {
      if (heads.empty() || heads.top().first != want)
        return Status::Corruption(manifest_path + ": object " + std::to_string(want) +
                                  " is in no shard, or in two");
      const uint32_t s = heads.top().second;
      heads.pop();
      if (++at[s] < ids[s].size()) heads.push({ids[s][at[s]], s});
    }
  }
  return std::unique_ptr<Database>(
      std::make_unique<ShardedDatabase>(manifest_path, std::move(m), std::move(shards), std::move(ids)));
}

}  // namespace mktree
