// An answer's ids in ascending order, and the check that none is there twice: what Database::Run and a
// store's batches do with each answer before delivering it.
// Thread safety: free functions; SortIds keeps one scratch buffer per thread.
#pragma once

#include <string>
#include <vector>

#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// Sorts ids ascending (a radix sort from 64 ids).
void SortIds(std::vector<ObjectId>* ids);

// After SortIds: Corruption naming `path` if an id is there twice (an object in two leaves, which the open
// and leaf checks let through only for leaf id digests crafted to collide).
Status CheckNoRepeatedIds(const std::vector<ObjectId>& sorted, const std::string& path);

}  // namespace mktree
