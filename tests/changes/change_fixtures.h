// What the change tests share: a store built from objects in RAM, the live set a test keeps beside it (the
// brute-force model of every revision), random batches, and answers compared against brute force over the
// stored geometry of the live set.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "engine/geometry/exact_geometry.h"
#include "engine/ingest/shard_build.h"
#include "engine/ingest/store_builder.h"
#include "mktree/changes.h"
#include "mktree/database.h"
#include "query/query_oracle.h"
#include "query/scene_fixtures.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree::testing {

// The live objects of one revision, by id.
using LiveSet = std::map<ObjectId, SceneObject>;

// A built scene's live set: every object under its id.
inline LiveSet LiveOf(const std::vector<SceneObject>& scene) {
  LiveSet live;
  for (const SceneObject& o : scene) live[o.id] = o;
  return live;
}

inline IngestOptions SmallPages(Backend backend) {
  IngestOptions o;
  o.store.backend = backend;
  o.store.params.block_size = 1024;
  o.store.params.blocks_per_page = 2;
  o.threads = 1;
  o.tuning.threads = 1;
  return o;
}

// An object of a second random scene moved to a random place of the first's extent: what an edit adds.
inline SceneObject MovedCopy(const SceneObject& from, std::mt19937_64& rng, const std::string& name) {
  std::uniform_real_distribution<double> d(-8, 8);
  SceneObject o = from;
  o.name = name;
  o.attributes = {{"edit", name}};
  const double dx = d(rng), dy = d(rng) / 2, dz = d(rng) / 4;
  for (size_t v = 0; v < o.mesh.vertex_count(); ++v) {
    o.mesh.vertices[3 * v] += dx;
    o.mesh.vertices[3 * v + 1] += dy;
    o.mesh.vertices[3 * v + 2] += dz;
  }
  return o;
}

// A random batch against `live`: `n` changes, about a third each add, remove and replace.
inline ChangeBatch RandomBatch(const LiveSet& live, size_t n, std::mt19937_64& rng, uint64_t* counter) {
  ChangeBatch b;
  std::vector<ObjectId> ids;
  for (const auto& [id, o] : live) ids.push_back(id);
  std::shuffle(ids.begin(), ids.end(), rng);
  const std::vector<SceneObject> donors = ClusteredScene(std::max<size_t>(n, 8), rng());
  size_t next = 0;
  for (size_t i = 0; i < n; ++i) {
    const int kind = static_cast<int>(rng() % 3);
    if (kind == 0 || next >= ids.size()) {
      b.add.push_back(MovedCopy(donors[i % donors.size()], rng, "add_" + std::to_string((*counter)++)));
    } else if (kind == 1) {
      b.remove.push_back(ids[next++]);
    } else {
      SceneObject o = MovedCopy(donors[i % donors.size()], rng, "rep_" + std::to_string((*counter)++));
      o.id = ids[next++];
      b.replace.push_back(std::move(o));
    }
  }
  return b;
}

// `live` after `batch` committed as `report` says.
inline void Apply(const ChangeBatch& batch, const CommitReport& report, LiveSet* live) {
  for (ObjectId id : batch.remove) live->erase(id);
  for (const SceneObject& o : batch.replace) (*live)[o.id] = o;
  for (size_t i = 0; i < batch.add.size(); ++i) {
    SceneObject o = batch.add[i];
    o.id = report.added_ids[i];
    (*live)[o.id] = o;
  }
}

// Brute force over the stored geometry of the live set, in the store's frame.
class LiveBruteForce {
 public:
  LiveBruteForce(const LiveSet& live, const Vec3d& origin) : origin_(origin) {
    std::vector<SceneObject> objs;
    for (const auto& [id, o] : live) objs.push_back(o);
    stored_ = StoredScene(objs, origin);
  }
  std::vector<ObjectId> Answer(const Query& q) const {
    std::vector<ObjectId> out;
    Box3d b;
    for (int a = 0; a < 3; ++a) {
      b.min[a] = (q.kind == Query::Kind::kPoint ? q.point[a] : q.box.min[a]) - origin_[a];
      b.max[a] = (q.kind == Query::Kind::kPoint ? q.point[a] : q.box.max[a]) - origin_[a];
    }
    for (const StoredObject& o : stored_) {
      if (!o.box.Intersects(b)) continue;
      if (q.mode == QueryMode::kExact) {
        if (q.kind == Query::Kind::kPoint) {
          const Vec3d p{b.min[0], b.min[1], b.min[2]};
          if (!PointInSolid(o.mesh, p)) continue;
        } else if (!MeshMeetsBox(o.mesh, b)) {
          continue;
        }
      }
      out.push_back(o.id);
    }
    return out;
  }

 private:
  Vec3d origin_;
  std::vector<StoredObject> stored_;
};

inline std::vector<Query> RandomQueries(size_t n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> x(-10, 110), y(-5, 45), z(-3, 23), size(0.2, 8);
  std::vector<Query> qs;
  for (size_t i = 0; i < n; ++i) {
    const QueryMode mode = i % 2 ? QueryMode::kExact : QueryMode::kAabb;
    if (i % 3 == 0) {
      qs.push_back(Query::Point({x(rng), y(rng), z(rng)}, mode));
    } else {
      Box3d b;
      b.min = {x(rng), y(rng), z(rng)};
      const double s = size(rng);
      b.max = {b.min[0] + s, b.min[1] + s / 2, b.min[2] + s / 3};
      qs.push_back(Query::Box(b, mode));
    }
  }
  return qs;
}

// Every query of `qs` answers at `db` as brute force over `live` does, by Run and by a batch; the live
// objects' names and the object count agree too.
inline void ExpectAnswers(const Database& db, const LiveSet& live, const Vec3d& origin,
                          const std::vector<Query>& qs, const std::string& where) {
  SCOPED_TRACE(where);
  ASSERT_EQ(db.object_count(), live.size());
  const LiveBruteForce brute(live, origin);
  std::vector<QueryResult> batch;
  ASSERT_TRUE(db.RunBatch(qs, 2, &batch).ok());
  for (size_t i = 0; i < qs.size(); ++i) {
    QueryResult r;
    ASSERT_TRUE(db.Run(qs[i], &r).ok());
    const std::vector<ObjectId> want = brute.Answer(qs[i]);
    ASSERT_EQ(r.hits, want) << "query " << i;
    ASSERT_EQ(batch[i].hits, want) << "batch query " << i;
    ASSERT_EQ(r.stats.hits, want.size());
  }
  size_t checked = 0;
  for (const auto& [id, o] : live) {
    if (checked++ % 7) continue;
    auto rec = db.Object(id);
    ASSERT_TRUE(rec.ok()) << rec.status().ToString();
    ASSERT_EQ(rec->name, o.name);
    auto mesh = db.ObjectGeometry(id);
    ASSERT_TRUE(mesh.ok()) << mesh.status().ToString();
    ASSERT_EQ(mesh->triangle_count(), o.mesh.triangle_count());
  }
}

// Clash pairs sorted, compared on ids and class.
inline std::vector<std::tuple<ObjectId, ObjectId, int>> SortedPairs(const std::vector<ClashPair>& pairs) {
  std::vector<std::tuple<ObjectId, ObjectId, int>> out;
  for (const ClashPair& p : pairs) out.emplace_back(p.a, p.b, static_cast<int>(p.cls));
  std::sort(out.begin(), out.end());
  return out;
}

inline std::vector<ClashPair> SelfClashPairs(const Database& db, const ClashOptions& o = {}) {
  std::vector<ClashPair> got;
  const Status st = db.SelfClash(
      o, [&](const ClashPair& p) { got.push_back(p); }, nullptr);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return got;
}

// The self-clash of `db` equals that of a fresh store of the same live objects (same frame).
inline void ExpectClashOfFreshBuild(const Database& db, const LiveSet& live,
                                    const IngestOptions& base_options, const Vec3d& origin,
                                    const std::string& dir) {
  std::vector<SceneObject> objs;
  std::vector<ObjectId> ids;
  for (const auto& [id, o] : live) {
    objs.push_back(o);
    objs.back().id = static_cast<ObjectId>(ids.size());
    ids.push_back(id);
  }
  IngestOptions o = base_options;
  o.origin = origin;
  const std::string fresh = dir + "/fresh.mkt";
  std::filesystem::remove(fresh);
  ASSERT_TRUE(BuildFromObjects(objs, fresh, o).ok());
  auto fdb = Database::Open(fresh);
  ASSERT_TRUE(fdb.ok());
  std::vector<ClashPair> want = SelfClashPairs(**fdb);
  for (ClashPair& p : want) {
    p.a = ids[p.a];
    p.b = ids[p.b];
    if (p.a > p.b) std::swap(p.a, p.b);
  }
  EXPECT_EQ(SortedPairs(SelfClashPairs(db)), SortedPairs(want));
}

// A sharded store of `objs` (ids 0..n-1) in `shards` shards, as `mktree build --shards` makes one.
inline Status BuildShardedFromObjects(const std::vector<SceneObject>& objs, const std::string& path,
                                      const IngestOptions& o, uint32_t shards) {
  std::vector<SceneOpener> in{[&objs](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objs, first));
  }};
  auto r = BuildShardedStore(in, path, o, shards);
  return r.ok() ? Status::Ok() : r.status();
}

}  // namespace mktree::testing
