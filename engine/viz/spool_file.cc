#include "engine/viz/spool_file.h"

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

Status CopySpool(std::FILE* spool, AtomicFile* out) {
  const std::string& out_name = out->target();
  if (std::fflush(spool) != 0 || std::fseek(spool, 0, SEEK_SET) != 0)
    return Status::IOError(out_name + ": scratch file: " + Errno());
  std::vector<char> buf(1 << 20);
  size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), spool)) > 0)
    MKTREE_RETURN_IF_ERROR(out->Write(buf.data(), n));
  if (std::ferror(spool)) return Status::IOError(out_name + ": scratch file read failed: " + Errno());
  return Status::Ok();
}

}  // namespace mktree
