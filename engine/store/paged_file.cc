// The paged-file backend (layout in docs/store_format.md):
//   [0, P)                       header page (P = MemPage bytes; fixed fields in the first 256 bytes)
//   [P * (1 + i), P * (2 + i))   leaf page i
//   then the sections, back to back: nodes, split nodes, leaves, object leaves, object name ends,
//   object names, stats JSON.
// The header is written last, at Commit, so an unfinished file has a zero header and is refused.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <boost/interprocess/exceptions.hpp>
#include <boost/interprocess/file_mapping.hpp>
#include <boost/interprocess/mapped_region.hpp>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <memory>

#include "engine/store/store_backend.h"
#include "storage/byte_io.h"
#include "storage/file_util.h"

namespace mktree {

using storage_internal::ErrnoText;
using storage_internal::Get;
using storage_internal::PreadFull;
using storage_internal::Put;
using storage_internal::PwriteFull;

namespace {

// 2: the leaf filter holds 10-bit levels in 8 bytes an object; 3: the store frame (an origin in the header,
// boxes relative to it, vertices in each object's local frame).
constexpr uint32_t kPagedFileVersion = 3;
constexpr uint32_t kFixedHeaderBytes = 512;  // the smallest page the builder accepts
constexpr uint32_t kParamsOffset = 16;
constexpr uint32_t kSectionCount = 8;
constexpr uint32_t kSectionTableOffset = 80;
constexpr uint32_t kHeaderChecksumOffset = kSectionTableOffset + kSectionCount * 24;  // 272
constexpr uint32_t kOriginOffset = kHeaderChecksumOffset + 8;                         // 280: 3 x f64
constexpr size_t kDirectAlign = 4096;
static_assert(kOriginOffset + 24 <= kFixedHeaderBytes);
static_assert(kParamsOffset + kParamsRecordBytes <= 48);

const char* const kSectionNames[kSectionCount] = {"nodes",         "split nodes",      "leaves",
                                                  "object leaves", "object name ends", "object names",
                                                  "stats JSON",    "leaf filter"};

uint64_t HeaderChecksum(const uint8_t* header_page, uint64_t mem_page) {
  // XXH3 of the whole header page with its checksum field taken as zero.
  std::vector<uint8_t> copy(header_page, header_page + mem_page);
  std::memset(copy.data() + kHeaderChecksumOffset, 0, 8);
  return Checksum(copy);
}

// A name for the file behind an open descriptor that keeps meaning that file after a rebuild renames a
// new store onto the path (Linux's /proc/self/fd). Opening the path again could reach the new store and
// mix its pages with the old store's tree: their checksums and leaf numbers agree, so nothing would tell.
std::string DescriptorPath(int fd) { return "/proc/self/fd/" + std::to_string(fd); }

bool SameFile(int a, int b) {
  struct stat x {
  }, y{};
  return ::fstat(a, &x) == 0 && ::fstat(b, &y) == 0 && x.st_dev == y.st_dev && x.st_ino == y.st_ino;
}

struct FreeDeleter {
  void operator()(uint8_t* p) const { std::free(p); }
};

class PagedFileStore : public PageStore {
 public:
  PagedFileStore(std::string name, int fd, uint64_t mem_page, uint64_t page_count,
                 FileOps& ops = DefaultFileOps())
      : name_(std::move(name)), fd_(fd), mem_page_(mem_page), count_(page_count), ops_(&ops) {}
  ~PagedFileStore() override { (void)Close(); }

  uint64_t page_bytes() const override { return mem_page_; }
  uint64_t page_count() const override { return count_; }
  const std::string& name() const override { return name_; }

  Status ReadPage(uint64_t index, uint8_t* out) const override {
    if (index >= count_) return PageOutOfRange(name_, index, count_);
    const uint64_t offset = (1 + index) * mem_page_;
    Status st;
    if (direct_fd_ >= 0) {
      if (reinterpret_cast<uintptr_t>(out) % kDirectAlign == 0) {
        st = PreadFull(direct_fd_, out, mem_page_, offset, name_);
      } else {
        // O_DIRECT needs an aligned buffer: bounce through a per-thread one.
        thread_local std::unique_ptr<uint8_t, FreeDeleter> bounce;
        thread_local size_t bounce_size = 0;
        if (bounce_size < mem_page_) {
          bounce.reset(static_cast<uint8_t*>(std::aligned_alloc(kDirectAlign, mem_page_)));
          bounce_size = mem_page_;
        }
        st = PreadFull(direct_fd_, bounce.get(), mem_page_, offset, name_);
        if (st.ok()) std::memcpy(out, bounce.get(), mem_page_);
      }
    } else {
      st = PreadFull(fd_, out, mem_page_, offset, name_);
      if (st.ok() && mapped_ != nullptr)
        read_once_[index / 64].fetch_or(uint64_t{1} << (index % 64), std::memory_order_relaxed);
    }
    if (!st.ok()) return Status::IOError(st.message() + " (page " + std::to_string(index) + ")");
    return Status::Ok();
  }

  Status WritePage(uint64_t index, const uint8_t* data) override {
    if (index > count_)
      return Status::InvalidArgument(name_ + ": page " + std::to_string(index) + " written out of order");
    MKTREE_RETURN_IF_ERROR(PwriteFull(fd_, data, mem_page_, (1 + index) * mem_page_, name_, *ops_));
    if (index == count_) ++count_;
    return Status::Ok();
  }

  Status Sync() override {
    if (ops_->Fsync(fd_) != 0) return Status::IOError(name_ + ": fsync: " + ErrnoText(errno));
    return Status::Ok();
  }

  // In place once the page has been read through the OS cache (ReadPage), which then holds it: touching an
  // uncached mapping would read the page 4 KiB at a time (one fault each), where ReadPage reads it in one
  // pread. (Should the OS drop it later, touching it still reads it, only in smaller steps.)
  const uint8_t* MappedPage(uint64_t index) const override {
    if (mapped_ == nullptr || index >= count_) return nullptr;
    if (!(read_once_[index / 64].load(std::memory_order_relaxed) & (uint64_t{1} << (index % 64))))
      return nullptr;
    return mapped_ + (1 + index) * mem_page_;
  }

  int fd() const { return fd_; }
  FileOps& ops() const { return *ops_; }
  void set_direct_fd(int fd) { direct_fd_ = fd; }
  // Maps the header and leaf pages read-only (buffered reads without a copy per cache miss). A store that
  // cannot be mapped is read with pread. Not with O_DIRECT, whose point is to bypass the OS cache.
  void MapPages() {
    namespace bip = boost::interprocess;
    try {
      bip::file_mapping file(DescriptorPath(fd_).c_str(), bip::read_only);
      if (!SameFile(file.get_mapping_handle().handle, fd_)) return;  // no /proc: read with pread
      region_ = bip::mapped_region(file, bip::read_only, 0, (1 + count_) * mem_page_);
      region_.advise(bip::mapped_region::advice_random);  // leaves are read one by one, not in file order
      read_once_ = std::make_unique<std::atomic<uint64_t>[]>((count_ + 63) / 64);
      mapped_ = static_cast<const uint8_t*>(region_.get_address());
    } catch (const bip::interprocess_exception&) {
      mapped_ = nullptr;
    }
  }
  // An error from close(2) is returned: some filesystems (NFS) report a deferred write error, such as a
  // full disk, only there.
  Status Close() {
    int err = 0;
    if (fd_ >= 0 && ::close(fd_) != 0 && errno != EINTR) err = errno;
    if (direct_fd_ >= 0) ::close(direct_fd_);
    fd_ = direct_fd_ = -1;
    if (err != 0) return Status::IOError(name_ + ": close: " + ErrnoText(err));
    return Status::Ok();
  }

 private:
  std::string name_;
  int fd_;
  int direct_fd_ = -1;
  uint64_t mem_page_;
  uint64_t count_;
  FileOps* ops_;  // writes (the writer's; fault injection in tests)
  boost::interprocess::mapped_region region_;
  const uint8_t* mapped_ = nullptr;
  std::unique_ptr<std::atomic<uint64_t>[]> read_once_;  // bit per page: read through the OS cache before
};

class PagedFileWriter : public StoreWriter::Impl {
 public:
  PagedFileWriter(std::string path, int fd, const BuildParams& params, FileOps& ops)
      : path_(path), store_(std::move(path), fd, params.mem_page(), 0, ops) {}
  PageStore& pages() override { return store_; }
  void Abort() override { (void)store_.Close(); }

  Status Finish(const StoreContents& c) override {
    const uint64_t mem_page = store_.page_bytes();
    // Sections are encoded one at a time, each freed once written: the tree and object table are in RAM
    // already, and at 10M objects an encoded copy of everything would be the build's peak.
    auto encode = [&c](uint32_t i) -> std::vector<uint8_t> {
      switch (i) {
        case 0:
          return EncodeNodes(c.tree.nodes);
        case 1:
          return EncodeSplitNodes(c.tree.split_nodes);
        case 2:
          return EncodeLeaves(c.tree.leaves);
        case 3:
          return EncodeObjectLeaves(c.objects);
        case 4:
          return EncodeObjectNameEnds(c.objects);
        case 5:
          return std::vector<uint8_t>(c.objects.names.begin(), c.objects.names.end());
        case 6:
          return std::vector<uint8_t>(c.stats_json.begin(), c.stats_json.end());
        default:
          return c.tree.leaf_filter;
      }
    };

    std::vector<uint8_t> header(mem_page, 0);
    uint8_t* h = header.data();
    std::memcpy(h, kPagedFileMagic, 8);
    Put<uint32_t>(h + 8, kPagedFileVersion);
    Put<uint32_t>(h + 12, kFixedHeaderBytes);
    const std::vector<uint8_t> params = EncodeParams(c.params, c.codec);
    std::memcpy(h + kParamsOffset, params.data(), params.size());
    Put<uint64_t>(h + 48, store_.page_count());
    Put<uint64_t>(h + 56, c.objects.size());
    Put<uint32_t>(h + 72, kSectionCount);
    for (int i = 0; i < 3; ++i) Put<double>(h + kOriginOffset + 8 * i, c.tree.origin[i]);

    uint64_t offset = (1 + store_.page_count()) * mem_page;
    for (uint32_t i = 0; i < kSectionCount; ++i) {
      const std::vector<uint8_t> s = encode(i);
      MKTREE_RETURN_IF_ERROR(PwriteFull(store_.fd(), s.data(), s.size(), offset, path_, store_.ops()));
      uint8_t* e = h + kSectionTableOffset + 24 * i;
      Put<uint64_t>(e, offset);
      Put<uint64_t>(e + 8, s.size());
      Put<uint64_t>(e + 16, Checksum(s));
      offset += s.size();
    }
    Put<uint64_t>(h + 64, offset);  // file bytes
    Put<uint64_t>(h + kHeaderChecksumOffset, HeaderChecksum(h, mem_page));
    FileOps& ops = store_.ops();
    if (ops.Ftruncate(store_.fd(), offset) != 0)
      return Status::IOError(path_ + ": truncate: " + ErrnoText(errno));
    // Data first, then the header that makes it a store.
    if (ops.Fsync(store_.fd()) != 0) return Status::IOError(path_ + ": fsync: " + ErrnoText(errno));
    MKTREE_RETURN_IF_ERROR(PwriteFull(store_.fd(), h, mem_page, 0, path_, ops));
    if (ops.Fsync(store_.fd()) != 0) return Status::IOError(path_ + ": fsync: " + ErrnoText(errno));
    return store_.Close();
  }

 private:
  std::string path_;
  PagedFileStore store_;
};

}  // namespace

Result<std::unique_ptr<StoreWriter::Impl>> CreatePagedFileWriter(const std::string& temp_path,
                                                                 const BuildParams& params, FileOps& ops) {
  const int fd = ::open(temp_path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status::IOError(temp_path + ": create: " + ErrnoText(errno));
  return std::unique_ptr<StoreWriter::Impl>(new PagedFileWriter(temp_path, fd, params, ops));
}

Result<OpenedStore> OpenPagedFile(const std::string& path, const ReadOptions& opts) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return Status::NotFound(path + ": no such file");
    return Status::IOError(path + ": open: " + ErrnoText(errno));
  }
  // Closes fd on every error path; released to the store at the end.
  struct FdGuard {
    int fd;
    ~FdGuard() {
      if (fd >= 0) ::close(fd);
    }
  } guard{fd};
  OpenedStore out;
  auto bad = [&](const std::string& m) { return Status::Corruption(path + ": " + m); };

  auto size_or = storage_internal::FileSize(fd, path);
  if (!size_or.ok()) return size_or.status();
  const uint64_t size = *size_or;
  if (size < kFixedHeaderBytes)
    return bad("truncated (" + std::to_string(size) + " bytes): not a complete mktree store");
  uint8_t fixed[kFixedHeaderBytes];
  MKTREE_RETURN_IF_ERROR(PreadFull(fd, fixed, kFixedHeaderBytes, 0, path));
  if (std::memcmp(fixed, kPagedFileMagic, 8) != 0) return bad("not an mktree paged-file store (bad magic)");
  const uint32_t version = Get<uint32_t>(fixed + 8);
  if (version != kPagedFileVersion)
    return storage_internal::UnsupportedFormatVersion(path, "paged-file", version, kPagedFileVersion);
  Status st = DecodeParams(std::span<const uint8_t>(fixed + kParamsOffset, kParamsRecordBytes),
                           &out.contents.params, &out.contents.codec);
  if (!st.ok()) return bad("header: " + st.message());
  const uint64_t mem_page = out.contents.params.mem_page();
  // The header page holds the fixed header (the writer refuses smaller pages): reading a smaller one as
  // a header page would run past its end.
  if (mem_page < kFixedHeaderBytes)
    return bad("header: page size " + std::to_string(mem_page) + " is smaller than the " +
               std::to_string(kFixedHeaderBytes) + "-byte header");
  if (size < mem_page)
    return bad("truncated (" + std::to_string(size) + " bytes, shorter than its header page)");
  std::vector<uint8_t> header(mem_page);
  MKTREE_RETURN_IF_ERROR(PreadFull(fd, header.data(), mem_page, 0, path));
  if (Get<uint64_t>(header.data() + kHeaderChecksumOffset) != HeaderChecksum(header.data(), mem_page))
    return bad("header checksum mismatch");
  const uint8_t* h = header.data();
  const uint64_t page_count = Get<uint64_t>(h + 48);
  const uint64_t object_count = Get<uint64_t>(h + 56);
  const uint64_t file_bytes = Get<uint64_t>(h + 64);
  if (Get<uint32_t>(h + 72) != kSectionCount) return bad("unexpected section count");
  if (file_bytes != size)
    return bad("file is " + std::to_string(size) + " bytes but its header says " +
               std::to_string(file_bytes) + (size < file_bytes ? " (truncated)" : " (trailing bytes)"));
  if (page_count > file_bytes / mem_page) return bad("page count larger than the file");

  std::vector<uint8_t> sections[kSectionCount];
  uint64_t expect = (1 + page_count) * mem_page;
  for (uint32_t i = 0; i < kSectionCount; ++i) {
    const uint8_t* e = h + kSectionTableOffset + 24 * i;
    const uint64_t off = Get<uint64_t>(e), bytes = Get<uint64_t>(e + 8), sum = Get<uint64_t>(e + 16);
    if (off != expect || bytes > file_bytes - off)
      return bad(std::string(kSectionNames[i]) + " section out of place");
    sections[i].resize(bytes);
    MKTREE_RETURN_IF_ERROR(PreadFull(fd, sections[i].data(), bytes, off, path));
    if (Checksum(sections[i]) != sum)
      return bad(std::string(kSectionNames[i]) + " section checksum mismatch");
    expect = off + bytes;
  }
  if (expect != file_bytes) return bad("sections do not end at the end of the file");

  StoreContents& c = out.contents;
  c.tree.params = c.params;
  for (int i = 0; i < 3; ++i) {
    c.tree.origin[i] = Get<double>(h + kOriginOffset + 8 * i);
    if (!std::isfinite(c.tree.origin[i])) return bad("header: origin is not finite");
  }
  if (!(st = DecodeNodes(sections[0], &c.tree.nodes)).ok() ||
      !(st = DecodeSplitNodes(sections[1], &c.tree.split_nodes)).ok() ||
      !(st = DecodeLeaves(sections[2], &c.tree.leaves)).ok() ||
      !(st = DecodeObjectTable(sections[3], sections[4], sections[5], &c.objects)).ok())
    return bad(st.message());
  c.stats_json.assign(sections[6].begin(), sections[6].end());
  c.tree.leaf_filter = std::move(sections[7]);
  if (c.objects.size() != object_count) return bad("object table size does not match the header");
  MKTREE_RETURN_IF_ERROR(ValidateStructure(c.tree, c.objects, page_count, path));

  auto store = std::make_unique<PagedFileStore>(path, fd, mem_page, page_count);
  guard.fd = -1;
  if (opts.direct_io) {
    if (mem_page % kDirectAlign != 0) {
      out.notice = path + ": O_DIRECT needs a page size that is a multiple of 4096 (it is " +
                   std::to_string(mem_page) + "); using buffered reads";
    } else {
      const int dfd = ::open(DescriptorPath(store->fd()).c_str(), O_RDONLY | O_CLOEXEC | O_DIRECT);
      if (dfd < 0) {
        out.notice = path + ": O_DIRECT refused (" + ErrnoText(errno) + "); using buffered reads";
      } else if (!SameFile(dfd, store->fd())) {
        ::close(dfd);
        out.notice = path + ": could not reopen the store for O_DIRECT (no /proc); using buffered reads";
      } else {
        // Some filesystems accept O_DIRECT at open and refuse the reads: try one.
        std::unique_ptr<uint8_t, FreeDeleter> probe(
            static_cast<uint8_t*>(std::aligned_alloc(kDirectAlign, mem_page)));
        Status pst = PreadFull(dfd, probe.get(), mem_page, 0, path);
        if (pst.ok()) {
          store->set_direct_fd(dfd);
        } else {
          ::close(dfd);
          out.notice = path + ": O_DIRECT reads refused (" + pst.message() + "); using buffered reads";
        }
      }
    }
  }
  if (!opts.direct_io || !out.notice.empty()) store->MapPages();
  out.pages = std::move(store);
  return out;
}

}  // namespace mktree
