// The Database over a store that is already open. Database::Open opens the file and calls this; tests open
// the StoreReader themselves to wrap its pages (StoreReader::WrapPages) before querying through it.
#pragma once

#include <memory>
#include <string>

#include "engine/clash/clash_engine.h"
#include "engine/store/store_file.h"
#include "mktree/database.h"

namespace mktree {

std::unique_ptr<Database> OpenStoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options);
// The clash engine's view (reader, page cache, checks) of a Database made by OpenStoreDatabase; the
// sharded store runs one clash over its shards' stores with it.
ClashStore StoreClashView(const Database& store);
// A sharded store's manifest and its shards (engine/query/sharded_database.cc, docs/shards.md).
Result<std::unique_ptr<Database>> OpenShardedDatabase(const std::string& manifest_path,
                                                      const OpenOptions& options);

}  // namespace mktree
