// The temporary folders of the tests: a fixture, a fresh folder under the system's temporary directory
// removed with everything in it at destruction, and the test program's own such folder.
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <stdexcept>
#include <string>

namespace mktree::testing {

class TempDir {
 public:
  // `prefix` names the folder ("<prefix>_XXXXXX"), so that a folder left by a crashed test says whose it is.
  explicit TempDir(const std::string& prefix = "mktree_test") {
    std::string tmpl = (std::filesystem::temp_directory_path() / (prefix + "_XXXXXX")).string();
    if (::mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + tmpl);
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;

  const std::filesystem::path& path() const { return path_; }
  operator const std::filesystem::path&() const { return path_; }  // where a folder is wanted
  // The path of `name` in the folder.
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }
  // Removes everything in the folder (the folder stays).
  void Clear() const {
    for (const auto& e : std::filesystem::directory_iterator(path_)) std::filesystem::remove_all(e.path());
  }

 private:
  std::filesystem::path path_;
};

// The test program's own folder (named after it, MKTREE_TEST_PROGRAM), made on first use and removed when
// the program ends: one for all its files, which tests/CMakeLists.txt compiles as a few unity sources.
inline const TempDir& ProgramDir() {
  static const TempDir dir(MKTREE_TEST_PROGRAM);
  return dir;
}

// The path of `name` in ProgramDir().
inline std::string TempPath(const std::string& name) { return ProgramDir().file(name); }

}  // namespace mktree::testing
