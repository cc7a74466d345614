// A build's inputs as one scene source: each input opened in turn at the id after the previous input's
// last (as BuildStore numbers them), its ids checked to follow on, its warnings kept until taken.
// Thread safety: one thread at a time, as any SceneSource.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "engine/ingest/store_builder.h"
#include "engine/scene/scene_source.h"

namespace mktree {

// An input as BuildFromFiles takes it: a scene file (refused at once when missing or not a regular file)
// or "tanker:N[:SEED]", which builds straight from the generator. A scene reader's scratch file goes to
// `read.spill_dir`.
Result<SceneOpener> OpenerForInput(const std::string& input, const SceneReadOptions& read);

class SceneInputs final : public SceneSource {
 public:
  // `inputs` must outlive this source.
  explicit SceneInputs(const std::vector<SceneOpener>& inputs) : inputs_(inputs) {}

  // The next object of the inputs; false after the last input's last. Internal if an input's ids do not
  // follow on, InvalidArgument past 2^32 - 1 objects.
  Result<bool> Next(SceneObject* obj) override {
    for (;;) {
      if (!source_) {
        if (input_ == inputs_.size()) return false;
        MKTREE_ASSIGN_OR_RETURN(source_, inputs_[input_](next_id_));
      }
      MKTREE_ASSIGN_OR_RETURN(const bool more, source_->Next(obj));
      if (more) break;
      for (std::string& w : source_->TakeWarnings()) warnings_.push_back(std::move(w));
      source_.reset();
      ++input_;
    }
    if (obj->id != next_id_)
      return Status::Internal("object '" + obj->name + "': source gave id " + std::to_string(obj->id) +
                              ", expected " + std::to_string(next_id_));
    if (next_id_ == kNoIndex) return Status::InvalidArgument("too many objects: ids are 32-bit");
    ++next_id_;
    return true;
  }
  // The warnings of the inputs finished so far, in input order, and no longer kept here.
  std::vector<std::string> TakeWarnings() override {
    std::vector<std::string> out;
    out.swap(warnings_);
    return out;
  }
  ObjectId objects_read() const { return next_id_; }

 private:
  const std::vector<SceneOpener>& inputs_;
  size_t input_ = 0;
  ObjectId next_id_ = 0;
  std::unique_ptr<SceneSource> source_;
  std::vector<std::string> warnings_;
};

}  // namespace mktree
