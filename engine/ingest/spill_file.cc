#include "engine/ingest/spill_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <memory>

namespace mktree {

namespace {
constexpr size_t kBufferBytes = 4 << 20;
}

SpillFile::~SpillFile() {
  if (fd_ >= 0) ::close(fd_);
}

Result<std::unique_ptr<SpillFile>> SpillFile::Create(const std::string& dir, const std::string& stem) {
  std::string pattern = (dir.empty() ? std::string(".") : dir) + "/" + stem + ".XXXXXX";
  std::vector<char> buf(pattern.begin(), pattern.end());
  buf.push_back('\0');
  int fd = ::mkstemp(buf.data());
  if (fd < 0) return Status::IOError(pattern + ": cannot create spill file: " + std::strerror(errno));
  // Unlinked at once: the open descriptor keeps it alive, and a killed build leaves no spill behind.
  ::unlink(buf.data());
  return std::unique_ptr<SpillFile>(new SpillFile(fd, std::string(buf.data())));
}

Result<uint64_t> SpillFile::Append(const void* data, uint64_t size) {
  const uint64_t offset = size_;
  const auto* p = static_cast<const uint8_t*>(data);
  buffer_.insert(buffer_.end(), p, p + size);
  size_ += size;
  if (buffer_.size() >= kBufferBytes) {
    Status st = Flush();
    if (!st.ok()) return st;
  }
  return offset;
}

Status SpillFile::Flush() {
  size_t done = 0;
  while (done < buffer_.size()) {
    ssize_t n = ::pwrite(fd_, buffer_.data() + done, buffer_.size() - done, static_cast<off_t>(flushed_ + done));
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
  if (offset + size > flushed_) return Status::Internal(path_ + ": read past the flushed end of the spill file");
  auto* p = static_cast<uint8_t*>(out);
  uint64_t done = 0;
  while (done < size) {
    ssize_t n = ::pread(fd_, p + done, size - done, static_cast<off_t>(offset + done));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Status::IOError(path_ + ": read failed: " + (n < 0 ? std::strerror(errno) : "short read"));
    done += static_cast<uint64_t>(n);
  }
  return Status::Ok();
}

}  // namespace mktree
