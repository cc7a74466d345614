#include "engine/store_format/store_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <boost/interprocess/exceptions.hpp>
#include <boost/interprocess/sync/file_lock.hpp>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <set>

#include "engine/core/guarded.h"
#include "engine/store_format/store_backend.h"
#include "engine/tree/page_budget.h"
#include "storage/atomic_file.h"
#include "storage/file_util.h"

namespace mktree {

using storage_internal::ErrnoText;

const char* BackendName(Backend b) { return b == Backend::kHdf5 ? "hdf5" : "pagefile"; }

// The writer lock on "<final_path>.lock". Boost's file_lock is an fcntl lock, which is per process: it
// keeps other processes out but not another writer in this process, and closing any descriptor of the
// file drops it. So, as LevelDB does, a process-wide table of held lock paths keeps out writers in this
// process, and the descriptor we open stays open as long as the lock is held.
class StoreWriter::Lock {
 public:
  static Result<std::unique_ptr<Lock>> Acquire(const std::string& final_path) {
    const std::string path = final_path + ".lock";
    const std::string key = std::filesystem::weakly_canonical(std::filesystem::absolute(path)).string();
    {
      std::lock_guard<std::mutex> g(TableMutex());
      if (!Table().insert(key).second) return Busy(final_path, path);
    }
    auto release_key = [&] {
      std::lock_guard<std::mutex> g(TableMutex());
      Table().erase(key);
    };
    // A finishing writer unlinks the lock file; if we locked a file that has just been unlinked, retry.
    for (int attempt = 0; attempt < 8; ++attempt) {
      const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
      if (fd < 0) {
        const int err = errno;
        release_key();
        return Status::IOError(path + ": create lock file: " + ErrnoText(err));
      }
      try {
        auto lock = std::make_unique<Lock>();
        lock->fd_ = fd;
        lock->path_ = path;
        lock->key_ = key;
        lock->lock_ = boost::interprocess::file_lock(path.c_str());
        if (!lock->lock_.try_lock()) {
          lock.reset();  // closes fd
          release_key();
          return Busy(final_path, path);
        }
        lock->locked_ = true;
        struct stat a, b;
        if (::fstat(fd, &a) == 0 && ::stat(path.c_str(), &b) == 0 && a.st_ino == b.st_ino &&
            a.st_dev == b.st_dev)
          return lock;
        lock->keep_key_ = true;  // retrying: the table entry stays ours
        lock.reset();
      } catch (const boost::interprocess::interprocess_exception& e) {
        ::close(fd);
        release_key();
        return Status::IOError(path + ": lock: " + e.what());
      }
    }
    release_key();
    return Status::IOError(path + ": could not acquire the writer lock");
  }

  Lock() = default;
  ~Lock() {
    // Unlink while still holding the lock, so no one else can lock the name we are about to drop.
    if (locked_ && !keep_key_) ::unlink(path_.c_str());
    if (locked_) lock_.unlock();
    lock_ = boost::interprocess::file_lock();
    if (fd_ >= 0) ::close(fd_);
    if (!keep_key_ && !key_.empty()) {
      std::lock_guard<std::mutex> g(TableMutex());
      Table().erase(key_);
    }
  }

 private:
  static Status Busy(const std::string& final_path, const std::string& lock_path) {
    return Status::IOError(final_path + ": another writer is building or changing this store (lock " +
                           lock_path + " is held)");
  }
  static std::mutex& TableMutex() {
    static std::mutex mu;
    return mu;
  }
  static std::set<std::string>& Table() {
    static std::set<std::string> held;
    return held;
  }

  int fd_ = -1;
  std::string path_, key_;
  boost::interprocess::file_lock lock_;
  bool locked_ = false;
  bool keep_key_ = false;
};

StoreWriter::StoreWriter(std::string final_path, std::string temp_path, StoreOptions opts,
                         std::unique_ptr<Impl> backend, std::unique_ptr<Lock> lock)
    : final_path_(std::move(final_path)),
      temp_path_(std::move(temp_path)),
      opts_(std::move(opts)),
      backend_(std::move(backend)),
      pages_(std::make_unique<WriteBehindPageStore>(&backend_->pages(), opts_.write_batch_bytes)),
      lock_(std::move(lock)) {}

StoreWriter::~StoreWriter() {
  record_pages_.reset();  // their threads may be writing to the backend
  pages_.reset();
  if (!done_) {
    backend_->Abort();
    ::unlink(temp_path_.c_str());
  }
  backend_.reset();
  lock_.reset();
}

Result<std::shared_ptr<void>> StoreWriter::HoldLock(const std::string& final_path) {
  MKTREE_ASSIGN_OR_RETURN(std::unique_ptr<Lock> lock, Lock::Acquire(final_path));
  return std::shared_ptr<void>(std::move(lock));
}

Result<std::unique_ptr<StoreWriter>> StoreWriter::Create(const std::string& final_path,
                                                         const StoreOptions& opts) {
  const uint64_t mem_page = opts.params.mem_page();
  if (opts.params.block_size == 0 || opts.params.blocks_per_page == 0 || mem_page < kMinPageBytes ||
      mem_page > (uint64_t{1} << 30))
    return Status::InvalidArgument(final_path + ": page size " + std::to_string(mem_page) +
                                   " out of range (512 bytes to 1 GiB)");
  if (!(opts.params.balance_r >= 0 && opts.params.balance_r < 0.5))
    return Status::InvalidArgument(final_path + ": balance ratio must be in [0, 0.5)");
  // Replacing anything but a regular file (or a link to one) would destroy what is not a store, or fail
  // only at the rename, after all the work.
  if (struct stat st{}; ::stat(final_path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    return Status::InvalidArgument(final_path + ": exists and is not a regular file: refusing to replace it");
  auto lock = Lock::Acquire(final_path);
  if (!lock.ok()) return lock.status();
  const std::string temp = AtomicTempPath(final_path);
  RemoveStaleTemps(final_path);  // we hold the lock: any temporary store of final_path is a killed writer's
  FileOps& ops = opts.file_ops ? *opts.file_ops : DefaultFileOps();
  auto backend = opts.backend == Backend::kHdf5 ? CreateHdf5Writer(temp, opts.params, ops)
                                                : CreatePagedFileWriter(temp, opts.params, ops);
  if (!backend.ok()) {
    ::unlink(temp.c_str());
    return backend.status();
  }
  return std::make_unique<StoreWriter>(final_path, temp, opts, std::move(backend).value(),
                                       std::move(lock).value());
}

PageStore& StoreWriter::pages() { return *pages_; }

void StoreWriter::SetCodecDictionary(std::shared_ptr<const CodecDictionary> dictionary) {
  opts_.codec.dictionary = std::move(dictionary);
}

Status LoadCodecDictionary(std::vector<uint8_t> bytes, CodecOptions* c) {
  c->dictionary.reset();
  if (bytes.empty()) return Status::Ok();
  if (c->codec != Codec::kZstd) return Status::Corruption("a codec dictionary, but the codec is not zstd");
  auto d = CodecDictionary::Load(std::move(bytes), std::nullopt);
  if (!d.ok()) return d.status();
  c->dictionary = std::move(d).value();
  return Status::Ok();
}

Status StoreWriter::BeginObjects(uint64_t leaf_pages) {
  if (done_) return Status::InvalidArgument(final_path_ + ": writer already committed");
  if (records_) return Status::InvalidArgument(final_path_ + ": objects already begun");
  if (pages_->page_count() > leaf_pages)
    return Status::InvalidArgument(final_path_ + ": " + std::to_string(pages_->page_count()) +
                                   " leaf pages written, more than the " + std::to_string(leaf_pages) +
                                   " declared");
  leaf_pages_ = leaf_pages;
  pages_->SetLimit(leaf_pages);
  record_pages_ =
      std::make_unique<WriteBehindPageStore>(&backend_->pages(), leaf_pages, opts_.write_batch_bytes);
  WriteBehindPageStore* out = record_pages_.get();
  records_ = std::make_unique<RecordPager>(
      out->page_bytes(), [out](const uint8_t* page) { return out->WritePage(out->page_count(), page); });
  return Status::Ok();
}

Status StoreWriter::AppendObject(ObjectId id, uint32_t leaf, const Box3f& box, std::string_view name,
                                 std::string_view source, std::span<const ObjectAttribute> attributes) {
  if (done_) return Status::InvalidArgument(final_path_ + ": writer already committed");
  if (id != objects_.size())
    return Status::InvalidArgument(final_path_ + ": object " + std::to_string(id) +
                                   " appended out of order (expected " + std::to_string(objects_.size()) +
                                   ")");
  if (!records_) {
    // The leaf pages written so far are all there are. A failed leaf page write surfaces here rather than
    // at Commit, after the whole object table.
    MKTREE_RETURN_IF_ERROR(pages_->Flush());
    MKTREE_RETURN_IF_ERROR(BeginObjects(pages_->page_count()));
  }
  const uint32_t source_index = sources_.Of(source);
  // Every leaf has a page, all written by now: a larger index is in no leaf.
  if (leaf >= leaf_pages_)
    return Status::InvalidArgument(final_path_ + ": object " + std::to_string(id) + " put in leaf " +
                                   std::to_string(leaf) + " of a store of " + std::to_string(leaf_pages_) +
                                   " leaf pages");
  record_.clear();
  Status st = EncodeRecord(box, source_index, leaf, name, attributes, &record_);
  if (!st.ok())
    return Status::InvalidArgument(final_path_ + ": object " + std::to_string(id) + ": " + st.message());
  MKTREE_RETURN_IF_ERROR(records_->Add(id, record_));
  if (leaf >= leaf_count_.size()) {
    leaf_count_.resize(leaf + 1, 0);
    objects_.leaf_digest.resize(leaf + 1, 0);
  }
  ++leaf_count_[leaf];
  objects_.leaf_digest[leaf] += ObjectIdHash(id);
  ++objects_.count;
  return Status::Ok();
}

Status StoreWriter::Commit(MKTree tree, const std::string& stats_json) {
  if (done_) return Status::InvalidArgument(final_path_ + ": writer already committed");
  auto fail = [&](Status st) {
    done_ = true;
    (void)pages_->Flush();  // their threads stop writing before the file is closed
    if (record_pages_) (void)record_pages_->Flush();
    backend_->Abort();
    ::unlink(temp_path_.c_str());
    return st;
  };
  if (tree.params.mem_page() != pages_->page_bytes())
    return fail(Status::InvalidArgument(
        final_path_ + ": the tree's page size " + std::to_string(tree.params.mem_page()) +
        " differs from the store's " + std::to_string(backend_->pages().page_bytes())));
  if (records_) {
    if (Status st = records_->Finish(); !st.ok()) return fail(st);
    if (Status st = record_pages_->Flush(); !st.ok()) return fail(st);
    objects_.record_directory = records_->TakeDirectory();
    if (record_pages_->page_count() != objects_.record_directory.size())
      return fail(Status::Internal(final_path_ + ": record pages written do not match their directory"));
    if (pages_->page_count() != leaf_pages_)
      return fail(Status::InvalidArgument(final_path_ + ": " + std::to_string(pages_->page_count()) + " of " +
                                          std::to_string(leaf_pages_) + " leaf pages written"));
  }
  // The objects appended must be the tree's: each leaf's count (ValidateStructure can only check sums).
  if (leaf_count_.size() > tree.leaves.size())
    return fail(Status::InvalidArgument(final_path_ + ": an object was put in leaf " +
                                        std::to_string(leaf_count_.size() - 1) + " of a tree of " +
                                        std::to_string(tree.leaves.size()) + " leaves"));
  leaf_count_.resize(tree.leaves.size(), 0);
  objects_.leaf_digest.resize(tree.leaves.size(), 0);
  for (size_t l = 0; l < tree.leaves.size(); ++l)
    if (leaf_count_[l] != tree.leaves[l].object_count)
      return fail(Status::InvalidArgument(final_path_ + ": leaf " + std::to_string(l) + " holds " +
                                          std::to_string(tree.leaves[l].object_count) + " objects but " +
                                          std::to_string(leaf_count_[l]) + " were put in it"));
  leaf_count_ = {};
  StoreContents c;
  c.params = tree.params;
  c.codec = opts_.codec;
  c.tree = std::move(tree);
  c.objects = std::move(objects_);
  c.stats_json = stats_json;
  if (Status st = pages_->Flush(); !st.ok()) return fail(st);
  Status st = ValidateStructure(c.tree, c.objects, backend_->pages().page_count(), final_path_);
  if (!st.ok()) return fail(Status::InvalidArgument(st.message()));
  st = ValidateStatsJson(c.stats_json);  // what Open would refuse
  if (!st.ok()) return fail(Status::InvalidArgument(final_path_ + ": " + st.message()));
  st = backend_->Finish(c);
  if (!st.ok()) return fail(st);
  c = StoreContents();
  // What a reader will check, before the previous store is replaced: a writer fault or a write the
  // system got wrong then fails the build instead of leaving a store that never opens.
  if (auto reread = StoreReader::Open(temp_path_); !reread.ok())
    return fail(Status::Corruption(final_path_ +
                                   ": the store just written does not read back, so the previous one "
                                   "is kept: " +
                                   reread.status().message()));
  FileOps& ops = opts_.file_ops ? *opts_.file_ops : DefaultFileOps();
  bool renamed = false;
  st = RenameOverTarget(temp_path_, final_path_, ops, "the new store", &renamed);
  if (!renamed) return fail(st);
  done_ = true;
  // A new store at final_path has none of the old one's changes (docs/changes.md): its changes folder goes,
  // set aside first so that no reader opens it half removed. Readers also ignore a folder whose revisions
  // do not match the store, which covers a crash before this.
  const std::string changes = final_path_ + ".changes";
  std::error_code ec;
  if (std::filesystem::exists(changes, ec)) {
    const std::string aside = changes + ".stale." + std::to_string(::getpid());
    std::filesystem::rename(changes, aside, ec);
    if (!ec) std::filesystem::remove_all(aside, ec);
  }
  return st;
}

Result<std::unique_ptr<StoreReader>> StoreReader::Open(const std::string& path, const ReadOptions& opts) {
  // Guarded: a store whose structure does not fit in memory (or under a memory limit) is an error.
  return Guarded(path, [&]() -> Result<std::unique_ptr<StoreReader>> {
    uint8_t magic[8] = {};
    auto n = storage_internal::ReadPrefix(path, magic, sizeof(magic));
    if (!n.ok()) return n.status();
    if (*n == 0) return Status::Corruption(path + ": empty file: not an mktree store");
    Result<OpenedStore> opened = Status::Internal("unreachable");
    if (*n == 8 && std::memcmp(magic, kPagedFileMagic, 8) == 0) {
      opened = OpenPagedFile(path, opts);
    } else if (*n == 8 && std::memcmp(magic, kHdf5Signature, 8) == 0) {
      opened = OpenHdf5(path, opts);
    } else {
      return Status::Corruption(path + ": not an mktree store (unknown file signature)");
    }
    if (!opened.ok()) return opened.status();
    OpenedStore& o = opened.value();
    // The statistics are printed as they are (mktree info --json): only what the builder writes passes.
    Status st = ValidateStatsJson(o.contents.stats_json);
    if (!st.ok()) return Status::Corruption(path + ": " + st.message());
    auto r = std::make_unique<StoreReader>();
    r->path_ = path;
    r->pages_ = std::move(o.pages);
    r->options_.backend =
        *n == 8 && std::memcmp(magic, kPagedFileMagic, 8) == 0 ? Backend::kPagedFile : Backend::kHdf5;
    r->options_.codec = o.contents.codec;
    r->options_.params = o.contents.params;
    r->options_.direct_io = opts.direct_io && o.notice.empty();
    r->tree_ = std::move(o.contents.tree);
    if (!r->tree_.IndexLeafFilter())
      return Status::Corruption(path + ": leaf filter does not match the leaves");
    if (!opts.keep_leaf_filter) {
      decltype(r->tree_.leaf_filter)().swap(r->tree_.leaf_filter);  // = {} would keep the capacity
      decltype(r->tree_.leaf_filter_begin)().swap(r->tree_.leaf_filter_begin);
    }
    r->objects_ = std::move(o.contents.objects);
    r->stats_json_ = std::move(o.contents.stats_json);
    r->notice_ = std::move(o.notice);
    return r;
  });
}

StoreReader::~StoreReader() = default;

RecordLayout StoreReader::record_layout() const {
  RecordLayout l;
  l.store = pages_.get();
  l.store_name = pages_->name();
  l.first_page = leaf_page_count();
  l.directory = objects_.record_directory;
  l.object_count = objects_.size();
  l.leaf_count = tree_.leaves.size();
  l.mem_page = options_.params.mem_page();
  return l;
}

Result<StoredRecord> StoreReader::ReadRecord(ObjectId id, PageCache* cache, bool verify_checksums,
                                             QueryStats* stats) const {
  RecordReader reader(record_layout(), cache, verify_checksums);
  auto r = reader.Get(id, stats);
  if (!r.ok()) return r.status();
  return **r;
}

Result<std::string> StoreReader::ObjectName(ObjectId id) const {
  auto r = ReadRecord(id, nullptr, true, nullptr);
  if (!r.ok()) return r.status();
  return std::move(r->name);
}

Result<std::string> StoreReader::SourceName(const StoredRecord& record) const {
  if (record.source >= objects_.sources.size())
    return Status::Corruption(path_ + ": an object record names source " + std::to_string(record.source) +
                              " of " + std::to_string(objects_.sources.size()));
  return objects_.sources[record.source];
}

Result<uint32_t> StoreReader::ObjectLeaf(ObjectId id, PageCache* cache, bool verify_checksums,
                                         QueryStats* stats) const {
  RecordReader reader(record_layout(), cache, verify_checksums);
  auto r = reader.Get(id, stats);
  if (!r.ok()) return r.status();
  return (*r)->leaf;
}

}  // namespace mktree
