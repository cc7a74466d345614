// Groups: one object hit by many clashes is one group; proximity groups are the single-linkage components
// of the clashes' places (checked against all pairs); the groups, their keys and members do not depend on
// the order the records come in.
#include "engine/coordination/clash_groups.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <numeric>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "engine/coordination/clash_keys.h"

namespace mktree {
namespace {

ObjectIdentity Object(int i, const Vec3d& at, double half = 0.1) {
  ObjectIdentity o;
  o.id = static_cast<ObjectId>(i);
  o.name = "o" + std::to_string(i);
  o.stable = "m.ifc|G" + std::to_string(i);
  for (int k = 0; k < 3; ++k) o.box.min[k] = at[k] - half, o.box.max[k] = at[k] + half;
  return o;
}

ClashRecord Record(const ObjectIdentity& a, const ObjectIdentity& b, ClashClass cls, double distance) {
  ClashRecord r;
  r.a = std::make_shared<const ObjectIdentity>(a);
  r.b = std::make_shared<const ObjectIdentity>(b);
  r.key = coordination::ClashKey("t", a.stable, b.stable);
  r.pair.a = a.id;
  r.pair.b = b.id;
  r.pair.cls = cls;
  r.pair.distance = distance;
  return r;
}

std::set<std::set<std::string>> Partition(const std::vector<ClashGroup>& groups) {
  std::set<std::set<std::string>> out;
  for (const ClashGroup& g : groups) {
    std::set<std::string> keys;
    for (const ClashRecord& r : g.members) keys.insert(r.key);
    out.insert(keys);
  }
  return out;
}

TEST(ClashGroups, OneBeamHitByTwelvePipesIsOneGroup) {
  std::vector<ClashRecord> records;
  const ObjectIdentity beam = Object(100, {0, 0, 0}, 5);
  for (int i = 0; i < 12; ++i)
    records.push_back(Record(Object(i, {i * 0.4, 0, 0}), beam,
                             i == 3 ? ClashClass::kHard : ClashClass::kTouch, i == 3 ? -0.02 : 0));
  records.push_back(Record(Object(20, {50, 0, 0}), Object(21, {50.1, 0, 0}), ClashClass::kClearance, 0.01));
  const auto groups = coordination::GroupClashes("t", records, ClashGrouping::kElement, 1);
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(groups[0].members.size(), 12u);  // worst first
  EXPECT_EQ(groups[0].worst, ClashClass::kHard);
  EXPECT_EQ(groups[0].worst_distance, -0.02);
  EXPECT_EQ(groups[0].key, coordination::Hex64(coordination::StableHash("element\nt\n" + beam.stable)));
  EXPECT_NE(groups[0].title.find("o100"), std::string::npos);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(groups[0].box.min[k], -5);
    EXPECT_EQ(groups[0].box.max[k], 5);
    EXPECT_EQ(groups[0].centre[k], 0);
  }
  EXPECT_EQ(groups[1].worst, ClashClass::kClearance);
  EXPECT_TRUE(std::is_sorted(groups[0].members.begin(), groups[0].members.end(),
                             [](const ClashRecord& x, const ClashRecord& y) { return x.key < y.key; }));
}

TEST(ClashGroups, ProximityIsSingleLinkageAndOrderFree) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0, 20);
  std::vector<ClashRecord> records;
  std::vector<Vec3d> at;
  for (int i = 0; i < 300; ++i) {
    const Vec3d p{u(rng), u(rng), u(rng) / 10};
    // Two objects whose boxes overlap around p: the clash's place is p.
    records.push_back(Record(Object(2 * i, {p.x - 0.05, p.y, p.z}), Object(2 * i + 1, {p.x + 0.05, p.y, p.z}),
                             ClashClass::kHard, -0.01));
    at.push_back(p);
  }
  const double d = 0.9;
  // Brute force: components of the graph joining places within d.
  std::vector<int> comp(at.size());
  std::iota(comp.begin(), comp.end(), 0);
  for (bool changed = true; changed;) {
    changed = false;
    for (size_t i = 0; i < at.size(); ++i)
      for (size_t j = 0; j < at.size(); ++j) {
        const double dx = at[i].x - at[j].x, dy = at[i].y - at[j].y, dz = at[i].z - at[j].z;
        if (dx * dx + dy * dy + dz * dz <= d * d && comp[j] < comp[i]) comp[i] = comp[j], changed = true;
      }
  }
  std::map<int, std::set<std::string>> want_by;
  for (size_t i = 0; i < at.size(); ++i) want_by[comp[i]].insert(records[i].key);
  std::set<std::set<std::string>> want;
  for (auto& [c, keys] : want_by) want.insert(keys);
  const auto groups = coordination::GroupClashes("t", records, ClashGrouping::kProximity, d);
  EXPECT_EQ(Partition(groups), want);
  EXPECT_GT(want.size(), 10u);
  EXPECT_LT(want.size(), at.size());
  // Any order of the records, and the element grouping too: the same groups.
  for (ClashGrouping by : {ClashGrouping::kProximity, ClashGrouping::kElement}) {
    const auto base = coordination::GroupClashes("t", records, by, d);
    auto shuffled = records;
    std::shuffle(shuffled.begin(), shuffled.end(), rng);
    for (ClashRecord& r : shuffled) std::swap(r.a, r.b);
    const auto again = coordination::GroupClashes("t", shuffled, by, d);
    ASSERT_EQ(again.size(), base.size());
    for (size_t i = 0; i < base.size(); ++i) {
      EXPECT_EQ(again[i].key, base[i].key);
      EXPECT_EQ(again[i].members.size(), base[i].members.size());
    }
  }
}

TEST(ClashGroups, StatusOfAGroup) {
  ClashGroup g;
  g.key = "k";
  ClashRecord a = Record(Object(1, {0, 0, 0}), Object(2, {0, 0, 0}), ClashClass::kTouch, 0);
  ClashRecord b = Record(Object(3, {0, 0, 0}), Object(4, {0, 0, 0}), ClashClass::kTouch, 0);
  a.status = ClashStatus::kActive;
  b.status = ClashStatus::kResolved;
  g.members = {a, b};
  coordination::FinishGroup(&g);
  EXPECT_EQ(g.status, ClashStatus::kActive);
  g.members[0].status = ClashStatus::kNew;
  coordination::FinishGroup(&g);
  EXPECT_EQ(g.status, ClashStatus::kNew);
  for (ClashRecord& r : g.members) r.status = ClashStatus::kResolved;
  coordination::FinishGroup(&g);
  EXPECT_EQ(g.status, ClashStatus::kResolved);
}

}  // namespace
}  // namespace mktree
