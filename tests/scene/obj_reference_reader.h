// The OBJ reader as it was before it went parallel (a single thread reading the file through a buffer,
// numbers through std::from_chars), kept as the reference the parallel reader must match object for object
// and error for error. Only source and attributes were added, the simplest way.
#pragma once

#include <memory>
#include <string>
#include <string_view>

#include "engine/scene/scene_source.h"

namespace mktree::reference {

Result<std::unique_ptr<SceneSource>> OpenObjFile(const std::string& path, ObjectId first_id = 0);
// One coordinate token as the reader takes it (std::from_chars; see ParseObjCoordinate).
bool ParseCoordinate(std::string_view tok, double* out, std::string* why);

}  // namespace mktree::reference
