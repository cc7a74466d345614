#include "engine/ingest/shard_build.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <random>
#include <string_view>

#include "engine/ingest/read_and_spill.h"
#include "engine/ingest/scene_inputs.h"
#include "engine/store_format/store_file.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// The objects of one shard (those of `all` that route to it), in order.
class FilterShard final : public SceneSource {
 public:
  FilterShard(std::unique_ptr<SceneSource> all, const TopLevels& top, uint32_t shard, ObjectBounds bounds)
      : all_(std::move(all)), top_(top), shard_(shard), bounds_(std::move(bounds)) {}
  Result<bool> Next(SceneObject* out) override {
    for (;;) {
      MKTREE_ASSIGN_OR_RETURN(const bool more, all_->Next(out));
      if (!more) return false;
      if (top_.ShardOf(bounds_ ? bounds_(*out) : out->mesh.Bounds()) == shard_) return true;
    }
  }
  // The input's warnings were reported by the scan (ScanForShards), not once per shard.

 private:
  std::unique_ptr<SceneSource> all_;
  const TopLevels& top_;
  uint32_t shard_;
  ObjectBounds bounds_;
};

// A shard's objects renumbered from first_id; their global ids go to *ids (increasing, else Internal).
class Renumber final : public SceneSource {
 public:
  Renumber(std::unique_ptr<SceneSource> objects, ObjectId first_id, std::vector<ObjectId>* ids)
      : objects_(std::move(objects)), next_local_(first_id), ids_(ids) {}
  Result<bool> Next(SceneObject* out) override {
    MKTREE_ASSIGN_OR_RETURN(const bool more, objects_->Next(out));
    if (!more) return false;
    if (!ids_->empty() && out->id <= ids_->back())
      return Status::Internal("object '" + out->name + "': shard objects out of global id order");
    ids_->push_back(out->id);
    out->id = next_local_++;
    return true;
  }
  std::vector<std::string> TakeWarnings() override { return objects_->TakeWarnings(); }

 private:
  std::unique_ptr<SceneSource> objects_;
  ObjectId next_local_;
  std::vector<ObjectId>* ids_;
};

Status Rename(const std::string& from, const std::string& to) {
  if (std::rename(from.c_str(), to.c_str()) != 0)
    return Status::IOError(to + ": rename from " + from + ": " + std::strerror(errno));
  return Status::Ok();
}

}  // namespace

Result<std::unique_ptr<ShardBuildLock>> ShardBuildLock::Acquire(const std::string& manifest_path) {
  const std::string path = manifest_path + ".build-lock";
  // A releasing build unlinks the file; if we locked a file that has just been unlinked, retry.
  for (int attempt = 0; attempt < 8; ++attempt) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd < 0) return Status::IOError(path + ": create lock file: " + std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int err = errno;
      ::close(fd);
      if (err == EWOULDBLOCK)
        return Status::IOError(manifest_path + ": another build of this sharded store is running (lock " +
                               path + " is held)");
      return Status::IOError(path + ": lock: " + std::strerror(err));
    }
    struct stat a {
    }, b{};
    if (::fstat(fd, &a) == 0 && ::stat(path.c_str(), &b) == 0 && a.st_ino == b.st_ino && a.st_dev == b.st_dev)
      return std::unique_ptr<ShardBuildLock>(new ShardBuildLock(path, fd));
    ::close(fd);
  }
  return Status::IOError(path + ": lock file keeps being replaced");
}

ShardBuildLock::~ShardBuildLock() {
  ::unlink(path_.c_str());  // while still locked: a waiting build retries on the unlinked file
  ::close(fd_);
}

size_t RemoveShardLeftovers(const std::string& manifest_path) {
  namespace fs = std::filesystem;
  const fs::path m(manifest_path);
  const fs::path dir = m.has_parent_path() ? m.parent_path() : fs::path(".");
  const std::string prefix = m.filename().string() + ".shard-";
  auto digits = [](std::string_view s) {
    return !s.empty() && s.find_first_not_of("0123456789") == std::string_view::npos;
  };
  // What follows "<manifest>.shard-N.": a staged file, its temporary or store lock, or a spill.
  auto leftover = [&](std::string_view rest) {
    for (std::string_view staged : {"mkt.new", "ids.new"}) {
      if (rest.substr(0, staged.size()) != staged) continue;
      const std::string_view tail = rest.substr(staged.size());
      if (tail.empty() || tail == ".lock" || (tail.substr(0, 5) == ".tmp." && digits(tail.substr(5))))
        return true;
    }
    return rest.substr(0, 9) == "mkt.from-" && rest.size() > 13 && rest.substr(rest.size() - 4) == ".new" &&
           digits(rest.substr(9, rest.size() - 13));
  };
  size_t removed = 0;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string_view rest = std::string_view(name).substr(prefix.size());
    const size_t dot = rest.find('.');
    if (dot == std::string_view::npos || !digits(rest.substr(0, dot)) || !leftover(rest.substr(dot + 1)))
      continue;
    std::error_code type_ec;
    if (!it->is_symlink(type_ec) && !it->is_regular_file(type_ec)) continue;  // not a file a build made
    if (::unlink(it->path().c_str()) == 0) ++removed;
  }
  return removed;
}

uint64_t NewBuildId() {
  return std::random_device{}() ^ (uint64_t{std::random_device{}()} << 32) ^
         static_cast<uint64_t>(Clock::now().time_since_epoch().count());
}

std::unique_ptr<SceneSource> ChainInputs(const std::vector<SceneOpener>& inputs) {
  return std::make_unique<SceneInputs>(inputs);
}

std::unique_ptr<SceneSource> ShardObjectsOf(std::unique_ptr<SceneSource> all, const TopLevels& top,
                                            uint32_t shard, ObjectBounds bounds) {
  return std::make_unique<FilterShard>(std::move(all), top, shard, std::move(bounds));
}

Result<ShardScan> ScanPart(SceneSource* part, const IngestOptions& options) {
  ShardScan scan;
  SceneObject obj;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, part->Next(&obj));
    if (!more) break;
    const Box3d box = obj.mesh.Bounds();
    if (scan.objects == 0) scan.first = box;
    scan.sample.Add(obj.id, box);
    ++scan.objects;
    if (options.progress && scan.objects % (1u << 16) == 0)
      options.progress(IngestStage::kRead, scan.objects, 0);
  }
  scan.warnings = part->TakeWarnings();
  return scan;
}

Result<ShardScan> ScanForShards(const std::vector<SceneOpener>& inputs,
                                const std::function<bool(ObjectId)>& mine, const IngestOptions& options) {
  ShardScan scan;
  SceneInputs all(inputs);
  SceneObject obj;
  for (;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, all.Next(&obj));
    if (!more) break;
    if (scan.objects == 0) scan.first = obj.mesh.Bounds();
    if (!mine || mine(obj.id)) scan.sample.Add(obj.id, scan.objects == 0 ? scan.first : obj.mesh.Bounds());
    ++scan.objects;
    if (options.progress && scan.objects % (1u << 16) == 0)
      options.progress(IngestStage::kRead, scan.objects, 0);
  }
  scan.warnings = all.TakeWarnings();
  return scan;
}

void DiscardShard(const std::string& manifest_path, uint32_t s) {
  std::error_code ec;
  std::filesystem::remove(ShardStorePath(manifest_path, s) + ".new", ec);
  std::filesystem::remove(ShardIdsPath(manifest_path, s) + ".new", ec);
}

Status PublishShard(const std::string& manifest_path, uint32_t s) {
  const std::string store = ShardStorePath(manifest_path, s), ids = ShardIdsPath(manifest_path, s);
  MKTREE_RETURN_IF_ERROR(Rename(store + ".new", store));
  return Rename(ids + ".new", ids);
}

Result<std::shared_ptr<const CodecDictionary>> TrainShardDictionary(const ShardObjects& shard0,
                                                                    const Manifest& m,
                                                                    const IngestOptions& options) {
  std::vector<ObjectId> ids;  // numbered from 0 as the shard's build numbers them
  const SceneOpener opener = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    MKTREE_ASSIGN_OR_RETURN(auto source, shard0());
    return std::unique_ptr<SceneSource>(std::make_unique<Renumber>(std::move(source), first, &ids));
  };
  return TrainBuildDictionary({opener}, options, m.origin);
}

Result<std::shared_ptr<const CodecDictionary>> TrainShardDictionary(const std::vector<SceneOpener>& inputs,
                                                                    const Manifest& m,
                                                                    const IngestOptions& options) {
  return TrainShardDictionary(
      [&]() -> Result<std::unique_ptr<SceneSource>> { return ShardObjectsOf(ChainInputs(inputs), m.top, 0); },
      m, options);
}

Result<ShardEntry> BuildShard(const std::vector<SceneOpener>& inputs, const std::string& manifest_path,
                              const Manifest& m, uint32_t s, const IngestOptions& options,
                              IngestReport* report) {
  return BuildShardFrom(
      [&]() -> Result<std::unique_ptr<SceneSource>> { return ShardObjectsOf(ChainInputs(inputs), m.top, s); },
      manifest_path, m, s, options, report);
}

Result<ShardEntry> BuildShardFrom(const ShardObjects& objects, const std::string& manifest_path,
                                  const Manifest& m, uint32_t s, const IngestOptions& options,
                                  IngestReport* report) {
  const std::string store_path = ShardStorePath(manifest_path, s), ids_path = ShardIdsPath(manifest_path, s);
  const std::string store_new = store_path + ".new", ids_new = ids_path + ".new";
  struct Discard {
    const std::string& path;
    uint32_t s;
    bool keep = false;
    ~Discard() {
      if (!keep) DiscardShard(path, s);
    }
  } discard{manifest_path, s};
  IngestOptions o = options;
  o.origin = m.origin;
  o.input_name =
      (options.input_name.empty() ? std::string() : options.input_name + ": ") + "shard " + std::to_string(s);
  std::vector<ObjectId> ids;
  const SceneOpener opener = [&](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    ids.clear();
    MKTREE_ASSIGN_OR_RETURN(auto source, objects());
    return std::unique_ptr<SceneSource>(std::make_unique<Renumber>(std::move(source), first, &ids));
  };
  MKTREE_ASSIGN_OR_RETURN(*report, BuildStore({opener}, store_new, o));  // names the store or the input
  if (ids.size() != report->objects)
    return Status::Internal(store_new + ": id count differs from the store's");
  ShardEntry e;
  e.objects = ids.size();
  {
    MKTREE_ASSIGN_OR_RETURN(auto reader, StoreReader::Open(store_new));
    e.box = reader->tree().nodes[0].box;
  }
  MKTREE_RETURN_IF_ERROR(WriteShardIds(ids_new, m.build_id, s, ids));
  MKTREE_ASSIGN_OR_RETURN(e.store, FingerprintFile(store_new));
  MKTREE_ASSIGN_OR_RETURN(e.ids, FingerprintFile(ids_new));
  e.store.name = std::filesystem::path(store_path).filename().string();
  e.ids.name = std::filesystem::path(ids_path).filename().string();
  discard.keep = true;
  return e;
}

Result<ShardedBuildReport> BuildShardedStore(const std::vector<SceneOpener>& inputs,
                                             const std::string& manifest_path, const IngestOptions& options,
                                             uint32_t shards) {
  const auto start = Clock::now();
  ShardedBuildReport report;
  if (shards == 0 || shards > 65536) return Status::InvalidArgument("shards must be from 1 to 65536");
  if (manifest_path.empty()) return Status::InvalidArgument("the store path is empty");
  if (std::filesystem::is_directory(manifest_path))
    return Status::InvalidArgument(manifest_path + ": not a regular file");
  // Before anything is staged: what killed builds of this path left is removed under the lock.
  MKTREE_ASSIGN_OR_RETURN(const std::unique_ptr<ShardBuildLock> lock, ShardBuildLock::Acquire(manifest_path));
  RemoveShardLeftovers(manifest_path);

  // 1. The sample and the scene's frame, in one pass.
  Manifest& m = report.manifest;
  MKTREE_ASSIGN_OR_RETURN(ShardScan scan, ScanForShards(inputs, nullptr, options));
  report.warnings = std::move(scan.warnings);
  m.objects = scan.objects;
  if (m.objects == 0)
    return Status::InvalidArgument((options.input_name.empty()
                                        ? manifest_path + ": not built"
                                        : options.input_name + ": " + manifest_path + " not built") +
                                   ": empty scene, no object with geometry in the input");
  m.origin = options.origin ? *options.origin : ChooseStoreOrigin(scan.first);
  report.sample_objects = scan.sample.size();
  MKTREE_ASSIGN_OR_RETURN(m.top, ChooseTopLevels(std::move(scan.sample).Items(), shards));
  report.sample_seconds = Seconds(start);
  // The id files carry it, so a shard of another build is refused even if its store fingerprints alike.
  m.build_id = NewBuildId();

  // 2. The shards, one after the other, under staging names.
  struct DiscardAll {
    const std::string& path;
    uint32_t built = 0;
    bool keep = false;
    ~DiscardAll() {
      for (uint32_t s = 0; s < built && !keep; ++s) DiscardShard(path, s);
    }
  } discard{manifest_path};
  // Every shard encodes with the dictionary shard 0's build would train (or none, as it would train
  // none): the parts of the store then share one, so that a compaction after changes copies every entry
  // (docs/changes.md); the distributed build trains the same one on rank 0.
  IngestOptions shard_options = options;
  if (!options.dictionary) {
    MKTREE_ASSIGN_OR_RETURN(shard_options.dictionary, TrainShardDictionary(inputs, m, options));
  }
  for (uint32_t s = 0; s < shards; ++s) {
    IngestReport shard_report;
    MKTREE_ASSIGN_OR_RETURN(ShardEntry e,
                            BuildShard(inputs, manifest_path, m, s, shard_options, &shard_report));
    ++discard.built;
    for (std::string& w : shard_report.warnings)
      report.warnings.push_back("shard " + std::to_string(s) + ": " + w);
    report.store_bytes += e.store.bytes + e.ids.bytes;
    m.shards.push_back(std::move(e));
    report.shards.push_back(std::move(shard_report));
  }

  // 3. Into place, the manifest last (atomic: a temporary renamed over the path).
  Status st;
  for (uint32_t s = 0; s < shards && st.ok(); ++s) st = PublishShard(manifest_path, s);
  if (st.ok()) st = WriteManifest(manifest_path, m);
  if (!st.ok()) {  // none of this build's files stays
    for (uint32_t s = 0; s < shards; ++s) {
      std::error_code ec;
      std::filesystem::remove(ShardStorePath(manifest_path, s), ec);
      std::filesystem::remove(ShardIdsPath(manifest_path, s), ec);
    }
    return st;
  }
  discard.keep = true;
  report.total_seconds = Seconds(start);
  return report;
}

}  // namespace mktree
