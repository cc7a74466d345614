// The Database over a store that is already open. Database::Open opens the file and calls this; tests open
// the StoreReader themselves to wrap its pages (StoreReader::WrapPages) before querying through it.
#pragma once

#include <memory>

#include "engine/store/store_file.h"
#include "mktree/database.h"

namespace mktree {

std::unique_ptr<Database> OpenStoreDatabase(std::unique_ptr<StoreReader> reader, const OpenOptions& options);

}  // namespace mktree
