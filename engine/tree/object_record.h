// BuildObject: what the tree builder keeps in RAM per object, never its geometry. Ingest makes one per
// object as it spills the object's entry (engine/ingest/store_builder.h); BuildMKTree consumes them.
#pragma once

#include <cstdint>

#include "mktree/geometry.h"
#include "mktree/scene.h"

namespace mktree {

struct BuildObject {
  ObjectId id = 0;
  uint32_t encoded_bytes = 0;  // bytes this object takes in a leaf page (entry header included)
  Box3f box;                   // in the store's frame
};

}  // namespace mktree
