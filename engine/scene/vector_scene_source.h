// A SceneSource over objects already in RAM (tests, benchmarks, API users with their own meshes).
// Ids are reassigned from `first_id` in vector order.
#pragma once

#include <vector>

#include "engine/scene/scene_source.h"

namespace mktree {

class VectorSceneSource final : public SceneSource {
 public:
  VectorSceneSource(const std::vector<SceneObject>* objects, ObjectId first_id)
      : objects_(objects), next_id_(first_id) {}
  Result<bool> Next(SceneObject* out) override {
    if (at_ >= objects_->size()) return false;
    *out = (*objects_)[at_++];
    out->id = next_id_++;
    return true;
  }

 private:
  const std::vector<SceneObject>* objects_;
  size_t at_ = 0;
  ObjectId next_id_;
};

}  // namespace mktree
