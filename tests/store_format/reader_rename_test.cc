// A reader opening a paged-file store while a rebuild renames another store onto its path reads one store
// only: the pages it maps or reads with O_DIRECT are those of the file whose tree it loaded. It used to map
// (and reopen for O_DIRECT) the path, so a rename in between mixed the new store's pages with the old
// store's tree: checksums and leaf numbers agree, and answers were silently wrong.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <thread>

#include "engine/store_format/store_file.h"
#include "store_format/store_test_util.h"

namespace mktree {
namespace {

using testing::BuiltStore;
using testing::TempDir;

// Two stores of the same structure (raw geometry: entry sizes depend on the counts alone) whose pages
// differ: the second scene is the first moved by half a metre.
Status WriteStore(const std::string& path, double shift, BuiltStore* built) {
  std::vector<SceneObject> objects = testing::MakeObjects(300, 21);
  for (SceneObject& o : objects)
    for (double& v : o.mesh.vertices) v += shift;
  StoreOptions opts;
  opts.backend = Backend::kPagedFile;
  opts.codec.codec = Codec::kNone;
  auto w = StoreWriter::Create(path, opts);
  if (!w.ok()) return w.status();
  MKTREE_RETURN_IF_ERROR(testing::BuildTestStore(objects, opts.codec, opts.params, &(*w)->pages(), built));
  for (const SceneObject& o : objects)
    MKTREE_RETURN_IF_ERROR((*w)->AppendObject(o.id, built->object_leaf[o.id], o.name));
  return (*w)->Commit(built->tree, "");
}

TEST(ReaderRenameTest, AReaderReadsOnlyTheStoreWhoseTreeItLoaded) {
  TempDir dir;
  const std::string a = dir.file("a.mkt"), b = dir.file("b.mkt"), path = dir.file("s.mkt");
  BuiltStore built_a, built_b;
  ASSERT_TRUE(WriteStore(a, 0, &built_a).ok());
  ASSERT_TRUE(WriteStore(b, 0.5, &built_b).ok());
  std::vector<std::vector<uint8_t>> pages[2];
  for (int s = 0; s < 2; ++s) {
    auto r = StoreReader::Open(s == 0 ? a : b);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    for (uint64_t p = 0; p < (*r)->pages().page_count(); ++p) {
      pages[s].emplace_back((*r)->pages().page_bytes());
      ASSERT_TRUE((*r)->pages().ReadPage(p, pages[s].back().data()).ok());
    }
  }
  ASSERT_EQ(pages[0].size(), pages[1].size());
  ASSERT_NE(pages[0], pages[1]);

  // A rebuild, as fast as it can: a or b renamed onto the path, in turn (the path always holds one).
  ASSERT_EQ(::link(a.c_str(), path.c_str()), 0);
  std::atomic<bool> stop{false};
  std::thread renamer([&] {
    const std::string tmp = dir.file("n.mkt");
    for (int i = 0; !stop; ++i) {
      ::unlink(tmp.c_str());
      if (::link(i % 2 ? b.c_str() : a.c_str(), tmp.c_str()) == 0) ::rename(tmp.c_str(), path.c_str());
    }
  });
  int opened = 0, mixed = 0;
  for (int i = 0; opened < 300; ++i) {
    ReadOptions ro;
    ro.direct_io = i % 2 == 1;
    auto r = StoreReader::Open(path, ro);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ++opened;
    const int s = SameTree((*r)->tree(), built_a.tree) ? 0 : 1;
    std::vector<uint8_t> buf((*r)->pages().page_bytes());
    for (uint64_t p = 0; p < (*r)->pages().page_count(); ++p) {
      ASSERT_TRUE((*r)->pages().ReadPage(p, buf.data()).ok());
      const uint8_t* mapped = (*r)->pages().MappedPage(p);
      if (buf != pages[s][p] ||
          (mapped != nullptr && std::memcmp(mapped, pages[s][p].data(), buf.size()) != 0)) {
        ++mixed;
        break;
      }
    }
  }
  stop = true;
  renamer.join();
  EXPECT_EQ(mixed, 0) << "of " << opened << " readers";
}

}  // namespace
}  // namespace mktree
