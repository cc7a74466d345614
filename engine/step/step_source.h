// The STEP reader's scene source inside the OCCT module (engine/scene/step_reader.h says what it produces).
// Thread-safety: one thread at a time, as any SceneSource.
#pragma once

#include <memory>
#include <string>

#include "engine/scene/scene_source.h"

namespace mktree {

// Reads `path` (the document and its leaves now, the meshes as Next takes them).
Result<std::unique_ptr<SceneSource>> OpenStepSource(const std::string& path, ObjectId first_id,
                                                    const SceneReadOptions& options);

}  // namespace mktree
