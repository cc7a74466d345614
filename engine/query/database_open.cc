// Database::Open: the one entry point above the implementations: a sharded store's manifest
// (sharded_database.h), a store that has taken changes (revision_database.h) or a store file alone
// (store_database.h).
#include "engine/core/guarded.h"
#include "engine/query/revision_database.h"
#include "engine/query/sharded_database.h"
#include "engine/query/store_database.h"
#include "engine/revision/change_folder.h"
#include "engine/shard/manifest.h"
#include "engine/store_format/store_file.h"
#include "mktree/database.h"

namespace mktree {

Result<std::unique_ptr<Database>> Database::Open(const std::string& path, const OpenOptions& options) {
  return Guarded(path, [&]() -> Result<std::unique_ptr<Database>> {
    // A store file, or a sharded store's manifest: either may have taken changes (a revision holds them).
    MKTREE_ASSIGN_OR_RETURN(StoreRevision at, OpenStoreRevision(path, options.revision));
    if (at.hold) return OpenRevisionDatabase(path, std::move(at.hold), options);
    if (IsManifestFile(path)) return OpenShardedDatabase(path, options);
    ReadOptions ro;
    ro.direct_io = options.direct_io;
    MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(path, ro));
    return std::unique_ptr<Database>(OpenStoreDatabase(std::move(reader), options));
  });
}

}  // namespace mktree
