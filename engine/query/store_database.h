// The Database over a store that is already open. Database::Open opens the file and calls this; tests open
// the StoreReader themselves to wrap its pages (StoreReader::WrapPages) before querying through it.
#pragma once

#include <memory>
#include <string>

#include "engine/store/store_file.h"
#include "mktree/database.h"

namespace mktree {

std::unique_ptr<Database> OpenStoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options);
// A sharded store's manifest and its shards (engine/query/sharded_database.cc, docs/shards.md).
Result<std::unique_ptr<Database>> OpenShardedDatabase(const std::string& manifest_path,
                                                      const OpenOptions& options);

}  // namespace mktree
