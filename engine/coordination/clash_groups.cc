#include "engine/coordination/clash_groups.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>
#include <string_view>
#include <tuple>
#include <unordered_map>

#include "engine/coordination/clash_keys.h"

namespace mktree::coordination {

namespace {

int ClassRank(ClashClass c) { return c == ClashClass::kHard ? 0 : c == ClashClass::kTouch ? 1 : 2; }

// Where a clash is, for proximity: the middle of the overlap of the two objects' boxes (of the gap between
// them for a clearance pair), which depends on the geometry only; the engine's contact point depends on
// which object is a (the lower id). A resolved record without boxes: the middle of its points.
Vec3d Where(const ClashRecord& r) {
  if (r.a->box.empty() || r.b->box.empty()) {
    const ClashPair& p = r.pair;
    return {(p.point_a.x + p.point_b.x) / 2, (p.point_a.y + p.point_b.y) / 2,
            (p.point_a.z + p.point_b.z) / 2};
  }
  Vec3d at;
  for (int i = 0; i < 3; ++i)
    at[i] = (std::max(r.a->box.min[i], r.b->box.min[i]) + std::min(r.a->box.max[i], r.b->box.max[i])) / 2;
  return at;
}

void Grow(Box3d* box, const Box3d& b) {
  if (b.empty()) return;
  box->Extend(b.min[0], b.min[1], b.min[2]);
  box->Extend(b.max[0], b.max[1], b.max[2]);
}

std::string Describe(const ObjectIdentity& o) {
  std::string s = o.name.empty() ? o.stable : o.name;
  if (!o.ifc_type.empty()) s = o.ifc_type + " " + s;
  return s;
}

// Records are taken in `order` (their indices by key) and moved into the groups.
std::vector<ClashGroup> ByElement(const std::string& test, std::vector<ClashRecord>* records,
                                  const std::vector<uint32_t>& order) {
  // Nodes: distinct stable identities; each node's clashes in key order.
  std::unordered_map<std::string_view, uint32_t> node_of;
  std::vector<std::string_view> identity;
  std::vector<std::vector<uint32_t>> incident;
  auto add = [&](std::string_view id, uint32_t record) {
    auto [it, added] = node_of.try_emplace(id, static_cast<uint32_t>(identity.size()));
    if (added) {
      identity.push_back(id);
      incident.emplace_back();
    }
    incident[it->second].push_back(record);
  };
  for (uint32_t i : order) {
    const ClashRecord& r = (*records)[i];
    add(r.a->stable, i);
    if (r.b->stable != r.a->stable) add(r.b->stable, i);
  }
  std::vector<uint32_t> nodes(identity.size());
  std::iota(nodes.begin(), nodes.end(), 0);
  std::sort(nodes.begin(), nodes.end(), [&](uint32_t x, uint32_t y) {
    if (incident[x].size() != incident[y].size()) return incident[x].size() > incident[y].size();
    return identity[x] < identity[y];
  });
  std::vector<uint8_t> taken(records->size(), 0);
  std::vector<std::vector<uint32_t>> members;
  std::vector<uint32_t> anchors;
  for (uint32_t n : nodes) {
    std::vector<uint32_t> m;
    for (uint32_t i : incident[n])
      if (!taken[i]) m.push_back(i), taken[i] = 1;
    if (m.empty()) continue;
    members.push_back(std::move(m));
    anchors.push_back(n);
  }
  std::vector<ClashGroup> groups(members.size());
  for (size_t k = 0; k < members.size(); ++k) {
    ClashGroup& g = groups[k];
    const std::string anchor_id(identity[anchors[k]]);
    g.key = Hex64(StableHash("element\n" + test + "\n" + anchor_id));
    const ClashRecord& first = (*records)[members[k].front()];
    const ObjectIdentity& anchor = first.a->stable == anchor_id ? *first.a : *first.b;
    const ObjectIdentity& other = first.a->stable == anchor_id ? *first.b : *first.a;
    g.title = members[k].size() == 1
                  ? Describe(anchor) + " with " + Describe(other)
                  : Describe(anchor) + ": " + std::to_string(members[k].size()) + " clashes";
  }
  // The records move last: the identities above are views into them.
  for (size_t k = 0; k < members.size(); ++k) {
    groups[k].members.reserve(members[k].size());
    for (uint32_t i : members[k]) groups[k].members.push_back(std::move((*records)[i]));
  }
  return groups;
}

struct UnionFind {
  std::vector<size_t> parent;
  explicit UnionFind(size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  size_t Find(size_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  }
  void Join(size_t x, size_t y) {
    x = Find(x);
    y = Find(y);
    if (x != y) parent[std::max(x, y)] = std::min(x, y);
  }
};

std::vector<ClashGroup> ByProximity(const std::string& test, std::vector<ClashRecord>* unordered,
                                    const std::vector<uint32_t>& order, double d) {
  std::vector<ClashRecord> sorted;
  sorted.reserve(order.size());
  for (uint32_t i : order) sorted.push_back(std::move((*unordered)[i]));
  std::vector<ClashRecord>* records = &sorted;
  const size_t n = records->size();
  std::vector<Vec3d> at(n);
  using Cell = std::tuple<int64_t, int64_t, int64_t>;
  struct CellHash {
    size_t operator()(const Cell& c) const {
      return std::hash<int64_t>()(std::get<0>(c) * 73856093 ^ std::get<1>(c) * 19349663 ^
                                  std::get<2>(c) * 83492791);
    }
  };
  std::unordered_map<Cell, std::vector<size_t>, CellHash> grid;
  auto cell = [&](const Vec3d& p) {
    return Cell{static_cast<int64_t>(std::floor(p.x / d)), static_cast<int64_t>(std::floor(p.y / d)),
                static_cast<int64_t>(std::floor(p.z / d))};
  };
  for (size_t i = 0; i < n; ++i) {
    at[i] = Where((*records)[i]);
    grid[cell(at[i])].push_back(i);
  }
  UnionFind uf(n);
  for (size_t i = 0; i < n; ++i) {
    const auto [cx, cy, cz] = cell(at[i]);
    for (int64_t dx = -1; dx <= 1; ++dx)
      for (int64_t dy = -1; dy <= 1; ++dy)
        for (int64_t dz = -1; dz <= 1; ++dz) {
          auto it = grid.find(Cell{cx + dx, cy + dy, cz + dz});
          if (it == grid.end()) continue;
          for (size_t j : it->second) {
            if (j <= i) continue;
            const double ex = at[i].x - at[j].x, ey = at[i].y - at[j].y, ez = at[i].z - at[j].z;
            if (ex * ex + ey * ey + ez * ez <= d * d) uf.Join(i, j);
          }
        }
  }
  std::map<size_t, ClashGroup> by_root;
  for (size_t i = 0; i < n; ++i) by_root[uf.Find(i)].members.push_back(std::move((*records)[i]));
  std::vector<ClashGroup> groups;
  for (auto& [root, g] : by_root) {
    std::string smallest = g.members.front().key;
    for (const ClashRecord& r : g.members) smallest = std::min(smallest, r.key);
    g.key = Hex64(StableHash("proximity\n" + test + "\n" + smallest));
    groups.push_back(std::move(g));
  }
  return groups;
}

}  // namespace

void FinishGroup(ClashGroup* g) {
  auto by_key = [](const ClashRecord& x, const ClashRecord& y) { return x.key < y.key; };
  if (!std::is_sorted(g->members.begin(), g->members.end(), by_key))
    std::sort(g->members.begin(), g->members.end(), by_key);
  int worst = 3;
  bool any_new = false, all_resolved = true, any_status = false;
  for (ClashRecord& r : g->members) {
    Grow(&g->box, r.a->box);
    Grow(&g->box, r.b->box);
    if (r.a->box.empty() || r.b->box.empty()) {
      g->box.Extend(r.pair.point_a.x, r.pair.point_a.y, r.pair.point_a.z);
      g->box.Extend(r.pair.point_b.x, r.pair.point_b.y, r.pair.point_b.z);
    }
    const int rank = ClassRank(r.pair.cls);
    if (rank < worst) {
      worst = rank;
      g->worst = r.pair.cls;
      g->worst_distance = r.pair.distance;
    } else if (rank == worst) {
      g->worst_distance = std::min(g->worst_distance, r.pair.distance);
    }
    any_status |= r.status != ClashStatus::kNone;
    any_new |= r.status == ClashStatus::kNew;
    all_resolved &= r.status == ClashStatus::kResolved;
  }
  for (int i = 0; i < 3; ++i) g->centre[i] = g->box.empty() ? 0 : (g->box.min[i] + g->box.max[i]) / 2;
  g->status = !any_status    ? ClashStatus::kNone
              : any_new      ? ClashStatus::kNew
              : all_resolved ? ClashStatus::kResolved
                             : ClashStatus::kActive;
  if (g->title.empty()) {
    char at[96];
    std::snprintf(at, sizeof at, "%zu clash%s near (%.3f, %.3f, %.3f)", g->members.size(),
                  g->members.size() == 1 ? "" : "es", g->centre.x, g->centre.y, g->centre.z);
    g->title = at;
  }
}

bool WorseGroup(const ClashGroup& x, const ClashGroup& y) {
  const int rx = ClassRank(x.worst), ry = ClassRank(y.worst);
  if (rx != ry) return rx < ry;
  if (x.worst_distance != y.worst_distance) return x.worst_distance < y.worst_distance;
  return x.key < y.key;
}

std::vector<ClashGroup> GroupClashes(const std::string& test, std::vector<ClashRecord> records,
                                     ClashGrouping grouping, double distance) {
  // Key order first, so that ties and unions do not depend on the order the records came in (indices
  // sorted, then each record moved once).
  std::vector<uint32_t> order(records.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](uint32_t x, uint32_t y) { return records[x].key < records[y].key; });
  std::vector<ClashGroup> groups = grouping == ClashGrouping::kElement
                                       ? ByElement(test, &records, order)
                                       : ByProximity(test, &records, order, distance);
  for (ClashGroup& g : groups) {
    g.test = test;
    FinishGroup(&g);
  }
  std::sort(groups.begin(), groups.end(), WorseGroup);
  return groups;
}

}  // namespace mktree::coordination
