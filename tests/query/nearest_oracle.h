// What the nearest and ray tests check answers against: brute force over the geometry a store keeps (every
// object's exact distance from every triangle and its solid; every triangle of every object along a ray),
// in the store's frame, and the random scenes they run on (rotated boxes, prisms, open surfaces).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "engine/geometry/mesh_edges.h"
#include "engine/geometry/mesh_separation.h"
#include "engine/geometry/ray_cast.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/geometry/triangle_pair.h"
#include "mktree/database.h"
#include "query/scene_fixtures.h"
#include "store_format/stored_geometry.h"

namespace mktree::testing {

// `m` turned by a random rotation about its bounds' centre.
inline Mesh Rotated(Mesh m, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ang(0, 2 * M_PI);
  const double a = ang(rng), b = ang(rng);
  const Box3d bb = m.Bounds();
  const double c[3] = {(bb.min[0] + bb.max[0]) / 2, (bb.min[1] + bb.max[1]) / 2, (bb.min[2] + bb.max[2]) / 2};
  for (size_t v = 0; v < m.vertex_count(); ++v) {
    double x = m.vertices[3 * v] - c[0], y = m.vertices[3 * v + 1] - c[1], z = m.vertices[3 * v + 2] - c[2];
    const double x1 = std::cos(a) * x - std::sin(a) * y, y1 = std::sin(a) * x + std::cos(a) * y;
    const double y2 = std::cos(b) * y1 - std::sin(b) * z, z2 = std::sin(b) * y1 + std::cos(b) * z;
    m.vertices[3 * v] = x1 + c[0];
    m.vertices[3 * v + 1] = y2 + c[1];
    m.vertices[3 * v + 2] = z2 + c[2];
  }
  return m;
}

// ClusteredScene with every 5th object rotated and every 7th opened (its last two triangles dropped: an
// open surface); `offset` moves the whole scene (far from 0 for frame tests).
inline std::vector<SceneObject> MixedScene(size_t n, uint64_t seed, double offset = 0) {
  std::vector<SceneObject> objs = ClusteredScene(n, seed);
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ull);
  for (size_t i = 0; i < objs.size(); ++i) {
    if (i % 5 == 1) objs[i].mesh = Rotated(objs[i].mesh, rng);
    if (i % 7 == 3) objs[i].mesh.triangles.resize(objs[i].mesh.triangles.size() - 6);
    for (double& v : objs[i].mesh.vertices) v += offset;
  }
  return objs;
}

// The stores the nearest and ray tests run on: a backend and the page cache's size.
struct StoreSetup {
  Backend backend;
  uint64_t cache_pages;
};

struct ExpectedNearest {
  ObjectId id;
  double distance;
};

// Brute force over the stored objects (store frame: world minus `origin`).
class NearestBruteForce {
 public:
  NearestBruteForce(const std::vector<SceneObject>& objs, const Vec3d& origin) : origin_(origin) {
    stored_ = StoredScene(objs, origin);
    for (const StoredObject& o : stored_) closed_.push_back(CheckEdges(o.mesh).closed);
  }
  NearestBruteForce(std::vector<StoredObject> stored, const Vec3d& origin)
      : origin_(origin), stored_(std::move(stored)) {
    for (const StoredObject& o : stored_) closed_.push_back(CheckEdges(o.mesh).closed);
  }

  Vec3d Local(const Vec3d& w) const { return {w.x - origin_.x, w.y - origin_.y, w.z - origin_.z}; }

  // Exact distance from world point p to object i (every triangle; 0 in a closed solid).
  double PointDistance(size_t i, const Vec3d& world) const {
    const Vec3d p = Local(world);
    const Mesh& m = stored_[i].mesh;
    if (closed_[i] && PointInSolid(m, p)) return 0;
    double best = INFINITY;
    for (size_t t = 0; t < m.triangle_count(); ++t) {
      const uint32_t* c = &m.triangles[3 * t];
      auto at = [&](uint32_t v) {
        return Vec3d{m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]};
      };
      best = std::min(best, PointTriangleClosest(p, at(c[0]), at(c[1]), at(c[2])).distance_squared);
    }
    return std::sqrt(best);
  }
  // Distance from the world box (a solid) to object i.
  double BoxDistance(size_t i, const Box3d& world) const {
    Box3d b;
    for (int a = 0; a < 3; ++a) b.min[a] = world.min[a] - origin_[a], b.max[a] = world.max[a] - origin_[a];
    const Mesh box = BoxMesh(b);
    const ClashShape sa(stored_[i].mesh), sb(box);
    const Separation s = Separate(sa, sb, INFINITY, nullptr);
    return s.meeting == Meeting::kApart ? s.distance : 0.0;
  }
  // Every object with its distance, nearest first, ties by id.
  std::vector<ExpectedNearest> Nearest(const Vec3d& p) const {
    std::vector<ExpectedNearest> out;
    for (size_t i = 0; i < stored_.size(); ++i) out.push_back({stored_[i].id, PointDistance(i, p)});
    Sort(&out);
    return out;
  }
  std::vector<ExpectedNearest> NearBox(const Box3d& b, double within) const {
    std::vector<ExpectedNearest> out;
    for (size_t i = 0; i < stored_.size(); ++i) {
      Box3d grown = b;
      for (int a = 0; a < 3; ++a) grown.min[a] -= within + 1e-6, grown.max[a] += within + 1e-6;
      Box3d sbox;
      for (int a = 0; a < 3; ++a)
        sbox.min[a] = stored_[i].box.min[a] + origin_[a], sbox.max[a] = stored_[i].box.max[a] + origin_[a];
      if (!BoxesMeet(grown, sbox)) continue;
      const double d = BoxDistance(i, b);
      if (d <= within) out.push_back({stored_[i].id, d});
    }
    Sort(&out);
    return out;
  }
  // Each object's first hit along the ray (every triangle of every object whose box the ray enters), in order
  // of t then id.
  std::vector<std::pair<ObjectId, double>> Hits(const RayQuery& q) const {
    const PreparedRay ray(Local(q.origin), q.direction);
    std::vector<std::pair<ObjectId, double>> out;
    for (const StoredObject& o : stored_) {
      // The stored box holds every triangle, and RayBoxEnter's interval holds every hit inside
      // (RayCast.BoxEnterIsALowerBoundOfEveryHitInside): objects whose box the ray misses have no hit.
      double enter;
      Box3d box;
      for (int a = 0; a < 3; ++a) box.min[a] = o.box.min[a], box.max[a] = o.box.max[a];
      if (!RayBoxEnter(ray, box, q.max_length, &enter)) continue;
      double best = INFINITY;
      const Mesh& m = o.mesh;
      for (size_t t = 0; t < m.triangle_count(); ++t) {
        const uint32_t* c = &m.triangles[3 * t];
        auto at = [&](uint32_t v) {
          return Vec3d{m.vertices[3 * v], m.vertices[3 * v + 1], m.vertices[3 * v + 2]};
        };
        RayHit3 h;
        if (RayTriangle(ray, at(c[0]), at(c[1]), at(c[2]), q.max_length, &h)) best = std::min(best, h.t);
      }
      if (best != INFINITY) out.push_back({o.id, best});
    }
    std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
      return a.second != b.second ? a.second < b.second : a.first < b.first;
    });
    return out;
  }
  size_t size() const { return stored_.size(); }
  const StoredObject& object(size_t i) const { return stored_[i]; }
  size_t IndexOf(ObjectId id) const {
    for (size_t i = 0; i < stored_.size(); ++i)
      if (stored_[i].id == id) return i;
    return stored_.size();
  }

 private:
  static void Sort(std::vector<ExpectedNearest>* v) {
    std::sort(v->begin(), v->end(), [](const ExpectedNearest& a, const ExpectedNearest& b) {
      return a.distance != b.distance ? a.distance < b.distance : a.id < b.id;
    });
  }
  Vec3d origin_;
  std::vector<StoredObject> stored_;
  std::vector<bool> closed_;
};

// Distances agree to double rounding of coordinates of this size.
inline double Tolerance(double scale) { return 1e-9 * std::max(1.0, scale); }

// `got` is the first got.size() of `want` as far as distances go (ids may differ only between equal
// distances), nearest first, ties by id, each id's distance its own, each closest point that far.
inline void ExpectNearestAnswer(const std::vector<NearestHit>& got, const std::vector<ExpectedNearest>& want,
                                size_t k, const NearestBruteForce& brute, const Vec3d& p, double scale) {
  const double tol = Tolerance(scale);
  ASSERT_EQ(got.size(), std::min(k, want.size()));
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_NEAR(got[i].distance, want[i].distance, tol) << "answer " << i;
    if (i > 0) {
      EXPECT_LE(got[i - 1].distance, got[i].distance) << "nearest first, answer " << i;
      if (got[i - 1].distance == got[i].distance) {
        EXPECT_LT(got[i - 1].id, got[i].id) << "ties by id";
      }
    }
    const size_t at = brute.IndexOf(got[i].id);
    ASSERT_LT(at, brute.size());
    EXPECT_NEAR(got[i].distance, brute.PointDistance(at, p), tol) << "id " << got[i].id;
    const double dx = got[i].point.x - p.x, dy = got[i].point.y - p.y, dz = got[i].point.z - p.z;
    EXPECT_NEAR(std::sqrt(dx * dx + dy * dy + dz * dz), got[i].distance, tol)
        << "closest point of " << got[i].id;
  }
}

}  // namespace mktree::testing
