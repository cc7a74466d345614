// The STEP reader (engine/scene/step_reader.h) on the test assembly that tests/step/writer wrote
// (tests/data/step/engine_assembly.step, layout in step_assembly_layout.h): every leaf solid once per
// instance, named by its assembly path and placed by its instances' locations (boxes against the layout's
// in metres), colours and products as attributes, closed meshes for solids, the chord tolerance kept on a
// cylinder, the round trip through `mktree build` and `mktree info --object`, and bad input.
#include "engine/scene/step_reader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "engine/geometry/mesh_edges.h"
#include "engine/geometry/solid_classifier.h"
#include "engine/scene/scene_source.h"
#include "step/writer/step_assembly_layout.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

namespace layout = step_test;

const std::string kAssembly = std::string(MKTREE_TESTS_DIR) + "/data/step/engine_assembly.step";
constexpr double kMm = 0.001;

std::vector<SceneObject> ReadAll(const std::string& path, const SceneReadOptions& options = {},
                                 std::vector<std::string>* warnings = nullptr, ObjectId first_id = 0) {
  auto source = OpenSceneFile(path, first_id, options);
  EXPECT_TRUE(source.ok()) << source.status().ToString();
  std::vector<SceneObject> out;
  if (!source.ok()) return out;
  for (;;) {
    SceneObject obj;
    auto more = (*source)->Next(&obj);
    EXPECT_TRUE(more.ok()) << more.status().ToString();
    if (!more.ok() || !*more) break;
    out.push_back(std::move(obj));
  }
  if (warnings) *warnings = (*source)->TakeWarnings();
  return out;
}

std::vector<std::string> Values(const SceneObject& obj, const std::string& key) {
  std::vector<std::string> out;
  for (const ObjectAttribute& a : obj.attributes)
    if (a.key == key) out.push_back(a.value);
  return out;
}

Box3d Metres(const layout::BoxMm& b, const std::array<double, 3>& at, bool quarter_turn = false) {
  double x0 = b.x0, y0 = b.y0, x1 = b.x1, y1 = b.y1;
  if (quarter_turn) {  // (x, y) -> (-y, x)
    x0 = -b.y1, x1 = -b.y0, y0 = b.x0, y1 = b.x1;
  }
  return Box3d{{(x0 + at[0]) * kMm, (y0 + at[1]) * kMm, (b.z0 + at[2]) * kMm},
               {(x1 + at[0]) * kMm, (y1 + at[1]) * kMm, (b.z1 + at[2]) * kMm}};
}

std::array<double, 3> Plus(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}

// What the layout says each object is: its name, box (metres), colours, product, closed or not.
struct Expected {
  std::string name;
  Box3d box;
  std::vector<std::string> colours;
  std::string product;
  bool solid;
  double slack;  // how far inside its layout box a tessellated object's box may lie (curved faces)
};

std::vector<Expected> ExpectedObjects(double chord) {
  std::vector<Expected> out;
  out.push_back({"engine/block", Metres(layout::kBlock, layout::kBlockAt), {"#cc2020"}, "block", true, 0});
  const double r = layout::kHeadRadius;
  for (int i = 0; i < layout::kPistons; ++i) {
    const std::string piston = "engine/piston[" + std::to_string(i + 1) + "]";
    const bool turn = layout::PistonTurned(i);
    out.push_back({piston + "/head",
                   Metres({-r, -r, 0, r, r, layout::kHeadHeight}, layout::PistonAt(i), turn),
                   {"#2040e0"},
                   "head",
                   true,
                   chord});
    out.push_back({piston + "/rod",
                   Metres(layout::kRod, Plus(layout::PistonAt(i), layout::kRodAt), turn),
                   {},
                   "rod",
                   true,
                   0});
  }
  out.push_back({"engine/bracket/solid[1]",
                 Metres(layout::kBracketA, layout::kBracketAt),
                 {"#20a040"},
                 "bracket",
                 true,
                 0});
  out.push_back({"engine/bracket/solid[2]",
                 Metres(layout::kBracketB, layout::kBracketAt),
                 {"#20a040"},
                 "bracket",
                 true,
                 0});
  out.push_back({"engine/cover", Metres(layout::kCover, layout::kCoverAt), {}, "cover", false, 0});
  out.push_back({"engine/sheet", Metres(layout::kSheet, layout::kSheetAt), {}, "sheet", false, 0});
  return out;
}

TEST(StepReader, EveryLeafOncePerInstanceNamedByItsPath) {
  const SceneReadOptions options;
  const std::vector<SceneObject> objects = ReadAll(kAssembly, options);
  const std::vector<Expected> expected = ExpectedObjects(options.chord_tolerance);
  ASSERT_EQ(objects.size(), expected.size());
  for (size_t i = 0; i < objects.size(); ++i) {
    SCOPED_TRACE(expected[i].name);
    const SceneObject& obj = objects[i];
    EXPECT_EQ(obj.id, i);
    EXPECT_EQ(obj.name, expected[i].name);
    EXPECT_EQ(obj.source, kAssembly);
    EXPECT_EQ(Values(obj, "step_path"), std::vector<std::string>{expected[i].name});
    EXPECT_EQ(Values(obj, "step_product"), std::vector<std::string>{expected[i].product});
    EXPECT_EQ(Values(obj, "step_colour"), expected[i].colours);
    EXPECT_EQ(Values(obj, "step_schema"), std::vector<std::string>{"AUTOMOTIVE_DESIGN"});
    const Box3d got = obj.mesh.Bounds(), want = expected[i].box;
    const double slack = expected[i].slack + 1e-9;
    for (int a = 0; a < 3; ++a) {
      // Vertices lie on the faces: the box is the layout's, or inside it by at most the chord tolerance.
      EXPECT_LE(got.min[a], want.min[a] + slack) << "axis " << a;
      EXPECT_GE(got.min[a], want.min[a] - 1e-9) << "axis " << a;
      EXPECT_GE(got.max[a], want.max[a] - slack) << "axis " << a;
      EXPECT_LE(got.max[a], want.max[a] + 1e-9) << "axis " << a;
    }
  }
}

TEST(StepReader, IdsStartAtTheFirstIdGiven) {
  const std::vector<SceneObject> objects = ReadAll(kAssembly, {}, nullptr, 40);
  ASSERT_FALSE(objects.empty());
  for (size_t i = 0; i < objects.size(); ++i) EXPECT_EQ(objects[i].id, 40 + i);
}

TEST(StepReader, SolidsAreClosedAndClassifyPoints) {
  const std::vector<SceneObject> objects = ReadAll(kAssembly);
  const std::vector<Expected> expected = ExpectedObjects(SceneReadOptions{}.chord_tolerance);
  ASSERT_EQ(objects.size(), expected.size());
  for (size_t i = 0; i < objects.size(); ++i) {
    SCOPED_TRACE(objects[i].name);
    EXPECT_EQ(IsClosedMesh(objects[i].mesh), expected[i].solid);
    if (!expected[i].solid) continue;
    const SolidClassifier inside(objects[i].mesh);
    const Box3d b = expected[i].box;
    const Vec3d centre{(b.min[0] + b.max[0]) / 2, (b.min[1] + b.max[1]) / 2, (b.min[2] + b.max[2]) / 2};
    EXPECT_TRUE(inside.Contains(centre));
    EXPECT_FALSE(inside.Contains(Vec3d{b.max[0] + 0.001, centre.y, centre.z}));
    EXPECT_FALSE(inside.Contains(Vec3d{centre.x, centre.y, b.min[2] - 0.001}));
  }
}

// The largest distance between the head cylinder's side triangles and the cylinder (radius r about the
// axis through (cx, cy) along z): sampled on a barycentric grid of each triangle.
double CylinderDeviation(const Mesh& mesh, double cx, double cy, double r, double z0, double z1) {
  double worst = 0;
  for (size_t t = 0; t < mesh.triangle_count(); ++t) {
    Vec3d p[3];
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.triangles[3 * t + k];
      p[k] = {mesh.vertices[3 * v], mesh.vertices[3 * v + 1], mesh.vertices[3 * v + 2]};
    }
    const bool cap = std::abs(p[0].z - p[1].z) < 1e-12 && std::abs(p[1].z - p[2].z) < 1e-12 &&
                     (std::abs(p[0].z - z0) < 1e-12 || std::abs(p[0].z - z1) < 1e-12);
    if (cap) continue;  // the flat ends lie on their planes
    constexpr int kSteps = 16;
    for (int i = 0; i <= kSteps; ++i)
      for (int j = 0; i + j <= kSteps; ++j) {
        const double a = double(i) / kSteps, b = double(j) / kSteps, c = 1 - a - b;
        const double x = a * p[0].x + b * p[1].x + c * p[2].x, y = a * p[0].y + b * p[1].y + c * p[2].y;
        worst = std::max(worst, std::abs(std::hypot(x - cx, y - cy) - r));
      }
  }
  return worst;
}

TEST(StepReader, ChordToleranceBoundsTheCylindersDeviation) {
  const std::array<double, 3> at = layout::PistonAt(0);
  const double r = layout::kHeadRadius * kMm, z0 = at[2] * kMm, z1 = (at[2] + layout::kHeadHeight) * kMm;
  size_t previous_triangles = 0;
  for (double chord : {0.003, 0.001, 0.0003, 0.0001, 0.00003}) {
    SCOPED_TRACE("chord tolerance " + std::to_string(chord));
    SceneReadOptions options;
    options.chord_tolerance = chord;
    options.angular_deflection = 3;  // the chord tolerance decides
    const std::vector<SceneObject> objects = ReadAll(kAssembly, options);
    auto head = std::find_if(objects.begin(), objects.end(),
                             [](const SceneObject& o) { return o.name == "engine/piston[1]/head"; });
    ASSERT_NE(head, objects.end());
    const double deviation = CylinderDeviation(head->mesh, at[0] * kMm, at[1] * kMm, r, z0, z1);
    EXPECT_LE(deviation, chord);
    EXPECT_GT(deviation, chord / 4);                             // the tolerance is used, not merely kept
    EXPECT_GT(head->mesh.triangle_count(), previous_triangles);  // finer with every step
    previous_triangles = head->mesh.triangle_count();
    EXPECT_TRUE(IsClosedMesh(head->mesh));
  }
}

TEST(StepReader, BadTessellationOptionsAreRefused) {
  for (double bad : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
    SceneReadOptions options;
    options.chord_tolerance = bad;
    auto source = OpenSceneFile(kAssembly, 0, options);
    ASSERT_FALSE(source.ok());
    EXPECT_EQ(source.status().code(), Status::Code::kInvalidArgument);
    EXPECT_NE(source.status().message().find(kAssembly), std::string::npos);
    options = SceneReadOptions{};
    options.angular_deflection = bad;
    EXPECT_FALSE(OpenSceneFile(kAssembly, 0, options).ok());
  }
}

TEST(StepReader, ExtensionsAnyCase) {
  testing::TempDir dir("step_ext");
  for (const char* name : {"a.STEP", "b.Stp", "c.stp"}) {
    std::filesystem::copy_file(kAssembly, dir / name);
    EXPECT_EQ(ReadAll(dir.file(name)).size(), ExpectedObjects(0).size()) << name;
  }
}

void Write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

std::string Slurp(const std::string& path) { return testing::Slurp(path); }

// Each bad file: OpenSceneFile fails naming the file (and `says`), and `mktree build` exits non-zero,
// names it, and leaves no store.
void ExpectRefused(const testing::TempDir& dir, const std::string& name, const std::string& text,
                   const std::string& says) {
  SCOPED_TRACE(name);
  const std::string path = dir.file(name);
  Write(path, text);
  auto source = OpenSceneFile(path, 0, SceneReadOptions{});
  ASSERT_FALSE(source.ok());
  EXPECT_NE(source.status().message().find(path), std::string::npos) << source.status().ToString();
  EXPECT_NE(source.status().message().find(says), std::string::npos) << source.status().ToString();
  const std::string store = dir.file(name + ".mkt");
  auto run = testing::RunMktree("build " + path + " -o " + store + " -q", dir.path());
  EXPECT_NE(run.code, 0);
  EXPECT_NE(run.err.find(path), std::string::npos) << run.err;
  EXPECT_NE(run.err.find(says), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(store));
}

TEST(StepReader, BadInputIsRefusedNamingTheFile) {
  testing::TempDir dir("step_bad");
  const std::string whole = Slurp(kAssembly);
  ExpectRefused(dir, "truncated.step", whole.substr(0, whole.size() / 2), "cannot");
  ExpectRefused(dir, "not_step.step", "solid cube\nendsolid cube\n", "not a STEP file");
  ExpectRefused(dir, "empty_file.stp", "", "not a STEP file");
  const std::string header = whole.substr(0, whole.find("DATA;"));
  ExpectRefused(dir, "empty_data.step", header + "DATA;\nENDSEC;\nEND-ISO-10303-21;\n", "no shape");
  std::string ifc = header;
  ifc.replace(ifc.find("AUTOMOTIVE_DESIGN"), 17, "IFC2X3");
  ExpectRefused(dir, "ifc_schema.step", ifc + "DATA;\nENDSEC;\nEND-ISO-10303-21;\n", "schema IFC2X3");
}

// Replaces every `from` in `text` by `to`; expects at least one.
std::string ReplaceAll(std::string text, const std::string& from, const std::string& to) {
  size_t n = 0;
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()), ++n)
    text.replace(at, from.size(), to);
  EXPECT_GT(n, 0u) << from;
  return text;
}

TEST(StepReader, FileUnitsBecomeMetres) {
  testing::TempDir dir("step_units");
  const std::string metres = dir.file("metres.step");
  Write(metres, ReplaceAll(Slurp(kAssembly), "SI_UNIT(.MILLI.,.METRE.)", "SI_UNIT($,.METRE.)"));
  const std::vector<SceneObject> in_mm = ReadAll(kAssembly), in_m = ReadAll(metres);
  ASSERT_EQ(in_m.size(), in_mm.size());
  ASSERT_EQ(in_m[0].name, "engine/block");
  const Box3d block = in_m[0].mesh.Bounds(), want = Metres(layout::kBlock, layout::kBlockAt);
  for (int a = 0; a < 3; ++a) {
    EXPECT_DOUBLE_EQ(block.min[a], 1000 * want.min[a]);
    EXPECT_DOUBLE_EQ(block.max[a], 1000 * want.max[a]);
  }
}

// A face whose corners are one point: the mesher gives it no triangle. The sheet is left out and
// reported by path and product; the rest is read, and `mktree build` builds it.
TEST(StepReader, ShapeWithoutTrianglesIsReportedAndTheRestRead) {
  testing::TempDir dir("step_sliver");
  const std::string path = dir.file("sliver.step");
  std::string text = Slurp(kAssembly);
  // The sheet's corners (entities of engine_assembly.step) moved onto its first corner, the origin.
  for (const char* corner :
       {"#1907 = CARTESIAN_POINT('',(0.,30.,0.));", "#1928 = CARTESIAN_POINT('',(60.,0.,0.));",
        "#1944 = CARTESIAN_POINT('',(60.,30.,0.));"})
    text = ReplaceAll(text, corner, std::string(corner, 8) + "CARTESIAN_POINT('',(0.,0.,0.));");
  Write(path, text);
  std::vector<std::string> warnings;
  const std::vector<SceneObject> objects = ReadAll(path, {}, &warnings);
  ASSERT_EQ(objects.size(), ExpectedObjects(0).size() - 1);
  for (const SceneObject& o : objects) EXPECT_NE(o.name, "engine/sheet");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find(path + ": 1 STEP shape(s) gave no triangle"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("engine/sheet (product 'sheet')"), std::string::npos) << warnings[0];
  auto run = testing::RunMktree("build " + path + " -o " + dir.file("s.mkt"), dir.path());
  EXPECT_EQ(run.code, 0) << run.err;
  EXPECT_NE(run.err.find("warning: " + path + ": 1 STEP shape(s) gave no triangle"), std::string::npos)
      << run.err;
  EXPECT_NE(run.out.find("built " + dir.file("s.mkt") + ": 10 objects"), std::string::npos) << run.out;
}

// A solid whose B-rep reference is broken (#57, the block's MANIFOLD_SOLID_BREP, points at a face set):
// OpenCASCADE leaves it out; the reader reads the rest and warns naming the entity.
TEST(StepReader, EntitiesOpenCascadeCannotTranslateAreReported) {
  testing::TempDir dir("step_entity");
  const std::string path = dir.file("broken.step");
  Write(path, ReplaceAll(Slurp(kAssembly), "#57 = MANIFOLD_SOLID_BREP('',#58);",
                         "#57 = MANIFOLD_SOLID_BREP('',#5);"));
  std::vector<std::string> warnings;
  const std::vector<SceneObject> objects = ReadAll(path, {}, &warnings);
  ASSERT_EQ(objects.size(), ExpectedObjects(0).size() - 1);
  EXPECT_EQ(objects[0].name, "engine/piston[1]/head");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find(path + ": OpenCASCADE reported "), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("#57 StepShape_ManifoldSolidBrep: "), std::string::npos) << warnings[0];
}

// A vertex whose point is a direction: OpenCASCADE dereferences the missing point (SIGSEGV inside
// StepToGeom::MakeCartesianPoint). The fault becomes a failed entity (engine/step/occt_signal_guard.h): the
// sheet is missing, the rest is read, the warning names the vertex, and the process lives on.
TEST(StepReader, CrashInsideOpenCascadeBecomesAFailedEntity) {
  testing::TempDir dir("step_fault");
  const std::string path = dir.file("vertex.step");
  Write(path,
        ReplaceAll(Slurp(kAssembly), "#1904 = VERTEX_POINT('',#1905);", "#1904 = VERTEX_POINT('',#1912);"));
  std::vector<std::string> warnings;
  const std::vector<SceneObject> objects = ReadAll(path, {}, &warnings);
  ASSERT_EQ(objects.size(), ExpectedObjects(0).size() - 1);
  EXPECT_EQ(objects.back().name, "engine/cover");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("#1904 StepShape_VertexPoint: "), std::string::npos) << warnings[0];
  auto run = testing::RunMktree("build " + path + " -o " + dir.file("v.mkt") + " -q", dir.path());
  EXPECT_EQ(run.code, 0) << run.err;
  EXPECT_TRUE(std::filesystem::exists(dir.file("v.mkt")));
}

// OpenCASCADE's "as1" assembly as OCCT wrote it (AP214) and as Unigraphics wrote it (AP203): 18 leaf solids
// each, every name unique, the same solids in the same places.
TEST(StepReader, ReadsOpenCascadesAs1InAp214AndAp203) {
  const std::string dir = std::string(MKTREE_TESTS_DIR) + "/data/step/";
  const std::vector<SceneObject> ap214 = ReadAll(dir + "as1-oc-214-mat.stp");
  const std::vector<SceneObject> ap203 = ReadAll(dir + "trj2_as1-ug-203.stp");
  ASSERT_EQ(ap214.size(), 18u);
  ASSERT_EQ(ap203.size(), 18u);
  EXPECT_EQ(ap214[0].name, "as1/rod-assembly_1/nut_1");
  EXPECT_EQ(Values(ap214[0], "step_product"), std::vector<std::string>{"nut"});
  EXPECT_EQ(Values(ap214[0], "step_colour"), std::vector<std::string>{"#ff0000"});
  EXPECT_EQ(Values(ap203[0], "step_schema"), std::vector<std::string>{"CONFIG_CONTROL_DESIGN"});
  // The exports differ in detail (the AP203 nuts are turned 30 degrees, its curves are B-splines), not
  // in the assembly's extent.
  Box3d all[2];
  for (int f = 0; f < 2; ++f) {
    std::set<std::string> names;
    for (const SceneObject& o : f == 0 ? ap214 : ap203) {
      EXPECT_TRUE(names.insert(o.name).second) << o.name;
      EXPECT_TRUE(IsClosedMesh(o.mesh)) << o.name;
      const Box3d b = o.mesh.Bounds();
      all[f].Extend(b.min[0], b.min[1], b.min[2]);
      all[f].Extend(b.max[0], b.max[1], b.max[2]);
    }
  }
  const double tolerance = SceneReadOptions{}.chord_tolerance;
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(all[0].min[a], all[1].min[a], tolerance);
    EXPECT_NEAR(all[0].max[a], all[1].max[a], tolerance);
  }
  // The assembly's extent in metres (the files are in millimetres).
  EXPECT_NEAR(all[0].min[0], -0.010, 1e-6);
  EXPECT_NEAR(all[0].max[0], 0.190, 1e-6);
  EXPECT_NEAR(all[0].max[1], 0.150, 1e-6);
  EXPECT_NEAR(all[0].max[2], 0.080, 1e-6);
}

TEST(StepReader, RoundTripsThroughBuildAndInfo) {
  testing::TempDir dir("step_cli");
  const std::string store = dir.file("engine.mkt");
  auto build =
      testing::RunMktree("build " + kAssembly + " -o " + store + " --chord-tolerance 0.0002 -q", dir.path());
  ASSERT_EQ(build.code, 0) << build.err;
  const std::vector<Expected> expected = ExpectedObjects(0.0002);
  for (size_t i = 0; i < expected.size(); ++i) {
    SCOPED_TRACE(expected[i].name);
    auto info =
        testing::RunMktree("info " + store + " --object " + std::to_string(i) + " --json", dir.path());
    ASSERT_EQ(info.code, 0) << info.err;
    EXPECT_NE(info.out.find("\"name\": \"" + expected[i].name + "\""), std::string::npos) << info.out;
    EXPECT_NE(info.out.find("{\"key\": \"step_product\", \"value\": \"" + expected[i].product + "\"}"),
              std::string::npos)
        << info.out;
    for (const std::string& c : expected[i].colours)
      EXPECT_NE(info.out.find("{\"key\": \"step_colour\", \"value\": \"" + c + "\"}"), std::string::npos)
          << info.out;
    EXPECT_NE(info.out.find("\"source\": \"" + kAssembly + "\""), std::string::npos) << info.out;
  }
  auto bad = testing::RunMktree("build " + kAssembly + " -o " + dir.file("x.mkt") + " --chord-tolerance 0",
                                dir.path());
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.err.find("--chord-tolerance"), std::string::npos) << bad.err;
}

// Without the module (here: $MKTREE_STEP_MODULE names a file that is not there), STEP input is refused
// naming the file and the module, and nothing is built.
TEST(StepReader, MissingModuleIsAClearError) {
  testing::TempDir dir("step_module");
  const std::string store = dir.file("m.mkt");
  auto run = testing::RunMktree("build " + kAssembly + " -o " + store + " -q", dir.path(),
                                "MKTREE_STEP_MODULE=" + dir.file("none.so") + " ");
  EXPECT_NE(run.code, 0);
  EXPECT_NE(run.err.find(kAssembly + ": the STEP reader's module (libmktree_step.so"), std::string::npos)
      << run.err;
  EXPECT_NE(run.err.find(dir.file("none.so")), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(store));
}

}  // namespace
}  // namespace mktree
