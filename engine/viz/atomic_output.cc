#include "engine/viz/atomic_output.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

namespace mktree {

namespace {

std::string Errno() { return std::strerror(errno); }

}  // namespace

Result<std::unique_ptr<AtomicOutputFile>> AtomicOutputFile::Create(const std::string& path) {
  if (path.empty()) return Status::InvalidArgument("empty output path");
  const std::string temp = path + ".tmp." + std::to_string(::getpid());
  FilePtr f(std::fopen(temp.c_str(), "wb"));
  if (!f) return Status::IOError(path + ": cannot write: " + Errno());
  return std::unique_ptr<AtomicOutputFile>(new AtomicOutputFile(path, temp, std::move(f)));
}

AtomicOutputFile::~AtomicOutputFile() {
  if (committed_) return;
  file_.reset();
  std::remove(temp_.c_str());
}

Status AtomicOutputFile::Write(const void* data, size_t n) {
  if (n && std::fwrite(data, 1, n, file_.get()) != n)
    return Status::IOError(path_ + ": write failed: " + Errno());
  return Status::Ok();
}

Status AtomicOutputFile::Commit() {
  if (std::fflush(file_.get()) != 0 || std::ferror(file_.get()))
    return Status::IOError(path_ + ": write failed: " + Errno());
  if (::fsync(::fileno(file_.get())) != 0) return Status::IOError(path_ + ": fsync failed: " + Errno());
  if (std::fclose(file_.release()) != 0) return Status::IOError(path_ + ": close failed: " + Errno());
  if (std::rename(temp_.c_str(), path_.c_str()) != 0)
    return Status::IOError(path_ + ": rename failed: " + Errno());
  committed_ = true;
  return Status::Ok();
}

Result<FilePtr> OpenSpoolFile(const std::string& near_path) {
  static std::atomic<uint64_t> counter{0};
  std::filesystem::path dir = std::filesystem::path(near_path).parent_path();
  if (dir.empty()) dir = ".";
  const std::string name =
      (dir / (".mktree_spool." + std::to_string(::getpid()) + "." + std::to_string(counter++))).string();
  FilePtr f(std::fopen(name.c_str(), "w+b"));
  if (!f)
    return Status::IOError(near_path + ": cannot create a scratch file in " + dir.string() + ": " + Errno());
  std::remove(name.c_str());  // unlinked: nothing is left behind, however the process ends
  return f;
}

Status CopySpool(std::FILE* spool, std::FILE* out, const std::string& out_name) {
  if (std::fflush(spool) != 0 || std::fseek(spool, 0, SEEK_SET) != 0)
    return Status::IOError(out_name + ": scratch file: " + Errno());
  std::vector<char> buf(1 << 20);
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), spool)) > 0)
    if (std::fwrite(buf.data(), 1, n, out) != n)
      return Status::IOError(out_name + ": write failed: " + Errno());
  if (std::ferror(spool)) return Status::IOError(out_name + ": scratch file read failed: " + Errno());
  return Status::Ok();
}

}  // namespace mktree
