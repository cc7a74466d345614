// mktree render: the PNG read back with libpng has the requested size and shows the level-k colouring
// where it should: two well-separated clusters at level 0 come out blue (left) and red (right) in about
// equal areas; bars across the split come out green; a level below every leaf is all grey; the object
// counts per group equal GroupAtLevel over the scene's own objects. Errors leave no file.
#include "engine/viz/level_render.h"

#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <filesystem>

#include "engine/ingest/store_builder.h"
#include "engine/scene/vector_scene_source.h"
#include "query/scene_fixtures.h"
#include "test_dirs.h"
#include "viz/png_image.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::TempPath;

// Pixels of the picture area (above the legend strip) by dominant hue.
struct Tally {
  uint64_t blue = 0, red = 0, green = 0, grey = 0;
  double blue_x = 0, red_x = 0;  // mean column
};
Tally Classify(const Image& img, uint32_t rows) {
  Tally t;
  for (uint32_t y = 0; y < rows; ++y)
    for (uint32_t x = 0; x < img.width; ++x) {
      const int r = img.at(x, y)[0], g = img.at(x, y)[1], b = img.at(x, y)[2];
      if (b > r + 40 && b > g + 40)
        ++t.blue, t.blue_x += x;
      else if (r > g + 40 && r > b + 40)
        ++t.red, t.red_x += x;
      else if (g > r + 40 && g > b + 40)
        ++t.green;
      else if (std::abs(r - g) < 12 && std::abs(g - b) < 12 && r < 235 && r > 30)
        ++t.grey;
    }
  if (t.blue) t.blue_x /= static_cast<double>(t.blue);
  if (t.red) t.red_x /= static_cast<double>(t.red);
  return t;
}

// Two clusters of boxes, x in [0, 10] and [50, 60]; with `bars`, long thin bars across both.
std::vector<SceneObject> TwoClusters(bool bars) {
  std::vector<SceneObject> objs;
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(0, 1);
  for (int c = 0; c < 2; ++c)
    for (int i = 0; i < 150; ++i) {
      Box3d b;
      const double x = c * 50 + u(rng) * 9, y = u(rng) * 9, z = u(rng) * 2;
      b.Extend(x, y, z);
      b.Extend(x + 0.5 + u(rng) * 0.5, y + 0.5 + u(rng) * 0.5, z + 0.2 + u(rng) * 0.5);
      SceneObject o;
      o.name = "box";
      o.mesh = testing::BoxMesh(b);
      objs.push_back(std::move(o));
    }
  if (bars)
    for (int i = 0; i < 6; ++i) {
      Box3d b;
      b.Extend(5, 1 + i * 1.4, 3);
      b.Extend(55, 1.6 + i * 1.4, 3.3);
      SceneObject o;
      o.name = "bar";
      o.mesh = testing::BoxMesh(b);
      objs.push_back(std::move(o));
    }
  for (size_t i = 0; i < objs.size(); ++i) objs[i].id = static_cast<ObjectId>(i);
  return objs;
}

std::unique_ptr<StoreReader> BuildReader(const std::vector<SceneObject>& objs, const std::string& path) {
  IngestOptions o;
  o.store.backend = Backend::kPagedFile;
  o.store.params.block_size = 1024;
  o.store.params.blocks_per_page = 2;
  std::vector<SceneOpener> in{[&objs](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(new VectorSceneSource(&objs, first));
  }};
  auto r = BuildStore(in, path, o);
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  auto reader = StoreReader::Open(path);
  EXPECT_TRUE(reader.ok()) << reader.status().ToString();
  return reader.ok() ? std::move(*reader) : nullptr;
}

GroupCounts Expect(const StoreReader& r, const std::vector<SceneObject>& objs, int k) {
  GroupCounts c{};
  for (const SceneObject& o : objs) ++c[GroupIndex(GroupAtLevel(r.tree(), *r.ObjectLeaf(o.id), o.Aabb(), k))];
  return c;
}

constexpr uint32_t kW = 600, kH = 300, kPictureRows = kH - 60;  // the legend lies below kPictureRows

TEST(LevelRenderTest, TwoClustersAtLevelZeroAreBlueAndRed) {
  const std::string store = TempPath("two.mkt"), png = TempPath("two.png");
  const auto objs = TwoClusters(false);
  auto reader = BuildReader(objs, store);
  ASSERT_TRUE(reader);
  ASSERT_FALSE(reader->tree().nodes[0].is_leaf());
  RenderOptions o;
  o.width = kW;
  o.height = kH;
  auto report = RenderLevel(*reader, png, o);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  EXPECT_EQ(report->objects, Expect(*reader, objs, 0));
  EXPECT_EQ(report->objects[0], 150u);
  EXPECT_EQ(report->objects[1], 150u);
  EXPECT_EQ(report->triangles, 300u * 12);

  const Image img = ReadPng(png);
  ASSERT_EQ(img.width, kW);
  ASSERT_EQ(img.height, kH);
  const Tally t = Classify(img, kPictureRows);
  EXPECT_GT(t.blue, 1000u);
  EXPECT_GT(t.red, 1000u);
  EXPECT_LT(t.green, 10u);  // disjoint children at the root: no overlap set
  const double ratio = static_cast<double>(t.blue) / static_cast<double>(t.red);
  EXPECT_GT(ratio, 0.67);
  EXPECT_LT(ratio, 1.5);
  EXPECT_LT(t.blue_x, kW / 2.0);  // left cluster blue
  EXPECT_GT(t.red_x, kW / 2.0);   // right cluster red
  // The legend shows all four swatches.
  const Tally legend = Classify(Image{img.width, img.height, img.rgb}, kH);
  EXPECT_GT(legend.green, t.green);

  // Looking along -x from the bow, the right cluster (nearer) hides the left one.
  o.view = RenderView::kFront;
  ASSERT_TRUE(RenderLevel(*reader, png, o).ok());
  const Tally front = Classify(ReadPng(png), kPictureRows);
  EXPECT_GT(front.red, 4 * front.blue);
  o.view = RenderView::kSide;
  o.overlay = true;
  ASSERT_TRUE(RenderLevel(*reader, png, o).ok());
  const Tally side = Classify(ReadPng(png), kPictureRows);
  EXPECT_GT(side.blue, 500u);
  EXPECT_GT(side.red, 500u);
  fs::remove(store);
  fs::remove(png);
}

TEST(LevelRenderTest, BarsAcrossTheSplitAreGreenAndDeepLevelsGrey) {
  const std::string store = TempPath("bars.mkt"), png = TempPath("bars.png");
  const auto objs = TwoClusters(true);
  auto reader = BuildReader(objs, store);
  ASSERT_TRUE(reader);
  RenderOptions o;
  o.width = kW;
  o.height = kH;
  o.overlay = true;
  auto report = RenderLevel(*reader, png, o);
  ASSERT_TRUE(report.ok()) << report.status().ToString();
  const GroupCounts expect = Expect(*reader, objs, 0);
  EXPECT_EQ(report->objects, expect);
  ASSERT_GT(expect[GroupIndex(LevelGroup::kOverlap)], 0u);
  // The bars lie on top (z 3..3.3) and are long: a good share of the picture is green.
  const Tally t = Classify(ReadPng(png), kPictureRows);
  EXPECT_GT(t.green, 2000u);
  EXPECT_GT(t.blue, 300u);
  EXPECT_GT(t.red, 300u);

  o.level = 64;  // below every leaf: all grey
  o.overlay = false;
  report = RenderLevel(*reader, png, o);
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->objects[GroupIndex(LevelGroup::kAboveLevel)], objs.size());
  const Tally g = Classify(ReadPng(png), kPictureRows);
  EXPECT_EQ(g.blue + g.red + g.green, 0u);
  EXPECT_GT(g.grey, 3000u);
  fs::remove(store);
  fs::remove(png);
}

TEST(LevelRenderTest, ErrorsLeaveNothing) {
  const std::string store = TempPath("err.mkt");
  const auto objs = TwoClusters(false);
  auto reader = BuildReader(objs, store);
  ASSERT_TRUE(reader);
  const std::string png = TempPath("err.png");
  RenderOptions o;
  o.level = -1;
  EXPECT_FALSE(RenderLevel(*reader, png, o).ok());
  o.level = 0;
  o.width = 32;
  EXPECT_FALSE(RenderLevel(*reader, png, o).ok());
  o.width = 64;
  o.height = 20000;
  EXPECT_FALSE(RenderLevel(*reader, png, o).ok());
  EXPECT_FALSE(fs::exists(png));
  o.width = 400;
  o.height = 200;
  const std::string bad = TempPath("no_such_dir") + "/x.png";
  auto r = RenderLevel(*reader, bad, o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(bad), std::string::npos) << r.status().message();
  fs::remove(store);
}

}  // namespace
}  // namespace mktree
