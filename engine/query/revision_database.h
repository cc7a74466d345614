// The Database over one revision of a store that has taken changes (docs/changes.md): the revision's base
// and delta stores, each a StoreDatabase whose local ids an id file maps to global ones, with the objects
// each part no longer answers for (removed since, or superseded by a later part) hidden. Queries, batches
// and clashes visit every part and skip hidden objects; Object and ObjectGeometry read the one part where
// the id is live. Database::Open calls it for a store with a changes folder.
// Thread safety: as Database: every const method may run on many threads at once.
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/query/store_database.h"
#include "engine/revision/change_folder.h"
#include "mktree/database.h"

namespace mktree {

// One store of a revision, opened and checked: the base store, one shard of a sharded base (the parts of a
// base hold disjoint ids), or a delta.
struct RevisionPartDb {
  std::unique_ptr<StoreDatabase> db;
  bool base = false;
  uint32_t index = 0;         // its place among the revision's parts: a sharded base's shards, then deltas
  std::vector<ObjectId> ids;  // local id -> global id, increasing; empty: identity
  std::vector<bool> hidden;   // by local id: not live at this revision
  uint64_t hidden_count = 0;
  ObjectId global(ObjectId local) const { return ids.empty() ? local : ids[local]; }
};

// The part of `parts` where `id` is live and its local id there; none when it is removed or never given.
std::optional<std::pair<size_t, ObjectId>> FindLive(const std::vector<RevisionPartDb>& parts, ObjectId id);

// The parts of revision `m` in the changes folder of `store_path`, each file checked against the manifest
// (size, fingerprint, id file of this store's history), with the hidden objects marked. A base that is a
// sharded store's manifest gives a part per shard, first (its shard files in the folder). Each part gets
// cache_pages / parts pages (rounded up). Corruption naming the file when a check fails. Parts of `reuse`
// (may be null) whose store file is one of m's are taken from it instead of opened again (a writer's
// parts from one revision to the next). A writer, which reads leaves whole, drops the leaf filters
// (ReadOptions::keep_leaf_filter). `open` (null: all) chooses the parts to open by index (mktree-mpi's
// ranks each open some): of a delta left closed only its id file is read, for the hidden marks of the parts
// before it, and the revision's live count is checked only when every part is open.
Result<std::vector<RevisionPartDb>> OpenRevisionParts(const std::string& store_path,
                                                      const RevisionManifest& m, const OpenOptions& options,
                                                      std::vector<RevisionPartDb>* reuse = nullptr,
                                                      bool keep_leaf_filters = true,
                                                      const std::vector<uint8_t>* open = nullptr);

// The number of parts of revision `m`, open or not: a sharded base's shards (`base_shards`; 0 or 1: the
// base is one store) and the deltas.
inline size_t RevisionPartCount(const RevisionManifest& m, size_t base_shards) {
  return std::max<size_t>(base_shards, 1) + m.deltas.size();
}

// The number of base parts of `parts` (1, or a sharded base's shards): they come first.
size_t BasePartCount(const std::vector<RevisionPartDb>& parts);

// The manifest of the revision `db` answers, when db is a revision of a store with changes; else null.
const RevisionManifest* RevisionManifestOf(const Database& db);

// The ids the batches after revision `since` up to db's revision touched (added, replaced, removed), from
// db's manifest, sorted. InvalidArgument when db is not a revision of a store with changes.
Result<std::vector<ObjectId>> TouchedSince(const Database& db, uint64_t since);

// db's self-clash limited to the pairs with an object in `focus` (global ids): RunMultiClash's focus over
// the revision's parts. A Database of a store without changes runs it over its one store, a sharded store
// over its shards. With `partner` (may be null): only the pairs with one object in `focus` and the other
// in `partner` (MultiClashScope::partner).
Status FocusedSelfClash(const Database& db, const std::vector<ObjectId>& focus, const ClashOptions& options,
                        const ClashVisitor& visit, ClashStats* stats,
                        const std::vector<ObjectId>* partner = nullptr);

// The stores of db's revision as clash parts (leaves, global ids, hidden objects); empty when db is not a
// revision of a store with changes. Valid while db is open.
std::vector<ClashPart> RevisionClashParts(const Database& db);

// Opens the revision `hold` holds, and keeps holding it for the Database's life.
Result<std::unique_ptr<Database>> OpenRevisionDatabase(const std::string& store_path,
                                                       std::unique_ptr<RevisionHold> hold,
                                                       const OpenOptions& options);

}  // namespace mktree
