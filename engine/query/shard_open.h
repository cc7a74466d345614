// One shard of a sharded store (docs/shards.md), opened and checked as the sharded Database opens each of
// its shards: the store's and the id file's sizes and fingerprints against the manifest's, the store's
// object count, root box and frame against the manifest's, the id file of the manifest's build. Used by
// OpenShardedDatabase and by mktree-mpi, which opens only some of a manifest's shards on each rank.
// Thread-safety: a free function; the shard's Database is as thread-safe as any Database.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "engine/query/store_database.h"
#include "engine/shard/manifest.h"
#include "mktree/database.h"

namespace mktree {

struct ManifestShard {
  std::unique_ptr<StoreDatabase> db;  // the shard's store, answering with local ids
  std::vector<ObjectId> ids;          // local id -> global id, increasing
};

// Shard s of manifest m read from manifest_path; `shard_options` are the shard's own (its share of the
// cache). Corruption naming the file and the shard when a check fails. Global ids are below `id_limit`
// (0: m.objects, a sharded build's ids; a compaction's shards keep the ids of the live objects, which may
// have gaps, docs/changes.md).
Result<ManifestShard> OpenManifestShard(const std::string& manifest_path, const Manifest& m, uint32_t s,
                                        const OpenOptions& shard_options, uint64_t id_limit = 0,
                                        bool keep_leaf_filter = true);

}  // namespace mktree
