#include "engine/ingest/store_builder.h"

#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <filesystem>

#include "engine/core/guarded.h"
#include "engine/ingest/build_stages.h"
#include "engine/ingest/leaf_page_writer.h"
#include "engine/ingest/object_table_writer.h"
#include "engine/ingest/read_and_spill.h"

namespace mktree {

Vec3d ChooseStoreOrigin(const Box3d& first) {
  Vec3d origin;
  for (int i = 0; i < 3; ++i) {
    const double centre = (first.min[i] + first.max[i]) / 2;
    if (std::isfinite(centre) && std::fabs(centre) >= 0x1p16) origin[i] = std::nearbyint(centre);
  }
  return origin;
}

const char* IngestStageName(IngestStage stage) {
  switch (stage) {
    case IngestStage::kRead:
      return "read";
    case IngestStage::kBuildTree:
      return "build tree";
    case IngestStage::kWritePages:
      return "write pages";
    case IngestStage::kWriteTable:
      return "write object table";
  }
  return "?";
}

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

// Stage 2: the tree, from the objects' records alone; its list spill goes beside the build's others.
Result<BuildResult> BuildTree(std::vector<BuildObject> objects, const IngestOptions& options,
                              const std::string& spill_dir, IngestReport* report) {
  const auto build_start = Clock::now();
  ReportProgress(options, IngestStage::kBuildTree, 0, 1);
  BuildTuning tuning = options.tuning;
  if (tuning.spill_dir.empty()) tuning.spill_dir = spill_dir;
  if (tuning.spill_file_ops == nullptr) tuning.spill_file_ops = options.spill_file_ops;
  MKTREE_ASSIGN_OR_RETURN(BuildResult built, BuildMKTree(std::move(objects), options.store.params, tuning));
  report->tree_stats = built.stats;
  report->build_seconds = Seconds(build_start);
  ReportProgress(options, IngestStage::kBuildTree, 1, 1);
  return built;
}

// Stages 3 and 4: the leaf pages, and the object table on a thread of its own meanwhile; then the commit.
Status WritePagesAndCommit(SpilledObjects& spilled, std::vector<uint32_t> entry_bytes, BuildResult& built,
                           StoreWriter& writer, const IngestOptions& options, IngestReport* report) {
  const uint64_t objects = report->objects;
  MKTREE_ASSIGN_OR_RETURN(SpilledEntries entries,
                          SpilledEntries::Index(*spilled.entries, std::move(entry_bytes)));
  built.tree.origin = report->origin;
  ObjectTableWriter table(writer, *spilled.records, spilled.sources, LeafOfObjects(built, objects));
  MKTREE_RETURN_IF_ERROR(table.Start(LeafPageCount(built.tree)));
  MKTREE_ASSIGN_OR_RETURN(report->pages, WriteLeafPages(std::move(entries), options.store.params.mem_page(),
                                                        &built, writer.pages(), options));
  // Freed, not cleared (`v = {}` keeps the capacity), with the entries' index: 16 bytes an object
  // otherwise held through the rest of the object table and Commit.
  std::vector<ObjectId>().swap(built.leaf_objects);
  ReportProgress(options, IngestStage::kWriteTable, 0, objects);
  MKTREE_RETURN_IF_ERROR(table.Finish());
  ReportProgress(options, IngestStage::kWriteTable, objects, objects);
  return writer.Commit(std::move(built.tree), built.stats.ToJson());
}

Result<IngestReport> BuildStoreUnguarded(const std::vector<SceneOpener>& inputs,
                                         const std::string& store_path, const IngestOptions& options) {
  const auto start = Clock::now();
  IngestReport report;
  // The writer first: its lock keeps a second build of the same store out before either has done any
  // work, and it removes what killed builds left (temp stores, spills) before this one writes anything.
  MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<StoreWriter> writer,
                          StoreWriter::Create(store_path, options.store));
  SpillPlace place{IngestSpillDir(store_path, options.spill_dir),
                   std::filesystem::path(store_path).filename().string(), options.spill_file_ops};
  // Spills of the store's own directory are covered by its lock; a shared spill_dir is not.
  if (options.spill_dir.empty()) RemoveStaleSpills(place.dir, place.stem);

  // 1. Read and spill.
  MKTREE_ASSIGN_OR_RETURN(ReadAndSpillOutput read, ReadAndSpill(inputs, options, place, &report));
  if (options.after_read) options.after_read();
  writer->SetCodecDictionary(read.dictionary);
  SpilledObjects& spilled = read.spilled;
  if (report.objects == 0)
    return Status::InvalidArgument((options.input_name.empty()
                                        ? store_path + ": not built"
                                        : options.input_name + ": " + store_path + " not built") +
                                   ": empty scene, no object with geometry in the input");
  report.read_seconds = Seconds(start);
  // The entry sizes outlive the objects, which the tree build consumes; they wait in the record spill.
  MKTREE_ASSIGN_OR_RETURN(const uint64_t sizes_at, ParkEntrySizes(spilled.objects, spilled.records.get()));

  // 2. The tree.
  MKTREE_ASSIGN_OR_RETURN(BuildResult built,
                          BuildTree(std::move(spilled.objects), options, place.dir, &report));
  MKTREE_ASSIGN_OR_RETURN(std::vector<uint32_t> entry_bytes,
                          ReadParkedEntrySizes(*spilled.records, sizes_at, report.objects));

  // 3 and 4. The leaf pages, the object table, the commit.
  const auto write_start = Clock::now();
  MKTREE_RETURN_IF_ERROR(
      WritePagesAndCommit(spilled, std::move(entry_bytes), built, *writer, options, &report));
  report.write_seconds = Seconds(write_start);

  struct stat st {};
  if (::stat(store_path.c_str(), &st) == 0) report.store_bytes = static_cast<uint64_t>(st.st_size);
  report.total_seconds = Seconds(start);
  return report;
}

}  // namespace

Result<uint64_t> ParkEntrySizes(const std::vector<BuildObject>& objects, SpillFile* records) {
  // Offsets are not kept through the tree build (8 bytes per object at its memory peak): entries were
  // spilled back to back in id order, so they are the prefix sums of the sizes, recomputed afterwards.
  std::vector<uint32_t> entry_bytes(objects.size());
  for (const BuildObject& r : objects) entry_bytes[r.id] = r.encoded_bytes;
  const uint64_t sizes_at = records->size();
  constexpr size_t kBlock = 1 << 16;  // sizes a write: the spill's buffer holds no copy of them all
  for (size_t i = 0; i < entry_bytes.size(); i += kBlock) {
    const size_t count = std::min(kBlock, entry_bytes.size() - i);
    if (auto st = records->Append(entry_bytes.data() + i, count * sizeof(uint32_t)); !st.ok())
      return st.status();
    MKTREE_RETURN_IF_ERROR(records->Flush());
  }
  return sizes_at;
}

Result<std::vector<uint32_t>> ReadParkedEntrySizes(const SpillFile& records, uint64_t at, uint64_t count) {
  std::vector<uint32_t> entry_bytes(count);
  MKTREE_RETURN_IF_ERROR(records.ReadAt(at, entry_bytes.size() * sizeof(uint32_t), entry_bytes.data()));
  return entry_bytes;
}

std::string IngestSpillDir(const std::string& store_path, const std::string& requested) {
  if (!requested.empty()) return requested;
  std::filesystem::path parent = std::filesystem::path(store_path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

Result<IngestReport> BuildStore(const std::vector<SceneOpener>& inputs, const std::string& store_path,
                                const IngestOptions& options) {
  // An exception (std::bad_alloc under a memory limit, ...) becomes a Status; the writer and the spill
  // files clean up as they unwind.
  return Guarded(store_path, [&] { return BuildStoreUnguarded(inputs, store_path, options); });
}

}  // namespace mktree
