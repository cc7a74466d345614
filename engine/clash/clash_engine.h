// The clash engine over an open store: the self-clash of every object pair and the clash of one mesh
// against the store, out of core (docs/clash.md §3). Database::SelfClash and Database::Collide call these.
#pragma once

#include <optional>

#include "engine/store/store_file.h"
#include "mktree/clash.h"
#include "mktree/status.h"
#include "storage/page_cache.h"

namespace mktree {

// Where the engine reads: the store, its page cache, and whether pages are verified on first read.
struct ClashStore {
  const StoreReader& reader;
  PageCache& cache;
  bool verify_checksums = true;
};

// Every pair of the store's objects that clashes under `options`, to `visit` in the plan's order.
// `stats` (may be null) is reset and filled. Errors name the store.
Status RunSelfClash(const ClashStore& store, const ClashOptions& options, const ClashVisitor& visit,
                    ClashStats* stats);

// Every object of the store that clashes with `mesh` (world coordinates) moved by `transform`; pairs
// have b = kCollideObject. InvalidArgument for an empty mesh, a non-finite vertex, an index out of range
// or a transform that is not a proper rotation.
Status RunCollide(const ClashStore& store, const Mesh& mesh, const std::optional<RigidTransform>& transform,
                  const ClashOptions& options, const ClashVisitor& visit, ClashStats* stats);

}  // namespace mktree
