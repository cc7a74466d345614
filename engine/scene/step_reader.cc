#include "engine/scene/step_reader.h"

#include <dlfcn.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "engine/scene/scene_source.h"

namespace mktree {

namespace {

// Where the module may lie, in the order tried: $MKTREE_STEP_MODULE alone if set; else beside the object
// holding this code as installed (libmktree.so in the library folder, the mktree program in the programs'
// folder), so that an installed tree may move; then the build tree; then the install prefix of the build.
std::vector<std::string> StepModuleCandidates() {
  if (const char* env = std::getenv("MKTREE_STEP_MODULE"); env && *env) return {env};
  std::vector<std::string> out;
  Dl_info self;
  if (::dladdr(reinterpret_cast<void*>(&StepModuleCandidates), &self) && self.dli_fname) {
    const std::string object = self.dli_fname;
    const std::string dir = object.substr(0, object.rfind('/') + 1);
    out.push_back(dir + "mktree/libmktree_step.so");
    out.push_back(dir + MKTREE_STEP_MODULE_BIN_TO_LIB "/mktree/libmktree_step.so");
  }
  out.push_back(MKTREE_STEP_MODULE_BUILD_PATH);
  out.push_back(MKTREE_STEP_MODULE_INSTALL_PATH);
  return out;
}

struct LoadedStepModule {
  StepModuleOpenFunction open = nullptr;
  std::string error;  // why no module was loaded
};

// The module is loaded once and never unloaded: its sources may outlive any caller.
LoadedStepModule LoadStepModule() {
  LoadedStepModule loaded;
  std::string tried;
  for (const std::string& path : StepModuleCandidates()) {
    tried += (tried.empty() ? "" : "; ") + path;
    void* handle = ::dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (!handle) {
      const char* error = ::dlerror();
      std::string why = error ? error : "not loaded";
      if (why.rfind(path + ": ", 0) == 0) why.erase(0, path.size() + 2);  // dlerror names the path too
      tried += ": " + why;
      continue;
    }
    auto abi = reinterpret_cast<StepModuleAbiFunction>(::dlsym(handle, kStepModuleAbiSymbol));
    auto open = reinterpret_cast<StepModuleOpenFunction>(::dlsym(handle, kStepModuleOpenSymbol));
    if (!abi || !open || std::strcmp(abi(), MKTREE_STEP_MODULE_ABI) != 0) {
      tried += ": built from other headers (ABI tag differs)";
      ::dlclose(handle);
      continue;
    }
    loaded.open = open;
    return loaded;
  }
  loaded.error = "the STEP reader's module (libmktree_step.so, OpenCASCADE) is not available: tried " + tried;
  return loaded;
}

}  // namespace

Result<std::unique_ptr<SceneSource>> OpenStepFile(const std::string& path, ObjectId first_id,
                                                  const SceneReadOptions& options) {
  if (!(std::isfinite(options.chord_tolerance) && options.chord_tolerance > 0))
    return Status::InvalidArgument(path + ": the chord tolerance must be a positive number of metres, not " +
                                   std::to_string(options.chord_tolerance));
  if (!(std::isfinite(options.angular_deflection) && options.angular_deflection > 0))
    return Status::InvalidArgument(path +
                                   ": the angular deflection must be a positive number of radians, not " +
                                   std::to_string(options.angular_deflection));
  static const LoadedStepModule module = LoadStepModule();
  if (!module.open) return Status::Unsupported(path + ": " + module.error);
  std::unique_ptr<SceneSource> source;
  Status status = Status::Internal(path + ": the STEP module gave no answer");
  StepModuleRequest request;
  request.path = &path;
  request.first_id = first_id;
  request.options = &options;
  request.source = &source;
  request.status = &status;
  module.open(&request);
  if (!source) return status;
  return source;
}

}  // namespace mktree
