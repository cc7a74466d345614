#include "engine/ingest/store_builder.h"

#include <sys/stat.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <span>

#include "engine/geometry/mesh_edges.h"
#include "engine/ingest/spill_file.h"
#include "engine/tree/leaf_filter.h"
#include "engine/tree/mktree_builder.h"
#include "storage/leaf_codec.h"
#include "storage/object_codec.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

constexpr uint64_t kProgressEvery = 1 << 15;

bool FiniteBox(const Box3f& b) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(b.min[i]) || !std::isfinite(b.max[i])) return false;
  return !b.empty();
}

std::string SpillDir(const std::string& store_path, const std::string& requested) {
  if (!requested.empty()) return requested;
  std::filesystem::path parent = std::filesystem::path(store_path).parent_path();
  return parent.empty() ? std::string(".") : parent.string();
}

}  // namespace

const char* IngestStageName(IngestStage stage) {
  switch (stage) {
    case IngestStage::kRead: return "read";
    case IngestStage::kBuildTree: return "build tree";
    case IngestStage::kWritePages: return "write pages";
    case IngestStage::kWriteTable: return "write object table";
  }
  return "?";
}

Result<IngestReport> BuildStore(const std::vector<SceneOpener>& inputs, const std::string& store_path,
                                const IngestOptions& options) {
  const auto start = Clock::now();
  IngestReport report;
  auto progress = [&](IngestStage s, uint64_t done, uint64_t total) {
    if (options.progress) options.progress(s, done, total);
  };
  const std::string stem = std::filesystem::path(store_path).filename().string();
  const std::string dir = SpillDir(store_path, options.spill_dir);
  auto geometry_spill = SpillFile::Create(dir, "." + stem + ".geometry-spill");
  if (!geometry_spill.ok()) return geometry_spill.status();
  auto name_spill = SpillFile::Create(dir, "." + stem + ".name-spill");
  if (!name_spill.ok()) return name_spill.status();
  SpillFile& geometry = **geometry_spill;
  SpillFile& names = **name_spill;

  // 1. Stream the objects: encode each alone, spill geometry and name, keep only the record.
  std::vector<ObjectRecord> records;
  std::vector<uint8_t> entry;
  SceneObject obj;
  ObjectId next_id = 0;
  for (const SceneOpener& open : inputs) {
    auto source = open(next_id);
    if (!source.ok()) return source.status();
    for (;;) {
      auto more = (*source)->Next(&obj);
      if (!more.ok()) return more.status();
      if (!*more) break;
      if (obj.id != next_id)
        return Status::Internal("object '" + obj.name + "': source gave id " + std::to_string(obj.id) +
                                ", expected " + std::to_string(next_id));
      if (next_id == kNoIndex) return Status::InvalidArgument("too many objects: ids are 32-bit");
      ObjectRecord rec;
      rec.id = obj.id;
      rec.box = obj.Aabb();
      if (!FiniteBox(rec.box))
        return Status::InvalidArgument("object " + std::to_string(obj.id) + " ('" + obj.name +
                                       "'): empty or non-finite bounds");
      entry.clear();
      const EdgeCheck edges = CheckEdges(obj.mesh);
      const uint8_t shape = kShapeKnown | (edges.even ? kShapeEvenEdges : 0) | (edges.closed ? kShapeClosed : 0);
      rec.encoded_bytes = EncodeObjectEntry(obj, options.store.codec, &entry, shape);
      if (rec.encoded_bytes == 0)
        return Status::InvalidArgument("object " + std::to_string(obj.id) + " ('" + obj.name +
                                       "'): geometry cannot be encoded (larger than 4 GiB or malformed)");
      auto offset = geometry.Append(entry.data(), entry.size());
      if (!offset.ok()) return offset.status();
      rec.spill_offset = *offset;
      const uint32_t name_len = static_cast<uint32_t>(obj.name.size());
      if (auto st = names.Append(&name_len, sizeof name_len); !st.ok()) return st.status();
      if (auto st = names.Append(obj.name.data(), name_len); !st.ok()) return st.status();
      records.push_back(rec);
      report.triangles += obj.mesh.triangle_count();
      report.raw_geometry_bytes += obj.mesh.RawGeometryBytes();
      report.encoded_bytes += rec.encoded_bytes;
      ++next_id;
      if (next_id % kProgressEvery == 0) progress(IngestStage::kRead, next_id, 0);
    }
  }
  report.objects = next_id;
  progress(IngestStage::kRead, next_id, next_id);
  if (report.objects == 0) return Status::InvalidArgument("empty scene: no object with geometry in the input");
  MKTREE_RETURN_IF_ERROR(geometry.Flush());
  MKTREE_RETURN_IF_ERROR(names.Flush());
  report.read_seconds = Seconds(start);

  // The spill offsets outlive the records, which the builder consumes.
  std::vector<uint64_t> spill_offset(records.size());
  std::vector<uint32_t> entry_bytes(records.size());
  for (const ObjectRecord& r : records) {
    spill_offset[r.id] = r.spill_offset;
    entry_bytes[r.id] = r.encoded_bytes;
  }

  // 2. The tree, from the records alone.
  const auto build_start = Clock::now();
  progress(IngestStage::kBuildTree, 0, 1);
  auto built = BuildMKTree(std::move(records), options.store.params, options.tuning);
  if (!built.ok()) return built.status();
  BuildResult& result = *built;
  report.tree_stats = result.stats;
  report.build_seconds = Seconds(build_start);
  progress(IngestStage::kBuildTree, 1, 1);

  // 3. Leaf pages in leaf order, assembled from the spill.
  const auto write_start = Clock::now();
  auto writer_or = StoreWriter::Create(store_path, options.store);
  if (!writer_or.ok()) return writer_or.status();
  StoreWriter& writer = **writer_or;
  const uint64_t mem_page = options.store.params.mem_page();
  MKTree& tree = result.tree;
  tree.leaf_filter.resize(uint64_t{kLeafFilterBytesPerObject} * report.objects);
  uint64_t filter_at = 0;
  std::vector<uint8_t> leaf_bytes;
  std::vector<std::span<const uint8_t>> entries;
  std::vector<uint32_t> leaf_of(report.objects, kNoIndex);
  uint64_t page = 0;
  for (uint32_t leaf = 0; leaf < tree.leaves.size(); ++leaf) {
    const uint64_t begin = result.leaf_offsets[leaf], end = result.leaf_offsets[leaf + 1];
    uint64_t total = 0;
    for (uint64_t i = begin; i < end; ++i) total += entry_bytes[result.leaf_objects[i]];
    leaf_bytes.resize(total);
    entries.clear();
    uint64_t at = 0;
    for (uint64_t i = begin; i < end; ++i) {
      const ObjectId id = result.leaf_objects[i];
      leaf_of[id] = leaf;
      MKTREE_RETURN_IF_ERROR(geometry.ReadAt(spill_offset[id], entry_bytes[id], leaf_bytes.data() + at));
      entries.emplace_back(leaf_bytes.data() + at, entry_bytes[id]);
      auto parsed = ParseObjectEntry(leaf_bytes.data() + at, entry_bytes[id]);
      if (!parsed.ok()) return parsed.status();
      QuantizeBox(tree.leaves[leaf].box, parsed->box, tree.leaf_filter.data() + filter_at);
      filter_at += kLeafFilterBytesPerObject;
      at += entry_bytes[id];
    }
    if (tree.leaves[leaf].first_page != page)
      return Status::Internal("leaf " + std::to_string(leaf) + " does not start at the next page");
    MKTREE_RETURN_IF_ERROR(EncodeLeafPages(leaf, entries, mem_page, [&](const uint8_t* bytes) {
      return writer.pages().WritePage(page++, bytes);
    }));
    if (page != tree.leaves[leaf].first_page + tree.leaves[leaf].page_count)
      return Status::Internal("leaf " + std::to_string(leaf) + " wrote an unexpected number of pages");
    if (leaf % 4096 == 0) progress(IngestStage::kWritePages, leaf, tree.leaves.size());
  }
  report.pages = page;
  if (!tree.IndexLeafFilter()) return Status::Internal("leaf filter does not match the leaves' object counts");
  progress(IngestStage::kWritePages, tree.leaves.size(), tree.leaves.size());
  spill_offset = {};
  entry_bytes = {};

  // 4. The object table, in id order, names streamed from their spill.
  std::string name;
  uint64_t name_at = 0;
  for (ObjectId id = 0; id < report.objects; ++id) {
    if (leaf_of[id] == kNoIndex) return Status::Internal("object " + std::to_string(id) + " is in no leaf");
    uint32_t len = 0;
    MKTREE_RETURN_IF_ERROR(names.ReadAt(name_at, sizeof len, &len));
    name.resize(len);
    MKTREE_RETURN_IF_ERROR(names.ReadAt(name_at + sizeof len, len, name.data()));
    name_at += sizeof len + len;
    MKTREE_RETURN_IF_ERROR(writer.AppendObject(id, leaf_of[id], name));
    if (id % kProgressEvery == 0) progress(IngestStage::kWriteTable, id, report.objects);
  }
  progress(IngestStage::kWriteTable, report.objects, report.objects);
  MKTREE_RETURN_IF_ERROR(writer.Commit(tree, result.stats.ToJson()));
  report.write_seconds = Seconds(write_start);

  struct stat st {};
  if (::stat(store_path.c_str(), &st) == 0) report.store_bytes = static_cast<uint64_t>(st.st_size);
  report.total_seconds = Seconds(start);
  return report;
}

}  // namespace mktree
