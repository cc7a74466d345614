#include "tools/path_checks.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>

namespace mktree::tools {

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

}  // namespace mktree::tools
