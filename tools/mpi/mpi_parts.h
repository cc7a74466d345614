// The stores a rank of mktree-mpi reads (docs/shards.md, "On MPI ranks"): the shards of a sharded store as
// built, or the parts of a revision of one that has taken changes (docs/changes.md, "Sharded stores"): its
// base's shards, then its delta stores, with the objects each no longer answers for hidden. Every rank
// answers the same revision: rank 0 chooses it (the one asked for, else the newest) and holds it, then the
// others hold it too, so no writer retires it while a rank reads.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/query/store_database.h"
#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"

namespace mktree {

// One part opened on a rank.
struct RankStore {
  uint32_t index = 0;  // among the revision's parts: the base's shards, then the deltas
  std::unique_ptr<StoreDatabase> db;
  std::vector<ObjectId> ids;  // local id -> global id
  std::vector<bool> hidden;   // by local id: not live at the revision (empty: every object is)
  uint64_t hidden_count = 0;

  bool Hidden(ObjectId local) const { return hidden_count && hidden[local]; }
  ClashPart AsClashPart() const { return ClashPart{&db->leaves(), &ids, hidden_count ? &hidden : nullptr}; }
};

// The revision the ranks answer, held on this rank, and how its parts fall to the ranks.
struct RankRevision {
  std::string manifest_path;
  std::unique_ptr<RevisionHold> hold;  // null: the store as built
  Manifest base;                       // the base's manifest: the store's as built
  uint64_t revision = 0;
  uint64_t live = 0;  // objects at the revision

  uint32_t shard_count() const { return static_cast<uint32_t>(base.shards.size()); }
  uint32_t part_count() const;
  // The rank answering for part `index`: a shard's is where the build wrote it (RankOfShard), a delta's
  // its shard's rank (unrouted deltas go round the ranks).
  int OwnerOf(uint32_t index, int ranks) const;
  // " and D delta stores (revision R)" for a revision, empty as built: for the closing lines.
  std::string DeltaNote() const;
};

// Collective: the revision `revision` (unset: the newest) of the sharded store at `manifest_path`, held on
// every rank. A store file that is not a manifest is refused, as before.
Result<RankRevision> HoldRankRevision(const std::string& manifest_path, std::optional<uint64_t> revision,
                                      int rank);

// The parts `open` marks (by index, part_count() of them), each with its share of cache_pages over all the
// revision's parts, as the one-process Database, checked as it checks them.
Result<std::vector<RankStore>> OpenRankStores(const RankRevision& r, const std::vector<uint8_t>& open,
                                              uint64_t cache_pages);

// Collective: Corruption on every rank unless the live objects of the parts each rank owns sum to the
// revision's (every object answered by exactly one rank).
Status CheckOwnedLive(const RankRevision& r, const std::vector<RankStore>& parts, int rank, int ranks);

}  // namespace mktree
