// The parts a rank of mktree-mpi reads, of a sharded store as built or of a revision of one (mpi_parts.h).
#include "tools/mpi/mpi_parts.h"

#include <mpi.h>

#include "engine/core/guarded.h"
#include "engine/ingest/distributed_build.h"  // RankOfShard
#include "engine/query/revision_database.h"
#include "engine/query/shard_open.h"

namespace mktree {

uint32_t RankRevision::part_count() const {
  return static_cast<uint32_t>(hold ? RevisionPartCount(hold->manifest(), shard_count()) : shard_count());
}

int RankRevision::OwnerOf(uint32_t index, int ranks) const {
  const uint32_t k = shard_count();
  if (index < k) return RankOfShard(index, k, ranks);
  // A delta routed to a shard goes with it (the reader refuses a shard the base has not); one written
  // before changes were routed goes round the ranks.
  const uint32_t shard = hold->manifest().deltas[index - k].shard;
  return shard < k ? RankOfShard(shard, k, ranks)
                   : static_cast<int>((index - k) % static_cast<uint32_t>(ranks));
}

std::string RankRevision::DeltaNote() const {
  if (!hold) return "";
  return " and " + std::to_string(part_count() - shard_count()) + " delta stores (revision " +
         std::to_string(revision) + ")";
}

Result<RankRevision> HoldRankRevision(const std::string& manifest_path, std::optional<uint64_t> revision,
                                      int rank) {
  return Guarded(manifest_path, [&]() -> Result<RankRevision> {
    RankRevision r;
    r.manifest_path = manifest_path;
    // Rank 0 chooses and holds first: a revision it holds is kept until every rank holds it too.
    Status chosen;
    uint64_t choice[2] = {0, 0};  // {rank 0 holds one, which}
    if (rank == 0) {
      auto at = OpenStoreRevision(manifest_path, revision);
      if (at.ok()) {
        r.hold = std::move(at->hold);
        choice[0] = r.hold ? 1 : 0;
        choice[1] = r.hold ? r.hold->manifest().revision : 0;
      } else {
        chosen = at.status();
        choice[0] = 2;
      }
    }
    MPI_Bcast(choice, 2, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    if (!chosen.ok()) return chosen;
    if (choice[0] == 2) return Status::Internal("");  // rank 0 said why
    if (rank != 0) {
      // Revision 0 when rank 0 read the store as built: the same shards, should a first change have come
      // since (its base is the manifest as built).
      MKTREE_ASSIGN_OR_RETURN(StoreRevision at, OpenStoreRevision(manifest_path, choice[1]));
      r.hold = std::move(at.hold);
    }
    if (!r.hold) {
      MKTREE_ASSIGN_OR_RETURN(r.base, ReadManifest(manifest_path));
      r.live = r.base.objects;
      return r;
    }
    const RevisionManifest& m = r.hold->manifest();
    const std::string base_path = ChangesFile(ChangesFolder(manifest_path), m.base.store.name);
    if (!IsManifestFile(base_path))
      return Status::Unsupported(manifest_path +
                                 ": not a sharded store (mktree-mpi reads a manifest that mktree build "
                                 "--shards or mktree-mpi wrote); use mktree query or clash");
    MKTREE_ASSIGN_OR_RETURN(r.base, ReadManifest(base_path));
    r.revision = m.revision;
    r.live = m.live;
    return r;
  });
}

Result<std::vector<RankStore>> OpenRankStores(const RankRevision& r, const std::vector<uint8_t>& open,
                                              uint64_t cache_pages) {
  return Guarded(r.manifest_path, [&]() -> Result<std::vector<RankStore>> {
    std::vector<RankStore> out;
    OpenOptions options;
    if (r.hold) {
      options.cache_pages = cache_pages;
      MKTREE_ASSIGN_OR_RETURN(
          std::vector<RevisionPartDb> parts,
          OpenRevisionParts(r.manifest_path, r.hold->manifest(), options, nullptr, true, &open));
      for (RevisionPartDb& p : parts)
        out.push_back(
            RankStore{p.index, std::move(p.db), std::move(p.ids), std::move(p.hidden), p.hidden_count});
      return out;
    }
    const uint64_t k = r.shard_count();
    options.cache_pages = (cache_pages + k - 1) / k;
    for (uint32_t s = 0; s < k; ++s) {
      if (!open[s]) continue;
      MKTREE_ASSIGN_OR_RETURN(ManifestShard shard, OpenManifestShard(r.manifest_path, r.base, s, options));
      out.push_back(RankStore{s, std::move(shard.db), std::move(shard.ids), {}, 0});
    }
    return out;
  });
}

Status CheckOwnedLive(const RankRevision& r, const std::vector<RankStore>& parts, int rank, int ranks) {
  uint64_t mine = 0, all = 0;
  for (const RankStore& p : parts)
    if (r.OwnerOf(p.index, ranks) == rank) mine += p.db->object_count() - p.hidden_count;
  MPI_Allreduce(&mine, &all, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  if (all == r.live) return Status::Ok();
  if (rank != 0) return Status::Internal("");  // rank 0 says why
  return Status::Corruption(r.manifest_path + ": the ranks' stores hold " + std::to_string(all) +
                            " live objects, revision " + std::to_string(r.revision) + " has " +
                            std::to_string(r.live));
}

}  // namespace mktree
