// The public build API (include/mktree/build.h) over BuildStore: options checked and translated, inputs
// opened as `mktree build` opens them, and the caller's objects checked as the readers check a file's.
#include <zstd.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <optional>
#include <string_view>
#include <system_error>

#include "engine/generator/tanker_generator.h"
#include "engine/generator/tanker_spec.h"
#include "engine/ingest/caller_object_check.h"
#include "engine/ingest/scene_inputs.h"
#include "engine/ingest/shard_build.h"
#include "engine/ingest/store_builder.h"
#include "mktree/build.h"
#include "storage/file_util.h"

namespace mktree {

namespace {

static_assert(static_cast<int>(BuildStage::kWriteTable) == static_cast<int>(IngestStage::kWriteTable));

Result<IngestOptions> ToIngestOptions(const BuildOptions& b) {
  IngestOptions o;
  o.store.backend = b.backend == BuildOptions::Backend::kPagedFile ? Backend::kPagedFile : Backend::kHdf5;
  o.store.codec.codec = b.codec == BuildOptions::Codec::kNone ? Codec::kNone : Codec::kZstd;
  if (b.zstd_level < ZSTD_minCLevel() || b.zstd_level > ZSTD_maxCLevel())
    return Status::InvalidArgument("zstd_level must be from " + std::to_string(ZSTD_minCLevel()) + " to " +
                                   std::to_string(ZSTD_maxCLevel()) + ", not " +
                                   std::to_string(b.zstd_level));
  o.store.codec.zstd_level = b.zstd_level;
  if (!(b.balance_r >= 0 && b.balance_r < 0.5))
    return Status::InvalidArgument("balance_r must be in [0, 0.5), not " + std::to_string(b.balance_r));
  if (b.block_size < 512 || b.blocks_per_page == 0 ||
      uint64_t{b.block_size} * b.blocks_per_page > (uint64_t{1} << 30))
    return Status::InvalidArgument(
        "block_size must be at least 512, blocks_per_page at least 1, and the page (block_size x "
        "blocks_per_page) at most 1 GiB");
  o.store.params.block_size = b.block_size;
  o.store.params.blocks_per_page = b.blocks_per_page;
  o.store.params.balance_r = b.balance_r;
  o.store.params.split_tree_node_budget = b.split_budget;
  switch (b.split_policy) {
    case BuildOptions::SplitPolicy::kCompact:
      o.tuning.split_policy = SplitPolicy::kCompact;
      break;
    case BuildOptions::SplitPolicy::kSoa:  // docs/design.md §3.5: the reference SOA exactly
      o.tuning.split_policy = SplitPolicy::kSoa;
      o.tuning.fill_aware = false;
      break;
    case BuildOptions::SplitPolicy::kSoaFill:
      o.tuning.split_policy = SplitPolicy::kSoa;
      break;
  }
  if (b.threads > (1u << 16)) return Status::InvalidArgument("threads must be at most 65536");
  o.threads = b.threads;
  o.tuning.threads = static_cast<int>(b.threads);
  o.spill_dir = b.spill_dir;
  if (!(std::isfinite(b.chord_tolerance) && b.chord_tolerance > 0))
    return Status::InvalidArgument("chord_tolerance must be a positive number of metres, not " +
                                   std::to_string(b.chord_tolerance));
  if (!(std::isfinite(b.angular_deflection) && b.angular_deflection > 0))
    return Status::InvalidArgument("angular_deflection must be a positive number of radians, not " +
                                   std::to_string(b.angular_deflection));
  if (b.progress) {
    o.progress = [progress = b.progress](IngestStage s, uint64_t done, uint64_t total) {
      progress(static_cast<BuildStage>(s), done, total);
    };
  }
  return o;
}

BuildStats ToStats(const IngestReport& r, const IngestOptions& o) {
  BuildStats s;
  s.objects = r.objects;
  s.triangles = r.triangles;
  s.leaves = r.tree_stats.leaves;
  s.pages = r.pages;
  s.page_bytes = o.store.params.mem_page();
  s.height = r.tree_stats.height;
  s.mean_page_fill = r.tree_stats.mean_page_fill;
  s.origin = r.origin;
  s.raw_geometry_bytes = r.raw_geometry_bytes;
  s.encoded_bytes = r.encoded_bytes;
  s.store_bytes = r.store_bytes;
  s.read_seconds = r.read_seconds;
  s.build_seconds = r.build_seconds;
  s.write_seconds = r.write_seconds;
  s.total_seconds = r.total_seconds;
  s.warnings = r.warnings;
  return s;
}

// The shards' statistics together: sums, the tallest shard's height, the fill weighted by pages.
Result<BuildStats> BuildSharded(const std::vector<SceneOpener>& openers, const std::string& path,
                                const IngestOptions& opts, uint32_t shards) {
  MKTREE_ASSIGN_OR_RETURN(const ShardedBuildReport r, BuildShardedStore(openers, path, opts, shards));
  BuildStats s;
  double fill = 0;
  for (const IngestReport& shard : r.shards) {
    const BuildStats one = ToStats(shard, opts);
    s.objects += one.objects;
    s.triangles += one.triangles;
    s.leaves += one.leaves;
    s.pages += one.pages;
    s.height = std::max(s.height, one.height);
    fill += one.mean_page_fill * static_cast<double>(one.pages);
    s.raw_geometry_bytes += one.raw_geometry_bytes;
    s.encoded_bytes += one.encoded_bytes;
    s.read_seconds += one.read_seconds;
    s.build_seconds += one.build_seconds;
    s.write_seconds += one.write_seconds;
  }
  s.page_bytes = opts.store.params.mem_page();
  s.mean_page_fill = s.pages ? fill / static_cast<double>(s.pages) : 0;
  s.origin = r.manifest.origin;
  s.store_bytes = r.store_bytes;
  s.read_seconds += r.sample_seconds;
  s.total_seconds = r.total_seconds;
  s.warnings = r.warnings;
  return s;
}

// The caller's objects as a scene stream: numbered in order, checked as a reader checks a file.
class CallerSource final : public SceneSource {
 public:
  CallerSource(const ObjectSource& source, ObjectId first_id) : source_(source), next_id_(first_id) {}

  Result<bool> Next(SceneObject* out) override {
    MKTREE_ASSIGN_OR_RETURN(const bool more, source_(out));
    if (!more) return false;
    MKTREE_RETURN_IF_ERROR(Check(*out));
    out->id = next_id_++;
    return true;
  }

 private:
  Status Check(const SceneObject& obj) const {
    return CheckCallerObject(obj, "object " + std::to_string(next_id_) + " '" + obj.name + "'");
  }

  ObjectSource source_;
  ObjectId next_id_;
};

}  // namespace

Result<SceneOpener> OpenerForInput(const std::string& input, const SceneReadOptions& read) {
  if (IsTankerSpec(input)) {
    const std::optional<TankerSpec> spec = ParseTankerSpec(input);
    if (!spec)
      return Status::InvalidArgument(input +
                                     ": expected tanker:N or tanker:N:SEED in decimal, 1 <= N <= 2^32");
    return SceneOpener([spec = *spec](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
      return MakeTankerSource(spec.objects, spec.seed, first);
    });
  }
  // Refused before anything is read (the scene reader would say the same, but only once it got there).
  MKTREE_RETURN_IF_ERROR(storage_internal::CheckInputFile(input));
  return SceneOpener([input, read](ObjectId first) { return OpenSceneFile(input, first, read); });
}

const char* BuildStageName(BuildStage stage) { return IngestStageName(static_cast<IngestStage>(stage)); }

Result<BuildStats> BuildFromFiles(const std::vector<std::string>& inputs, const std::string& store_path,
                                  const BuildOptions& options) {
  MKTREE_ASSIGN_OR_RETURN(IngestOptions opts, ToIngestOptions(options));
  if (inputs.empty()) return Status::InvalidArgument(store_path + ": not built: no input");
  std::vector<SceneOpener> openers;
  SceneReadOptions read;
  read.spill_dir = IngestSpillDir(store_path, opts.spill_dir);
  read.chord_tolerance = options.chord_tolerance;
  read.angular_deflection = options.angular_deflection;
  for (const std::string& in : inputs) {
    MKTREE_ASSIGN_OR_RETURN(SceneOpener opener, OpenerForInput(in, read));
    openers.push_back(std::move(opener));
  }
  MKTREE_RETURN_IF_ERROR(storage_internal::CheckOutputFile(store_path, inputs));
  for (const std::string& in : inputs) opts.input_name += (opts.input_name.empty() ? "" : ", ") + in;
  if (options.shards > 0) return BuildSharded(openers, store_path, opts, options.shards);
  MKTREE_ASSIGN_OR_RETURN(const IngestReport report, BuildStore(openers, store_path, opts));
  return ToStats(report, opts);
}

Result<BuildStats> BuildFromObjects(const ObjectSource& source, const std::string& store_path,
                                    const BuildOptions& options) {
  MKTREE_ASSIGN_OR_RETURN(IngestOptions opts, ToIngestOptions(options));
  if (store_path.empty()) return Status::InvalidArgument("the store path is empty");
  if (!source) return Status::InvalidArgument(store_path + ": not built: no object source");
  opts.input_name = "the objects given";
  const SceneOpener opener = [&source](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(std::make_unique<CallerSource>(source, first));
  };
  if (options.shards > 0)
    return Status::InvalidArgument(
        store_path +
        ": a sharded build reads its objects more than once: give them as a vector "
        "or as files");
  MKTREE_ASSIGN_OR_RETURN(const IngestReport report, BuildStore({opener}, store_path, opts));
  return ToStats(report, opts);
}

Result<BuildStats> BuildFromObjects(const std::vector<SceneObject>& objects, const std::string& store_path,
                                    const BuildOptions& options) {
  if (options.shards > 0) {  // each pass of the sharded build reads the vector from its start
    MKTREE_ASSIGN_OR_RETURN(IngestOptions opts, ToIngestOptions(options));
    if (store_path.empty()) return Status::InvalidArgument("the store path is empty");
    opts.input_name = "the objects given";
    const SceneOpener opener = [&objects](ObjectId first) -> Result<std::unique_ptr<SceneSource>> {
      ObjectSource from_start = [&objects, next = size_t{0}](SceneObject* out) mutable -> Result<bool> {
        if (next == objects.size()) return false;
        *out = objects[next++];
        return true;
      };
      return std::unique_ptr<SceneSource>(std::make_unique<CallerSource>(std::move(from_start), first));
    };
    return BuildSharded({opener}, store_path, opts, options.shards);
  }
  size_t next = 0;
  return BuildFromObjects(
      [&](SceneObject* out) -> Result<bool> {
        if (next == objects.size()) return false;
        *out = objects[next++];
        return true;
      },
      store_path, options);
}

}  // namespace mktree
