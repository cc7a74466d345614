#include "engine/ingest/spill_file.h"

#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>

#include "storage/file_util.h"

namespace mktree {

namespace {
constexpr size_t kBufferBytes = 4 << 20;
// ReadMany reads through gaps up to this size: copying 4 KiB costs less than a system call.
constexpr uint64_t kMaxGapBytes = 4 << 10;
constexpr size_t kMaxIovecs = 1024;  // Linux UIO_MAXIOV
constexpr size_t kCursorBlockBytes = 1 << 20;

// preadv until every byte of iov[0, n) is read; advances through the iovecs on short reads.
Status PreadvFull(FileOps& ops, int fd, iovec* iov, size_t n, uint64_t offset, const std::string& path) {
  while (n > 0) {
    const ssize_t got = ops.Preadv(fd, iov, static_cast<int>(n), offset);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0)
      return Status::IOError(path + ": read failed: " + (got < 0 ? std::strerror(errno) : "short read"));
    offset += static_cast<uint64_t>(got);
    size_t left = static_cast<size_t>(got);
    while (n > 0 && left >= iov->iov_len) {
      left -= iov->iov_len;
      ++iov;
      --n;
    }
    if (n > 0) {
      iov->iov_base = static_cast<uint8_t*>(iov->iov_base) + left;
      iov->iov_len -= left;
    }
  }
  return Status::Ok();
}
}  // namespace

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
}

Result<std::unique_ptr<SpillFile>> SpillFile::Create(const std::string& dir, const std::string& stem,
                                                     FileOps& ops) {
  MKTREE_ASSIGN_OR_RETURN(storage_internal::UnnamedFile file,
                          storage_internal::OpenUnnamedFile(dir.empty() ? "." : dir, stem, "a spill file"));
  return std::unique_ptr<SpillFile>(new SpillFile(file.fd, std::move(file.where), ops));
}

Result<uint64_t> SpillFile::Append(const void* data, uint64_t size) {
  const uint64_t offset = size_;
  const auto* p = static_cast<const uint8_t*>(data);
  buffer_.insert(buffer_.end(), p, p + size);
  size_ += size;
  if (buffer_.size() >= kBufferBytes) {
    Status st = WriteBuffer();
    if (!st.ok()) return st;
  }
  return offset;
}

Status SpillFile::Flush() {
  MKTREE_RETURN_IF_ERROR(WriteBuffer());
  // Reading comes next: the buffer's pages (4-8 MiB) would otherwise stay through the tree build.
  std::vector<uint8_t>().swap(buffer_);
  return Status::Ok();
}

Status SpillFile::WriteBuffer() {
  size_t done = 0;
  while (done < buffer_.size()) {
    ssize_t n = ops_->Pwrite(fd_, buffer_.data() + done, buffer_.size() - done, flushed_ + done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return Status::IOError(path_ + ": write failed: " + std::strerror(errno));
    }
    done += static_cast<size_t>(n);
  }
  flushed_ += buffer_.size();
  buffer_.clear();
  return Status::Ok();
}

Status SpillFile::ReadAt(uint64_t offset, uint64_t size, void* out) const {
  if (offset + size > flushed_)
    return Status::Internal(path_ + ": read past the flushed end of the spill file");
  auto* p = static_cast<uint8_t*>(out);
  uint64_t done = 0;
  while (done < size) {
    ssize_t n = ops_->Pread(fd_, p + done, size - done, offset + done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      return Status::IOError(path_ + ": read failed: " + (n < 0 ? std::strerror(errno) : "short read"));
    done += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

Status SpillFile::ReadMany(std::vector<Range>* ranges) const {
  std::sort(ranges->begin(), ranges->end(),
            [](const Range& a, const Range& b) { return a.offset < b.offset; });
  std::vector<uint8_t> gap(kMaxGapBytes);  // discarded; preadv writes each gap here
  std::vector<iovec> iov;
  iov.reserve(kMaxIovecs);
  uint64_t run_start = 0, run_end = 0;  // file range the pending iovecs cover
  auto flush = [&]() -> Status {
    Status st = PreadvFull(*ops_, fd_, iov.data(), iov.size(), run_start, path_);
    iov.clear();
    return st;
  };
  for (const Range& r : *ranges) {
    if (r.offset + r.size > flushed_)
      return Status::Internal(path_ + ": read past the flushed end of the spill file");
    if (r.size == 0) continue;
    // Ranges may overlap (two readers of one entry): then start a new run rather than read backwards.
    const bool joins = !iov.empty() && r.offset >= run_end && r.offset - run_end <= kMaxGapBytes &&
                       iov.size() + 2 <= kMaxIovecs;
    if (!joins) {
      if (!iov.empty()) MKTREE_RETURN_IF_ERROR(flush());
      run_start = run_end = r.offset;
    }
    if (r.offset > run_end) iov.push_back({gap.data(), static_cast<size_t>(r.offset - run_end)});
    iov.push_back({r.out, static_cast<size_t>(r.size)});
    run_end = r.offset + r.size;
  }
  return iov.empty() ? Status::Ok() : flush();
}

Status SpillCursor::Read(uint64_t size, void* out) {
  auto* p = static_cast<uint8_t*>(out);
  while (size > 0) {
    if (at_ == block_.size()) {
      block_offset_ += block_.size();
      const uint64_t left = file_.size() - block_offset_;
      if (left == 0) return Status::Internal(file_.path() + ": read past the end of the spill file");
      block_.resize(static_cast<size_t>(std::min<uint64_t>(left, kCursorBlockBytes)));
      MKTREE_RETURN_IF_ERROR(file_.ReadAt(block_offset_, block_.size(), block_.data()));
      at_ = 0;
    }
    const size_t n = static_cast<size_t>(std::min<uint64_t>(size, block_.size() - at_));
    std::memcpy(p, block_.data() + at_, n);
    p += n;
    at_ += n;
    size -= n;
  }
  return Status::Ok();
}

}  // namespace mktree
