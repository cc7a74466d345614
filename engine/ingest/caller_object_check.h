// The checks a caller's object passes before a build takes it (BuildFromObjects, a change batch's added
// and replacing objects), as the scene readers check a file's: whole coordinate triples and triangles, at
// least one triangle, finite coordinates within kMaxCoordinate, indices below the vertex count.
// Thread safety: a free function.
#pragma once

#include <string>

#include "mktree/scene.h"
#include "mktree/status.h"

namespace mktree {

// InvalidArgument "<what>: ..." naming the first fault.
Status CheckCallerObject(const SceneObject& obj, const std::string& what);

}  // namespace mktree
