// What the ingest tests share: the hash of a file's bytes, to check that a failed build left a store as
// it was.
#pragma once

#include <xxhash.h>

#include <cstdint>
#include <fstream>
#include <iterator>
#include <string>

namespace mktree::testing {

inline uint64_t FileHash(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), {});
  return XXH3_64bits(bytes.data(), bytes.size());
}

}  // namespace mktree::testing
