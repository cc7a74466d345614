#include "engine/generator/tanker_generator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdio>
#include <map>
#include <set>

#include "generator/mesh_checks.h"

namespace mktree {
namespace {

using testing::ClosedManifoldError;
using testing::Drain;
using testing::SignedVolume6;

std::vector<SceneObject> Tanker(uint64_t n, uint64_t seed, ObjectId first_id = 0) {
  auto source = MakeTankerSource(n, seed, first_id);
  return Drain(source.get());
}

std::string ClassOf(const std::string& name) { return name.substr(0, name.find('_')); }

TEST(TankerGeneratorTest, YieldsExactlyNObjectsWithConsecutiveIds) {
  for (uint64_t n : {1, 2, 7, 59, 100, 1001}) {
    const auto objects = Tanker(n, 5, 17);
    ASSERT_EQ(objects.size(), n);
    for (size_t i = 0; i < objects.size(); ++i) {
      EXPECT_EQ(objects[i].id, 17 + i);
      EXPECT_EQ(objects[i].source, "tanker:" + std::to_string(n) + ":5");  // the spec that rebuilds it
      EXPECT_TRUE(objects[i].attributes.empty());
    }
  }
  auto source = MakeTankerSource(3, 5);
  SceneObject o;
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(*source->Next(&o));
  for (int i = 0; i < 2; ++i) {  // stays at the end
    Result<bool> more = source->Next(&o);
    ASSERT_TRUE(more.ok());
    EXPECT_FALSE(*more);
  }
}

TEST(TankerGeneratorTest, EmptyAndOverflowingRequests) {
  EXPECT_TRUE(Tanker(0, 1).empty());
  auto source = MakeTankerSource(10, 1, UINT32_MAX - 5);
  SceneObject o;
  Result<bool> r = source->Next(&o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument);
}

TEST(TankerGeneratorTest, SameSeedSameObjectsOtherSeedOtherObjects) {
  const auto a = Tanker(2000, 42), b = Tanker(2000, 42), c = Tanker(2000, 43);
  ASSERT_EQ(a.size(), b.size());
  size_t differing = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].name, b[i].name);
    EXPECT_EQ(a[i].mesh.vertices, b[i].mesh.vertices) << i;
    EXPECT_EQ(a[i].mesh.triangles, b[i].mesh.triangles) << i;
    differing += a[i].mesh.vertices != c[i].mesh.vertices;
  }
  EXPECT_GT(differing, a.size() * 9 / 10);
}

// A pinned checksum of the geometry: fails if the output changes on another platform or after an edit
// (an intended change of the generator must update it, since it changes every generated scene).
TEST(TankerGeneratorTest, OutputIsPinned) {
  uint64_t h = 1469598103934665603ULL;  // FNV-1a over names, vertex bits and indices
  auto mix = [&h](uint64_t v) {
    for (int i = 0; i < 8; ++i) h = (h ^ ((v >> (8 * i)) & 0xff)) * 1099511628211ULL;
  };
  for (const SceneObject& o : Tanker(500, 7)) {
    for (char ch : o.name) mix(static_cast<uint8_t>(ch));
    for (float v : o.mesh.vertices) mix(std::bit_cast<uint32_t>(v));
    for (uint32_t t : o.mesh.triangles) mix(t);
  }
  EXPECT_EQ(h, 1865750813809032953ULL) << "pinned tanker checksum: " << h;
}

TEST(TankerGeneratorTest, EveryMeshIsClosedAndOutwardFacing) {
  for (const SceneObject& o : Tanker(4000, 3)) {
    ASSERT_GE(o.mesh.triangle_count(), 12u) << o.name;
    const std::string err = ClosedManifoldError(o.mesh);
    ASSERT_TRUE(err.empty()) << o.name << ": " << err;
    ASSERT_GT(SignedVolume6(o.mesh), 0.0) << o.name;
  }
}

TEST(TankerGeneratorTest, ClassProportionsAndNamesAtSeveralSizes) {
  for (uint64_t n : {100, 1000, 12345, 100000}) {
    std::map<std::string, uint64_t> count;
    for (const SceneObject& o : Tanker(n, 11)) {
      const std::string cls = ClassOf(o.name);
      // Name = class + running number within the class, at least six digits.
      char expected[32];
      std::snprintf(expected, sizeof(expected), "%s_%06llu", cls.c_str(),
                    static_cast<unsigned long long>(count[cls]++));
      ASSERT_EQ(o.name, expected);
    }
    ASSERT_EQ(count.size(), 3u) << n;
    const double total = static_cast<double>(n);
    EXPECT_NEAR(count["pipe"] / total, 0.6, 0.05) << n;
    EXPECT_NEAR(count["plate"] / total, 0.3, 0.05) << n;
    EXPECT_NEAR(count["equipment"] / total, 0.1, 0.05) << n;
    const TankerClassCounts expected = TankerExpectedCounts(n);
    EXPECT_EQ(count["pipe"], expected.pipes);
    EXPECT_EQ(count["plate"], expected.plates);
    EXPECT_EQ(count["equipment"], expected.equipment);
  }
}

TEST(TankerGeneratorTest, ObjectsStayInsideTheHull) {
  const Box3d hull = TankerHullBounds();
  EXPECT_NEAR(hull.max[0] - hull.min[0], 300.0, 1e-9);
  EXPECT_NEAR(hull.max[1] - hull.min[1], 50.0, 1e-9);
  EXPECT_NEAR(hull.max[2] - hull.min[2], 30.0, 1e-9);
  for (uint64_t n : {100, 20000}) {
    Box3d all;
    for (const SceneObject& o : Tanker(n, 9)) {
      const Box3d b = o.mesh.Bounds();
      for (int d = 0; d < 3; ++d) {
        ASSERT_GE(b.min[d], hull.min[d] - 1e-3) << o.name;
        ASSERT_LE(b.max[d], hull.max[d] + 1e-3) << o.name;
      }
      all.Extend(b.min[0], b.min[1], b.min[2]);
      all.Extend(b.max[0], b.max[1], b.max[2]);
    }
    // ... and fill it: the scene spans most of the hull in every direction.
    for (int d = 0; d < 3; ++d) EXPECT_GT(all.max[d] - all.min[d], 0.9 * (hull.max[d] - hull.min[d])) << n;
  }
}

// The axis of a prism is the coordinate on which its vertices take exactly two values (its end faces).
int PrismAxis(const Mesh& m) {
  for (int d = 0; d < 3; ++d) {
    std::set<float> values;
    for (size_t i = d; i < m.vertices.size(); i += 3) values.insert(m.vertices[i]);
    if (values.size() == 2) return d;
  }
  return -1;
}

TEST(TankerGeneratorTest, PipesArePrismsOfTheSpecifiedShape) {
  std::set<int> sides_seen, axes_seen;
  double longest = 0;
  for (const SceneObject& o : Tanker(20000, 21)) {
    if (ClassOf(o.name) != "pipe") continue;
    const int sides = static_cast<int>(o.mesh.vertex_count() / 2);
    ASSERT_GE(sides, 8) << o.name;
    ASSERT_LE(sides, 16) << o.name;
    sides_seen.insert(sides);
    const int axis = PrismAxis(o.mesh);
    ASSERT_GE(axis, 0) << o.name;
    axes_seen.insert(axis);
    const Box3d b = o.mesh.Bounds();
    const double length = b.max[axis] - b.min[axis];
    EXPECT_GE(length, 0.3 - 1e-3) << o.name;
    EXPECT_LE(length, 40.0 + 1e-3) << o.name;
    longest = std::max(longest, length);
    for (int d = 0; d < 3; ++d) {
      if (d == axis) continue;
      const double across = b.max[d] - b.min[d];  // between the inscribed and circumscribed diameters
      EXPECT_GE(across, 0.05 * 0.92 - 2e-4) << o.name;
      EXPECT_LE(across, 0.5 + 2e-4) << o.name;
    }
  }
  EXPECT_EQ(sides_seen.size(), 9u);  // 8..16
  EXPECT_EQ(axes_seen.size(), 3u);
  EXPECT_GT(longest, 20.0);  // long runs through bulkheads exist
}

// More objects make a finer structure: plates are tiled more finely, compartments get smaller.
TEST(TankerGeneratorTest, StructureGetsFinerWithSize) {
  auto mean_plate_volume = [](uint64_t n) {
    double sum = 0;
    uint64_t plates = 0;
    for (const SceneObject& o : Tanker(n, 1)) {
      if (ClassOf(o.name) != "plate") continue;
      const Box3d b = o.mesh.Bounds();
      sum += (b.max[0] - b.min[0]) * (b.max[1] - b.min[1]) * (b.max[2] - b.min[2]);
      ++plates;
    }
    return sum / static_cast<double>(plates);
  };
  const double small = mean_plate_volume(1000), large = mean_plate_volume(100000);
  EXPECT_LT(large, small / 4);
}

}  // namespace
}  // namespace mktree
