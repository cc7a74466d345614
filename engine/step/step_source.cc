#include "engine/step/step_source.h"

#include <BRepTools.hxx>
#include <Standard_ErrorHandler.hxx>
#include <Standard_Failure.hxx>
#include <TopoDS_TShape.hxx>
#include <cmath>
#include <unordered_map>
#include <vector>

#include "engine/step/occt_signal_guard.h"
#include "engine/step/step_assembly.h"
#include "engine/step/step_document.h"
#include "engine/step/step_tessellation.h"

namespace mktree {

namespace {

constexpr size_t kLeavesNamedInWarning = 5;

class StepSource final : public SceneSource {
 public:
  StepSource(std::string path, ObjectId first_id, const SceneReadOptions& options, StepDocument document,
             std::vector<StepLeaf> leaves)
      : path_(std::move(path)),
        next_id_(first_id),
        options_(options),
        document_(std::move(document)),
        leaves_(std::move(leaves)) {
    for (const StepLeaf& leaf : leaves_) ++instances_left_[leaf.shape.TShape().get()];
  }
  ~StepSource() override {
    leaves_.clear();
    CloseStepDocument(&document_);
  }

  Result<bool> Next(SceneObject* out) override {
    while (next_leaf_ < leaves_.size()) {
      StepLeaf& leaf = leaves_[next_leaf_++];
      StepTessellation t =
          TessellateStepShape(leaf.shape, options_.chord_tolerance, options_.angular_deflection);
      ReleaseTriangulation(leaf.shape);
      if (t.mesh.triangles.empty()) {
        NoteSkipped(leaf, t);
        continue;
      }
      if (t.faces_without_mesh > 0) NoteHoles(leaf, t);
      for (double v : t.mesh.vertices)
        if (!std::isfinite(v) || std::abs(v) > kMaxCoordinate)
          return Status::Corruption(path_ + ": " + leaf.path + " (product '" + leaf.product +
                                    "'): a coordinate beyond the largest a scene may hold");
      out->id = next_id_++;
      out->name = leaf.path;
      out->source = path_;
      out->attributes.clear();
      out->attributes.push_back({"step_product", leaf.product});
      out->attributes.push_back({"step_path", leaf.path});
      for (const std::string& c : leaf.colours) out->attributes.push_back({"step_colour", c});
      out->attributes.push_back({"step_schema", document_.schema});
      out->mesh = std::move(t.mesh);
      leaf = StepLeaf();  // its shape and strings are not needed again
      return true;
    }
    return false;
  }

  std::vector<std::string> TakeWarnings() override {
    std::vector<std::string> out;
    if (!skipped_.empty()) {
      std::string names;
      for (size_t i = 0; i < skipped_.size() && i < kLeavesNamedInWarning; ++i)
        names += (i ? "; " : "") + skipped_[i];
      out.push_back(path_ + ": " + std::to_string(skipped_.size()) +
                    " STEP shape(s) gave no triangle and were left out: " + names +
                    (skipped_.size() > kLeavesNamedInWarning ? "; ..." : ""));
    }
    if (!holed_.empty()) {
      std::string names;
      for (size_t i = 0; i < holed_.size() && i < kLeavesNamedInWarning; ++i)
        names += (i ? "; " : "") + holed_[i];
      out.push_back(path_ + ": " + std::to_string(holed_.size()) +
                    " STEP shape(s) have faces that gave no triangle (their meshes have holes): " + names +
                    (holed_.size() > kLeavesNamedInWarning ? "; ..." : ""));
    }
    if (document_.read_failure_count > 0) {
      out.push_back(path_ + ": OpenCASCADE reported " + std::to_string(document_.read_failure_count) +
                    " failure(s) while reading (what failed is missing), the first: " +
                    document_.read_failures.front());
      document_.read_failure_count = 0;
    }
    skipped_.clear();
    holed_.clear();
    return out;
  }

 private:
  // Each part is meshed once; its triangulation goes when its last instance has been taken.
  void ReleaseTriangulation(const TopoDS_Shape& shape) {
    auto it = instances_left_.find(shape.TShape().get());
    if (it == instances_left_.end() || --it->second > 0) return;
    instances_left_.erase(it);
    try {
      BRepTools::Clean(shape);
    } catch (const Standard_Failure&) {
      // Only memory is at stake: the triangulation stays.
    }
  }

  static std::string Describe(const StepLeaf& leaf) {
    return leaf.path + " (product '" + leaf.product + "')";
  }

  void NoteSkipped(const StepLeaf& leaf, const StepTessellation& t) {
    std::string why =
        t.failure.empty() ? std::to_string(t.faces) + " face(s), none meshed" : "OpenCASCADE: " + t.failure;
    skipped_.push_back(Describe(leaf) + ": " + why);
  }
  void NoteHoles(const StepLeaf& leaf, const StepTessellation& t) {
    holed_.push_back(Describe(leaf) + ": " + std::to_string(t.faces_without_mesh) + " of " +
                     std::to_string(t.faces) + " faces");
  }

  std::string path_;
  ObjectId next_id_;
  SceneReadOptions options_;
  StepDocument document_;
  std::vector<StepLeaf> leaves_;
  size_t next_leaf_ = 0;
  std::unordered_map<const TopoDS_TShape*, int> instances_left_;
  std::vector<std::string> skipped_, holed_;
};

}  // namespace

Result<std::unique_ptr<SceneSource>> OpenStepSource(const std::string& path, ObjectId first_id,
                                                    const SceneReadOptions& options) {
  MKTREE_ASSIGN_OR_RETURN(StepDocument document, ReadStepDocument(path));
  Result<std::vector<StepLeaf>> leaves = Status::Internal(path + ": no leaves");
  {
    const OcctSignalGuard signals;
    try {
      OCC_CATCH_SIGNALS
      leaves = CollectStepLeaves(document.doc, path);
    } catch (const Standard_Failure& e) {
      leaves =
          Status::Corruption(path + ": OpenCASCADE failed walking the assembly: " + e.GetMessageString());
    }
  }
  if (!leaves.ok()) {
    CloseStepDocument(&document);
    return leaves.status();
  }
  return std::unique_ptr<SceneSource>(
      std::make_unique<StepSource>(path, first_id, options, std::move(document), std::move(*leaves)));
}

}  // namespace mktree
