// The Database over a sharded store (docs/shards.md): a manifest, and the shards' stores, each held as a
// StoreDatabase whose local ids the shard's id file maps to global ones. Database::Open calls
// OpenShardedDatabase for a manifest.
// Thread safety: as Database: every const method may run on many threads at once.
#pragma once

#include <memory>
#include <string>

#include "engine/clash/clash_engine.h"
#include "mktree/database.h"

namespace mktree {

// Opens the manifest and every shard it names, checking each shard's files against the manifest (sizes,
// checksums, object counts, bounds, frame) and that every global id is in exactly one shard. Each shard
// gets a cache of options.cache_pages / shard count pages (rounded up). Errors name the file and the shard.
Result<std::unique_ptr<Database>> OpenShardedDatabase(const std::string& manifest_path,
                                                      const OpenOptions& options);

// The shards of a sharded store as clash parts (leaves and global ids); empty when `db` is not one.
std::vector<ClashPart> ShardedClashParts(const Database& db);

// A sharded store's self-clash within `scope` (MultiClashScope: focus and partner sets of global ids; the
// part pairs filter is ignored). Unsupported when `db` is not a sharded store.
Status ShardedScopedClash(const Database& db, const MultiClashScope& scope, const ClashOptions& options,
                          const ClashVisitor& visit, ClashStats* stats);

}  // namespace mktree
