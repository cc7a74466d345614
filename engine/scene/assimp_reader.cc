#include "engine/scene/assimp_reader.h"

#include <assimp/config.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <pthread.h>

#include <algorithm>
#include <array>
#include <assimp/Importer.hpp>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <limits>
#include <system_error>
#include <utility>
#include <vector>

#include "engine/scene/assimp_input_checks.h"
#include "engine/scene/assimp_metadata.h"

namespace mktree {
namespace {

// The import thread's stack (address space; pages are committed only as deep as the import reaches).
// Depth costs about 1.3 KiB a node level in assimp's glTF importer, whose files are checked to at most
// kMaxNodeDepth levels; formats without a check get room for a few hundred thousand levels.
constexpr size_t kImportStackBytes = size_t{512} << 20;

// Row-major affine transform in double precision (assimp's own matrices are float).
struct Transform {
  std::array<std::array<double, 4>, 3> m{{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};

  static Transform FromAssimp(const aiMatrix4x4& a) {
    Transform t;
    const ai_real* rows[3] = {a[0], a[1], a[2]};
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) t.m[r][c] = rows[r][c];
    return t;
  }
  // this * o (apply o first).
  Transform Then(const Transform& o) const {
    Transform t;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        double v = m[r][0] * o.m[0][c] + m[r][1] * o.m[1][c] + m[r][2] * o.m[2][c];
        if (c == 3) v += m[r][3];
        t.m[r][c] = v;
      }
    }
    return t;
  }
  void Apply(const aiVector3D& p, double out[3]) const {
    for (int r = 0; r < 3; ++r) out[r] = m[r][0] * p.x + m[r][1] * p.y + m[r][2] * p.z + m[r][3];
  }
};

bool IsTriangleMesh(const aiMesh& mesh) {
  // SortByPType leaves one primitive type per mesh (plus the n-gon encoding flag on some importers).
  constexpr unsigned kDropped = aiPrimitiveType_POINT | aiPrimitiveType_LINE;
  return mesh.mNumFaces > 0 && (mesh.mPrimitiveTypes & kDropped) == 0 &&
         (mesh.mPrimitiveTypes & (aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON)) != 0;
}

class AssimpReader final : public SceneSource {
 public:
  AssimpReader(std::string path, std::unique_ptr<Assimp::Importer> importer, const aiScene* scene,
               ObjectId first_id)
      : path_(std::move(path)),
        ifc_(IsIfcPath(path_)),
        importer_(std::move(importer)),
        scene_(scene),
        next_id_(first_id) {
    if (scene_->mRootNode != nullptr)
      stack_.push_back({scene_->mRootNode, Transform::FromAssimp(scene_->mRootNode->mTransformation)});
  }

  Result<bool> Next(SceneObject* out) override {
    while (!stack_.empty()) {
      auto [node, world] = std::move(stack_.back());
      stack_.pop_back();
      // Children pushed in reverse so that they pop in file order.
      for (unsigned i = node->mNumChildren; i-- > 0;) {
        const aiNode* child = node->mChildren[i];
        stack_.push_back({child, world.Then(Transform::FromAssimp(child->mTransformation))});
      }
      Mesh mesh;
      MKTREE_RETURN_IF_ERROR(Convert(*node, world, &mesh));
      if (mesh.triangle_count() == 0) continue;
      if (next_id_ > std::numeric_limits<ObjectId>::max())
        return Status::InvalidArgument(path_ + ": more than 2^32 objects");
      out->id = static_cast<ObjectId>(next_id_++);
      out->name =
          node->mName.length > 0 ? std::string(node->mName.C_Str()) : "object_" + std::to_string(out->id);
      out->source = path_;
      out->attributes.clear();
      if (ifc_) {
        // A product's mapped representation (an IfcMappedItem node: doors, windows, furniture) belongs to
        // the nearest ancestor that names an IFC product, whose type, GlobalId and properties it takes.
        for (const aiNode* n = node; n != nullptr; n = n->mParent) {
          if (!AppendIfcNameAttributes(std::string_view(n->mName.C_Str(), n->mName.length), &out->attributes))
            continue;
          if (n != node && n->mMetaData != nullptr) AppendMetadataAttributes(*n->mMetaData, &out->attributes);
          break;
        }
      }
      if (node->mMetaData != nullptr) AppendMetadataAttributes(*node->mMetaData, &out->attributes);
      out->mesh = std::move(mesh);
      coarse_.Check(*out);
      return true;
    }
    return false;
  }

  std::vector<std::string> TakeWarnings() override {
    std::vector<std::string> w;
    if (coarse_.count > 0) w.push_back(coarse_.Warning(path_));
    coarse_ = {};
    return w;
  }

 private:
  struct Pending {
    const aiNode* node;
    Transform world;
  };

  // Objects whose coordinates, as the float32 values assimp holds them in, resolve less than 2^-10 of
  // their size: the detail was lost in the reader, before mktree's double-precision path.
  struct CoarseObjects {
    uint64_t count = 0;
    double worst_ratio = 0, worst_size = 0, worst_distance = 0;
    std::string worst_name;

    void Check(const SceneObject& obj) {
      const Box3d b = obj.mesh.Bounds();
      double size = 0, distance = 0;
      for (int i = 0; i < 3; ++i) {
        size = std::max(size, b.max[i] - b.min[i]);
        distance = std::max({distance, std::fabs(b.min[i]), std::fabs(b.max[i])});
      }
      const double resolution = distance * 0x1p-24;
      if (resolution <= size * 0x1p-10) return;
      ++count;
      const double ratio = size > 0 ? resolution / size : std::numeric_limits<double>::infinity();
      if (count == 1 || ratio > worst_ratio) {
        worst_ratio = ratio;
        worst_size = size;
        worst_distance = distance;
        worst_name = obj.name.substr(0, 100);
        for (char& c : worst_name)
          if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
      }
    }
    std::string Warning(const std::string& path) const {
      char buf[256];
      std::snprintf(buf, sizeof buf, " (worst: '%s', size %.3g at %.3g from 0, float32 resolution %.3g)",
                    worst_name.c_str(), worst_size, worst_distance, worst_distance * 0x1p-24);
      return path + ": " + std::to_string(count) +
             " objects lie too far from 0 for the float32 coordinates assimp reads them in to keep 1/1024 of "
             "their size" +
             buf + ": convert the scene to OBJ or .mks to keep double precision";
    }
  };

  // Merges the node's triangle meshes into `out`, keeping only vertices that triangles use.
  Status Convert(const aiNode& node, const Transform& world, Mesh* out) {
    for (unsigned k = 0; k < node.mNumMeshes; ++k) {
      if (node.mMeshes[k] >= scene_->mNumMeshes) {
        return Status::Corruption(path_ + ": node '" + node.mName.C_Str() + "' references a missing mesh");
      }
      const aiMesh& mesh = *scene_->mMeshes[node.mMeshes[k]];
      if (!IsTriangleMesh(mesh)) continue;
      remap_.assign(mesh.mNumVertices, kUnused);
      for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
        const aiFace& face = mesh.mFaces[f];
        if (face.mNumIndices < 3) continue;  // a stray point/line left in a triangle mesh carries no area
        local_.clear();
        for (unsigned j = 0; j < face.mNumIndices; ++j) {
          unsigned v = face.mIndices[j];
          if (v >= mesh.mNumVertices) {
            return Status::Corruption(path_ + ": node '" + node.mName.C_Str() +
                                      "': vertex index out of range");
          }
          if (remap_[v] == kUnused) {
            const aiVector3D& p = mesh.mVertices[v];
            double w[3];
            world.Apply(p, w);
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z) || !std::isfinite(w[0]) ||
                !std::isfinite(w[1]) || !std::isfinite(w[2])) {
              return Status::Corruption(
                  path_ + ": node '" + node.mName.C_Str() +
                  "': non-finite vertex coordinate (in the file or after its transform)");
            }
            if (std::fabs(w[0]) > kMaxCoordinate || std::fabs(w[1]) > kMaxCoordinate ||
                std::fabs(w[2]) > kMaxCoordinate)
              return Status::Corruption(
                  path_ + ": node '" + node.mName.C_Str() +
                  "': vertex coordinate beyond 2^124 in magnitude (after its transform)");
            remap_[v] = static_cast<uint32_t>(out->vertex_count());
            out->vertices.insert(out->vertices.end(), w, w + 3);
          }
          local_.push_back(remap_[v]);
        }
        // Triangulate has already run; a fan only guards an importer that left a polygon behind.
        for (size_t i = 1; i + 1 < local_.size(); ++i) {
          out->triangles.insert(out->triangles.end(), {local_[0], local_[i], local_[i + 1]});
        }
      }
    }
    return Status::Ok();
  }

  static constexpr uint32_t kUnused = std::numeric_limits<uint32_t>::max();

  static bool IsIfcPath(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext == ".ifc";
  }

  const std::string path_;
  const bool ifc_;                              // node names carry the IFC entity's type, name and GlobalId
  std::unique_ptr<Assimp::Importer> importer_;  // owns scene_
  const aiScene* scene_;
  uint64_t next_id_;
  std::vector<Pending> stack_;   // nodes still to visit, with their world transforms
  std::vector<uint32_t> remap_;  // scratch: source vertex -> local index
  std::vector<uint32_t> local_;  // scratch: one face's local indices
  CoarseObjects coarse_;
};

}  // namespace

namespace {

// Runs `fn` on a thread with a `bytes` stack (or here, if no such thread can be made).
void RunWithStack(size_t bytes, const std::function<void()>& fn) {
  pthread_attr_t attr;
  pthread_t thread;
  bool started = pthread_attr_init(&attr) == 0;
  started = started && pthread_attr_setstacksize(&attr, bytes) == 0 &&
            pthread_create(
                &thread, &attr,
                [](void* f) -> void* {
                  (*static_cast<const std::function<void()>*>(f))();
                  return nullptr;
                },
                const_cast<std::function<void()>*>(&fn)) == 0;
  pthread_attr_destroy(&attr);
  if (started) {
    pthread_join(thread, nullptr);
  } else {
    fn();
  }
}

// The scene as the importer left it, before any post-processing step: JoinIdenticalVertices would merge a
// NaN vertex into another one, and deep node trees would overflow the stack of the steps that recurse.
Status ValidateImported(const aiScene& scene, const std::string& path) {
  for (unsigned m = 0; m < scene.mNumMeshes; ++m) {
    const aiMesh* mesh = scene.mMeshes[m];
    if (mesh == nullptr)
      return Status::Corruption(path + ": assimp: mesh " + std::to_string(m) + " is missing");
    const std::string name = "mesh " + std::to_string(m) +
                             (mesh->mName.length ? " '" + std::string(mesh->mName.C_Str()) + "'" : "");
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        return Status::Corruption(path + ": " + name + ": non-finite vertex coordinate (vertex " +
                                  std::to_string(v) + ")");
    }
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      for (unsigned j = 0; j < face.mNumIndices; ++j)
        if (face.mIndices[j] >= mesh->mNumVertices)
          return Status::Corruption(path + ": " + name + ": vertex index " +
                                    std::to_string(face.mIndices[j]) + " out of range (" +
                                    std::to_string(mesh->mNumVertices) + " vertices)");
    }
  }
  std::vector<std::pair<const aiNode*, uint32_t>> stack;  // node, depth (the root is 1)
  if (scene.mRootNode != nullptr) stack.push_back({scene.mRootNode, 1});
  while (!stack.empty()) {
    const auto [node, depth] = stack.back();
    stack.pop_back();
    if (depth > kMaxNodeDepth)
      return Status::Corruption(path + ": nodes nested deeper than " + std::to_string(kMaxNodeDepth) +
                                " levels");
    for (unsigned i = 0; i < node->mNumChildren; ++i) {
      if (node->mChildren[i] == nullptr) return Status::Corruption(path + ": assimp: a missing node");
      stack.push_back({node->mChildren[i], depth + 1});
    }
  }
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<SceneSource>> OpenAssimpFile(const std::string& path, ObjectId first_id) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return Status::NotFound(path + ": no such file");
  if (!std::filesystem::is_regular_file(path, ec)) return Status::IOError(path + ": not a regular file");
  MKTREE_RETURN_IF_ERROR(CheckBeforeAssimp(path));

  auto importer = std::make_unique<Assimp::Importer>();
  // Only positions matter: removing the other vertex components lets JoinIdenticalVertices merge by
  // position alone, and drops data we would throw away anyway.
  importer->SetPropertyInteger(
      AI_CONFIG_PP_RVC_FLAGS, aiComponent_NORMALS | aiComponent_TANGENTS_AND_BITANGENTS | aiComponent_COLORS |
                                  aiComponent_TEXCOORDS | aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS |
                                  aiComponent_TEXTURES | aiComponent_LIGHTS | aiComponent_CAMERAS);
  // Line and point meshes are skipped in Convert() rather than removed by SortByPType
  // (AI_CONFIG_PP_SBP_REMOVE): removal fails a file that holds only lines ("No meshes remaining"), where
  // the right answer, as for an OBJ file of `l` lines, is a scene without objects.
  // No PreTransformVertices / OptimizeMeshes / OptimizeGraph: they would merge objects or bake transforms.
  // The steps run after ValidateImported has seen the scene as read.
  constexpr unsigned kSteps = aiProcess_RemoveComponent | aiProcess_Triangulate | aiProcess_SortByPType |
                              aiProcess_JoinIdenticalVertices;
  const aiScene* scene = nullptr;
  Status status;
  // Importers recurse over the file's structure (elements, nodes): formats without a check of their own
  // (assimp_input_checks.h) are read with a stack that deep files do not exhaust.
  RunWithStack(kImportStackBytes, [&] {
    try {
      scene = importer->ReadFile(path, aiProcess_ValidateDataStructure);
      if (scene == nullptr) {
        status = Status::Corruption(path + ": assimp: " + importer->GetErrorString());
      } else if ((scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE) != 0) {
        status = Status::Corruption(path + ": assimp: the file was read only partly (incomplete scene)");
      } else if (status = ValidateImported(*scene, path); status.ok()) {
        scene = importer->ApplyPostProcessing(kSteps);
        if (scene == nullptr) status = Status::Corruption(path + ": assimp: " + importer->GetErrorString());
      }
    } catch (const std::exception& e) {
      status = Status::Corruption(path + ": assimp: " + e.what());
    } catch (...) {
      status = Status::Corruption(path + ": assimp: unknown failure");
    }
    if (!status.ok()) importer.reset();  // a refused scene may be deep: freed on this stack too
  });
  if (!status.ok()) return status;
  return std::unique_ptr<SceneSource>(new AssimpReader(path, std::move(importer), scene, first_id));
}

}  // namespace mktree
