// The level-k colouring of docs/design.md §9, read from a store: every object with its group at its depth-k
// ancestor node, visited leaf by leaf straight from the leaf pages, so that `mktree export` and
// `mktree render` hold one leaf (plus their own output state) in RAM, never the scene.
//
// Colours (the paper's figures): blue = Sn1 side (WW/W), red = Sn2 side (BB/B), green = overlap set Sm,
// grey = objects whose leaf is at depth <= k (LevelGroup::kAboveLevel: no node at depth k splits them).
//
// Thread safety: ForEachObjectAtLevel reads `store` (const) only; it may run on many threads at once.
#pragma once

#include <array>
#include <cstdint>
#include <functional>

#include "engine/store_format/object_codec.h"
#include "engine/store_format/store_file.h"
#include "engine/viz/level_groups.h"
#include "mktree/status.h"

namespace mktree {

struct Rgb {
  uint8_t r = 0, g = 0, b = 0;
  bool operator==(const Rgb&) const = default;
};

inline constexpr int kLevelGroups = 4;  // LevelGroup values, usable as array indices
inline int GroupIndex(LevelGroup g) { return static_cast<int>(g); }
Rgb GroupColour(LevelGroup g);
// "Sn1", "Sn2", "Sm", "above" (for reports and legends).
const char* GroupName(LevelGroup g);

// Objects per group, indexed by GroupIndex.
using GroupCounts = std::array<uint64_t, kLevelGroups>;

// Called once per object, in leaf order. `entry.geometry` is valid only during the call (decode it with
// DecodeObjectMesh if needed). A non-ok status stops the scan and is returned.
using LevelVisitor = std::function<Status(uint32_t leaf, const ObjectEntryView& entry, LevelGroup group)>;

// Reads every leaf of `store` once (through a PageCache that holds only the pinned leaf) and calls `visit`
// for each of its objects with its group at level `k` (GroupAtLevel, level_groups.h). `progress` (optional)
// gets (leaves done, leaves total). Errors (unreadable or corrupt pages) name the store and page. REQUIRES: k
// >= 0.
Status ForEachObjectAtLevel(const StoreReader& store, int k, const LevelVisitor& visit,
                            const std::function<void(uint64_t, uint64_t)>& progress = {});

}  // namespace mktree
