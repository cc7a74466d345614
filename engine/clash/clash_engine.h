// The clash engine over an open store: the self-clash of every object pair and the clash of one mesh
// against the store, out of core (docs/clash.md §3). Database::SelfClash and Database::Collide call these.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "engine/store_format/leaf_source.h"
#include "mktree/clash.h"
#include "mktree/status.h"

namespace mktree {

// Every pair of the store's objects that clashes under `options`, to `visit` in the plan's order.
// `stats` (may be null) is reset and filled. Errors name the store.
Status RunSelfClash(const LeafSource& leaves, const ClashOptions& options, const ClashVisitor& visit,
                    ClashStats* stats);

// One store of a clash over several stores (the shards of a sharded store, or the base and delta stores
// of a revision: one frame): its leaves, the global id of each local id (increasing; null: the local ids
// are the global ones), and the objects that are not there (hidden[local id]: an object removed or
// superseded since the store was written; null: none). A hidden object takes part in no pair: it is no
// candidate, no excluded pair, and its mesh is not decoded; the visible objects of all parts have
// distinct global ids (a hidden one may share its id with a visible one of another part).
// REQUIRES: hidden, when set, has one flag per object of the store.
struct ClashPart {
  const LeafSource* leaves = nullptr;
  const std::vector<ObjectId>* ids = nullptr;
  const std::vector<bool>* hidden = nullptr;
};

// Which pairs of parts (i <= j; i == j: the pairs inside part i) a clash over several stores covers.
using ClashPartPairs = std::function<bool(uint32_t i, uint32_t j)>;

// What a clash over several stores covers: the part pairs `want` accepts (null: all), and of their object
// pairs only those with at least one object in `focus` (global ids in any order, repeats and ids no part
// holds ignored; null: every pair). A focused clash costs in proportion to the focus: each focused object's
// record is read (straight from its store, not counted in ClashStats, as the names of exclusions are) for
// its leaf and box, the traversal descends only into subtrees that hold a focused object, and a leaf pair
// whose leaf filter admits no pair with a focused object is neither read nor tested. candidate_pairs and
// excluded_pairs count only pairs with a focused object.
// With `partner` as well (a set against a set: clash tests, engine/coordination/): only the pairs with one
// object in `focus` and the other in `partner` (an object may be in both); the traversal descends only
// into node pairs where one side may hold a focused object and the other a partner, and a leaf pair whose
// leaf filter admits no such object pair is neither read nor tested. Needs `focus`.
struct MultiClashScope {
  ClashPartPairs want;
  const std::vector<ObjectId>* focus = nullptr;
  const std::vector<ObjectId>* partner = nullptr;
};

// The self-clash of the union of `parts` within `scope`: each object pair is found once, by the one part
// pair holding its two objects, in one sweep over the leaves of all parts (each leaf read about once).
// Pairs carry global ids; exclusions see global ids and names. The statistics sum the parts' (store_pages:
// of all parts). RunSelfClash is this with one part.
Status RunMultiClash(const std::vector<ClashPart>& parts, const MultiClashScope& scope,
                     const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats);
// The same limited to the part pairs `want` accepts (null: all), without a focus.
Status RunMultiClash(const std::vector<ClashPart>& parts, const ClashPartPairs& want,
                     const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats);

// Every object of the store that clashes with `mesh` (world coordinates) moved by `transform`; pairs
// have b = kCollideObject. InvalidArgument for an empty mesh, a non-finite vertex, an index out of range
// or a transform that is not a proper rotation.
Status RunCollide(const LeafSource& leaves, const Mesh& mesh, const std::optional<RigidTransform>& transform,
                  const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats);
// The same over one part: pairs and the exclusion predicate carry its global ids, and its hidden objects
// are no candidates (not counted). Internal when the part's id map or hidden flags do not match its
// objects.
Status RunCollide(const ClashPart& part, const Mesh& mesh, const std::optional<RigidTransform>& transform,
                  const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats);

// Adds the counts and phase seconds of `b` to `a` (the window's bytes: the larger; total_seconds is left
// to the caller): a run over several stores or ranks.
void AddClashStats(ClashStats* a, const ClashStats& b);

// RunCollide's checks of its mesh and transform (the same InvalidArgument).
Status CheckCollideMesh(const Mesh& mesh, const std::optional<RigidTransform>& transform);

}  // namespace mktree
