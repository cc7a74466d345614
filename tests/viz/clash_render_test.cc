// mktree render --clashes: a store built from an OBJ (two crossing boxes under a plate, a touching pair, a
// far box, a row of filler boxes) and a pairs file written by hand. The PNG read back shows the hard
// colour where the crossing boxes project (through the plate above them), orange where the touching pair
// does, grey at the far box; the counts per class are the file's; --focus frames the pair; every malformed
// pairs file gives an error naming the file and line, exit 1 and no picture. Both backends.
#include "engine/viz/clash_render.h"

#include <gtest/gtest.h>
#include <png.h>

#include <array>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "engine/ingest/store_builder.h"
#include "engine/scene/obj_reader.h"
#include "engine/viz/clash_pairs_file.h"
#include "engine/viz/level_export.h"
#include "test_dirs.h"
#include "tool_runner.h"
#include "viz/png_image.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

using testing::ProgramDir;
using testing::TempPath;

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

enum class Hue { kRed, kOrange, kYellow, kGrey, kWhite, kOther };
Hue HueOf(const uint8_t* p) {
  const int r = p[0], g = p[1], b = p[2];
  if (r > 240 && g > 240 && b > 240) return Hue::kWhite;
  if (std::abs(r - g) < 12 && std::abs(g - b) < 12 && r > 90) return Hue::kGrey;
  if (r > 80 && b < r / 4) {
    const double q = static_cast<double>(g) / r;
    if (q < 0.3) return Hue::kRed;
    if (q > 0.35 && q < 0.7) return Hue::kOrange;
    if (q > 0.75) return Hue::kYellow;
  }
  return Hue::kOther;
}

// Axis-aligned box as an OBJ object (8 vertices, 12 triangles); `v` counts the vertices written so far.
std::string ObjBox(const std::string& name, const Box3d& b, int* v) {
  std::string s = "o " + name + "\n";
  for (int i = 0; i < 8; ++i)
    s += "v " + std::to_string(i & 1 ? b.max[0] : b.min[0]) + " " +
         std::to_string(i & 2 ? b.max[1] : b.min[1]) + " " + std::to_string(i & 4 ? b.max[2] : b.min[2]) +
         "\n";
  static const int kFaces[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  for (const auto& f : kFaces)
    s += "f " + std::to_string(*v + f[0] + 1) + " " + std::to_string(*v + f[1] + 1) + " " +
         std::to_string(*v + f[2] + 1) + "\n";
  *v += 8;
  return s;
}

Box3d MakeBox(double x0, double y0, double z0, double x1, double y1, double z1) {
  Box3d b;
  b.Extend(x0, y0, z0);
  b.Extend(x1, y1, z1);
  return b;
}

// Ids follow the file: 0 and 1 cross, 2 and 3 touch (faces at x = 7), 4 is far, 5 is a plate above the
// crossing (nearer the viewer in the top view), 6.. a row of filler boxes (several leaves).
const Box3d kA = MakeBox(0, 0, 0, 4, 1, 1), kB = MakeBox(1.5, -1.5, 0.2, 2.5, 2.5, 0.8);
const Box3d kC = MakeBox(6, 0, 0, 7, 1, 1), kD = MakeBox(7, 0, 0, 8, 1, 1);
const Box3d kFar = MakeBox(20, 10, 0, 21, 11, 1), kPlate = MakeBox(-0.5, -2, 2, 4.5, 3, 2.2);
constexpr int kFillers = 60;
constexpr uint64_t kObjects = 6 + kFillers;

std::string SceneObj() {
  int v = 0;
  std::string s;  // appended one by one: `v` must count in file order
  for (const auto& [name, box] : {std::pair{"cross_a", kA},
                                  {"cross_b", kB},
                                  {"touch_c", kC},
                                  {"touch_d", kD},
                                  {"far", kFar},
                                  {"plate", kPlate}})
    s += ObjBox(name, box, &v);
  for (int i = 0; i < kFillers; ++i)
    s += ObjBox("filler" + std::to_string(i), MakeBox(i * 0.35, 8, 0, i * 0.35 + 0.3, 8.3, 0.3), &v);
  return s;
}

const char* kPairs =
    "{\"a\": 0, \"b\": 1, \"class\": \"hard\", \"distance\": -0.8, \"depth_lower\": 0.6, \"depth_upper\": "
    "0.8, "
    "\"point_a\": [2, 0.5, 0.5], \"point_b\": [2, 0.5, 0.5], \"meeting\": \"cross\", \"extra\": {\"x\": [1, "
    "{\"y\": null}], \"s\": \"q\\\"\\u00e9\"}}\n"
    "\n"
    "{\"b\": 3, \"a\": 2, \"class\": \"touch\", \"distance\": 0, \"depth_lower\": 0, \"depth_upper\": 0, "
    "\"point_a\": [7, 0.5, 0.5], \"point_b\": [7, 0.5, 0.5], \"meeting\": \"cross\"}\r\n"
    "{\"summary\": true, \"pairs\": 2, \"hard\": 1, \"touch\": 1, \"clearance\": 0}";

class ClashRenderTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    name_ = GetParam() == Backend::kHdf5 ? "h5" : "pf";
    obj_ = TempPath("scene.obj");
    WriteFile(obj_, SceneObj());
    store_ = TempPath("scene_" + name_ + ".mkt");
    IngestOptions o;
    o.store.backend = GetParam();
    o.store.params.block_size = 1024;
    o.store.params.blocks_per_page = 2;
    const std::string obj = obj_;
    std::vector<SceneOpener> in{[obj](ObjectId first) { return OpenObjFile(obj, first); }};
    auto built = BuildStore(in, store_, o);
    ASSERT_TRUE(built.ok()) << built.status().ToString();
    auto reader = StoreReader::Open(store_);
    ASSERT_TRUE(reader.ok()) << reader.status().ToString();
    reader_ = std::move(*reader);
    ASSERT_EQ(reader_->object_count(), kObjects);
    ASSERT_GT(reader_->tree().leaves.size(), 1u);
    pairs_ = TempPath("pairs.jsonl");
    WriteFile(pairs_, kPairs);
  }

  // The pixel where world point (x, y, z) projects.
  static const uint8_t* At(const Image& img, const ClashRenderReport& r, double x, double y, double z) {
    const double p[3] = {x, y, z};
    const int px = static_cast<int>(r.frame.X(r.frame.U(p))), py = static_cast<int>(r.frame.Y(r.frame.V(p)));
    EXPECT_TRUE(px >= 0 && py >= 0 && px < static_cast<int>(img.width) && py < static_cast<int>(img.height));
    return img.at(std::clamp<int>(px, 0, img.width - 1), std::clamp<int>(py, 0, img.height - 1));
  }

  std::string name_, obj_, store_, pairs_;
  std::unique_ptr<StoreReader> reader_;
};

TEST_P(ClashRenderTest, PairsFileCountsWorstClasses) {
  auto marks = ReadClashPairs(pairs_, kObjects);
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  EXPECT_EQ(marks->pair_count(), 2u);
  EXPECT_EQ(marks->pairs[int(ClashMark::kHard)], 1u);
  EXPECT_EQ(marks->pairs[int(ClashMark::kTouch)], 1u);
  EXPECT_EQ(marks->pairs[int(ClashMark::kClearance)], 0u);
  EXPECT_EQ(marks->other_lines, 1u);
  EXPECT_EQ(marks->objects[int(ClashMark::kHard)], 2u);
  EXPECT_EQ(marks->objects[int(ClashMark::kTouch)], 2u);
  EXPECT_EQ(marks->objects[int(ClashMark::kNone)], kObjects - 4);
  EXPECT_EQ(marks->Of(0), ClashMark::kHard);
  EXPECT_EQ(marks->Of(3), ClashMark::kTouch);
  EXPECT_EQ(marks->Of(4), ClashMark::kNone);
  EXPECT_FALSE(marks->focus);

  // An object in several pairs keeps its worst class, whatever the order.
  const std::string p = TempPath("worst.jsonl");
  WriteFile(p,
            "{\"a\": 0, \"b\": 4, \"class\": \"clearance\"}\n{\"a\": 4, \"b\": 9, \"class\": \"hard\"}\n"
            "{\"a\": 4, \"b\": 5, \"class\": \"touch\"}\n{\"a\": 0, \"b\": 9, \"class\": \"touch\"}\n");
  marks = ReadClashPairs(p, kObjects, 3);
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  EXPECT_EQ(marks->Of(0), ClashMark::kTouch);
  EXPECT_EQ(marks->Of(4), ClashMark::kHard);
  EXPECT_EQ(marks->Of(9), ClashMark::kHard);
  EXPECT_EQ(marks->Of(5), ClashMark::kTouch);
  ASSERT_TRUE(marks->focus);
  EXPECT_EQ(marks->focus->a, 4u);
  EXPECT_EQ(marks->focus->b, 5u);
  EXPECT_EQ(marks->focus->line, 3u);
  auto beyond = ReadClashPairs(p, kObjects, 5);
  ASSERT_FALSE(beyond.ok());
  EXPECT_NE(beyond.status().message().find(p + ": has 4 pairs"), std::string::npos)
      << beyond.status().message();
}

TEST_P(ClashRenderTest, HighlightsThePairsThroughTheScene) {
  auto marks = ReadClashPairs(pairs_, kObjects);
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  const std::string png = TempPath("top_" + name_ + ".png");
  ClashRenderOptions o;
  o.width = 800;
  o.height = 600;
  auto r = RenderClashes(*reader_, *marks, png, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->objects[int(ClashMark::kHard)], 2u);
  EXPECT_EQ(r->objects[int(ClashMark::kTouch)], 2u);
  EXPECT_EQ(r->objects[int(ClashMark::kClearance)], 0u);
  EXPECT_EQ(r->objects[int(ClashMark::kNone)], kObjects - 4);
  EXPECT_EQ(r->triangles, kObjects * 12);
  const Image img = ReadPng(png);
  ASSERT_EQ(img.width, 800u);
  ASSERT_EQ(img.height, 600u);
  // The crossing: red, though the plate (not in a pair) lies above it; where A and B cross, where only A
  // is and where only B is.
  EXPECT_EQ(HueOf(At(img, *r, 2.0, 0.5, 2.2)), Hue::kRed);
  EXPECT_EQ(HueOf(At(img, *r, 0.7, 0.5, 2.2)), Hue::kRed);
  EXPECT_EQ(HueOf(At(img, *r, 2.0, -1.0, 2.2)), Hue::kRed);
  // The plate beside the boxes: grey. The touching pair: orange. The far box and a filler: grey.
  EXPECT_EQ(HueOf(At(img, *r, 4.2, 2.7, 2.2)), Hue::kGrey);
  EXPECT_EQ(HueOf(At(img, *r, 6.5, 0.5, 1)), Hue::kOrange);
  EXPECT_EQ(HueOf(At(img, *r, 7.5, 0.5, 1)), Hue::kOrange);
  EXPECT_EQ(HueOf(At(img, *r, 20.5, 10.5, 1)), Hue::kGrey);
  EXPECT_EQ(HueOf(At(img, *r, 10 * 0.35 + 0.15, 8.15, 0.3)), Hue::kGrey);
  // Between the objects: background.
  EXPECT_EQ(HueOf(At(img, *r, 14, 5, 0)), Hue::kWhite);
  // No yellow in the picture area (no clearance pair); the legend shows its swatch.
  uint64_t yellow = 0, red = 0;
  const int legend_top = static_cast<int>(r->frame.Y(r->framed.min[1])) + 2;
  for (int y = 0; y < legend_top; ++y)
    for (int x = 0; x < static_cast<int>(img.width); ++x) {
      yellow += HueOf(img.at(x, y)) == Hue::kYellow;
      red += HueOf(img.at(x, y)) == Hue::kRed;
    }
  EXPECT_EQ(yellow, 0u);
  // A and B cover 4 + 4 - 1 = 7 square units.
  const double expect_red = 7 * r->pixels_per_metre * r->pixels_per_metre;
  EXPECT_GT(red, 0.8 * expect_red);
  EXPECT_LT(red, 1.2 * expect_red);
  uint64_t legend_yellow = 0;
  for (int y = legend_top; y < static_cast<int>(img.height); ++y)
    for (int x = 0; x < static_cast<int>(img.width); ++x)
      legend_yellow += HueOf(img.at(x, y)) == Hue::kYellow;
  EXPECT_GT(legend_yellow, 20u);

  // Side view (x right, z up, looking along +y): B's end (y = -1.5) is nearest, the plate above.
  o.view = RenderView::kSide;
  r = RenderClashes(*reader_, *marks, png, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const Image side = ReadPng(png);
  EXPECT_EQ(HueOf(At(side, *r, 2.0, 0, 0.5)), Hue::kRed);
  EXPECT_EQ(HueOf(At(side, *r, 0.5, 0, 0.5)), Hue::kRed);
  EXPECT_EQ(HueOf(At(side, *r, 2.0, 0, 2.1)), Hue::kGrey);
  EXPECT_EQ(HueOf(At(side, *r, 6.5, 0, 0.5)), Hue::kOrange);
}

TEST_P(ClashRenderTest, FocusFramesThePair) {
  auto marks = ReadClashPairs(pairs_, kObjects, 1);
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  const std::string png = TempPath("focus_" + name_ + ".png");
  ClashRenderOptions o;
  o.width = 600;
  o.height = 600;
  o.focus = true;
  auto r = RenderClashes(*reader_, *marks, png, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  // The union of A and B: x 0..4, y -1.5..2.5.
  EXPECT_FLOAT_EQ(r->pair_box.min[0], 0);
  EXPECT_FLOAT_EQ(r->pair_box.max[0], 4);
  EXPECT_FLOAT_EQ(r->pair_box.min[1], -1.5);
  EXPECT_FLOAT_EQ(r->pair_box.max[1], 2.5);
  const Image img = ReadPng(png);
  uint64_t red = 0, orange = 0;
  int x0 = 1 << 30, x1 = -1, y0 = 1 << 30, y1 = -1;
  for (int y = 0; y < 600; ++y)
    for (int x = 0; x < 600; ++x) {
      const Hue h = HueOf(img.at(x, y));
      if (h == Hue::kRed) {
        ++red;
        x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
      }
      orange += h == Hue::kOrange;
    }
  // The pair covers a large part of the picture: its projection (4 x 4 units) spans most of the width
  // and height, and its 7 square units are over a sixth of the whole image.
  EXPECT_GT(x1 - x0, 0.6 * 600);
  EXPECT_GT(y1 - y0, 0.45 * 600);
  EXPECT_GT(static_cast<double>(red), 600.0 * 600 / 6);
  // The touching pair, right of x = 6 (beyond the frame's 4 + 0.6), is not in the picture; the
  // legend's swatch is the only orange.
  EXPECT_LT(orange, 20u * 20u);
  EXPECT_GT(r->pixels_per_metre, 80);

  // The whole scene at the same size is much smaller.
  o.focus = false;
  auto whole = RenderClashes(*reader_, *marks, png, o);
  ASSERT_TRUE(whole.ok());
  EXPECT_GT(r->pixels_per_metre, 3 * whole->pixels_per_metre);
}

TEST_P(ClashRenderTest, ToolPrintsCountsAndRefusesMalformedPairs) {
  const fs::path scratch = ProgramDir().path();
  const std::string png = TempPath("tool_" + name_ + ".png");
  auto run = testing::RunMktree(
      "render " + store_ + " --clashes " + pairs_ + " -o " + png + " --size 500x400", scratch);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.out.find("2 pairs (1 other lines)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("hard                 1 pairs            2 objects"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("touch                1 pairs            2 objects"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("clearance            0 pairs            0 objects"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find(std::to_string(kObjects - 4) + " objects"), std::string::npos) << run.out;
  ASSERT_TRUE(fs::exists(png));
  fs::remove(png);
  run = testing::RunMktree("render " + store_ + " --clashes " + pairs_ + " -o " + png + " --focus 2 -q",
                           scratch);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_TRUE(fs::exists(png));
  fs::remove(png);

  const std::string good = "{\"a\": 0, \"b\": 1, \"class\": \"hard\"}\n";
  const struct {
    std::string line, why;
  } cases[] = {
      {"not json", "not a pair line"},
      {"[0, 1]", "not a JSON object"},
      {"{\"a\": 0, \"b\": 1, \"class\": \"hard\"", "expected ',' or '}'"},
      {"{\"a\": 0, \"b\": 1, \"class\": \"hard\"} x", "text after the JSON object"},
      {"{\"a\": 0, \"b\": 1, \"class\": \"hard\", \"d\": nan}", "expected a JSON value"},
      {"{\"a\": 0, \"b\": 66, \"class\": \"hard\"}", "b = 66 is not an object of the store, which has 66"},
      {"{\"a\": 99999999999999999999999, \"b\": 1, \"class\": \"hard\"}", "is not an object id"},
      {"{\"a\": -1, \"b\": 1, \"class\": \"hard\"}", "a = -1 is not an object id"},
      {"{\"a\": 0.5, \"b\": 1, \"class\": \"hard\"}", "a = 0.5 is not an object id"},
      {"{\"a\": \"0\", \"b\": 1, \"class\": \"hard\"}", "a = \"0\" is not an object id"},
      {"{\"a\": 3, \"b\": 2, \"class\": \"hard\"}", "a = 3 and b = 2: a pair has a < b"},
      {"{\"a\": 2, \"b\": 2, \"class\": \"touch\"}", "a = 2 and b = 2: a pair has a < b"},
      {"{\"a\": 0, \"b\": 1, \"class\": \"severe\"}", "class severe is not"},
      {"{\"a\": 0, \"b\": 1, \"class\": 3}", "class 3 is not"},
      {"{\"a\": 0, \"b\": 1}", "a pair line without \"class\""},
      {"{\"a\": 0, \"class\": \"hard\"}", "a pair line without \"b\""},
      {"{\"a\": 0, \"a\": 0, \"b\": 1, \"class\": \"hard\"}", "key \"a\" given twice"},
      {"{\"a\": 0, \"b\": 1, \"class\": \"hard\", \"s\": \"\\x\"}", "expected a JSON value"},
      {"{\"a\": 0, \"b\": 1, \"class\": \"hard\", \"v\": [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[["
       "[[[[[[[[[[[[[[[[[[[[]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]}",
       "expected a JSON value"},
      {std::string(3 << 20, ' '), "longer than"},
  };
  for (const auto& c : cases) {
    const std::string bad = TempPath("bad.jsonl");
    WriteFile(bad, good + "\n" + c.line + "\n" + good);
    run = testing::RunMktree("render " + store_ + " --clashes " + bad + " -o " + png, scratch);
    EXPECT_EQ(run.code, 1) << c.line.substr(0, 80);
    EXPECT_NE(run.err.find(bad + ":3: "), std::string::npos) << c.line.substr(0, 80) << "\n" << run.err;
    EXPECT_NE(run.err.find(c.why), std::string::npos) << c.line.substr(0, 80) << "\n" << run.err;
    EXPECT_FALSE(fs::exists(png)) << c.line.substr(0, 80);
    EXPECT_EQ(run.out, "");
  }
  // Files that cannot be used as a whole: errors naming the file.
  run =
      testing::RunMktree("render " + store_ + " --clashes " + pairs_ + " -o " + png + " --focus 3", scratch);
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find(pairs_ + ": has 2 pairs; there is no pair 3"), std::string::npos) << run.err;
  const std::string missing = TempPath("missing.jsonl");
  run = testing::RunMktree("render " + store_ + " --clashes " + missing + " -o " + png, scratch);
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find(missing + ": cannot open"), std::string::npos) << run.err;
  run = testing::RunMktree("render " + store_ + " --clashes " + pairs_ + " --level 1 -o " + png, scratch);
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find("exactly one"), std::string::npos) << run.err;
  run = testing::RunMktree("render " + store_ + " --level 1 --focus 1 -o " + png, scratch);
  EXPECT_EQ(run.code, 1);
  EXPECT_FALSE(fs::exists(png));
  // --level alone still works.
  run = testing::RunMktree("render " + store_ + " --level 1 -o " + png + " -q", scratch);
  EXPECT_EQ(run.code, 0) << run.err;
  EXPECT_TRUE(fs::exists(png));
  fs::remove(png);
}

// export --clashes: the PLY's vertex colours are the clash colours, each where its objects are; the GLB has
// one mesh per class present.
TEST_P(ClashRenderTest, ExportColoursVerticesByClass) {
  auto marks = ReadClashPairs(pairs_, kObjects);
  ASSERT_TRUE(marks.ok()) << marks.status().ToString();
  const std::string ply = TempPath("clash_" + name_ + ".ply"), glb = TempPath("clash_" + name_ + ".glb");
  ExportOptions o;
  o.clashes = &*marks;
  auto r = ExportLevel(*reader_, ply, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->objects[int(ClashMark::kHard)], 2u);
  EXPECT_EQ(r->objects[int(ClashMark::kTouch)], 2u);
  EXPECT_EQ(r->objects[int(ClashMark::kClearance)], 0u);
  EXPECT_EQ(r->objects[int(ClashMark::kNone)], kObjects - 4);
  const std::string text = testing::Slurp(ply);
  const std::string end = "end_header\n";
  const size_t body = text.find(end);
  ASSERT_NE(body, std::string::npos);
  EXPECT_NE(text.find("comment mktree export: clashes"), std::string::npos);
  const uint64_t nv = r->total_vertices();
  ASSERT_GE(text.size(), body + end.size() + 15 * nv);
  std::array<uint64_t, kClashMarks> seen{};
  for (uint64_t i = 0; i < nv; ++i) {
    const char* v = text.data() + body + end.size() + 15 * i;
    float xyz[3];
    std::memcpy(xyz, v, 12);
    const Rgb c{static_cast<uint8_t>(v[12]), static_cast<uint8_t>(v[13]), static_cast<uint8_t>(v[14])};
    int cls = -1;
    for (int k = 0; k < kClashMarks; ++k)
      if (c == ClashColour(static_cast<ClashMark>(k))) cls = k;
    ASSERT_GE(cls, 0) << "vertex " << i << " has a colour of no class";
    ++seen[cls];
    auto inside = [&](const Box3d& b) {
      for (int k = 0; k < 3; ++k)
        if (xyz[k] < b.min[k] - 1e-4 || xyz[k] > b.max[k] + 1e-4) return false;
      return true;
    };
    if (cls == int(ClashMark::kHard)) {
      EXPECT_TRUE(inside(kA) || inside(kB)) << xyz[0] << " " << xyz[1];
    }
    if (cls == int(ClashMark::kTouch)) {
      EXPECT_TRUE(inside(kC) || inside(kD)) << xyz[0] << " " << xyz[1];
    }
  }
  for (int k = 0; k < kClashMarks; ++k) EXPECT_EQ(seen[k], r->vertices[k]) << k;
  EXPECT_GT(seen[int(ClashMark::kHard)], 0u);

  o.boxes = true;
  o.format = ExportFormat::kGlb;
  r = ExportLevel(*reader_, glb, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->vertices[int(ClashMark::kHard)], 16u);
  const std::string g = testing::Slurp(glb);
  EXPECT_NE(g.find("\"name\":\"hard\""), std::string::npos);
  EXPECT_NE(g.find("\"name\":\"touch\""), std::string::npos);
  EXPECT_NE(g.find("\"name\":\"no_clash\""), std::string::npos);
  EXPECT_EQ(g.find("\"name\":\"clearance\""), std::string::npos);
  EXPECT_NE(g.find("mktree export (clashes)"), std::string::npos);

  // The tool: counts on stdout; a malformed pairs file leaves no output.
  const fs::path scratch = ProgramDir().path();
  fs::remove(ply);
  auto run = testing::RunMktree("export " + store_ + " --clashes " + pairs_ + " -o " + ply, scratch);
  ASSERT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.out.find("(hard 2, touch 2, clearance 0, no clash " + std::to_string(kObjects - 4) + ")"),
            std::string::npos)
      << run.out;
  fs::remove(ply);
  const std::string bad = TempPath("bad_export.jsonl");
  WriteFile(bad, "{\"a\": 5, \"b\": 4, \"class\": \"hard\"}\n");
  run = testing::RunMktree("export " + store_ + " --clashes " + bad + " -o " + ply, scratch);
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find(bad + ":1: a = 5 and b = 4"), std::string::npos) << run.err;
  EXPECT_FALSE(fs::exists(ply));
  run = testing::RunMktree("export " + store_ + " -o " + ply, scratch);
  EXPECT_EQ(run.code, 1);
  EXPECT_NE(run.err.find("exactly one"), std::string::npos) << run.err;
}

INSTANTIATE_TEST_SUITE_P(Backends, ClashRenderTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const ::testing::TestParamInfo<Backend>& i) {
                           return std::string(i.param == Backend::kHdf5 ? "Hdf5" : "PagedFile");
                         });

}  // namespace
}  // namespace mktree
