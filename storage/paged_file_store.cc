#include "storage/paged_file_store.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <new>

#include "storage/byte_io.h"
#include "storage/file_util.h"

namespace mktree {

using storage_internal::ErrnoText;
using storage_internal::Get;
using storage_internal::PreadFull;
using storage_internal::Put;
using storage_internal::PwriteFull;

namespace {

constexpr size_t kDirectAlign = 4096;

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

}  // namespace

Result<std::unique_ptr<PagedFileStore>> PagedFileStore::Create(const std::string& path, uint64_t page_bytes,
                                                               FileOps& ops) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status::IOError(path + ": create: " + ErrnoText(errno));
  return std::make_unique<PagedFileStore>(path, fd, page_bytes, 0, ops);
}

std::string PagedFileStore::StartReading(bool direct_io) {
  std::string notice;
  if (direct_io) {
    if (page_bytes_ % kDirectAlign != 0) {
      notice = name_ + ": O_DIRECT needs a page size that is a multiple of 4096 (it is " +
               std::to_string(page_bytes_) + "); using buffered reads";
    } else {
      const int dfd = ::open(DescriptorPath(fd_).c_str(), O_RDONLY | O_CLOEXEC | O_DIRECT);
      if (dfd < 0) {
        notice = name_ + ": O_DIRECT refused (" + ErrnoText(errno) + "); using buffered reads";
      } else if (!SameFile(dfd, fd_)) {
        ::close(dfd);
        notice = name_ + ": could not reopen the store for O_DIRECT (no /proc); using buffered reads";
      } else {
        // Some filesystems accept O_DIRECT at open and refuse the reads: try one.
        std::unique_ptr<uint8_t, FreeDeleter> probe(
            static_cast<uint8_t*>(std::aligned_alloc(kDirectAlign, page_bytes_)));
        Status pst = PreadFull(dfd, probe.get(), page_bytes_, 0, name_);
        if (pst.ok()) {
          direct_fd_ = dfd;
        } else {
          ::close(dfd);
          notice = name_ + ": O_DIRECT reads refused (" + pst.message() + "); using buffered reads";
        }
      }
    }
  }
  return notice;
}

PagedFileStore::PagedFileStore(std::string name, int fd, uint64_t page_bytes, uint64_t page_count,
                               FileOps& ops)
    : name_(std::move(name)), fd_(fd), page_bytes_(page_bytes), count_(page_count), ops_(&ops) {}

PagedFileStore::~PagedFileStore() { (void)Close(); }

Status PagedFileStore::ReadPage(uint64_t index, uint8_t* out) const {
  if (index >= count_) return PageOutOfRange(name_, index, count_);
  const uint64_t offset = (1 + index) * page_bytes_;
  Status st;
  if (direct_fd_ >= 0) {
    if (reinterpret_cast<uintptr_t>(out) % kDirectAlign == 0) {
      st = PreadFull(direct_fd_, out, page_bytes_, offset, name_);
    } else {
      // O_DIRECT needs an aligned buffer: bounce through a per-thread one.
      thread_local std::unique_ptr<uint8_t, FreeDeleter> bounce;
      thread_local size_t bounce_size = 0;
      if (bounce_size < page_bytes_) {
        bounce.reset(static_cast<uint8_t*>(std::aligned_alloc(kDirectAlign, page_bytes_)));
        bounce_size = page_bytes_;
      }
      st = PreadFull(direct_fd_, bounce.get(), page_bytes_, offset, name_);
      if (st.ok()) std::memcpy(out, bounce.get(), page_bytes_);
    }
  } else {
    st = PreadFull(fd_, out, page_bytes_, offset, name_);
  }
  if (!st.ok()) return Status::IOError(st.message() + " (page " + std::to_string(index) + ")");
  return Status::Ok();
}

Status PagedFileStore::WritePages(uint64_t first, uint64_t count, const uint8_t* data) {
  MKTREE_RETURN_IF_ERROR(PwriteFull(fd_, data, count * page_bytes_, (1 + first) * page_bytes_, name_, *ops_));
  std::lock_guard<std::mutex> lock(write_mu_);
  count_.store(std::max(count_.load(std::memory_order_relaxed), first + count), std::memory_order_relaxed);
  writeback_.Wrote(fd_, count * page_bytes_);
  return Status::Ok();
}

Status PagedFileStore::Sync() {
  if (ops_->Fsync(fd_) != 0) return Status::IOError(name_ + ": fsync: " + ErrnoText(errno));
  return Status::Ok();
}

Status PagedFileStore::Close() {
  int err = 0;
  if (fd_ >= 0 && ::close(fd_) != 0 && errno != EINTR) err = errno;
  if (direct_fd_ >= 0) ::close(direct_fd_);
  fd_ = direct_fd_ = -1;
  if (err != 0) return Status::IOError(name_ + ": close: " + ErrnoText(err));
  return Status::Ok();
}

Result<uint64_t> WriteSections(int fd, uint64_t offset, uint32_t count,
                               const std::function<std::vector<uint8_t>(uint32_t)>& encode, uint8_t* table,
                               const std::string& path, FileOps& ops) {
  for (uint32_t i = 0; i < count; ++i) {
    const std::vector<uint8_t> s = encode(i);
    MKTREE_RETURN_IF_ERROR(PwriteFull(fd, s.data(), s.size(), offset, path, ops));
    uint8_t* e = table + kSectionEntryBytes * i;
    Put<uint64_t>(e, offset);
    Put<uint64_t>(e + 8, s.size());
    Put<uint64_t>(e + 16, XXH3_64bits(s.data(), s.size()));
    offset += s.size();
  }
  return offset;
}

SectionReader::SectionReader(int fd, uint64_t offset, uint64_t bytes, const std::string& path)
    : fd_(fd), offset_(offset), bytes_(bytes), path_(path), state_(XXH3_createState()) {
  if (state_ == nullptr) throw std::bad_alloc();
  XXH3_64bits_reset(static_cast<XXH3_state_t*>(state_));
}

SectionReader::~SectionReader() { XXH3_freeState(static_cast<XXH3_state_t*>(state_)); }

Status SectionReader::Read(void* dst, uint64_t n) {
  if (n > left()) return Status::Internal(path_ + ": section read past its end");
  MKTREE_RETURN_IF_ERROR(PreadFull(fd_, dst, n, offset_ + done_, path_));
  XXH3_64bits_update(static_cast<XXH3_state_t*>(state_), dst, n);
  done_ += n;
  return Status::Ok();
}

uint64_t SectionReader::Checksum() const { return XXH3_64bits_digest(static_cast<XXH3_state_t*>(state_)); }

Result<uint64_t> ReadSections(int fd, const uint8_t* table, std::span<const char* const> names,
                              uint64_t offset, uint64_t file_bytes, const std::string& path,
                              const std::function<Status(size_t i, SectionReader& reader)>& take) {
  for (size_t i = 0; i < names.size(); ++i) {
    const uint8_t* e = table + kSectionEntryBytes * i;
    const uint64_t off = Get<uint64_t>(e), bytes = Get<uint64_t>(e + 8), sum = Get<uint64_t>(e + 16);
    if (off != offset || off > file_bytes || bytes > file_bytes - off)
      return Status::Corruption(path + ": " + names[i] + " section out of place");
    SectionReader reader(fd, off, bytes, path);
    MKTREE_RETURN_IF_ERROR(take(i, reader));
    if (reader.left() != 0) return Status::Internal(path + ": " + names[i] + " section not read to its end");
    if (reader.Checksum() != sum)
      return Status::Corruption(path + ": " + names[i] + " section checksum mismatch");
    offset = off + bytes;
  }
  return offset;
}

}  // namespace mktree
