#include "engine/ingest/shard_build.h"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>

#include "engine/store/store_file.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// Every input in order, numbered globally from 0, as BuildStore numbers them.
class AllInputs {
 public:
  explicit AllInputs(const std::vector<SceneOpener>& inputs) : inputs_(inputs) {}
  Result<bool> Next(SceneObject* obj) {
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
  std::vector<std::string>& warnings() { return warnings_; }

 private:
  const std::vector<SceneOpener>& inputs_;
  size_t input_ = 0;
  ObjectId next_id_ = 0;
  std::unique_ptr<SceneSource> source_;
  std::vector<std::string> warnings_;
};

// The objects of one shard, renumbered from first_id; their global ids go to *ids.
class ShardSource final : public SceneSource {
 public:
  ShardSource(const std::vector<SceneOpener>& inputs, const TopLevels& top, uint32_t shard, ObjectId first_id,
              std::vector<ObjectId>* ids)
      : all_(inputs), top_(top), shard_(shard), next_local_(first_id), ids_(ids) {}
  Result<bool> Next(SceneObject* out) override {
    for (;;) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, all_.Next(out));
      if (!more) return false;
      if (top_.ShardOf(out->mesh.Bounds()) != shard_) continue;
      ids_->push_back(out->id);
      out->id = next_local_++;
      return true;
    }
  }

 private:
  AllInputs all_;
  const TopLevels& top_;
  uint32_t shard_;
  ObjectId next_local_;
  std::vector<ObjectId>* ids_;
};

// The files this build made, removed unless it succeeds.
struct Staged {
  std::vector<std::string> paths;
  bool keep = false;
  ~Staged() {
    if (keep) return;
    for (const std::string& p : paths) {
      std::error_code ec;
      std::filesystem::remove(p, ec);
    }
  }
};

Status Rename(const std::string& from, const std::string& to) {
  if (std::rename(from.c_str(), to.c_str()) != 0)
    return Status::IOError(to + ": rename from " + from + ": " + std::strerror(errno));
  return Status::Ok();
}

}  // namespace

Result<ShardedBuildReport> BuildShardedStore(const std::vector<SceneOpener>& inputs,
                                             const std::string& manifest_path, const IngestOptions& options,
                                             uint32_t shards) {
  const auto start = Clock::now();
  ShardedBuildReport report;
  if (shards == 0 || shards > 65536) return Status::InvalidArgument("shards must be from 1 to 65536");
  if (manifest_path.empty()) return Status::InvalidArgument("the store path is empty");
  if (std::filesystem::is_directory(manifest_path))
    return Status::InvalidArgument(manifest_path + ": not a regular file");

  // 1. The sample and the scene's frame, in one pass.
  ShardSample sample;
  Manifest& m = report.manifest;
  {
    AllInputs all(inputs);
    SceneObject obj;
    bool first = true;
    for (;;) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, all.Next(&obj));
      if (!more) break;
      const Box3d box = obj.mesh.Bounds();
      if (first) m.origin = options.origin ? *options.origin : ChooseStoreOrigin(box);
      first = false;
      sample.Add(obj.id, box);
      ++m.objects;
      if (options.progress && m.objects % (1u << 16) == 0) options.progress(IngestStage::kRead, m.objects, 0);
    }
    report.warnings = std::move(all.warnings());
  }
  if (m.objects == 0)
    return Status::InvalidArgument((options.input_name.empty()
                                        ? manifest_path + ": not built"
                                        : options.input_name + ": " + manifest_path + " not built") +
                                   ": empty scene, no object with geometry in the input");
  report.sample_objects = sample.size();
  MKTREE_ASSIGN_OR_RETURN(m.top, ChooseTopLevels(sample.Items(), shards));
  report.sample_seconds = Seconds(start);
  // Any 64-bit value that differs between builds: the id files carry it, so a shard of another build is
  // refused even if its store happens to fingerprint alike.
  m.build_id = std::random_device{}() ^ (uint64_t{std::random_device{}()} << 32) ^
               static_cast<uint64_t>(Clock::now().time_since_epoch().count());

  // 2. The shards, one after the other, under staging names.
  Staged staged;
  std::vector<std::pair<std::string, std::string>> renames;
  for (uint32_t s = 0; s < shards; ++s) {
    const std::string store_path = ShardStorePath(manifest_path, s),
                      ids_path = ShardIdsPath(manifest_path, s);
    const std::string store_new = store_path + ".new", ids_new = ids_path + ".new";
    IngestOptions o = options;
    o.origin = m.origin;
    o.input_name = (options.input_name.empty() ? std::string() : options.input_name + ": ") + "shard " +
                   std::to_string(s);
    std::vector<ObjectId> ids;
    const SceneOpener opener = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
      ids.clear();
      return std::unique_ptr<SceneSource>(std::make_unique<ShardSource>(inputs, m.top, s, first, &ids));
    };
    staged.paths.push_back(store_new);
    auto built = BuildStore({opener}, store_new, o);
    if (!built.ok()) return built.status();  // names the shard's store or the input's file and line
    if (ids.size() != built->objects)
      return Status::Internal(store_new + ": id count differs from the store's");
    for (std::string& w : built->warnings) report.warnings.push_back("shard " + std::to_string(s) + ": " + w);
    ShardEntry e;
    e.objects = ids.size();
    {
      MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(store_new));
      e.box = reader->tree().nodes[0].box;
    }
    staged.paths.push_back(ids_new);
    MKTREE_RETURN_IF_ERROR(WriteShardIds(ids_new, m.build_id, s, ids));
    MKTREE_ASSIGN_OR_RETURN(e.store, FingerprintFile(store_new));
    MKTREE_ASSIGN_OR_RETURN(e.ids, FingerprintFile(ids_new));
    e.store.name = std::filesystem::path(store_path).filename().string();
    e.ids.name = std::filesystem::path(ids_path).filename().string();
    report.store_bytes += e.store.bytes + e.ids.bytes;
    m.shards.push_back(std::move(e));
    report.shards.push_back(std::move(*built));
    renames.push_back({store_new, store_path});
    renames.push_back({ids_new, ids_path});
  }

  // 3. Into place, the manifest last (atomic: a temporary renamed over the path).
  for (const auto& [from, to] : renames) {
    MKTREE_RETURN_IF_ERROR(Rename(from, to));
    staged.paths.push_back(to);
  }
  MKTREE_RETURN_IF_ERROR(WriteManifest(manifest_path, m));
  staged.keep = true;
  report.total_seconds = Seconds(start);
  return report;
}

}  // namespace mktree
