// Ingest keeps only per-object records in RAM: a scene whose geometry is ten times a memory budget
// builds within that budget. The build runs in a child process so that its peak RSS is its own.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "child_peak_rss.h"
#include "engine/ingest/store_builder.h"
#include "mktree/database.h"
#include "test_dirs.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

// Streams `count` heavy objects (each a closed prism of `sides` sides, ~100 KB of geometry), one at a
// time, never holding more than the current one.
class HeavyPrisms final : public SceneSource {
 public:
  HeavyPrisms(uint32_t count, int sides, ObjectId first) : count_(count), sides_(sides), next_(first) {}
  Result<bool> Next(SceneObject* out) override {
    if (made_ == count_) return false;
    const double x = (made_ % 40) * 3.0, y = (made_ / 40 % 40) * 3.0, z = (made_ / 1600) * 30.0;
    Mesh& m = out->mesh;
    m.vertices.clear();
    m.triangles.clear();
    const uint32_t n = static_cast<uint32_t>(sides_);
    for (int end = 0; end < 2; ++end)
      for (uint32_t s = 0; s < n; ++s) {
        // Jittered radius so that the geometry does not compress to nothing.
        const double r = 1.0 + 0.01 * std::sin(s * 12.9898 + made_ * 78.233);
        m.vertices.insert(m.vertices.end(), {static_cast<float>(x + r * std::cos(2 * M_PI * s / n)),
                                             static_cast<float>(y + r * std::sin(2 * M_PI * s / n)),
                                             static_cast<float>(z + end * 25.0)});
      }
    for (uint32_t s = 0; s < n; ++s) {
      const uint32_t a = s, b = (s + 1) % n;
      m.triangles.insert(m.triangles.end(), {a, b, b + n, a, b + n, a + n});
    }
    for (uint32_t s = 1; s + 1 < n; ++s) {
      m.triangles.insert(m.triangles.end(), {0, s + 1, s});
      m.triangles.insert(m.triangles.end(), {n, n + s, n + s + 1});
    }
    out->id = next_++;
    out->name = "heavy_" + std::to_string(made_++);
    return true;
  }

 private:
  uint32_t count_;
  int sides_;
  ObjectId next_;
  uint32_t made_ = 0;
};

TEST(BoundedMemory, GeometryTenTimesTheBudgetBuildsWithinIt) {
  // The budget covers the build's fixed costs, which do not grow with the scene: the encoder threads'
  // batches, the two write-behind page streams, the object table's thread and their malloc arenas.
  constexpr uint64_t kBudget = 64ull << 20;
  constexpr uint32_t kObjects = 8000;
  constexpr int kSides = 1200;  // 2400 vertices, 7196 triangles: ~115 KB raw each
  const uint64_t raw_per_object = 8 + 4 * (3ull * 2 * kSides) + 4 * (3ull * (2 * kSides + 2 * (kSides - 2)));
  ASSERT_GE(raw_per_object * kObjects, 10 * kBudget);

  const testing::TempDir dir("mktree_bounded");
  const std::string store = dir.file("scene.mkt");
  const testing::ChildRun run = testing::RunForPeakRss([&] {
    IngestOptions opts;
    opts.store.backend = Backend::kPagedFile;
    auto r = BuildStore({[&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
                          return std::unique_ptr<SceneSource>(new HeavyPrisms(kObjects, kSides, first));
                        }},
                        store, opts);
    return r.ok() && r->objects == kObjects ? 0 : 3;
  });
  ASSERT_TRUE(run.exited);
  ASSERT_EQ(run.code, 0);
  const uint64_t peak = run.peak_rss;
  EXPECT_LE(peak, kBudget) << "peak RSS " << (peak >> 20) << " MiB for "
                           << ((raw_per_object * kObjects) >> 20) << " MiB of geometry";
  auto db = Database::Open(store);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  EXPECT_EQ((*db)->object_count(), kObjects);
  QueryResult r;
  ASSERT_TRUE((*db)->Run(Query::Point({0, 0, 12}, QueryMode::kExact), &r).ok());
  EXPECT_EQ(r.hits, std::vector<ObjectId>{0});
}

}  // namespace
}  // namespace mktree
