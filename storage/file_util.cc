#include "storage/file_util.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>

namespace mktree {

ssize_t FileOps::Pwrite(int fd, const void* buf, size_t n, uint64_t offset) {
  return ::pwrite(fd, buf, n, static_cast<off_t>(offset));
}
ssize_t FileOps::Pread(int fd, void* buf, size_t n, uint64_t offset) {
  return ::pread(fd, buf, n, static_cast<off_t>(offset));
}
ssize_t FileOps::Preadv(int fd, const iovec* iov, int count, uint64_t offset) {
  return ::preadv(fd, iov, count, static_cast<off_t>(offset));
}
int FileOps::Ftruncate(int fd, uint64_t size) { return ::ftruncate(fd, static_cast<off_t>(size)); }
int FileOps::Fsync(int fd) { return ::fsync(fd); }
int FileOps::Rename(const std::string& from, const std::string& to) {
  return ::rename(from.c_str(), to.c_str());
}

FileOps& DefaultFileOps() {
  static FileOps posix;
  return posix;
}

}  // namespace mktree

namespace mktree::storage_internal {

std::string ErrnoText(int err) { return std::strerror(err); }

Result<UnnamedFile> OpenUnnamedFile(const std::string& dir, const std::string& stem,
                                    const std::string& what) {
  std::string folder = dir;
  if (folder.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    folder = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  }
  UnnamedFile file;
  file.where = folder + "/" + stem + ".XXXXXX";
#ifdef O_TMPFILE
  file.fd = ::open(folder.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (file.fd >= 0) return file;
#endif
  file.fd = ::mkostemp(file.where.data(), O_CLOEXEC);
  if (file.fd < 0) return Status::IOError(folder + ": cannot create " + what + ": " + ErrnoText(errno));
  ::unlink(file.where.c_str());
  return file;
}

Status PreadFull(int fd, void* buf, size_t n, uint64_t offset, const std::string& name, FileOps& ops) {
  auto* p = static_cast<uint8_t*>(buf);
  size_t done = 0;
  while (done < n) {
    const ssize_t r = ops.Pread(fd, p + done, n - done, offset + done);
    if (r < 0) {
      if (errno == EINTR) continue;
      return Status::IOError(name + ": read at offset " + std::to_string(offset + done) + ": " +
                             ErrnoText(errno));
    }
    if (r == 0)
      return Status::IOError(name + ": short read at offset " + std::to_string(offset + done) +
                             " (file truncated)");
    done += static_cast<size_t>(r);
  }
  return Status::Ok();
}

void WritebackPacer::Wrote(int fd, uint64_t bytes) {
  pending_ += bytes;
  if (pending_ < kBytes) return;
  pending_ = 0;
#ifdef __linux__
  // The whole file (length 0: to its end): its dirty pages not yet under writeback, wherever the writer
  // put them (HDF5 writes its metadata here and there).
  static_cast<void>(::sync_file_range(fd, 0, 0, SYNC_FILE_RANGE_WRITE));
#else
  static_cast<void>(fd);
#endif
}

Status PwriteFull(int fd, const void* buf, size_t n, uint64_t offset, const std::string& name, FileOps& ops) {
  const auto* p = static_cast<const uint8_t*>(buf);
  size_t done = 0;
  while (done < n) {
    const ssize_t r = ops.Pwrite(fd, p + done, n - done, offset + done);
    if (r < 0) {
      if (errno == EINTR) continue;
      return Status::IOError(name + ": write at offset " + std::to_string(offset + done) + ": " +
                             ErrnoText(errno));
    }
    done += static_cast<size_t>(r);
  }
  return Status::Ok();
}

Result<uint64_t> FileSize(int fd, const std::string& name) {
  struct stat st;
  if (::fstat(fd, &st) != 0) return Status::IOError(name + ": stat: " + ErrnoText(errno));
  return static_cast<uint64_t>(st.st_size);
}

Status SyncParentDir(const std::string& path, FileOps& ops) {
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  const std::string dir = parent.empty() ? std::string(".") : parent.string();
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Status::IOError(dir + ": open directory: " + ErrnoText(errno));
  const int r = ops.Fsync(fd);
  const int err = errno;
  ::close(fd);
  if (r != 0) return Status::IOError(dir + ": fsync directory: " + ErrnoText(err));
  return Status::Ok();
}

Result<size_t> ReadPrefix(const std::string& path, void* buf, size_t n) {
  if (path.empty()) return Status::InvalidArgument("empty file name");
  // O_NONBLOCK: opening a FIFO must not wait for a writer; anything but a regular file is refused below.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) return Status::NotFound(path + ": no such file");
    return Status::IOError(path + ": open: " + ErrnoText(err));
  }
  if (struct stat st{}; ::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return Status::InvalidArgument(path + ": not a regular file");
  }
  size_t done = 0;
  while (done < n) {
    const ssize_t r = ::read(fd, static_cast<uint8_t*>(buf) + done, n - done);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) break;
    done += static_cast<size_t>(r);
  }
  ::close(fd);
  return done;
}

Status UnsupportedFormatVersion(const std::string& path, const std::string& format, uint32_t found,
                                uint32_t reads) {
  return Status::Unsupported(path + ": " + format + " format version " + std::to_string(found) +
                             " (this build reads version " + std::to_string(reads) +
                             "): build the store again from its scene");
}

namespace {

const char* KindOf(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "a special file";
}

}  // namespace

Status CheckInputFile(const std::string& path) {
  if (path.empty()) return Status::InvalidArgument("an input file name is empty");
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT) return Status::NotFound(path + ": no such file");
    return Status::IOError(path + ": " + std::strerror(err));
  }
  if (!S_ISREG(st.st_mode))
    return Status::InvalidArgument(path + ": not a regular file (" + KindOf(st.st_mode) + ")");
  return Status::Ok();
}

Status CheckOutputFile(const std::string& output, const std::vector<std::string>& inputs) {
  if (output.empty()) return Status::InvalidArgument("the output file name is empty");
  struct stat out {};
  if (::stat(output.c_str(), &out) != 0) return Status::Ok();  // nothing there (or a dangling link): no input
  if (!S_ISREG(out.st_mode))
    return Status::InvalidArgument(output + ": the output exists and is " + KindOf(out.st_mode) +
                                   ": refusing to replace it");
  for (const std::string& in : inputs) {
    struct stat st {};
    if (::stat(in.c_str(), &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino)
      return Status::InvalidArgument(output + ": the output is the input " + in +
                                     ": refusing to overwrite it");
  }
  return Status::Ok();
}

}  // namespace mktree::storage_internal
