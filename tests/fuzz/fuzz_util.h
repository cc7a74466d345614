// Helpers shared by the fuzz targets (tests/fuzz/*_fuzzer.cc): the input as a file, and a count of inputs
// the parser accepted whole, which the replay tests check so that a corpus that no longer reaches past the
// first checks (after a format change) fails loudly instead of silently fuzzing nothing.
#pragma once

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace mktree::fuzz {

// Inputs that went all the way through (parsed without error); read by replay_main.cc.
inline uint64_t g_accepted = 0;

// With MKTREE_FUZZ_VERBOSE set (triage), prints why an input was refused.
inline void Refused(const std::string& why) {
  static const bool verbose = std::getenv("MKTREE_FUZZ_VERBOSE") != nullptr;
  if (verbose) std::fprintf(stderr, "refused: %s\n", why.c_str());
}

// The input as a file, rewritten for each input; readers open it by its path like any other file. By
// default an in-memory file (memfd, opened through /proc/self/fd); Named() is a file in $TMPDIR (or /tmp)
// for libraries that need a real path (HDF5 resolves it), removed at exit.
class InputFile {
 public:
  static InputFile& Get() {
    static InputFile f(false);
    return f;
  }
  static InputFile& Named() {
    static InputFile f(true);
    return f;
  }
  ~InputFile() {
    if (!unlink_.empty()) ::unlink(unlink_.c_str());
  }
  // Replaces the file's contents with data[0, n) and returns its path.
  const std::string& Write(const uint8_t* data, size_t n) {
    if (::ftruncate(fd_, 0) != 0) Die("ftruncate");
    size_t done = 0;
    while (done < n) {
      const ssize_t w = ::pwrite(fd_, data + done, n - done, static_cast<off_t>(done));
      if (w <= 0) Die("pwrite");
      done += static_cast<size_t>(w);
    }
    return path_;
  }

 private:
  explicit InputFile(bool named) {
    if (!named) fd_ = ::memfd_create("mktree-fuzz", MFD_CLOEXEC);
    if (fd_ >= 0) {
      path_ = "/proc/self/fd/" + std::to_string(fd_);
      return;
    }
    const char* dir = std::getenv("TMPDIR");
    std::string tmpl = std::string(dir && *dir ? dir : "/tmp") + "/mktree-fuzz-XXXXXX";
    fd_ = ::mkstemp(tmpl.data());
    if (fd_ < 0) Die("mkstemp");
    path_ = unlink_ = tmpl;
  }
  [[noreturn]] static void Die(const char* what) {
    std::perror(what);
    std::abort();
  }
  int fd_ = -1;
  std::string path_, unlink_;
};

}  // namespace mktree::fuzz
