// Scenes at real-world coordinates (UTM-sized, 5e5 / 5e6 m from 0) with millimetre features: answers in
// AABB and exact mode, through the OBJ reader and the store, both backends, against brute force over the
// input geometry (points kept at least 0.1 mm from every face) and over the stored geometry (any point).
#include <gtest/gtest.h>
#include <unistd.h>

#include <charconv>
#include <filesystem>
#include <fstream>
#include <random>

#include "engine/geometry/exact_geometry.h"
#include "engine/ingest/store_builder.h"
#include "mktree/database.h"
#include "query/scene_fixtures.h"
#include "store_format/stored_geometry.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

constexpr double kUtm[3] = {500000, 5000000, 100};

class FarCoordinatesTest : public ::testing::TestWithParam<Backend> {
 protected:
  // Writes `objs` as OBJ text (shortest decimals that read back to the same doubles) and builds a store from
  // the file, so the reader's precision is part of what is tested.
  std::unique_ptr<Database> BuildFromObj(const std::vector<SceneObject>& objs,
                                         IngestReport* report = nullptr) {
    const std::string obj = (dir_ / "scene.obj").string(), store = (dir_ / "scene.mkt").string();
    {
      std::ofstream out(obj);
      char buf[32];
      size_t base = 1;
      for (const SceneObject& o : objs) {
        out << "o " << o.name << "\n";
        for (size_t i = 0; i < o.mesh.vertices.size(); i += 3) {
          out << "v";
          for (int k = 0; k < 3; ++k)
            out << " " << std::string(buf, std::to_chars(buf, buf + sizeof buf, o.mesh.vertices[i + k]).ptr);
          out << "\n";
        }
        for (size_t t = 0; t < o.mesh.triangles.size(); t += 3)
          out << "f " << base + o.mesh.triangles[t] << " " << base + o.mesh.triangles[t + 1] << " "
              << base + o.mesh.triangles[t + 2] << "\n";
        base += o.mesh.vertex_count();
      }
    }
    IngestOptions opts;
    opts.store.backend = GetParam();
    auto r = BuildStore({[&](ObjectId first) { return OpenSceneFile(obj, first); }}, store, opts);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) return nullptr;
    if (report) *report = *r;
    auto db = Database::Open(store, {.cache_pages = 16});
    EXPECT_TRUE(db.ok()) << db.status().ToString();
    return db.ok() ? std::move(*db) : nullptr;
  }

  testing::TempDir dir_{"mktree_far"};
};

Box3d Cube(const double corner[3], double side) {
  Box3d b;
  for (int k = 0; k < 3; ++k) {
    b.min[k] = corner[k];
    b.max[k] = corner[k] + side;
  }
  return b;
}

std::vector<ObjectId> Hits(const Database& db, const Vec3d& p, QueryMode mode) {
  QueryResult r;
  EXPECT_TRUE(db.Run(Query::Point(p, mode), &r).ok());
  return r.hits;
}

// The case: a 0.2 m cube at (500000, 5000000, 100) was not found at its centre, in either mode.
// Now it is, and points 0.1 mm outside any face are not, in either mode.
TEST_P(FarCoordinatesTest, ASmallCubeFarFromZeroIsFoundExactly) {
  SceneObject cube;
  cube.name = "cube";
  const double corner[3] = {kUtm[0] - 0.1, kUtm[1] - 0.1, kUtm[2] - 0.1};
  cube.mesh = testing::BoxMesh(Cube(corner, 0.2));
  IngestReport report;
  auto db = BuildFromObj({cube}, &report);
  ASSERT_TRUE(db);
  EXPECT_EQ(report.origin.x, 500000);
  EXPECT_EQ(report.origin.y, 5000000);
  EXPECT_EQ(report.origin.z, 0);  // |z| < 2^16: the axis keeps its coordinates
  EXPECT_TRUE(report.warnings.empty()) << report.warnings[0];
  for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
    EXPECT_EQ(Hits(*db, {kUtm[0], kUtm[1], kUtm[2]}, mode), std::vector<ObjectId>{0});
    for (int k = 0; k < 3; ++k) {
      for (double side : {-0.1, 0.1}) {
        Vec3d p{kUtm[0], kUtm[1], kUtm[2]};
        p[k] += side + (side > 0 ? 1e-4 : -1e-4);
        EXPECT_TRUE(Hits(*db, p, mode).empty()) << "axis " << k << " side " << side;
        p[k] = kUtm[k] + side + (side > 0 ? -1e-4 : 1e-4);
        EXPECT_EQ(Hits(*db, p, mode), std::vector<ObjectId>{0}) << "axis " << k << " side " << side;
      }
    }
  }
  const Box3d bounds = db->bounds();
  EXPECT_NEAR(bounds.min[1], kUtm[1] - 0.1, 1e-6);
  EXPECT_NEAR(bounds.max[1], kUtm[1] + 0.1, 1e-6);
}

// 1 mm cubes 1 mm apart (and 1 mm pipes) in a UTM-sized frame: random points at least 0.1 mm from every
// face give the input geometry's answer in both modes; any point, boxes too, gives brute force's answer over
// the stored geometry.
TEST_P(FarCoordinatesTest, MillimetreFeaturesMatchBruteForce) {
  std::vector<SceneObject> objs;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      for (int k = 0; k < 2; ++k) {
        SceneObject o;
        o.id = static_cast<ObjectId>(objs.size());
        o.name = "mm_" + std::to_string(o.id);
        const double corner[3] = {kUtm[0] + 0.002 * i, kUtm[1] + 0.002 * j, kUtm[2] + 0.002 * k};
        o.mesh = testing::BoxMesh(Cube(corner, 0.001));
        objs.push_back(std::move(o));
      }
  for (int i = 0; i < 20; ++i) {  // 1 mm pipes, 8 sides, above the cubes
    SceneObject o;
    o.id = static_cast<ObjectId>(objs.size());
    o.name = "pipe_" + std::to_string(i);
    o.mesh = testing::PrismMesh(0, kUtm[1] + 0.003 * i, kUtm[2] + 0.01, 0.0005, kUtm[0], kUtm[0] + 0.03, 8);
    objs.push_back(std::move(o));
  }
  IngestReport report;
  auto db = BuildFromObj(objs, &report);
  ASSERT_TRUE(db);
  EXPECT_TRUE(report.warnings.empty());
  const Vec3d origin = report.origin;
  const auto stored = testing::StoredScene(objs, origin);

  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0, 1);
  int clear_points = 0, inside = 0;
  for (int q = 0; q < 3000; ++q) {
    // Half the points among the cubes, half among the pipes.
    const Vec3d p = q % 2 == 0
                        ? Vec3d{kUtm[0] - 0.001 + 0.026 * unit(rng), kUtm[1] - 0.001 + 0.026 * unit(rng),
                                kUtm[2] - 0.001 + 0.006 * unit(rng)}
                        : Vec3d{kUtm[0] - 0.001 + 0.032 * unit(rng), kUtm[1] - 0.001 + 0.06 * unit(rng),
                                kUtm[2] + 0.009 + 0.002 * unit(rng)};
    const Vec3d ps{p.x - origin.x, p.y - origin.y, p.z - origin.z};
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      std::vector<ObjectId> want_stored, want_input;
      bool clear = true;
      for (size_t i = 0; i < objs.size(); ++i) {
        if (stored[i].box.Contains(ps) && (mode == QueryMode::kAabb || PointInSolid(stored[i].mesh, ps)))
          want_stored.push_back(objs[i].id);
        // Near: within 0.1 mm of the box (cubes are their boxes), or anywhere in a pipe's box (its slanted
        // faces are not measured).
        const Box3d b = objs[i].mesh.Bounds();
        const bool pipe = objs[i].name[0] == 'p';
        bool in_box = true, in_grown = true, in_shrunk = true;
        for (int k = 0; k < 3; ++k) {
          in_box &= p[k] >= b.min[k] && p[k] <= b.max[k];
          in_grown &= p[k] >= b.min[k] - 1e-4 && p[k] <= b.max[k] + 1e-4;
          in_shrunk &= p[k] >= b.min[k] + 1e-4 && p[k] <= b.max[k] - 1e-4;
        }
        clear &= !(in_grown && (pipe || !in_shrunk));
        if (in_box && (mode == QueryMode::kAabb || PointInSolid(objs[i].mesh, p)))
          want_input.push_back(objs[i].id);
      }
      const std::vector<ObjectId> got = Hits(*db, p, mode);
      ASSERT_EQ(got, want_stored) << "point " << q;
      if (clear) {
        ASSERT_EQ(got, want_input) << "point " << q;
        ++clear_points;
        inside += !got.empty();
      }
    }
    // A box around the point, 0.5-3 mm wide.
    Box3d box;
    for (int k = 0; k < 3; ++k) {
      const double h = 0.00025 + 0.00125 * unit(rng);
      box.min[k] = p[k] - h;
      box.max[k] = p[k] + h;
    }
    Box3d bs;
    for (int k = 0; k < 3; ++k) {
      bs.min[k] = box.min[k] - origin[k];
      bs.max[k] = box.max[k] - origin[k];
    }
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      std::vector<ObjectId> want;
      for (size_t i = 0; i < objs.size(); ++i)
        if (stored[i].box.Intersects(bs) && (mode == QueryMode::kAabb || MeshMeetsBox(stored[i].mesh, bs)))
          want.push_back(objs[i].id);
      QueryResult got;
      ASSERT_TRUE(db->Run(Query::Box(box, mode), &got).ok());
      ASSERT_EQ(got.hits, want) << "box " << q;
    }
  }
  EXPECT_GT(clear_points, 1000);  // the input-geometry check covers most points...
  EXPECT_GT(inside, 100);         // ...and many of them inside a cube
}

// The whole clustered test scene moved 5e6 m away answers as brute force over what the store keeps.
TEST_P(FarCoordinatesTest, ShiftedClusteredSceneMatchesBruteForce) {
  std::vector<SceneObject> objs = testing::ClusteredScene(600, 8);
  for (SceneObject& o : objs)
    for (size_t i = 0; i < o.mesh.vertices.size(); ++i) o.mesh.vertices[i] += kUtm[i % 3];
  IngestReport report;
  auto db = BuildFromObj(objs, &report);
  ASSERT_TRUE(db);
  const Vec3d origin = report.origin;
  EXPECT_NE(origin.x, 0);
  const auto stored = testing::StoredScene(objs, origin);
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> unit(0, 1);
  for (int q = 0; q < 300; ++q) {
    const testing::StoredObject& near = stored[rng() % stored.size()];
    Vec3d ps;
    for (int k = 0; k < 3; ++k)
      ps[k] = q % 3 == 0 ? (rng() % 2 ? near.box.min[k] : near.box.max[k])
                         : near.box.min[k] + unit(rng) * (near.box.max[k] - near.box.min[k]);
    const Vec3d p{ps.x + origin.x, ps.y + origin.y, ps.z + origin.z};
    const Vec3d back{p.x - origin.x, p.y - origin.y, p.z - origin.z};
    for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
      std::vector<ObjectId> want;
      for (const testing::StoredObject& o : stored)
        if (o.box.Contains(back) && (mode == QueryMode::kAabb || PointInSolid(o.mesh, back)))
          want.push_back(o.id);
      ASSERT_EQ(Hits(*db, p, mode), want) << "point " << q;
    }
  }
}

// Objects far from the origin chosen from the first object get boxes coarse for their size: the build says
// so (exact answers stay right; AABB answers are that much larger).
TEST_P(FarCoordinatesTest, CoarseBoxesAreReported) {
  SceneObject near, far;
  near.name = "near";
  const double at0[3] = {0, 0, 0}, at_utm[3] = {kUtm[0], kUtm[1], kUtm[2]};
  near.mesh = testing::BoxMesh(Cube(at0, 1));
  far.name = "far";
  far.id = 1;
  far.mesh = testing::BoxMesh(Cube(at_utm, 0.001));
  IngestReport report;
  auto db = BuildFromObj({near, far}, &report);
  ASSERT_TRUE(db);
  ASSERT_EQ(report.warnings.size(), 1u);
  EXPECT_NE(report.warnings[0].find("1 objects lie so far from the store's origin (0, 0, 0)"),
            std::string::npos)
      << report.warnings[0];
  EXPECT_NE(report.warnings[0].find("object 1 'far'"), std::string::npos) << report.warnings[0];
  const Vec3d centre{kUtm[0] + 0.0005, kUtm[1] + 0.0005, kUtm[2] + 0.0005};
  EXPECT_EQ(Hits(*db, centre, QueryMode::kExact), std::vector<ObjectId>{1});
  EXPECT_TRUE(Hits(*db, {kUtm[0] + 0.0015, kUtm[1] + 0.0005, kUtm[2] + 0.0005}, QueryMode::kExact).empty());
}

// assimp reads coordinates as float32: a 0.2 m cube at UTM coordinates in a PLY file has lost its detail
// before mktree sees it. The build says so and names the file and the object.
TEST_P(FarCoordinatesTest, FloatOnlyReadersWarnWhenDetailIsLost) {
  const std::string ply = (dir_ / "far.ply").string(), store = (dir_ / "far.mkt").string();
  {
    std::ofstream out(ply);
    out << "ply\nformat ascii 1.0\nelement vertex 8\nproperty double x\nproperty double y\nproperty double "
           "z\n"
           "element face 12\nproperty list uchar int vertex_indices\nend_header\n";
    const Mesh m = testing::BoxMesh(Cube(kUtm, 0.2));
    out.precision(17);
    for (size_t i = 0; i < m.vertices.size(); i += 3)
      out << m.vertices[i] << " " << m.vertices[i + 1] << " " << m.vertices[i + 2] << "\n";
    for (size_t t = 0; t < m.triangles.size(); t += 3)
      out << "3 " << m.triangles[t] << " " << m.triangles[t + 1] << " " << m.triangles[t + 2] << "\n";
  }
  IngestOptions opts;
  opts.store.backend = GetParam();
  auto r = BuildStore({[&](ObjectId first) { return OpenSceneFile(ply, first); }}, store, opts);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_FALSE(r->warnings.empty());
  EXPECT_EQ(r->warnings[0].rfind(ply + ": 1 objects lie too far from 0", 0), 0u) << r->warnings[0];
  EXPECT_NE(r->warnings[0].find("convert the scene to OBJ or .mks"), std::string::npos) << r->warnings[0];
}

INSTANTIATE_TEST_SUITE_P(Backends, FarCoordinatesTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const auto& info) {
                           return info.param == Backend::kHdf5 ? "Hdf5" : "PagedFile";
                         });

TEST(ChooseStoreOriginTest, ZeroNearZeroElseTheRoundedCentre) {
  Box3d b;
  b.min = {-10, 65000, -70000.6};
  b.max = {10, 65535, -70000.2};
  const Vec3d o = ChooseStoreOrigin(b);
  EXPECT_EQ(o.x, 0);
  EXPECT_EQ(o.y, 0);  // centre 65267.5 < 2^16
  EXPECT_EQ(o.z, -70000);
  EXPECT_EQ(ChooseStoreOrigin(Box3d{}).x, 0);  // empty or non-finite: 0
}

}  // namespace
}  // namespace mktree
