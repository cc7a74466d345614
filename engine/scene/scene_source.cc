#include "engine/scene/scene_source.h"

#include <algorithm>
#include <filesystem>

#include "engine/scene/assimp_reader.h"
#include "engine/scene/mkscene_format.h"
#include "engine/scene/obj_reader.h"

namespace mktree {

Result<std::unique_ptr<SceneSource>> OpenSceneFile(const std::string& path, ObjectId first_id) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".obj") return OpenObjFile(path, first_id);  // streamed; assimp would load it whole
  if (ext == ".mks") return OpenMkSceneFile(path, first_id);
  return OpenAssimpFile(path, first_id);
}

}  // namespace mktree
