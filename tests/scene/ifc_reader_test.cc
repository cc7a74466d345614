// The IFC reader through web-ifc (engine/scene/ifc_reader.h): every product with a body once, with its
// GlobalId, type and relations as the file states them (parsed here from the file's text, the brute force),
// coordinates in the model's frame (Z up, metres) against boxes worked out by hand from the files'
// placements and extrusions, federated builds, and bad input through the command line.
#include "engine/scene/ifc_reader.h"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/wait.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "scene/scene_test_util.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

namespace fs = std::filesystem;

const std::string kDuplex = std::string(MKTREE_SHARED_DATA) + "/buildings/duplex.ifc";
const std::string kOffice = std::string(MKTREE_SHARED_DATA) + "/buildings/Office_A_20110811.ifc";
std::string TestFile(const std::string& name) { return std::string(MKTREE_TESTS_DIR) + "/data/ifc/" + name; }

std::string Value(const SceneObject& o, const std::string& key) {
  for (const ObjectAttribute& a : o.attributes)
    if (a.key == key) return a.value;
  return "<missing>";
}

std::vector<std::string> Values(const SceneObject& o, const std::string& key) {
  std::vector<std::string> out;
  for (const ObjectAttribute& a : o.attributes)
    if (a.key == key) out.push_back(a.value);
  return out;
}

const SceneObject* ByGlobalId(const std::vector<SceneObject>& objects, const std::string& id) {
  for (const SceneObject& o : objects)
    if (Value(o, "ifc_global_id") == id) return &o;
  return nullptr;
}

// What the IFC text itself says: each entity's type and GlobalId by its #id, and the relations.
struct IfcText {
  std::map<std::string, std::string> type_of;       // "#123" -> "IFCDOOR"
  std::map<std::string, std::string> global_id_of;  // "#123" -> GlobalId
  std::map<std::string, std::string> voided_by;     // opening -> element it voids
  std::map<std::string, std::string> filled_by;     // door/window -> opening
  std::map<std::string, std::string> container_of;  // element -> spatial structure
  std::map<std::string, size_t> count;              // type -> entities
};

std::vector<std::string> Refs(const std::string& s) {
  std::vector<std::string> out;
  static const std::regex ref("#[0-9]+");
  for (auto it = std::sregex_iterator(s.begin(), s.end(), ref); it != std::sregex_iterator(); ++it)
    out.push_back(it->str());
  return out;
}

IfcText ParseIfc(const std::string& path) {
  IfcText t;
  std::ifstream in(path);
  std::string line;
  static const std::regex entity(R"(^(#[0-9]+)\s*=\s*(IFC[A-Z0-9]+)\s*\((.*)\);\s*$)");
  static const std::regex gid(R"(^'([0-9A-Za-z_$]{22})')");
  std::smatch m;
  while (std::getline(in, line)) {
    if (!std::regex_match(line, m, entity)) continue;
    const std::string id = m[1], type = m[2], args = m[3];
    t.type_of[id] = type;
    ++t.count[type];
    std::smatch g;
    if (std::regex_search(args, g, gid)) t.global_id_of[id] = g[1];
    const std::vector<std::string> refs = Refs(args);
    if (type == "IFCRELVOIDSELEMENT" && refs.size() >= 3) t.voided_by[refs[2]] = refs[1];
    if (type == "IFCRELFILLSELEMENT" && refs.size() >= 3) t.filled_by[refs[2]] = refs[1];
    if (type == "IFCRELCONTAINEDINSPATIALSTRUCTURE" && refs.size() >= 2)
      for (size_t i = 1; i + 1 < refs.size(); ++i) t.container_of[refs[i]] = refs.back();
  }
  return t;
}

// The objects of `path` read once per test program (each read runs Node).
const std::vector<SceneObject>& ReadOnce(const std::string& path) {
  static std::map<std::string, std::vector<SceneObject>> cache;
  auto it = cache.find(path);
  if (it == cache.end()) {
    auto r = ReadAllFrom(OpenSceneFile(path, 0));
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    it = cache.emplace(path, r.ok() ? std::move(*r) : std::vector<SceneObject>{}).first;
  }
  return it->second;
}

void ExpectBox(const SceneObject& o, Vec3d lo, Vec3d hi, double tolerance) {
  const Box3d b = o.mesh.Bounds();
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.min[k], lo[k], tolerance) << o.name << " axis " << k;
    EXPECT_NEAR(b.max[k], hi[k], tolerance) << o.name << " axis " << k;
  }
}

// Every product of the types web-ifc makes geometry for is one object with its GlobalId and type, as the
// file lists them; none is named after a representation item.
void ExpectProductsOnce(const std::string& path, const std::map<std::string, size_t>& known_counts) {
  if (!fs::exists(path)) GTEST_SKIP() << path << " missing";
  const std::vector<SceneObject>& objects = ReadOnce(path);
  const IfcText text = ParseIfc(path);
  std::map<std::string, size_t> by_type;
  std::set<std::string> ids;
  for (size_t i = 0; i < objects.size(); ++i) {
    const SceneObject& o = objects[i];
    EXPECT_EQ(o.id, i);
    EXPECT_EQ(o.source, path);
    EXPECT_NE(o.name.find("IfcMappedItem"), 0u) << o.name;
    const std::string id = Value(o, "ifc_global_id"), type = Value(o, "ifc_type");
    EXPECT_TRUE(ids.insert(id).second) << "GlobalId " << id << " twice";
    ++by_type[type];
    EXPECT_EQ(Value(o, "ifc_schema"), "IFC2X3");
    ASSERT_GT(o.mesh.triangle_count(), 0u) << o.name;
  }
  // Each object's GlobalId is an entity of its type in the file.
  std::map<std::string, std::string> type_by_gid;
  for (const auto& [ref, g] : text.global_id_of) type_by_gid[g] = text.type_of.at(ref);
  for (const SceneObject& o : objects) {
    std::string upper = Value(o, "ifc_type");
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    EXPECT_EQ(type_by_gid[Value(o, "ifc_global_id")], upper) << o.name;
  }
  // Types whose every entity has a body: as many objects as entities.
  for (const auto& [type, n] : known_counts) {
    std::string upper = type;
    for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    EXPECT_EQ(by_type[type], n) << type;
    EXPECT_EQ(text.count.at(upper), n) << type << " in the file";
  }
}

TEST(IfcReader, DuplexProductsOnceWithGlobalIdAndType) {
  ExpectProductsOnce(kDuplex, {{"IfcDoor", 14},
                               {"IfcWindow", 24},
                               {"IfcFurnishingElement", 61},
                               {"IfcSpace", 21},
                               {"IfcOpeningElement", 50}});
  const std::vector<SceneObject>& objects = ReadOnce(kDuplex);
  size_t solid = 0;
  for (const SceneObject& o : objects) solid += Value(o, "ifc_spatial") != "true";
  EXPECT_EQ(solid, 215u);  // what the assimp reader gave as objects, now each with its product
}

// Doors and windows fill their host wall's opening, openings void their element, elements sit in their
// storey: as the file's IfcRelFillsElement, IfcRelVoidsElement and IfcRelContainedInSpatialStructure say.
TEST(IfcReader, DuplexRelationsAsTheFileStatesThem) {
  if (!fs::exists(kDuplex)) GTEST_SKIP() << kDuplex << " missing";
  const std::vector<SceneObject>& objects = ReadOnce(kDuplex);
  const IfcText text = ParseIfc(kDuplex);
  std::map<std::string, std::string> ref_of;  // GlobalId -> #id
  for (const auto& [ref, g] : text.global_id_of) ref_of[g] = ref;
  size_t fills = 0, voids = 0, contained = 0;
  for (const SceneObject& o : objects) {
    const std::string ref = ref_of[Value(o, "ifc_global_id")];
    const auto filled = text.filled_by.find(ref);
    if (filled != text.filled_by.end()) {
      const std::string host = text.global_id_of.at(text.voided_by.at(filled->second));
      EXPECT_EQ(Value(o, "ifc_fills"), host) << o.name;
      // The host is an object, or a whole (a roof) whose parts are.
      bool host_parts = false;
      for (const SceneObject& part : objects) host_parts |= Value(part, "ifc_aggregate") == host;
      EXPECT_TRUE(ByGlobalId(objects, host) != nullptr || host_parts) << "host of " << o.name;
      ++fills;
    } else {
      EXPECT_EQ(Value(o, "ifc_fills"), "<missing>") << o.name;
    }
    const auto voided = text.voided_by.find(ref);
    if (voided != text.voided_by.end()) {
      EXPECT_EQ(Value(o, "ifc_voids"), text.global_id_of.at(voided->second)) << o.name;
      EXPECT_EQ(Value(o, "ifc_spatial"), "true") << o.name;
      ++voids;
    }
    const auto container = text.container_of.find(ref);
    if (container != text.container_of.end()) {
      EXPECT_EQ(Value(o, "ifc_container"), text.global_id_of.at(container->second)) << o.name;
      const std::string container_type = text.type_of.at(container->second);
      EXPECT_TRUE(container_type == "IFCBUILDINGSTOREY" || container_type == "IFCSPACE") << container_type;
      EXPECT_NE(Value(o, "ifc_storey"), "<missing>") << o.name;  // a space's storey, through aggregation
      ++contained;
    }
  }
  EXPECT_EQ(fills, 14u + 24u);
  EXPECT_EQ(voids, 50u);
  EXPECT_GT(contained, 150u);
  // A wall: its materials (layer set) and property sets.
  const SceneObject* wall = ByGlobalId(objects, "0iEHWY1$XA8eQeeULq4jpl");
  ASSERT_NE(wall, nullptr);
  EXPECT_EQ(Values(*wall, "ifc_material"), (std::vector<std::string>{"Plasterboard", "Metal - Stud Layer"}));
  EXPECT_EQ(Value(*wall, "ifc_storey"), "Level 1");
  EXPECT_EQ(Value(*wall, "pset:Pset_WallCommon.LoadBearing"), "false");
  EXPECT_EQ(Value(*wall, "pset:PSet_Revit_Constraints.Base Constraint"), "Level 1");
}

// #5165, "Floor:127mm Slab on Grade:141232": placement (0.417, -9.725, -0.127); extrusion at (3.983, 4.654,
// 0.127) with Z = (0, 0, -1), X = (-1, 0, 0) (so Y = (0, 1, 0)) of a profile spanning u in [-3.983, 3.983],
// v in [-4.654, 4.654], depth 0.127 along -Z: x in [0.417, 8.383], y in [-9.725, -0.417], z in [-0.127, 0].
// Z up: the Y-up frame web-ifc hands out would give this slab a height of 9.308 m.
TEST(IfcReader, DuplexSlabInTheModelsFrame) {
  if (!fs::exists(kDuplex)) GTEST_SKIP() << kDuplex << " missing";
  const SceneObject* slab = ByGlobalId(ReadOnce(kDuplex), "2O2Fr$t4X7Zf8NOew3FK4F");
  ASSERT_NE(slab, nullptr);
  EXPECT_EQ(slab->name, "Floor:127mm Slab on Grade:141232");
  ExpectBox(*slab, {0.417, -9.725, -0.127}, {8.383, -0.417, 0.0}, 1e-5);
}

// IFC4, millimetres: profile x in [-400, 1400] (arcs through (1400, 2000) and (-400, 2000)), y in [0, 4000],
// placed at z = -200 and extruded 200: the box in metres.
TEST(IfcReader, Ifc4SlabInMetres) {
  auto r = ReadAllFrom(OpenSceneFile(TestFile("slab-standard-case.ifc"), 7));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 1u);
  const SceneObject& slab = (*r)[0];
  EXPECT_EQ(slab.id, 7u);
  EXPECT_EQ(Value(slab, "ifc_global_id"), "1uKP3mPKPDSxR9_M8BpQJz");
  EXPECT_EQ(Value(slab, "ifc_type"), "IfcSlabStandardCase");
  EXPECT_EQ(Value(slab, "ifc_schema"), "IFC4");
  EXPECT_EQ(Value(slab, "ifc_container"), "385$tKiSf6rQEPOC3cePN3");
  EXPECT_EQ(Value(slab, "ifc_material"), "Concrete");
  ExpectBox(slab, {-0.4, 0, -0.2}, {1.4, 4.0, 0}, 1e-6);
}

// IfcMapConversion: eastings 458658.78, northings 5438232.79, height 113.7 (metres), the model in
// millimetres with Scale omitted. The cone (radius 150, height 500 below z = 500) and the cylinder (radius
// 50 from z = 500 to 1000) stand on the map point: z in [113.7, 114.7], centred on (E, N).
TEST(IfcReader, MapConversionPlacesTheModel) {
  auto r = ReadAllFrom(OpenSceneFile(TestFile("geographic-referencing.ifc")));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 1u);
  const Box3d b = (*r)[0].mesh.Bounds();
  EXPECT_NEAR((b.min[0] + b.max[0]) / 2, 458658.78, 1e-3);
  EXPECT_NEAR((b.min[1] + b.max[1]) / 2, 5438232.79, 1e-3);
  EXPECT_NEAR(b.min[2], 113.7, 1e-4);
  EXPECT_NEAR(b.max[2], 114.7, 1e-4);
  EXPECT_LE(b.max[0] - b.min[0], 0.3 + 1e-6);
  EXPECT_GT(b.max[0] - b.min[0], 0.25);
  EXPECT_EQ(Value((*r)[0], "ifc_storey"), "Storey 1");
}

// IFC 4.3: the slab with its round opening (radius 50 at (100, 300)) and rectangular recess (1000 x 500 at
// (500, 1000), 50 deep) subtracted; the openings kept as spatial objects that name the slab.
TEST(IfcReader, Ifc4x3OpeningsSubtractedAndKept) {
  auto r = ReadAllFrom(OpenSceneFile(TestFile("slab-openings-ifc4x3.ifc")));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 3u);
  const SceneObject* slab = ByGlobalId(*r, "1wAj$J2Az2V8wnBiVYd3bU");
  ASSERT_NE(slab, nullptr);
  EXPECT_EQ(Value(*slab, "ifc_schema"), "IFC4X3");
  ExpectBox(*slab, {-0.4, 0, -0.2}, {1.4, 4.0, 0}, 1e-6);
  size_t on_hole = 0, recess_floor = 0;
  const std::vector<double>& v = slab->mesh.vertices;
  for (size_t i = 0; i < v.size(); i += 3) {
    if (std::fabs(std::hypot(v[i] - 0.1, v[i + 1] - 0.3) - 0.05) < 1e-4) ++on_hole;
    if (std::fabs(v[i + 2] + 0.05) < 1e-6 && v[i] > -1e-6 && v[i] < 1 + 1e-6) ++recess_floor;
  }
  EXPECT_GE(on_hole, 8u) << "the round opening is cut through the slab";
  EXPECT_GE(recess_floor, 4u) << "the recess leaves a floor 50 mm down";
  for (const char* id : {"15RSTHd8nFVQWMRE7og7sd", "0w93HZ19H2D99zbAVNb4o2"}) {
    const SceneObject* opening = ByGlobalId(*r, id);
    ASSERT_NE(opening, nullptr) << id;
    EXPECT_EQ(Value(*opening, "ifc_type"), "IfcOpeningElement");
    EXPECT_EQ(Value(*opening, "ifc_spatial"), "true");
    EXPECT_EQ(Value(*opening, "ifc_voids"), "1wAj$J2Az2V8wnBiVYd3bU");
  }
}

// Four IfcMappedItems of one box (12 triangles each) are one object, the product's.
TEST(IfcReader, MappedItemsMergedUnderTheirProduct) {
  auto r = ReadAllFrom(OpenSceneFile(TestFile("mapped-shape-with-multiple-items-ifc4x3.ifc")));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->size(), 1u);
  EXPECT_EQ((*r)[0].name, "P-1");
  EXPECT_EQ(Value((*r)[0], "ifc_type"), "IfcBuildingElementProxy");
  EXPECT_EQ((*r)[0].mesh.triangle_count(), 48u);
  EXPECT_EQ((*r)[0].mesh.vertex_count(), 32u);
}

// A product web-ifc makes no geometry for (its extrusion's profile is a point) is reported by GlobalId and
// counted; the rest is read.
TEST(IfcReader, ProductWithoutGeometryIsReportedAndTheRestRead) {
  auto src = OpenSceneFile(TestFile("broken-geometry.ifc"));
  ASSERT_TRUE(src.ok()) << src.status().ToString();
  std::vector<SceneObject> objects;
  for (SceneObject o;;) {
    auto more = (*src)->Next(&o);
    ASSERT_TRUE(more.ok()) << more.status().ToString();
    if (!*more) break;
    objects.push_back(o);
  }
  ASSERT_EQ(objects.size(), 1u);
  EXPECT_EQ(Value(objects[0], "ifc_global_id"), "1uKP3mPKPDSxR9_M8BpQJz");
  const std::vector<std::string> warnings = (*src)->TakeWarnings();
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[0].find(TestFile("broken-geometry.ifc")), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[0].find("0BadGeometry0000000001"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[1].find("1 of 2 products"), std::string::npos) << warnings[1];
}

// Stopping early (a build that failed on another input) kills and reaps the subprocess.
TEST(IfcReader, SourceDestroyedEarly) {
  auto src = OpenSceneFile(TestFile("slab-openings-ifc4x3.ifc"));
  ASSERT_TRUE(src.ok()) << src.status().ToString();
  SceneObject o;
  ASSERT_TRUE(*(*src)->Next(&o));
  src->reset();
  EXPECT_EQ(::waitpid(-1, nullptr, WNOHANG), -1) << "no child left";
}

// A stand-in for mktree-ifc.mjs in its own folder (with the web-ifc marker the reader looks for) whose
// body is `script` (JavaScript with `out(buffer)` writing to stdout and `record(name, attrs, v, t)`).
std::string FakeReader(const testing::TempDir& dir, const std::string& script) {
  fs::create_directories(dir / "node_modules" / "web-ifc");
  std::ofstream(dir / "node_modules" / "web-ifc" / "package.json") << "{}";
  std::ofstream(dir / "mktree-ifc.mjs")
      << "import fs from 'node:fs';\n"
         "const out = (b) => fs.writeSync(1, b);\n"
         "const u32 = (v) => { const b = Buffer.alloc(4); b.writeUInt32LE(v); return b; };\n"
         "const str = (s) => Buffer.concat([u32(Buffer.byteLength(s)), Buffer.from(s)]);\n"
         "const header = () => out(Buffer.concat([Buffer.from('MKIFCS\\0\\0', 'latin1'), u32(1), u32(0)]));\n"
         "const record = (name, attrs, v, t) => out(Buffer.concat([Buffer.from('MKOB'), str(name),\n"
         "  u32(attrs.length), ...attrs.flatMap(([k, x]) => [str(k), str(x)]), u32(v.length / 3),\n"
         "  u32(t.length / 3), Buffer.from(Float64Array.from(v).buffer), "
         "Buffer.from(Uint32Array.from(t).buffer)]));\n"
         "const end = (n) => { const b = Buffer.alloc(16); b.write('MKEN'); b.writeBigUInt64LE(BigInt(n), "
         "8);\n"
         "  out(b); };\n"
      << script << "\n";
  return dir.path().string();
}

// What the reader checks of the stream, whatever the program: finite coordinates and indices in range
// (naming the product by GlobalId), a program that dies (its exit status and stderr), an end that is not.
TEST(IfcReaderStream, BadObjectsAndDeadProgramsAreErrorsNamingTheFile) {
  const std::string input = TestFile("slab-standard-case.ifc");
  struct Case {
    const char* script;
    const char* says;
  } cases[] = {
      {"header(); record('w', [['ifc_global_id', '2O2Fr$t4X7Zf8NOew3FK4F'], ['ifc_type', 'IfcWall']], "
       "[0, 0, 0, 1, 0, 0, 0, NaN, 0], [0, 1, 2]); end(1);",
       "2O2Fr$t4X7Zf8NOew3FK4F IfcWall, 'w'): non-finite vertex coordinate"},
      {"header(); record('w', [['ifc_global_id', 'g']], [0, 0, 0, 1, 0, 0, 0, 1, 0], [0, 1, 3]); end(1);",
       "triangle index 3 out of range"},
      {"header(); record('w', [], [0, 0, 0, 1, 0, 0, 0, 1, 0], [0, 1, 2]); "
       "process.stderr.write('boom\\n'); process.exit(3);",
       "stopped before the end of its stream (exit status 3: boom)"},
      {"header(); end(2);", "end record says 2 objects, 0 were read"},
      {"out(Buffer.from('hello world, not a stream'));", "wrote no MKIFCS stream"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.script);
    testing::TempDir dir("mktree_ifc_fake");
    ::setenv("MKTREE_IFC_READER", FakeReader(dir, c.script).c_str(), 1);
    auto r = ReadAllFrom(OpenSceneFile(input));
    ::unsetenv("MKTREE_IFC_READER");
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find(input), std::string::npos) << r.status().ToString();
    EXPECT_NE(r.status().message().find(c.says), std::string::npos) << r.status().ToString();
  }
}

// A saved stream (.mkifcs) reads as the IFC it came from, without Node; cut short, it is refused.
TEST(IfcReaderStream, SavedStreamReadsAsTheIfc) {
  testing::TempDir dir("mktree_ifc_saved");
  const std::string ifc = TestFile("slab-openings-ifc4x3.ifc"), saved = dir.file("slab.mkifcs");
  const std::string cmd = "node " + IfcReaderProgram() + " " + ifc + " > " + saved;
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  auto direct = ReadAllFrom(OpenSceneFile(ifc, 5));
  auto from_file = ReadAllFrom(OpenSceneFile(saved, 5));
  ASSERT_TRUE(direct.ok()) << direct.status().ToString();
  ASSERT_TRUE(from_file.ok()) << from_file.status().ToString();
  ASSERT_EQ(from_file->size(), 3u);
  ASSERT_EQ(direct->size(), from_file->size());
  for (size_t i = 0; i < direct->size(); ++i) {
    const SceneObject &a = (*direct)[i], &b = (*from_file)[i];
    EXPECT_EQ(b.id, 5 + i);
    EXPECT_EQ(b.source, saved);
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.attributes, b.attributes);
    EXPECT_EQ(a.mesh.vertices, b.mesh.vertices);
    EXPECT_EQ(a.mesh.triangles, b.mesh.triangles);
  }
  const std::string bytes = testing::Slurp(saved), cut = dir.file("cut.mkifcs");
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() - 100);
  auto r = ReadAllFrom(OpenSceneFile(cut));
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), Status::Code::kCorruption);
  EXPECT_NE(r.status().message().find(cut + ": truncated MKIFCS stream"), std::string::npos)
      << r.status().ToString();
  std::ofstream(cut, std::ios::binary) << "ISO-10303-21;";
  r = ReadAllFrom(OpenSceneFile(cut));
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find(cut + ": "), std::string::npos) << r.status().ToString();
}

// ---- through the command line ----------------------------------------------------------------------

class IfcCli : public ::testing::Test {
 protected:
  testing::TempDir dir_{"mktree_ifc"};
  // Builds `inputs` into dir/out.mkt; the run.
  testing::ToolRun Build(const std::string& inputs, const std::string& env = "") {
    return testing::RunMktree("build " + inputs + " -o " + dir_.file("out.mkt"), dir_.path(), env);
  }
  // `info --object id`'s attributes and source.
  std::vector<ObjectAttribute> Record(ObjectId id, std::string* source) {
    const testing::ToolRun r =
        testing::RunMktree("info " + dir_.file("out.mkt") + " --object " + std::to_string(id), dir_.path());
    EXPECT_EQ(r.code, 0) << r.err;
    std::vector<ObjectAttribute> out;
    std::istringstream in(r.out);
    for (std::string line; std::getline(in, line);) {
      if (line.rfind("source", 0) == 0) *source = line.substr(line.find_first_not_of(' ', 6));
      if (line.rfind("  ", 0) != 0) continue;
      const size_t eq = line.find(" = ");
      if (eq != std::string::npos) out.push_back({line.substr(2, eq - 2), line.substr(eq + 3)});
    }
    return out;
  }
  // Bad input: exit non-zero, an error naming the file and saying `what`, no store left.
  void ExpectRefused(const std::string& input, const std::string& what, const std::string& env = "") {
    const testing::ToolRun r = Build(input, env);
    EXPECT_NE(r.code, 0);
    EXPECT_NE(r.err.find(input), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
    for (const auto& e : fs::directory_iterator(dir_.path()))
      EXPECT_EQ(e.path().string().find("out.mkt"), std::string::npos) << e.path() << " left";
  }
};

TEST_F(IfcCli, AttributesRoundTripToInfoObject) {
  if (!fs::exists(kDuplex)) GTEST_SKIP() << kDuplex << " missing";
  const testing::ToolRun r = Build(kDuplex);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::vector<SceneObject>& objects = ReadOnce(kDuplex);
  size_t checked = 0;
  for (const SceneObject& o : objects) {
    const std::string type = Value(o, "ifc_type");
    if (type != "IfcDoor" && type != "IfcOpeningElement" && type != "IfcWallStandardCase") continue;
    std::string source;
    EXPECT_EQ(Record(o.id, &source), o.attributes) << o.name;
    EXPECT_EQ(source, kDuplex);
    if (++checked == 6) break;
  }
  EXPECT_EQ(checked, 6u);
}

TEST_F(IfcCli, FederatedBuildKeepsEachObjectsSource) {
  const std::string a = TestFile("slab-standard-case.ifc"), b = TestFile("slab-openings-ifc4x3.ifc");
  const testing::ToolRun r = Build(a + " " + b);
  ASSERT_EQ(r.code, 0) << r.err;
  const std::vector<std::string> want = {a, b, b, b};
  const std::vector<std::string> ids = {"1uKP3mPKPDSxR9_M8BpQJz", "1wAj$J2Az2V8wnBiVYd3bU",
                                        "15RSTHd8nFVQWMRE7og7sd", "0w93HZ19H2D99zbAVNb4o2"};
  for (ObjectId id = 0; id < 4; ++id) {
    std::string source;
    const std::vector<ObjectAttribute> attributes = Record(id, &source);
    EXPECT_EQ(source, want[id]);
    ASSERT_FALSE(attributes.empty());
    EXPECT_EQ(attributes[0], (ObjectAttribute{"ifc_global_id", ids[id]}));
  }
}

TEST_F(IfcCli, TruncatedFileRefused) {
  const std::string input = dir_.file("cut.ifc");
  std::ofstream(input) << testing::Slurp(TestFile("slab-standard-case.ifc")).substr(0, 2000);
  ExpectRefused(input, "truncated");
}

TEST_F(IfcCli, UnsupportedSchemaRefused) {
  const std::string input = dir_.file("old.ifc");
  std::string text = testing::Slurp(TestFile("slab-standard-case.ifc"));
  text.replace(text.find("'IFC4'"), 6, "'IFC2X2_FINAL'");
  std::ofstream(input) << text;
  ExpectRefused(input, "unsupported IFC schema 'IFC2X2_FINAL'");
}

TEST_F(IfcCli, NonIfcFileRefused) {
  const std::string input = dir_.file("notes.ifc");
  std::ofstream(input) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  ExpectRefused(input, "not an IFC file");
}

TEST_F(IfcCli, NodeMissingSaysWhatToInstall) {
  ExpectRefused(TestFile("slab-standard-case.ifc"), "install the package nodejs",
                "MKTREE_NODE=/nonexistent/node ");
  ExpectRefused(TestFile("slab-standard-case.ifc"), "needs Node.js", "PATH=/nonexistent ");
}

TEST_F(IfcCli, WebIfcMissingSaysWhatToRun) {
  const fs::path bare = dir_.path() / "bare";
  fs::create_directories(bare);
  fs::copy_file(IfcReaderProgram(), bare / "mktree-ifc.mjs");
  ExpectRefused(TestFile("slab-standard-case.ifc"), "run scripts/setup.sh",
                "MKTREE_IFC_READER=" + bare.string() + " ");
}

TEST_F(IfcCli, AssimpReaderStillReachable) {
  if (!fs::exists(kDuplex)) GTEST_SKIP() << kDuplex << " missing";
  const testing::ToolRun r = Build(kDuplex, "MKTREE_IFC_READER=assimp ");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("215 objects"), std::string::npos) << r.out;
}

// Office_A (IFC 2x3, 4 MB): its doors, windows, spaces and openings each once.
TEST(IfcReaderLarge, OfficeProductsOnce) {
  ExpectProductsOnce(kOffice,
                     {{"IfcDoor", 102}, {"IfcWindow", 69}, {"IfcSpace", 99}, {"IfcOpeningElement", 181}});
}

}  // namespace
}  // namespace mktree
