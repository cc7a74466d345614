// Paged-file headers that decode but cannot be a header page (found by tests/fuzz store_open).
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>

#include "engine/store/store_file.h"
#include "store/store_test_util.h"

namespace mktree {
namespace {

// A page size the parameter record allows (more than 64 bytes) but smaller than the paged file's 512-byte
// fixed header: Open read the header's fields and checksum past the end of a page-sized buffer (and
// zeroed 8 bytes there), a heap overflow, before refusing the file as a checksum mismatch.
TEST(PagedFileHeaderTest, PageSmallerThanTheHeaderIsRefused) {
  testing::TempDir dir;
  const std::string path = dir.file("small.mkt");
  StoreOptions opts;
  opts.backend = Backend::kPagedFile;
  opts.params.block_size = 512;
  opts.params.blocks_per_page = 1;
  auto w = StoreWriter::Create(path, opts);
  ASSERT_TRUE(w.ok()) << w.status().ToString();
  MKTree tree;
  tree.params = opts.params;
  ASSERT_TRUE((*w)->Commit(tree, "").ok());
  std::vector<uint8_t> file;
  {
    std::ifstream in(path, std::ios::binary);
    file.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GE(file.size(), 512u);
  for (uint32_t block : {65u, 100u, 279u, 511u}) {
    SCOPED_TRACE(block);
    const uint32_t one = 1;
    std::memcpy(file.data() + 16, &block, 4);  // parameter record: block_size, blocks_per_page
    std::memcpy(file.data() + 20, &one, 4);
    {
      std::ofstream out(path, std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
    }
    auto r = StoreReader::Open(path);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Status::Code::kCorruption);
    EXPECT_NE(r.status().message().find(path + ": header: page size " + std::to_string(block) +
                                        " is smaller than the 512-byte header"),
              std::string::npos)
        << r.status().message();
  }
}

}  // namespace
}  // namespace mktree
