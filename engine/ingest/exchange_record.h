// A scene object as the ranks of the distributed build send it to each other and spill it
// (engine/ingest/distributed_build.h): u32 id, name, source, u32 attribute count, (key, value)...,
// u32 vertex count, f64 xyz..., u32 triangle count, u32 abc... (strings: u32 length, bytes), little-endian.
// World coordinates in float64, so the receiver's store is bit for bit the one a single process builds.
// A spill file holds such records one after the other, each preceded by its u32 length.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "engine/scene/scene_source.h"
#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// Appends the record of `object` to *out.
void EncodeExchangeRecord(const SceneObject& object, std::vector<uint8_t>* out);
// A spill file's records as a source, in file order (IOError naming the file when it cannot be read or
// ends inside a record, Internal for a damaged record). Thread-safety: one thread at a time.
Result<std::unique_ptr<SceneSource>> OpenExchangeSpill(const std::string& path);

}  // namespace mktree
