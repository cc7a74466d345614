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

// Every record of the run's groups (resolved ones included), by test and key.
inline std::vector<ClashRecord> Records(const ClashRun& run) {
  std::vector<ClashRecord> out;
  for (const ClashGroup& g : run.groups) out.insert(out.end(), g.members.begin(), g.members.end());
  std::sort(out.begin(), out.end(), [](const ClashRecord& x, const ClashRecord& y) {
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
