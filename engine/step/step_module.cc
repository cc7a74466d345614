// libmktree_step.so's entry points (engine/scene/step_reader.h: the module's interface). Nothing else of
// the module is visible outside it.
#include <exception>

#include "engine/scene/step_reader.h"
#include "engine/step/step_source.h"

extern "C" __attribute__((visibility("default"))) const char* mktree_step_module_abi() {
  return MKTREE_STEP_MODULE_ABI;
}

extern "C" __attribute__((visibility("default"))) void mktree_step_module_open(
    mktree::StepModuleRequest* request) {
  try {
    auto source = mktree::OpenStepSource(*request->path, request->first_id, *request->options);
    if (source.ok())
      *request->source = std::move(*source);
    else
      *request->status = source.status();
  } catch (const std::exception& e) {
    *request->status = mktree::Status::Internal(*request->path + ": the STEP reader failed: " + e.what());
  } catch (...) {
    *request->status = mktree::Status::Internal(*request->path + ": the STEP reader failed");
  }
}
