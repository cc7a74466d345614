#include "engine/ingest/leaf_page_writer.h"

#include <future>
#include <span>
#include <utility>

#include "engine/store_format/leaf_codec.h"
#include "engine/store_format/object_codec.h"
#include "engine/tree/leaf_filter.h"

namespace mktree {

namespace {

// Entry bytes read from the spill at a time: large enough that a window's reads gather well, small enough
// to be a minor part of the memory bound.
constexpr uint64_t kWindowBytes = 4 << 20;

// The entries of leaves [begin, end), leaf by leaf.
struct Window {
  uint32_t begin = 0, end = 0;
  std::vector<uint8_t> bytes;
  std::vector<SpillFile::Range> ranges;
};

class LeafPageWriter {
 public:
  LeafPageWriter(const SpilledEntries& entries, uint64_t mem_page, BuildResult* built, PageStore& pages,
                 const IngestOptions& options)
      : entries_(entries),
        mem_page_(mem_page),
        built_(*built),
        tree_(built->tree),
        leaf_count_(static_cast<uint32_t>(built->tree.leaves.size())),
        pages_(pages),
        options_(options) {}

  Result<uint64_t> Run() {
    tree_.leaf_filter.resize(uint64_t{kLeafFilterBytesPerObject} * entries_.count());
    Window windows[2];
    if (leaf_count_ > 0) {
      Plan(0, &windows[0]);
      MKTREE_RETURN_IF_ERROR(Load(&windows[0]));
    }
    for (int cur = 0; windows[cur].begin < windows[cur].end; cur ^= 1) {
      Window& w = windows[cur];
      Window& next = windows[cur ^ 1];
      next.begin = next.end = w.end;
      // While this window is assembled into pages, the next is read on another thread (its reads are
      // system calls and copies that would otherwise stall this loop). On an early return the future's
      // destructor waits for the read, so `next` outlives it.
      std::future<Status> next_read;
      if (w.end < leaf_count_) {
        Plan(w.end, &next);
        next_read = std::async(std::launch::async, [this, &next] { return Load(&next); });
      }
      MKTREE_RETURN_IF_ERROR(WriteWindow(w));
      if (next_read.valid()) MKTREE_RETURN_IF_ERROR(next_read.get());
    }
    if (!tree_.IndexLeafFilter())
      return Status::Internal("leaf filter does not match the leaves' object counts");
    ReportProgress(options_, IngestStage::kWritePages, leaf_count_, leaf_count_);
    return page_;
  }

 private:
  // Whole leaves from `leaf` up to kWindowBytes of entries (at least one leaf, however large).
  void Plan(uint32_t leaf, Window* w) const {
    w->begin = w->end = leaf;
    uint64_t bytes = 0;
    while (w->end < leaf_count_) {
      uint64_t leaf_bytes = 0;
      for (uint64_t i = built_.leaf_offsets[w->end]; i < built_.leaf_offsets[w->end + 1]; ++i)
        leaf_bytes += entries_.size(built_.leaf_objects[i]);
      if (w->end > leaf && bytes + leaf_bytes > kWindowBytes) break;
      bytes += leaf_bytes;
      ++w->end;
    }
    w->bytes.resize(bytes);
  }

  // Reads the planned window's entries; touches only what is read-only by now and the window itself.
  Status Load(Window* w) const {
    w->ranges.clear();
    uint64_t at = 0;
    for (uint64_t i = built_.leaf_offsets[w->begin]; i < built_.leaf_offsets[w->end]; ++i) {
      const ObjectId id = built_.leaf_objects[i];
      w->ranges.push_back({entries_.offset(id), entries_.size(id), w->bytes.data() + at});
      at += entries_.size(id);
    }
    return entries_.file().ReadMany(&w->ranges);
  }

  // Writes the loaded window's leaves, page by page, and their objects' boxes into the leaf filter.
  Status WriteWindow(const Window& w) {
    uint64_t at = 0;
    for (uint32_t leaf = w.begin; leaf < w.end; ++leaf) {
      leaf_entries_.clear();
      for (uint64_t i = built_.leaf_offsets[leaf]; i < built_.leaf_offsets[leaf + 1]; ++i) {
        const uint32_t size = entries_.size(built_.leaf_objects[i]);
        leaf_entries_.emplace_back(w.bytes.data() + at, size);
        auto parsed = ParseObjectEntry(w.bytes.data() + at, size);
        if (!parsed.ok()) return parsed.status();
        QuantizeBox(tree_.leaves[leaf].box, parsed->box, tree_.leaf_filter.data() + filter_at_);
        filter_at_ += kLeafFilterBytesPerObject;
        at += size;
      }
      if (tree_.leaves[leaf].first_page != page_)
        return Status::Internal("leaf " + std::to_string(leaf) + " does not start at the next page");
      MKTREE_RETURN_IF_ERROR(EncodeLeafPages(leaf, leaf_entries_, mem_page_, [&](const uint8_t* bytes) {
        return pages_.WritePage(page_++, bytes);
      }));
      if (page_ != tree_.leaves[leaf].first_page + tree_.leaves[leaf].page_count)
        return Status::Internal("leaf " + std::to_string(leaf) + " wrote an unexpected number of pages");
      if (leaf % 4096 == 0) ReportProgress(options_, IngestStage::kWritePages, leaf, leaf_count_);
    }
    return Status::Ok();
  }

  const SpilledEntries& entries_;
  const uint64_t mem_page_;
  const BuildResult& built_;
  MKTree& tree_;
  const uint32_t leaf_count_;
  PageStore& pages_;
  const IngestOptions& options_;
  std::vector<std::span<const uint8_t>> leaf_entries_;  // the leaf being written
  uint64_t page_ = 0;                                   // the next page to write
  uint64_t filter_at_ = 0;                              // the next object's place in the leaf filter
};

}  // namespace

Result<SpilledEntries> SpilledEntries::Index(const SpillFile& file, std::vector<uint32_t> sizes) {
  SpilledEntries e(file);
  e.sizes_ = std::move(sizes);
  e.offsets_.resize((e.sizes_.size() + kStride - 1) / kStride);
  uint64_t spilled = 0;
  for (size_t id = 0; id < e.sizes_.size(); ++id) {
    if (id % kStride == 0) e.offsets_[id / kStride] = spilled;
    spilled += e.sizes_[id];
  }
  if (spilled != file.size())
    return Status::Internal(file.path() + ": spill size does not match its entries");
  return e;
}

uint64_t SpilledEntries::offset(ObjectId id) const {
  uint64_t at = offsets_[id / kStride];
  for (size_t j = id - id % kStride; j < id; ++j) at += sizes_[j];
  return at;
}

Result<uint64_t> WriteLeafPages(SpilledEntries entries, uint64_t mem_page, BuildResult* built,
                                PageStore& pages, const IngestOptions& options) {
  return LeafPageWriter(entries, mem_page, built, pages, options).Run();
}

}  // namespace mktree
