// A store file: the leaf pages plus everything needed to query them (tree, object table, build
// parameters, codec, build statistics), in one file, in one of two backends (docs/store_format.md):
//   - HDF5: pages in a chunked 2-D uint8 dataset (one chunk per page), the rest in compound datasets and
//     attributes that h5dump/h5py can read;
//   - paged file: a header page (magic "MKTREEPF"), raw pages at page-aligned offsets, then checksummed
//     sections.
// Both start with a magic and a version and checksum every byte that matters; a store that fails a check
// is refused at Open with an error naming the file, never half-read.
//
// Building is atomic: StoreWriter writes "<final_path>.tmp.<pid>" (storage/atomic_file.h), and Commit
// fsyncs it, renames it to final_path and fsyncs the directory. Nothing appears under final_path before
// Commit; a destroyed or killed writer leaves nothing that opens as a store.
//
// Concurrency: one StoreWriter per final path at a time, across processes and threads: the writer holds
// an exclusive Boost.Interprocess file_lock on "<final_path>.lock" (removed at the end); a second writer
// fails at Create. Readers take no lock and never wait: because the writer only touches final_path by an
// atomic rename, a reader opening the store during a build sees the last committed store (or NotFound),
// and an open reader keeps reading the file it opened even if a new build replaces it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "engine/store_format/object_codec.h"
#include "engine/store_format/record_codec.h"
#include "engine/store_format/tree_codec.h"
#include "engine/tree/mktree.h"
#include "mktree/scene.h"
#include "mktree/status.h"
#include "storage/file_ops.h"
#include "storage/page_store.h"
#include "storage/write_behind_page_store.h"

namespace mktree {

// The smallest page a store accepts: the paged file's header page must hold its section table.
inline constexpr uint64_t kMinPageBytes = 512;

enum class Backend { kHdf5, kPagedFile };
const char* BackendName(Backend b);  // "hdf5", "pagefile"

struct StoreOptions {
  Backend backend = Backend::kHdf5;  // file layout
  CodecOptions codec;                // how object geometry is encoded in leaf entries (recorded in the store)
  BuildParams params;                // page size etc.; must match the tree given to Commit
  bool direct_io = false;            // reads only (see ReadOptions); ignored when writing
  // The writer's system calls (storage/file_ops.h); null: POSIX. Tests inject faults through it.
  FileOps* file_ops = nullptr;
  // Bytes of consecutive pages the writer gathers into one write (WriteBehindPageStore); tests set one
  // page, so that a fault can hit each page's write.
  uint64_t write_batch_bytes = WriteBehindPageStore::kDefaultBatchBytes;
};

// Thread safety: a StoreWriter is used by one thread, but for AppendObject after BeginObjects (which may
// run on a second thread until Commit).
class StoreWriter {
 public:
  // Takes the writer lock, removes the temporary stores of killed writers and creates
  // "<final_path>.tmp.<pid>". Fails if another writer is building final_path, if final_path exists and is
  // not a regular file (a directory, FIFO, device), or if params give an unusable page size.
  static Result<std::unique_ptr<StoreWriter>> Create(const std::string& final_path, const StoreOptions& opts);
  // The writer lock of final_path alone, held until the returned object is destroyed: what a store's
  // change writer holds (engine/changes), so that a build and a change of one store exclude each other.
  static Result<std::shared_ptr<void>> HoldLock(const std::string& final_path);
  // Removes the temporary file unless committed, and releases the lock.
  ~StoreWriter();

  // Where leaf pages go: write pages 0, 1, 2, ... in increasing order (rewriting a page is allowed), all
  // from one thread.
  // They reach the file on a thread of their own (storage/write_behind_page_store.h): a failed write is
  // returned by a later WritePage, the first AppendObject or Commit.
  PageStore& pages();
  // Declares that the store has `leaf_pages` leaf pages, written through pages() (before or after this
  // call), and that the objects start: from now on AppendObject may run on one other thread while this
  // one writes leaf pages (their record pages go to the pages after the leaf pages, on a thread of their
  // own). Pages() then refuses pages from leaf_pages on, and Commit fails unless every leaf page was
  // written. Without it, the first AppendObject declares the leaf pages written so far.
  // REQUIRES: no object appended yet.
  Status BeginObjects(uint64_t leaf_pages);
  // The objects, appended in id order 0..N-1: each object's leaf goes to the object table, its record (box
  // in the store frame, name, source file, attributes) to the record pages, which follow the leaf pages
  // and are written as they fill (no name is held in RAM).
  // REQUIRES: id == number of objects appended so far.
  Status AppendObject(ObjectId id, uint32_t leaf, const Box3f& box, std::string_view name,
                      std::string_view source, std::span<const ObjectAttribute> attributes);
  // A record of a name only (empty box, no source, no attribute).
  Status AppendObject(ObjectId id, uint32_t leaf, std::string_view name) {
    return AppendObject(id, leaf, Box3f(), name, {}, {});
  }
  uint64_t object_count() const { return objects_.size(); }
  // The zstd dictionary the entries were compressed with (CodecOptions::dictionary), kept in the store;
  // null: none. Replaces the one StoreOptions gave Create.
  void SetCodecDictionary(std::shared_ptr<const CodecDictionary> dictionary);

  // Validates tree against the pages and objects written (ValidateStructure, tree.params page size ==
  // the store's) and stats_json (ValidateStatsJson: empty or TreeStats::ToJson's), writes the tree,
  // object table, parameters, codec, stats JSON and the header with checksums; fsyncs; opens the file as a
  // reader would (every check of StoreReader::Open, no leaf page), so that a store that would not open
  // never replaces the previous one; renames to final_path; fsyncs the directory. After Commit
  // (successful or not) the writer accepts no more calls. If the directory's fsync fails, the new store is
  // in place but may not survive a power loss, and the error says so.
  // The tree is taken by value: move it in when it is not needed afterwards (it is not copied again).
  Status Commit(MKTree tree, const std::string& stats_json);

  const std::string& final_path() const { return final_path_; }
  const std::string& temp_path() const { return temp_path_; }

  class Impl;  // implementation (engine/store_format/store_backend.h)
  class Lock;
  StoreWriter(std::string final_path, std::string temp_path, StoreOptions opts, std::unique_ptr<Impl> backend,
              std::unique_ptr<Lock> lock);

 private:
  std::string final_path_, temp_path_;
  StoreOptions opts_;
  std::unique_ptr<Impl> backend_;
  std::unique_ptr<WriteBehindPageStore> pages_;  // writes to backend_->pages(); stopped before backend_ is
  std::unique_ptr<Lock> lock_;
  ObjectTable objects_;  // count, leaf digests and sources; the directory comes from records_ at Commit
  std::vector<uint32_t> leaf_count_;  // objects appended per leaf
  SourceIndex sources_{&objects_.sources};
  std::unique_ptr<WriteBehindPageStore> record_pages_;  // the pages after the leaf pages
  std::unique_ptr<RecordPager> records_;                // made by BeginObjects, writes to record_pages_
  uint64_t leaf_pages_ = 0;
  std::vector<uint8_t> record_;
  bool done_ = false;
};

struct ReadOptions {
  // Paged file: read leaf pages with O_DIRECT (bypassing the OS page cache, for honest cold reads). If the
  // filesystem or page size does not allow it, reads fall back to buffered I/O and notice() says why.
  // HDF5: not supported; notice() says so.
  bool direct_io = false;
  // false: the leaf filter is checked, then dropped (a change writer reads leaves whole; it would only add
  // 8 bytes an object to a compaction's peak). Queries still answer, testing every entry of a leaf.
  bool keep_leaf_filter = true;
};

// Thread safety: after Open, every const method (and pages().ReadPage) may be called from many threads.
class StoreReader {
 public:
  // Reads the header and the in-RAM structure (no leaf page); checks magic, version, checksums, sizes and
  // structural consistency. Truncated, foreign or corrupt files are refused with an error naming the file.
  // The backend is detected from the file's first bytes.
  static Result<std::unique_ptr<StoreReader>> Open(const std::string& path, const ReadOptions& opts = {});
  ~StoreReader();

  const MKTree& tree() const { return tree_; }
  const PageStore& pages() const { return *pages_; }
  const StoreOptions& options() const { return options_; }
  const std::string& stats_json() const { return stats_json_; }
  uint64_t object_count() const { return objects_.size(); }
  // One object's record, read from its record pages through `cache` (a counted lookup per page, added to
  // *stats) or, with a null cache, straight from the store. InvalidArgument for an id past the end;
  // Corruption naming the store and the page for a damaged record page.
  Result<StoredRecord> ReadRecord(ObjectId id, PageCache* cache, bool verify_checksums,
                                  QueryStats* stats) const;
  // The record's name (ReadRecord without a cache).
  Result<std::string> ObjectName(ObjectId id) const;
  // The leaf that holds the object, from its record (ReadRecord's reads and errors); checked against the
  // tree: Corruption naming the store and the record page if its record names no leaf of the tree.
  Result<uint32_t> ObjectLeaf(ObjectId id, PageCache* cache = nullptr, bool verify_checksums = true,
                              QueryStats* stats = nullptr) const;
  // Where the record pages are, for a RecordReader (valid as long as this reader).
  RecordLayout record_layout() const;
  // The input file of a record, or Corruption if its index is not in the sources table.
  Result<std::string> SourceName(const StoredRecord& record) const;
  uint64_t leaf_page_count() const { return pages_->page_count() - objects_.record_directory.size(); }
  const ObjectTable& objects() const { return objects_; }
  const std::string& path() const { return path_; }
  // Non-fatal remarks from Open (e.g. "O_DIRECT refused by the filesystem; using buffered reads").
  const std::string& notice() const { return notice_; }
  // Test seam: puts wrap(pages) in place of the page store, e.g. a FaultyPageStore that fails or damages
  // reads. REQUIRES: nothing is reading the pages.
  void WrapPages(const std::function<std::unique_ptr<PageStore>(std::unique_ptr<PageStore>)>& wrap) {
    pages_ = wrap(std::move(pages_));
  }

  StoreReader() = default;  // use Open

 private:
  std::string path_;
  std::unique_ptr<PageStore> pages_;
  StoreOptions options_;
  MKTree tree_;
  ObjectTable objects_;
  std::string stats_json_;
  std::string notice_;
};

}  // namespace mktree
