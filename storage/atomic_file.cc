#include "storage/atomic_file.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "storage/file_util.h"

namespace mktree {

using storage_internal::ErrnoText;

namespace {

constexpr size_t kBufferBytes = size_t{1} << 20;  // appends reach the file in writes of this size

// Whether `fd` is still the file named `path` (a stale-temp cleanup may have unlinked it meanwhile).
bool IsNamed(int fd, const std::string& path) {
  struct stat a {
  }, b{};
  return ::fstat(fd, &a) == 0 && ::stat(path.c_str(), &b) == 0 && a.st_ino == b.st_ino &&
         a.st_dev == b.st_dev;
}

}  // namespace

std::string AtomicTempPath(const std::string& target) {
  return target + ".tmp." + std::to_string(::getpid());
}

void RemoveStaleTemps(const std::string& target) {
  namespace fs = std::filesystem;
  const fs::path target_p(target);
  const fs::path dir = target_p.has_parent_path() ? target_p.parent_path() : fs::path(".");
  const std::string prefix = target_p.filename().string() + ".tmp.";
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    if (name.find_first_not_of("0123456789", prefix.size()) != std::string::npos) continue;
    const std::string path = it->path().string();
    std::error_code type_ec;
    if (!it->is_symlink(type_ec) && it->is_regular_file(type_ec)) {
      // A live writer holds its flock; taking it means the writer is gone. Unlinked while held, so that a
      // writer starting now cannot take the name in between.
      const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
      if (fd < 0) continue;
      if (::flock(fd, LOCK_EX | LOCK_NB) == 0 && IsNamed(fd, path)) ::unlink(path.c_str());
      ::close(fd);
    } else {
      std::error_code rm;
      fs::remove(it->path(), rm);  // not a file any writer made (a link, an empty folder): no flock to ask
    }
  }
}

Status RenameOverTarget(const std::string& temp, const std::string& target, FileOps& ops,
                        const std::string& what, bool* renamed) {
  *renamed = false;
  if (ops.Rename(temp, target) != 0) {
    const int err = errno;
    return Status::IOError(target + ": rename from " + temp + ": " + ErrnoText(err));
  }
  *renamed = true;
  const Status st = storage_internal::SyncParentDir(target, ops);
  if (!st.ok())
    return Status::IOError(st.message() + " (" + what + " is in place but may not survive a power loss)");
  return Status::Ok();
}

AtomicFile::AtomicFile(std::string target, std::string temp, int fd, FileOps& ops)
    : target_(std::move(target)), temp_(std::move(temp)), fd_(fd), ops_(&ops) {}

Result<std::unique_ptr<AtomicFile>> AtomicFile::Create(const std::string& target, FileOps& ops) {
  if (target.empty()) return Status::InvalidArgument("empty output path");
  RemoveStaleTemps(target);
  const std::string temp = AtomicTempPath(target);
  // O_EXCL: what is left under the name after the cleanup belongs to a live writer. A cleanup by another
  // process can unlink the file between its creation and the flock: then the name is free again.
  for (int attempt = 0; attempt < 8; ++attempt) {
    const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
      const int err = errno;
      if (err == EEXIST)
        return Status::IOError(target + ": cannot create file: " + temp +
                               " exists and another writer of the same file holds it");
      return Status::IOError(target + ": cannot create file: " + ErrnoText(err));
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0 && IsNamed(fd, temp))
      return std::unique_ptr<AtomicFile>(new AtomicFile(target, temp, fd, ops));
    ::close(fd);
  }
  return Status::IOError(target + ": cannot create file: " + temp + " was removed while being created");
}

AtomicFile::~AtomicFile() {
  if (!done_) Discard();
}

void AtomicFile::Discard() {
  done_ = true;
  if (fd_ < 0) return;
  ::unlink(temp_.c_str());  // before the close: the flock keeps cleanups of other writers away until then
  ::close(fd_);
  fd_ = -1;
}

Status AtomicFile::PwriteAll(const void* data, size_t n, uint64_t offset) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (n > 0) {
    const ssize_t r = ops_->Pwrite(fd_, p, n, offset);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      const int err = r < 0 ? errno : EIO;
      return Status::IOError(target_ + ": write failed: " + ErrnoText(err));
    }
    p += r;
    n -= static_cast<size_t>(r);
    offset += static_cast<uint64_t>(r);
  }
  return Status::Ok();
}

Status AtomicFile::Flush() {
  if (buffer_.empty()) return Status::Ok();
  MKTREE_RETURN_IF_ERROR(PwriteAll(buffer_.data(), buffer_.size(), flushed_));
  flushed_ += buffer_.size();
  buffer_.clear();
  return Status::Ok();
}

Status AtomicFile::Write(const void* data, size_t n) {
  if (done_) return Status::Internal(target_ + ": write after Commit()");
  if (buffer_.size() + n > kBufferBytes) MKTREE_RETURN_IF_ERROR(Flush());
  if (n >= kBufferBytes) {  // large writes go straight to the file
    MKTREE_RETURN_IF_ERROR(PwriteAll(data, n, flushed_));
    flushed_ += n;
  } else {
    if (buffer_.capacity() == 0) buffer_.reserve(kBufferBytes);
    buffer_.insert(buffer_.end(), static_cast<const uint8_t*>(data), static_cast<const uint8_t*>(data) + n);
  }
  size_ += n;
  return Status::Ok();
}

Status AtomicFile::WriteAt(uint64_t offset, const void* data, size_t n) {
  if (done_) return Status::Internal(target_ + ": write after Commit()");
  if (offset > size_ || n > size_ - offset)
    return Status::Internal(target_ + ": overwrite past the end of what was written");
  MKTREE_RETURN_IF_ERROR(Flush());
  return PwriteAll(data, n, offset);
}

Status AtomicFile::Commit() {
  if (done_) return Status::Internal(target_ + ": Commit() called twice");
  Status st = Flush();
  if (st.ok() && ops_->Fsync(fd_) != 0) {
    const int err = errno;
    st = Status::IOError(target_ + ": fsync failed: " + ErrnoText(err));
  }
  if (!st.ok()) {
    Discard();
    return st;
  }
  // Renamed while the descriptor (and so the flock) is held: no cleanup can take the temporary first. A
  // close after fsync loses nothing, so its result is not an error.
  bool renamed = false;
  st = RenameOverTarget(temp_, target_, *ops_, target_, &renamed);
  if (!renamed) {
    Discard();
    return st;
  }
  done_ = true;
  ::close(fd_);
  fd_ = -1;
  return st;
}

}  // namespace mktree
