// What the report tests share: a clash run made by hand (names that need escaping, objects with and
// without IFC GlobalIds, every class and status), a run from a real store (the duplex OBJ built into a
// store, its self-clash pairs one group each), and the archive's entries unpacked for xmllint.
#pragma once

#include <gtest/gtest.h>
#include <zip.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "engine/coordination/clash_issues.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/obj_reader.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"
#include "test_dirs.h"

namespace mktree {

inline ObjectIdentity Ident(ObjectId id, std::string name, std::string type, std::string guid) {
  ObjectIdentity o;
  o.id = id;
  o.name = std::move(name);
  o.source = "models/duplex.ifc";
  o.ifc_type = std::move(type);
  o.global_id = std::move(guid);
  o.stable = o.source + "|" + (o.global_id.empty() ? o.name : o.global_id);
  return o;
}

inline ClashRecord Record(const std::string& test, const ObjectIdentity& a, const ObjectIdentity& b,
                          ClashClass c, double distance, ClashStatus status) {
  ClashRecord r;
  r.key = test + "|" + std::min(a.stable, b.stable) + "|" + std::max(a.stable, b.stable);
  r.a = std::make_shared<const ObjectIdentity>(a);
  r.b = std::make_shared<const ObjectIdentity>(b);
  r.pair.a = a.id;
  r.pair.b = b.id;
  r.pair.cls = c;
  r.pair.distance = distance;
  if (distance < 0) r.pair.depth_lower = r.pair.depth_upper = -distance;
  r.status = status;
  return r;
}

inline ClashGroup Group(std::string test, std::string key, std::string title,
                        std::vector<ClashRecord> members, Box3d box, ClashStatus status) {
  ClashGroup g;
  g.key = std::move(key);
  g.test = std::move(test);
  g.title = std::move(title);
  g.box = box;
  g.centre = {(box.min[0] + box.max[0]) / 2, (box.min[1] + box.max[1]) / 2, (box.min[2] + box.max[2]) / 2};
  g.members = std::move(members);
  g.worst = ClashClass::kClearance;
  g.worst_distance = std::numeric_limits<double>::infinity();
  for (const ClashRecord& r : g.members)
    if (static_cast<int>(r.pair.cls) < static_cast<int>(g.worst)) g.worst = r.pair.cls;
  for (const ClashRecord& r : g.members)
    if (r.pair.cls == g.worst) g.worst_distance = std::min(g.worst_distance, r.pair.distance);
  g.status = status;
  return g;
}

inline Box3d BoxOf(double x0, double y0, double z0, double x1, double y1, double z1) {
  Box3d b;
  b.min = {x0, y0, z0};
  b.max = {x1, y1, z1};
  return b;
}

// Three groups: a beam hit by two ducts (hard, new; a name full of XML's special characters), a touch
// between two objects without GlobalIds (active), a resolved clearance group.
inline ClashRun HandRun() {
  ClashRun run;
  run.store = "/data/duplex.mkt";
  run.revision = 3;
  const auto beam = Ident(1, "Beam <B-12> & \"main\" 'east'", "IfcBeam", "2O2Fr$t4X7Zf8NOew3FLOH");
  const auto duct1 = Ident(2, "Duct D-1", "IfcDuctSegment", "1hOSvn6df7F8_7GcBWlR72");
  const auto duct2 = Ident(3, "Duct D-2 \xc3\xa9t\xc3\xa9", "IfcDuctSegment", "0M6o6c5d10Dvr_2QzXZ9fY");
  const auto wall = Ident(4, "wall-north", "", "");
  const auto slab = Ident(5, "slab-1", "", "");
  const auto pipe = Ident(6, "Pipe P-7", "IfcPipeSegment", "3Fz8s$7kX0PuAqk2mlF5e1");
  ClashTestSummary mep{.name = "mep-vs-structure",
                       .mode = "clearance",
                       .clearance = 0.05,
                       .touch_tolerance = 0.002,
                       .selected_a = 12,
                       .selected_b = 40,
                       .hard = 2,
                       .touch = 0,
                       .clearance_pairs = 1,
                       .new_clashes = 2,
                       .active = 0,
                       .resolved = 1,
                       .excluded_by_rule = {{"hosted_filling", 7}}};
  ClashTestSummary self{.name = "architecture",
                        .mode = "hard",
                        .clearance = 0,
                        .touch_tolerance = 0.002,
                        .selected_a = 30,
                        .selected_b = 30,
                        .hard = 0,
                        .touch = 1,
                        .clearance_pairs = 0,
                        .new_clashes = 0,
                        .active = 1,
                        .resolved = 0,
                        .excluded_by_rule = {{"same_aggregate", 3}},
                        .warnings = {"selection b matched nothing"}};
  run.tests = {mep, self};
  run.groups.push_back(Group(
      "mep-vs-structure", "mep-vs-structure|" + beam.stable, "IfcBeam Beam B-12 hit by 2 IfcDuctSegment",
      {Record("mep-vs-structure", beam, duct1, ClashClass::kHard, -0.04, ClashStatus::kNew),
       Record("mep-vs-structure", beam, duct2, ClashClass::kHard, -0.012, ClashStatus::kActive)},
      BoxOf(0, 0, 2.5, 6, 0.4, 3.1), ClashStatus::kNew));
  run.groups.push_back(
      Group("architecture", "architecture|" + wall.stable, "wall-north touches slab-1",
            {Record("architecture", wall, slab, ClashClass::kTouch, 0, ClashStatus::kActive)},
            BoxOf(-1, -1, 0, 9, 0.3, 3), ClashStatus::kActive));
  run.groups.push_back(
      Group("mep-vs-structure", "mep-vs-structure|" + pipe.stable, "Pipe P-7 near Beam B-12",
            {Record("mep-vs-structure", beam, pipe, ClashClass::kClearance, 0.03, ClashStatus::kResolved)},
            BoxOf(5, 0, 2.4, 6.2, 0.5, 3.1), ClashStatus::kResolved));
  return run;
}

// The archive's entries, by name.
inline std::map<std::string, std::string> ZipEntries(const std::string& path) {
  std::map<std::string, std::string> out;
  int err = 0;
  zip_t* z = zip_open(path.c_str(), ZIP_RDONLY, &err);
  EXPECT_NE(z, nullptr) << path;
  if (!z) return out;
  for (zip_int64_t i = 0; i < zip_get_num_entries(z, 0); ++i) {
    zip_stat_t st;
    zip_stat_index(z, static_cast<zip_uint64_t>(i), 0, &st);
    zip_file_t* f = zip_fopen_index(z, static_cast<zip_uint64_t>(i), 0);
    std::string bytes(st.size, '\0');
    EXPECT_EQ(zip_fread(f, bytes.data(), st.size), static_cast<zip_int64_t>(st.size));
    zip_fclose(f);
    out[st.name] = std::move(bytes);
  }
  zip_discard(z);
  return out;
}

inline std::string ReadFileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

inline bool HasProgram(const char* name) {
  return std::system((std::string("command -v ") + name + " >/dev/null 2>&1").c_str()) == 0;
}

// The duplex OBJ built into a store in `dir`, and its self-clash pairs (clearance 0.05), each pair a
// group of its own (keys from the objects' names), at most `max_groups`.
struct StoreRun {
  std::string store;
  std::unique_ptr<StoreReader> reader;
  ClashRun run;
};

inline std::unique_ptr<StoreRun> DuplexRun(const testing::TempDir& dir, size_t max_groups) {
  const std::string obj = std::string(MKTREE_SHARED_DATA) + "/buildings/duplex.obj";
  if (!std::filesystem::exists(obj)) return nullptr;
  auto out = std::make_unique<StoreRun>();
  out->store = dir.file("duplex.mkt");
  std::vector<SceneOpener> in{[obj](ObjectId first) { return OpenObjFile(obj, first); }};
  auto built = BuildStore(in, out->store, IngestOptions{});
  EXPECT_TRUE(built.ok()) << built.status().ToString();
  auto db = Database::Open(out->store);
  EXPECT_TRUE(db.ok());
  std::vector<ClashPair> pairs;
  ClashOptions o;
  o.clearance = 0.05;
  EXPECT_TRUE((*db)
                  ->SelfClash(
                      o, [&](const ClashPair& p) { pairs.push_back(p); }, nullptr)
                  .ok());
  std::stable_sort(pairs.begin(), pairs.end(), [](const ClashPair& x, const ClashPair& y) {
    return static_cast<int>(x.cls) < static_cast<int>(y.cls) || (x.cls == y.cls && x.distance < y.distance);
  });
  out->run.store = out->store;
  out->run.tests.push_back(
      {.name = "self", .mode = "clearance", .clearance = 0.05, .touch_tolerance = 0.002});
  ClashTestSummary& t = out->run.tests[0];
  for (const ClashPair& p : pairs) {
    (p.cls == ClashClass::kHard ? t.hard : p.cls == ClashClass::kTouch ? t.touch : t.clearance_pairs)++;
    if (out->run.groups.size() == max_groups) continue;
    auto ra = (*db)->Object(p.a);
    auto rb = (*db)->Object(p.b);
    EXPECT_TRUE(ra.ok() && rb.ok());
    ObjectIdentity a = Ident(p.a, ra->name, "", ""), b = Ident(p.b, rb->name, "", "");
    a.source = b.source = ra->source;
    ClashRecord r = Record("self", a, b, p.cls, p.distance, ClashStatus::kNone);
    r.pair = p;
    Box3d box = ra->box;
    for (int k = 0; k < 3; ++k)
      box.min[k] = std::min(box.min[k], rb->box.min[k]), box.max[k] = std::max(box.max[k], rb->box.max[k]);
    out->run.groups.push_back(Group("self", "self|" + std::to_string(p.a) + "|" + std::to_string(p.b),
                                    ra->name + " and " + rb->name, {r}, box, ClashStatus::kNone));
  }
  auto reader = StoreReader::Open(out->store);
  EXPECT_TRUE(reader.ok());
  out->reader = std::move(*reader);
  return out;
}

}  // namespace mktree
