// The checks of BuildMKTree's REQUIRES (mktree_builder.h): parameters, finite boxes with min <= max, unique
// ids. Each error is InvalidArgument and names the first bad object in input order. Internal to engine/tree.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/tree/build_memory.h"
#include "engine/tree/mktree.h"
#include "engine/tree/object_record.h"
#include "mktree/geometry.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree::build {

// The checks of BuildMKTree's REQUIRES but unique ids (CheckUniqueIds), the per-record ones on two halves;
// an error names the first bad record in input order. *bounds: the union of the boxes (the layout's).
Status Validate(const std::vector<BuildObject>& records, const BuildParams& params, int threads,
                Box3f* bounds, ObjectId* max_id);

// Unique ids, checked in input order before the layout: a bitmap when ids are dense (the normal 0-based
// case), else a sorted copy of the ids. An error names the first object in input order whose id came
// before (the bitmap), or the least duplicate id (the sorted copy).
Status CheckUniqueIds(const std::vector<BuildObject>& records, ObjectId max_id);

}  // namespace mktree::build
