// Replays fuzz inputs without libFuzzer (the gcc build and CI): feeds every file given, or found under a
// directory given, to LLVMFuzzerTestOneInput, so that each saved corpus unit and crash input stays a test.
//   fuzz_<target> [--min-accepted=K] PATH...
// A crash, sanitizer report or hang fails the test (ctest's timeout); --min-accepted=K additionally fails
// when fewer than K inputs were accepted whole (fuzz_util.h: the seeds no longer reach the deep code).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  uint64_t min_accepted = 0;
  std::vector<fs::path> files;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--min-accepted=", 0) == 0) {
      min_accepted = std::strtoull(arg.c_str() + 15, nullptr, 10);
      continue;
    }
    std::error_code ec;
    if (fs::is_directory(arg, ec)) {
      for (const auto& e : fs::recursive_directory_iterator(arg))
        if (e.is_regular_file() && e.path().filename().string()[0] != '.') files.push_back(e.path());
    } else if (fs::is_regular_file(arg, ec)) {
      files.push_back(arg);
    } else {
      std::fprintf(stderr, "%s: no such file or directory\n", arg.c_str());
      return 2;
    }
  }
  std::sort(files.begin(), files.end());
  for (const fs::path& f : files) {
    std::ifstream in(f, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) {
      std::fprintf(stderr, "%s: read failed\n", f.c_str());
      return 2;
    }
    std::fprintf(stderr, "replay %s (%zu bytes)\n", f.c_str(), bytes.size());
    // Like libFuzzer, hand over a heap copy of exactly the input's size, so overreads are caught.
    std::vector<uint8_t> copy(bytes);
    LLVMFuzzerTestOneInput(copy.data(), copy.size());
  }
  std::printf("%zu inputs replayed, %llu accepted\n", files.size(),
              static_cast<unsigned long long>(mktree::fuzz::g_accepted));
  if (mktree::fuzz::g_accepted < min_accepted) {
    std::fprintf(stderr,
                 "only %llu inputs accepted, expected at least %llu: the seeds no longer reach past the "
                 "parser's first checks (format changed? regenerate them: tests/fuzz/make_seeds.sh)\n",
                 static_cast<unsigned long long>(mktree::fuzz::g_accepted),
                 static_cast<unsigned long long>(min_accepted));
    return 1;
  }
  return 0;
}
