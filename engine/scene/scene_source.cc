#include "engine/scene/scene_source.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "engine/scene/assimp_reader.h"
#include "engine/scene/ifc_reader.h"
#include "engine/scene/mkscene_format.h"
#include "engine/scene/obj_reader.h"
#include "engine/scene/step_reader.h"

namespace mktree {

Result<int> OpenSceneInput(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) return Status::NotFound(path + ": no such file");
    return Status::IOError(path + ": " + std::strerror(err));
  }
  struct stat st;
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || ::fcntl(fd, F_SETFL, 0) != 0) {
    ::close(fd);
    return Status::IOError(path + ": not a regular file");
  }
  return fd;
}

Result<std::unique_ptr<SceneSource>> OpenSceneFile(const std::string& path, ObjectId first_id,
                                                   const SceneReadOptions& options) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  if (ext == ".obj") {  // streamed; assimp would load it whole
    ObjReadOptions obj_options;
    obj_options.spill_dir = options.spill_dir;
    return OpenObjFile(path, first_id, obj_options);
  }
  if (ext == ".mks") return OpenMkSceneFile(path, first_id);
  if (ext == ".ifc" && !IfcThroughAssimp()) return OpenIfcFile(path, first_id, options.spill_dir);
  if (ext == ".mkifcs") return OpenIfcStreamFile(path, first_id);
  if (ext == ".step" || ext == ".stp") return OpenStepFile(path, first_id, options);
  return OpenAssimpFile(path, first_id);
}

Result<std::unique_ptr<SceneSource>> OpenSceneFile(const std::string& path, ObjectId first_id,
                                                   const std::string& spill_dir) {
  SceneReadOptions options;
  options.spill_dir = spill_dir;
  return OpenSceneFile(path, first_id, options);
}

}  // namespace mktree
