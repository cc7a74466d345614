// Paged-file headers that decode but cannot be a header page (found by tests/fuzz store_open), and damaged
// sections.
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <iterator>
#include <span>
#include <vector>

#include "engine/store_format/store_file.h"
#include "engine/store_format/tree_codec.h"
#include "store_format/store_test_util.h"

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

// The sections are read straight into the structures they decode to, and checked only once read: a
// flipped byte in any of them is still a checksum mismatch naming the section, never an open store.
class PagedFileSectionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::vector<SceneObject> objects = testing::MakeObjects(300, 3);
    StoreOptions opts;
    opts.backend = Backend::kPagedFile;
    auto w = StoreWriter::Create(path_, opts);
    ASSERT_TRUE(w.ok()) << w.status().ToString();
    testing::BuiltStore built;
    ASSERT_TRUE(testing::BuildTestStore(objects, opts.codec, opts.params, &(*w)->pages(), &built).ok());
    for (const SceneObject& o : objects)
      ASSERT_TRUE((*w)->AppendObject(o.id, built.object_leaf[o.id], o.name).ok());
    ASSERT_TRUE((*w)->Commit(built.tree, "").ok());
    std::ifstream in(path_, std::ios::binary);
    file_.assign(std::istreambuf_iterator<char>(in), {});
    ASSERT_GT(file_.size(), 4096u);
  }
  uint64_t U64(size_t at) const {
    uint64_t v;
    std::memcpy(&v, file_.data() + at, 8);
    return v;
  }
  void PutU64(std::vector<uint8_t>* f, size_t at, uint64_t v) { std::memcpy(f->data() + at, &v, 8); }
  // Section i's offset and size, from the header's table (at byte 80, 24 bytes an entry).
  uint64_t SectionOffset(int i) const { return U64(80 + 24 * i); }
  uint64_t SectionBytes(int i) const { return U64(80 + 24 * i + 8); }
  Status OpenWith(const std::vector<uint8_t>& f) {
    {
      std::ofstream out(path_, std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(f.data()), static_cast<std::streamsize>(f.size()));
    }
    return StoreReader::Open(path_).status();
  }

  testing::TempDir dir_;
  std::string path_ = dir_.file("sections.mkt");
  std::vector<uint8_t> file_;
};

TEST_F(PagedFileSectionTest, AFlippedByteInAnySectionIsAChecksumMismatch) {
  const char* const names[] = {"nodes",   "split nodes", "leaves",      "leaf id digests", "record directory",
                               "sources", "stats JSON",  "leaf filter", "codec dictionary"};
  ASSERT_TRUE(OpenWith(file_).ok());
  for (int i = 0; i < 9; ++i) {
    SCOPED_TRACE(names[i]);
    if (SectionBytes(i) == 0) continue;  // the statistics and the dictionary, here (dictionary_test.cc)
    std::vector<uint8_t> f = file_;
    f[SectionOffset(i) + SectionBytes(i) / 2] ^= 0x40;
    const Status st = OpenWith(f);
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
    EXPECT_NE(st.message().find(path_ + ": " + names[i] + " section checksum mismatch"), std::string::npos)
        << st.message();
  }
}

TEST_F(PagedFileSectionTest, ASplitNodeLabelOutOfRangeIsRefusedBehindValidChecksums) {
  // Split node 0's label (byte 13 of its 16) set to 7, the section's and the header's checksums redone.
  const uint64_t mem_page = 12288;
  ASSERT_GT(SectionBytes(1), 0u);
  std::vector<uint8_t> f = file_;
  f[SectionOffset(1) + 13] = 7;
  PutU64(&f, 80 + 24 * 1 + 16,
         Checksum(std::span<const uint8_t>(f.data() + SectionOffset(1), SectionBytes(1))));
  PutU64(&f, 296, 0);
  PutU64(&f, 296, Checksum(std::span<const uint8_t>(f.data(), mem_page)));
  const Status st = OpenWith(f);
  EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
  EXPECT_NE(st.message().find(path_ + ": split node label out of range"), std::string::npos) << st.message();
}

}  // namespace
}  // namespace mktree
