// Scenes with attributes for the clash-test tests: clustered objects (tests/query/scene_fixtures.h) given
// IFC types, GlobalIds, two source models, name groups, layers and the IFC relations of COMMON's keys
// (ifc_fills, ifc_voids, ifc_aggregate, ifc_spatial) planted on pairs whose boxes meet, so that every rule
// has pairs to remove; and the stores built from them.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "mktree/build.h"
#include "mktree/clash_tests.h"
#include "mktree/database.h"
#include "query/scene_fixtures.h"

namespace mktree::testing {

inline std::string Attr(const SceneObject& o, const std::string& key) {
  for (const ObjectAttribute& a : o.attributes)
    if (a.key == key) return a.value;
  return "";
}

inline bool BoxesMeet(const SceneObject& a, const SceneObject& b) {
  const Box3d x = a.mesh.Bounds(), y = b.mesh.Bounds();
  for (int i = 0; i < 3; ++i)
    if (x.max[i] < y.min[i] || y.max[i] < x.min[i]) return false;
  return true;
}

// n objects; ids 0..n-1 in order. Names unique ("grpK/obj_i" for every fourth), GlobalIds "G<i>" except
// every ninth object (identified by name).
inline std::vector<SceneObject> AttributedScene(size_t n, uint64_t seed) {
  std::vector<SceneObject> objs = ClusteredScene(n, seed);
  std::mt19937_64 rng(seed + 1);
  static const char* kTypes[] = {"IfcWall",   "IfcWallStandardCase", "IfcDoor",        "IfcWindow",
                                 "IfcBeam",   "IfcDuctSegment",      "IfcPipeSegment", "IfcSpace",
                                 "IfcColumn", "IfcOpeningElement",   "IfcSlab",        "IfcFurniture"};
  for (size_t i = 0; i < objs.size(); ++i) {
    SceneObject& o = objs[i];
    o.id = static_cast<ObjectId>(i);
    o.name = (i % 4 == 0 ? "grp" + std::to_string(i % 5) + "/" : std::string()) + "obj_" + std::to_string(i);
    o.source = i % 3 == 0 ? "models/structure.ifc" : "models/mep.ifc";
    o.attributes.push_back({"ifc_type", kTypes[rng() % 12]});
    if (i % 9 != 0) o.attributes.push_back({"ifc_global_id", "G" + std::to_string(i)});
    o.attributes.push_back({"layer", "L" + std::to_string(rng() % 4)});
    if (i % 11 == 0) o.attributes.push_back({"ifc_spatial", "true"});
  }
  // Relations on pairs that meet, in one model.
  for (size_t i = 0; i < objs.size(); ++i) {
    const std::string type = Attr(objs[i], "ifc_type");
    for (size_t j = 0; j < objs.size(); ++j) {
      if (i == j || !BoxesMeet(objs[i], objs[j]) || objs[i].source != objs[j].source) continue;
      const std::string gid = Attr(objs[j], "ifc_global_id");
      if (gid.empty()) continue;
      if (type == "IfcDoor" || type == "IfcWindow") {
        objs[i].attributes.push_back({"ifc_fills", gid});
        break;
      }
      if (type == "IfcOpeningElement") {
        objs[i].attributes.push_back({"ifc_voids", gid});
        break;
      }
      if (i % 7 == 0) {
        objs[i].attributes.push_back({"ifc_aggregate", i % 2 ? gid : "AGG" + std::to_string(j % 3)});
        break;
      }
    }
  }
  return objs;
}

// A small cube (named `name`, GlobalId `gid`) at the middle of the box of an object other than `avoid_a`
// and `avoid_b` and not spatial (no rule removes its pairs), where no other object's box comes within
// 0.05: it clashes with that object (*host) alone.
inline SceneObject CubeClashingWithOne(const std::vector<SceneObject>& scene, ObjectId avoid_a,
                                       ObjectId avoid_b, const std::string& name, const std::string& gid,
                                       ObjectId* host) {
  for (ObjectId h = 0; h < scene.size(); ++h) {
    const std::string type = Attr(scene[h], "ifc_type");
    if (h == avoid_a || h == avoid_b || Attr(scene[h], "ifc_spatial") == "true" || type == "IfcSpace" ||
        type == "IfcOpeningElement")
      continue;
    const Box3d hb = scene[h].mesh.Bounds();
    if (hb.max[0] - hb.min[0] < 0.1 || hb.max[1] - hb.min[1] < 0.1 || hb.max[2] - hb.min[2] < 0.1) continue;
    const Vec3d at{(hb.min[0] + hb.max[0]) / 2, (hb.min[1] + hb.max[1]) / 2, (hb.min[2] + hb.max[2]) / 2};
    bool alone = true;
    for (ObjectId o = 0; o < scene.size() && alone; ++o) {
      if (o == h) continue;
      const Box3d ob = scene[o].mesh.Bounds();
      bool near = true;
      for (int i = 0; i < 3; ++i) near = near && at[i] + 0.05 >= ob.min[i] && at[i] - 0.05 <= ob.max[i];
      alone = !near;
    }
    if (!alone) continue;
    SceneObject cube;
    cube.name = name;
    cube.source = scene[h].source;
    cube.attributes = {{"ifc_global_id", gid}, {"ifc_type", "IfcPipeSegment"}};
    Box3d b;
    for (int i = 0; i < 3; ++i) b.min[i] = at[i] - 0.01, b.max[i] = at[i] + 0.01;
    cube.mesh = BoxMesh(b);
    *host = h;
    return cube;
  }
  ADD_FAILURE() << "no place for a cube clashing with one object";
  return {};
}

inline void BuildScene(const std::vector<SceneObject>& objs, const std::string& path, uint32_t shards = 0) {
  BuildOptions o;
  o.backend = BuildOptions::Backend::kPagedFile;
  o.block_size = 512;
  o.blocks_per_page = 2;
  o.shards = shards;
  auto r = BuildFromObjects(objs, path, o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
}

inline std::unique_ptr<Database> OpenStore(const std::string& path, uint64_t cache_pages = 4096) {
  auto db = Database::Open(path, {.cache_pages = cache_pages});
  EXPECT_TRUE(db.ok()) << db.status().ToString();
  return db.ok() ? std::move(*db) : nullptr;
}

inline ClashTestFile Tests(const std::string& json) {
  auto f = ParseClashTests(json, "tests.json");
  EXPECT_TRUE(f.ok()) << f.status().ToString();
  return f.ok() ? *f : ClashTestFile();
}

inline ClashRun RunTests(const Database& db, const ClashTestFile& tests, const ClashTestOptions& o = {}) {
  ClashRun run;
  const Status st = RunClashTests(db, tests, o, &run);
  EXPECT_TRUE(st.ok()) << st.ToString();
  return run;
}

// A record of a run with its group's test and key.
struct RunRecord : ClashRecord {
  std::string test, group;
};

// Every record of the run's groups (resolved ones included), by test and key.
inline std::vector<RunRecord> Records(const ClashRun& run) {
  std::vector<RunRecord> out;
  for (const ClashGroup& g : run.groups)
    for (const ClashRecord& r : g.members) out.push_back({r, g.test, g.key});
  std::sort(out.begin(), out.end(), [](const RunRecord& x, const RunRecord& y) {
    return std::tie(x.test, x.key) < std::tie(y.test, y.key);
  });
  return out;
}

inline const ClashTestSummary* Summary(const ClashRun& run, const std::string& test) {
  for (const ClashTestSummary& s : run.tests)
    if (s.name == test) return &s;
  return nullptr;
}

inline uint64_t RuleCount(const ClashTestSummary& s, const std::string& rule) {
  for (const auto& [name, n] : s.excluded_by_rule)
    if (name == rule) return n;
  return 0;
}

}  // namespace mktree::testing
