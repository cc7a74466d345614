#include "engine/ingest/store_builder.h"

#include <sys/stat.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <future>
#include <limits>
#include <span>
#include <unordered_map>

#include "engine/core/guarded.h"
#include "engine/ingest/object_encoder.h"
#include "engine/ingest/spill_file.h"
#include "engine/store/leaf_codec.h"
#include "engine/store/object_codec.h"
#include "engine/store/record_codec.h"
#include "engine/tree/leaf_filter.h"
#include "engine/tree/mktree_builder.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

constexpr uint64_t kProgressEvery = 1 << 15;
// Entry bytes read from the spill at a time when writing pages: large enough that a window's reads
// gather well, small enough to be a minor part of the memory bound.
constexpr uint64_t kWindowBytes = 4 << 20;

// Boxes rounded by more than this fraction of their object's size draw a warning.
constexpr double kBoxRoundingWarnFraction = 1.0 / 16;

// Objects whose float32 box in the store frame is coarse against their size: counted, and the worst kept.
struct CoarseBoxes {
  uint64_t count = 0;
  double worst_ratio = 0;
  ObjectId worst_id = 0;
  std::string worst_name;
  double worst_size = 0, worst_rounding = 0;

  void Check(const SceneObject& obj, const Box3f& box) {
    double size = 0, far = 0;
    for (int i = 0; i < 3; ++i) {
      size = std::max(size, static_cast<double>(box.max[i]) - box.min[i]);
      far = std::max({far, std::fabs(double{box.min[i]}), std::fabs(double{box.max[i]})});
    }
    const double rounding = far * 0x1p-23;  // float32's spacing near `far`, within a factor of 2
    if (rounding <= kBoxRoundingWarnFraction * size) return;
    ++count;
    const double ratio = size > 0 ? rounding / size : std::numeric_limits<double>::infinity();
    if (count == 1 || ratio > worst_ratio) {
      worst_ratio = ratio;
      worst_id = obj.id;
      worst_name = obj.name;
      worst_size = size;
      worst_rounding = rounding;
    }
  }
  std::string Warning(const Vec3d& origin) const {
    std::string name = worst_name.substr(0, 100);
    for (char& c : name)
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';  // one line, whatever the name holds
    char buf[512];
    std::snprintf(
        buf, sizeof buf,
        "%llu objects lie so far from the store's origin (%.17g, %.17g, %.17g) that their float32 boxes "
        "are rounded by more than 1/16 of their size (worst: object %u '%.100s', size %.3g, rounding "
        "%.3g): AABB-mode answers and routing treat them as that much larger; exact answers are not "
        "affected",
        static_cast<unsigned long long>(count), origin.x, origin.y, origin.z, worst_id, name.c_str(),
        worst_size, worst_rounding);
    return buf;
  }
};

// Removes "<dir>/.<stem>.{geometry,record,name}-spill.XXXXXX" (the names SpillFile::Create gives; "name"
// was the record spill's name before format 4): spills that were still named when their build was killed
// (see spill_file.h). REQUIRES: the store's writer lock.
void RemoveStaleSpills(const std::string& dir, const std::string& stem) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    for (const char* kind : {".geometry-spill.", ".record-spill.", ".name-spill."}) {
      const std::string prefix = "." + stem + kind;
      if (name.size() == prefix.size() + 6 && name.compare(0, prefix.size(), prefix) == 0) {
        std::error_code rm;
        fs::remove(it->path(), rm);
      }
    }
  }
}

}  // namespace

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

static Result<IngestReport> BuildStoreUnguarded(const std::vector<SceneOpener>& inputs,
                                                const std::string& store_path, const IngestOptions& options) {
  const auto start = Clock::now();
  IngestReport report;
  auto progress = [&](IngestStage s, uint64_t done, uint64_t total) {
    if (options.progress) options.progress(s, done, total);
  };
  // The writer first: its lock keeps a second build of the same store out before either has done any
  // work, and it removes what killed builds left (temp stores, spills) before this one writes anything.
  auto writer_or = StoreWriter::Create(store_path, options.store);
  if (!writer_or.ok()) return writer_or.status();
  StoreWriter& writer = **writer_or;
  const std::string stem = std::filesystem::path(store_path).filename().string();
  const std::string dir = IngestSpillDir(store_path, options.spill_dir);
  // Spills of the store's own directory are covered by its lock; a shared spill_dir is not.
  if (options.spill_dir.empty()) RemoveStaleSpills(dir, stem);
  auto geometry_spill = SpillFile::Create(dir, "." + stem + ".geometry-spill");
  if (!geometry_spill.ok()) return geometry_spill.status();
  auto record_spill = SpillFile::Create(dir, "." + stem + ".record-spill");
  if (!record_spill.ok()) return record_spill.status();
  SpillFile& geometry = **geometry_spill;
  SpillFile& records_spill = **record_spill;
  // The distinct input files, by the index the spilled records carry (a few: one per input file).
  std::vector<std::string> sources;
  SourceIndex source_index(&sources);
  std::vector<uint8_t> record_bytes;

  // 1. Stream the objects: encoded on worker threads (object_encoder.h), spilled here in id order;
  //    only the record stays.
  std::vector<BuildObject> records;
  ObjectId next_id = 0;
  size_t input = 0;
  std::unique_ptr<SceneSource> source;
  auto read = [&](SceneObject* obj) -> Result<bool> {
    for (;;) {
      if (!source) {
        if (input == inputs.size()) return false;
        auto opened = inputs[input](next_id);
        if (!opened.ok()) return opened.status();
        source = std::move(opened).value();
      }
      auto more = source->Next(obj);
      if (!more.ok()) return more.status();
      if (*more) break;
      for (std::string& w : source->TakeWarnings()) report.warnings.push_back(std::move(w));
      source.reset();
      ++input;
    }
    if (obj->id != next_id)
      return Status::Internal("object '" + obj->name + "': source gave id " + std::to_string(obj->id) +
                              ", expected " + std::to_string(next_id));
    if (next_id == kNoIndex) return Status::InvalidArgument("too many objects: ids are 32-bit");
    ++next_id;
    // Reported here, on the calling thread, not by the sink (a drain thread): a progress callback may
    // need the caller's thread (Python checks Ctrl-C only on its main thread).
    if (next_id % kProgressEvery == 0) progress(IngestStage::kRead, next_id, 0);
    return true;
  };
  CoarseBoxes coarse;
  auto spill = [&](const SceneObject& obj, const EncodedObject& encoded) -> Status {
    coarse.Check(obj, encoded.box);
    BuildObject rec;
    rec.id = obj.id;
    rec.box = encoded.box;
    rec.encoded_bytes = static_cast<uint32_t>(encoded.entry.size());
    // Entries go back to back in id order: their offsets are recomputed from the sizes (step 3).
    if (auto offset = geometry.Append(encoded.entry.data(), encoded.entry.size()); !offset.ok())
      return offset.status();
    // The object's record (box, source, name, attributes) as the store encodes it, spilled in id order.
    record_bytes.clear();
    if (Status st =
            EncodeRecord(encoded.box, source_index.Of(obj.source), obj.name, obj.attributes, &record_bytes);
        !st.ok())
      return Status::InvalidArgument("object " + std::to_string(obj.id) + " '" + obj.name.substr(0, 100) +
                                     "': " + st.message());
    if (auto st = records_spill.Append(record_bytes.data(), record_bytes.size()); !st.ok())
      return st.status();
    records.push_back(rec);
    report.triangles += obj.mesh.triangle_count();
    report.raw_geometry_bytes += obj.mesh.RawGeometryBytes();
    report.encoded_bytes += rec.encoded_bytes;
    return Status::Ok();
  };
  // The store frame, chosen from the first object before any is encoded (entries hold boxes in it).
  SceneObject first;
  auto got_first = read(&first);
  if (!got_first.ok()) return got_first.status();
  bool first_pending = *got_first;
  report.origin = options.origin  ? *options.origin
                  : first_pending ? ChooseStoreOrigin(first.mesh.Bounds())
                                  : Vec3d{};
  // The store's dictionary (object_codec.h), trained on the first objects before any is encoded: they are
  // read ahead, packed as the encoder will pack them, and handed to the encoder after `first`.
  std::deque<SceneObject> ahead;
  EncoderOptions encoder;
  encoder.codec = options.store.codec;
  encoder.codec.dictionary.reset();
  encoder.origin = report.origin;
  encoder.threads = options.threads;
  if (first_pending && encoder.codec.codec == Codec::kZstd) {
    const auto train_start = Clock::now();
    std::vector<uint8_t> sample;
    std::vector<size_t> sizes;
    // An object that cannot be packed is left to the encoder, which reports it in order.
    auto add = [&](const SceneObject& obj) {
      const size_t before = sample.size();
      if (!PackObjectGeometry(obj, report.origin, encoder.codec.shuffle, &sample).ok()) return false;
      if (sample.size() > kDictionarySampleBytes) {  // whole objects only
        sample.resize(before);
        return false;
      }
      sizes.push_back(sample.size() - before);
      return true;
    };
    for (bool more = add(first); more;) {
      SceneObject obj;
      auto got = read(&obj);
      if (!got.ok()) return got.status();
      if (!*got) break;
      ahead.push_back(std::move(obj));
      more = add(ahead.back());
    }
    std::vector<uint8_t> dictionary = TrainDictionary(sample, sizes, encoder.codec.zstd_level);
    if (!dictionary.empty()) {
      auto loaded = CodecDictionary::Load(std::move(dictionary), encoder.codec.zstd_level);
      if (!loaded.ok())
        return Status::Internal("the dictionary just trained does not load: " + loaded.status().message());
      encoder.codec.dictionary = *loaded;
    }
    report.dictionary_bytes = encoder.codec.dictionary ? encoder.codec.dictionary->bytes().size() : 0;
    report.dictionary_seconds = Seconds(train_start);
  }
#if defined(__GLIBC__)
  // Training's buffers (the sample, zstd's tables: ~12 MiB) are free: hand them back before encoding.
  malloc_trim(0);
#endif
  writer.SetCodecDictionary(encoder.codec.dictionary);
  auto read_all = [&](SceneObject* obj) -> Result<bool> {
    if (first_pending) {
      std::swap(*obj, first);
      first_pending = false;
      return true;
    }
    if (ahead.empty()) return read(obj);
    std::swap(*obj, ahead.front());
    ahead.pop_front();
    return true;
  };
  MKTREE_RETURN_IF_ERROR(EncodeObjects(encoder, read_all, spill));
#if defined(__GLIBC__)
  // The pipeline's threads freed their batches and buffers into their own malloc arenas, which keep the
  // pages; hand them back before the tree build, the build's memory peak.
  malloc_trim(0);
#endif
  if (coarse.count > 0) report.warnings.push_back(coarse.Warning(report.origin));
  report.objects = next_id;
  progress(IngestStage::kRead, next_id, next_id);
  if (report.objects == 0)
    return Status::InvalidArgument((options.input_name.empty()
                                        ? store_path + ": not built"
                                        : options.input_name + ": " + store_path + " not built") +
                                   ": empty scene, no object with geometry in the input");
  MKTREE_RETURN_IF_ERROR(geometry.Flush());
  MKTREE_RETURN_IF_ERROR(records_spill.Flush());
  report.read_seconds = Seconds(start);

  // The entry sizes outlive the records, which the builder consumes. Offsets are not kept through the
  // tree build (8 bytes per object at its memory peak): entries were spilled back to back in id order,
  // so they are the prefix sums of the sizes, recomputed below.
  std::vector<uint32_t> entry_bytes(records.size());
  for (const BuildObject& r : records) entry_bytes[r.id] = r.encoded_bytes;
  // They wait at the end of the record spill (past the records its cursor reads) while the tree is built:
  // 4 bytes an object at that stage's peak.
  const uint64_t sizes_at = records_spill.size();
  constexpr size_t kBlock = 1 << 16;  // sizes a write: the spill's buffer holds no copy of them all
  for (size_t i = 0; i < entry_bytes.size(); i += kBlock) {
    const size_t count = std::min(kBlock, entry_bytes.size() - i);
    if (auto st = records_spill.Append(entry_bytes.data() + i, count * sizeof(uint32_t)); !st.ok())
      return st.status();
    MKTREE_RETURN_IF_ERROR(records_spill.Flush());
  }
  std::vector<uint32_t>().swap(entry_bytes);

  // 2. The tree, from the records alone.
  const auto build_start = Clock::now();
  progress(IngestStage::kBuildTree, 0, 1);
  BuildTuning tuning = options.tuning;
  if (tuning.spill_dir.empty()) tuning.spill_dir = dir;  // the tree build's spill file beside the others
  auto built = BuildMKTree(std::move(records), options.store.params, tuning);
  if (!built.ok()) return built.status();
  BuildResult& result = *built;
  report.tree_stats = result.stats;
  report.build_seconds = Seconds(build_start);
  progress(IngestStage::kBuildTree, 1, 1);
  entry_bytes.resize(report.objects);
  MKTREE_RETURN_IF_ERROR(
      records_spill.ReadAt(sizes_at, entry_bytes.size() * sizeof(uint32_t), entry_bytes.data()));

  // 3. Leaf pages in leaf order, assembled from the spill a window of leaves at a time. The spill is in id
  //    order and leaves are not, so a leaf's entries are scattered: reading a window's entries together
  //    (sorted, neighbours gathered into one preadv) costs ~1 system call per run of nearby entries
  //    instead of one per entry (1M pread calls were ~1 s of a 1M-object build).
  const auto write_start = Clock::now();
  // Every kOffsetStride-th offset is kept, the others summed from the sizes when read (8 bytes an object
  // in the write stage's peak otherwise).
  constexpr size_t kOffsetStride = 32;
  std::vector<uint64_t> spill_offset((entry_bytes.size() + kOffsetStride - 1) / kOffsetStride);
  uint64_t spilled = 0;
  for (size_t id = 0; id < entry_bytes.size(); ++id) {
    if (id % kOffsetStride == 0) spill_offset[id / kOffsetStride] = spilled;
    spilled += entry_bytes[id];
  }
  if (spilled != geometry.size())
    return Status::Internal(geometry.path() + ": spill size does not match its entries");
  auto offset_of = [&](ObjectId id) {
    uint64_t at = spill_offset[id / kOffsetStride];
    for (size_t j = id - id % kOffsetStride; j < id; ++j) at += entry_bytes[j];
    return at;
  };
  const uint64_t mem_page = options.store.params.mem_page();
  MKTree& tree = result.tree;
  tree.origin = report.origin;
  const uint32_t leaf_count = static_cast<uint32_t>(tree.leaves.size());
  tree.leaf_filter.resize(uint64_t{kLeafFilterBytesPerObject} * report.objects);
  uint64_t filter_at = 0;
  // A window: the entries of leaves [begin, end), leaf by leaf. While one is assembled into pages, the
  // next is read from the spill on another thread (its reads are system calls and copies that would
  // otherwise stall this loop).
  struct Window {
    uint32_t begin = 0, end = 0;
    std::vector<uint8_t> bytes;
    std::vector<SpillFile::Range> ranges;
  };
  // Whole leaves from `leaf` up to kWindowBytes of entries (at least one leaf, however large).
  auto plan = [&](uint32_t leaf, Window* w) {
    w->begin = w->end = leaf;
    uint64_t bytes = 0;
    while (w->end < leaf_count) {
      uint64_t leaf_bytes = 0;
      for (uint64_t i = result.leaf_offsets[w->end]; i < result.leaf_offsets[w->end + 1]; ++i)
        leaf_bytes += entry_bytes[result.leaf_objects[i]];
      if (w->end > leaf && bytes + leaf_bytes > kWindowBytes) break;
      bytes += leaf_bytes;
      ++w->end;
    }
    w->bytes.resize(bytes);
  };
  // Reads the planned window's entries; touches only what is read-only by now and the window itself.
  auto load = [&](Window* w) -> Status {
    w->ranges.clear();
    uint64_t at = 0;
    for (uint64_t i = result.leaf_offsets[w->begin]; i < result.leaf_offsets[w->end]; ++i) {
      const ObjectId id = result.leaf_objects[i];
      w->ranges.push_back({offset_of(id), entry_bytes[id], w->bytes.data() + at});
      at += entry_bytes[id];
    }
    return geometry.ReadMany(&w->ranges);
  };
  // 4. The object table and record pages, in id order, records streamed from their spill (read in large
  //    blocks), one at a time, on a thread of their own while the leaf pages are written: the record
  //    pages start at the leaf pages' total, which the tree fixes (StoreWriter::BeginObjects).
  std::vector<uint32_t> leaf_of(report.objects, kNoIndex);
  for (uint32_t leaf = 0; leaf < leaf_count; ++leaf)
    for (uint64_t i = result.leaf_offsets[leaf]; i < result.leaf_offsets[leaf + 1]; ++i)
      leaf_of[result.leaf_objects[i]] = leaf;
  const uint64_t leaf_pages =
      leaf_count == 0 ? 0 : uint64_t{tree.leaves.back().first_page} + tree.leaves.back().page_count;
  MKTREE_RETURN_IF_ERROR(writer.BeginObjects(leaf_pages));
  std::atomic<bool> stop_table{false};
  auto write_table = [&]() -> Status {
    StoredRecord record;
    std::vector<uint8_t> bytes;
    SpillCursor record_cursor(records_spill);
    for (ObjectId id = 0; id < report.objects && !stop_table.load(std::memory_order_relaxed); ++id) {
      if (leaf_of[id] == kNoIndex) return Status::Internal("object " + std::to_string(id) + " is in no leaf");
      uint32_t len = 0;
      MKTREE_RETURN_IF_ERROR(record_cursor.Read(sizeof len, &len));
      bytes.resize(4 + uint64_t{len});
      std::memcpy(bytes.data(), &len, 4);
      MKTREE_RETURN_IF_ERROR(record_cursor.Read(len, bytes.data() + 4));
      uint64_t used = 0;
      if (Status st = ParseRecord(bytes.data(), bytes.size(), &used, &record);
          !st.ok() || record.source >= sources.size())
        return Status::Internal(records_spill.path() + ": object " + std::to_string(id) +
                                ": spilled record unreadable");
      MKTREE_RETURN_IF_ERROR(writer.AppendObject(id, leaf_of[id], record.box, record.name,
                                                 sources[record.source], record.attributes));
    }
    return Status::Ok();
  };
  std::future<Status> table = std::async(std::launch::async, write_table);
  // An early return below stops the table's thread and waits for it before what it reads is destroyed.
  struct TableGuard {
    std::atomic<bool>& stop;
    std::future<Status>& table;
    ~TableGuard() {
      stop = true;
      if (table.valid()) table.wait();
    }
  } table_guard{stop_table, table};

  Window windows[2];
  std::vector<std::span<const uint8_t>> entries;
  uint64_t page = 0;
  if (leaf_count > 0) {
    plan(0, &windows[0]);
    MKTREE_RETURN_IF_ERROR(load(&windows[0]));
  }
  for (int cur = 0; windows[cur].begin < windows[cur].end; cur ^= 1) {
    Window& w = windows[cur];
    Window& next = windows[cur ^ 1];
    next.begin = next.end = w.end;
    // On an early return the future's destructor waits for the read, so `next` outlives it.
    std::future<Status> next_read;
    if (w.end < leaf_count) {
      plan(w.end, &next);
      next_read = std::async(std::launch::async, [&load, &next] { return load(&next); });
    }
    uint64_t at = 0;
    for (uint32_t leaf = w.begin; leaf < w.end; ++leaf) {
      entries.clear();
      for (uint64_t i = result.leaf_offsets[leaf]; i < result.leaf_offsets[leaf + 1]; ++i) {
        const ObjectId id = result.leaf_objects[i];
        entries.emplace_back(w.bytes.data() + at, entry_bytes[id]);
        auto parsed = ParseObjectEntry(w.bytes.data() + at, entry_bytes[id]);
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
      if (leaf % 4096 == 0) progress(IngestStage::kWritePages, leaf, leaf_count);
    }
    if (next_read.valid()) MKTREE_RETURN_IF_ERROR(next_read.get());
  }
  windows[0] = windows[1] = {};
  report.pages = page;
  if (!tree.IndexLeafFilter())
    return Status::Internal("leaf filter does not match the leaves' object counts");
  progress(IngestStage::kWritePages, tree.leaves.size(), tree.leaves.size());
  // Freed, not cleared (`v = {}` keeps the capacity), with the leaves' objects: 16 bytes an object
  // otherwise held through the rest of the object table and Commit.
  std::vector<uint64_t>().swap(spill_offset);
  std::vector<uint32_t>().swap(entry_bytes);
  std::vector<ObjectId>().swap(result.leaf_objects);
  progress(IngestStage::kWriteTable, 0, report.objects);
  MKTREE_RETURN_IF_ERROR(table.get());
  progress(IngestStage::kWriteTable, report.objects, report.objects);
  std::vector<uint32_t>().swap(leaf_of);
  MKTREE_RETURN_IF_ERROR(writer.Commit(std::move(tree), result.stats.ToJson()));
  report.write_seconds = Seconds(write_start);

  struct stat st {};
  if (::stat(store_path.c_str(), &st) == 0) report.store_bytes = static_cast<uint64_t>(st.st_size);
  report.total_seconds = Seconds(start);
  return report;
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
