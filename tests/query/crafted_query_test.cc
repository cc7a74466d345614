// The public API on crafted stores (tests/storage/crafted_store.h): a tampered store gives a Corruption
// naming the file (at Database::Open or at the query that reads the bad leaf), never a hang, a duplicated
// or missing id. Crafted* suites run under a short timeout.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <string>

#include "mktree/database.h"
#include "storage/crafted_store.h"

namespace mktree {
namespace {

using testing::StoreImage;

Box3d Everything(const StoreImage& img) {
  const Box3f& r = img.contents.tree.nodes[0].box;
  Box3d b;
  for (int i = 0; i < 3; ++i) {
    b.min[i] = r.min[i] - 1.0;
    b.max[i] = r.max[i] + 1.0;
  }
  return b;
}

class CraftedQueryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto img = testing::MakeTestImage(300, 11);
    ASSERT_TRUE(img.ok()) << img.status().ToString();
    image_ = std::move(img).value();
    path_ = dir_.file("crafted.mkt");
  }
  Result<std::unique_ptr<Database>> WriteAndOpen() {
    MKTREE_RETURN_IF_ERROR(testing::WriteStoreImage(image_, path_, Backend::kPagedFile));
    return Database::Open(path_);
  }
  void ExpectCorruptionNamingTheFile(const Status& st) {
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
    EXPECT_NE(st.message().find(path_), std::string::npos) << st.message();
  }

  testing::TempDir dir_;
  StoreImage image_;
  std::string path_;
};

TEST_F(CraftedQueryTest, TheUntouchedStoreAnswersEveryObjectOnce) {
  auto db = WriteAndOpen();
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  std::vector<ObjectId> hits;
  ASSERT_TRUE((*db)->QueryBox(Everything(image_), QueryMode::kAabb, &hits, nullptr).ok());
  ASSERT_EQ(hits.size(), 300u);
  for (ObjectId i = 0; i < 300; ++i) EXPECT_EQ(hits[i], i);
}

// Routing these would loop forever (a SplitTree cycle) or queue nodes without end (a child cycle).
TEST_F(CraftedQueryTest, CyclesAreRefusedAtOpen) {
  testing::FlattenBoxes(&image_);
  const StoreImage flat = image_;
  image_.tree().nodes[testing::NodeWithTwoLeaves(image_.tree())].child[1] = 0;
  ExpectCorruptionNamingTheFile(WriteAndOpen().status());
  image_ = flat;
  const uint32_t s = image_.tree().nodes[0].split_root;
  image_.tree().split_nodes[s].child[0] = s;
  ExpectCorruptionNamingTheFile(WriteAndOpen().status());
}

TEST_F(CraftedQueryTest, LeafReferencedTwiceIsRefusedNotAnsweredTwice) {
  testing::FlattenBoxes(&image_);
  const TreeNode& n = image_.tree().nodes[testing::NodeWithTwoLeaves(image_.tree())];
  image_.tree().nodes[n.child[1]].leaf = image_.tree().nodes[n.child[0]].leaf;
  ExpectCorruptionNamingTheFile(WriteAndOpen().status());
}

TEST_F(CraftedQueryTest, TamperedPagesAreCorruptionAtTheQueryNotAnAnswer) {
  const uint32_t l = testing::LeafWithObjects(image_.tree(), 3);
  std::vector<uint8_t>& page = image_.pages[image_.tree().leaves[l].first_page];
  const std::vector<size_t> at = testing::EntryOffsets(page);
  storage_internal::Put<uint32_t>(page.data() + at[1], storage_internal::Get<uint32_t>(page.data() + at[0]));
  testing::ResealPage(&page);
  auto db = WriteAndOpen();
  ASSERT_TRUE(db.ok()) << db.status().ToString();  // the page is only read by a query
  std::vector<ObjectId> hits;
  ExpectCorruptionNamingTheFile((*db)->QueryBox(Everything(image_), QueryMode::kAabb, &hits, nullptr));
  ExpectCorruptionNamingTheFile((*db)->QueryBox(Everything(image_), QueryMode::kExact, &hits, nullptr));

}

}  // namespace
}  // namespace mktree
