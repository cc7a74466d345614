// Crafted stores (tests/store_format/crafted_store.h): a tree, object table or leaf page changed behind valid
// checksums must be refused with a Corruption error naming the file, at open or at the read of the bad
// leaf; never a hang, a crash, unbounded memory or a duplicated or missing id. Both backends.
// These suites run under a short ctest timeout (tests/CMakeLists.txt): a hang fails them.
#include "store_format/crafted_store.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <random>

#include "engine/store_format/leaf_source.h"
#include "storage/page_cache.h"

namespace mktree {
namespace {

using testing::StoreImage;

class CraftedStoreTest : public ::testing::TestWithParam<Backend> {
 protected:
  void SetUp() override {
    auto img = testing::MakeTestImage(300, 7);
    ASSERT_TRUE(img.ok()) << img.status().ToString();
    image_ = std::move(img).value();
    path_ = dir_.file("crafted.mkt");
  }

  // Writes the image and opens it; then reads every leaf. Returns the first error.
  Status WriteOpenAndReadAll() {
    MKTREE_RETURN_IF_ERROR(testing::WriteStoreImage(image_, path_, GetParam()));
    auto r = StoreReader::Open(path_);
    if (!r.ok()) return r.status();
    PageCache cache(&(*r)->pages(), 4);
    const LeafSource leaves(**r, cache, true);
    PinnedLeaf pinned;
    for (uint32_t l = 0; l < (*r)->tree().leaves.size(); ++l)
      MKTREE_RETURN_IF_ERROR(leaves.Read(l, nullptr, &pinned));
    // And every object's record (its leaf among them).
    for (ObjectId id = 0; id < (*r)->object_count(); ++id)
      MKTREE_RETURN_IF_ERROR((*r)->ObjectLeaf(id, &cache, true, nullptr).status());
    return Status::Ok();
  }
  // Expects a Corruption naming the file and saying `why`.
  void ExpectRefused(const std::string& why) {
    Status st = WriteOpenAndReadAll();
    EXPECT_EQ(st.code(), Status::Code::kCorruption) << st.ToString();
    EXPECT_NE(st.message().find(path_), std::string::npos) << st.message();
    EXPECT_NE(st.message().find(why), std::string::npos) << st.message();
  }
  MKTree& tree() { return image_.tree(); }
  // Rewrites the record pages for the first `n` of the image's 300 objects (MakeObjects(300, 7)).
  void SetRecordsOf(uint32_t n) {
    std::vector<SceneObject> objects = testing::MakeObjects(300, 7);
    objects.resize(n);
    ASSERT_TRUE(testing::SetObjectRecords(&image_, objects).ok());
  }
  // Rewrites the payload of `leaf`'s single page through `edit` (given the page and its entry offsets),
  // then reseals it.
  void EditLeafPage(uint32_t leaf,
                    const std::function<void(std::vector<uint8_t>&, const std::vector<size_t>&)>& edit) {
    std::vector<uint8_t>& page = image_.pages[tree().leaves[leaf].first_page];
    edit(page, testing::EntryOffsets(page));
    testing::ResealPage(&page);
  }
  static uint32_t IdAt(const std::vector<uint8_t>& page, size_t off) {
    return storage_internal::Get<uint32_t>(page.data() + off);
  }
  static void SetIdAt(std::vector<uint8_t>& page, size_t off, uint32_t id) {
    storage_internal::Put<uint32_t>(page.data() + off, id);
  }

  testing::TempDir dir_;
  StoreImage image_;
  std::string path_;
};

TEST_P(CraftedStoreTest, TheUntouchedImageAndItsFlattenedBoxesAreAccepted) {
  EXPECT_TRUE(WriteOpenAndReadAll().ok());
  testing::FlattenBoxes(&image_);
  Status st = WriteOpenAndReadAll();
  EXPECT_TRUE(st.ok()) << st.ToString();
}

TEST_P(CraftedStoreTest, ChildCycleIsRefused) {
  testing::FlattenBoxes(&image_);
  const uint32_t p = testing::NodeWithTwoLeaves(tree());
  tree().nodes[p].child[1] = 0;  // back to the root: routing would loop, its stack growing without end
  ExpectRefused("reached twice (a cycle or a shared child)");
}

TEST_P(CraftedStoreTest, SelfCycleIsRefused) {
  testing::FlattenBoxes(&image_);
  const uint32_t p = testing::NodeWithTwoLeaves(tree());
  tree().nodes[p].child[0] = p;
  ExpectRefused("node " + std::to_string(p) + ": reached twice");
}

TEST_P(CraftedStoreTest, SharedChildIsRefused) {
  testing::FlattenBoxes(&image_);
  tree().nodes[0].child[1] = tree().nodes[0].child[0];  // the left subtree answered twice
  ExpectRefused("reached twice (a cycle or a shared child)");
}

TEST_P(CraftedStoreTest, OrphanNodeIsRefused) {
  TreeNode extra = tree().nodes[tree().leaves[0].node];
  tree().nodes.push_back(extra);
  ExpectRefused("node " + std::to_string(tree().nodes.size() - 1) + ": not reachable from the root");
}

TEST_P(CraftedStoreTest, NodesOutOfPreorderAreRefused) {
  testing::FlattenBoxes(&image_);
  std::swap(tree().nodes[0].child[0], tree().nodes[0].child[1]);  // a tree, but not in depth-first order
  ExpectRefused("not reached in depth-first order");
}

TEST_P(CraftedStoreTest, LeafReferencedTwiceIsRefused) {
  testing::FlattenBoxes(&image_);
  const uint32_t p = testing::NodeWithTwoLeaves(tree());
  const TreeNode& n = tree().nodes[p];
  const uint32_t first = tree().nodes[n.child[0]].leaf;
  tree().nodes[n.child[1]].leaf = first;  // leaf `first` answered twice, the next one never
  ExpectRefused("leaf " + std::to_string(first) + " referenced twice");
}

TEST_P(CraftedStoreTest, LeafNeverReferencedIsRefused) {
  LeafInfo extra = tree().leaves.back();
  tree().leaves.push_back(extra);
  ExpectRefused("leaf " + std::to_string(tree().leaves.size() - 1) + ": not referenced by any node");
}

TEST_P(CraftedStoreTest, LeafBackReferenceMustMatch) {
  const uint32_t p = testing::NodeWithTwoLeaves(tree());
  tree().leaves[tree().nodes[tree().nodes[p].child[0]].leaf].node = p;
  ExpectRefused("refers to node " + std::to_string(p));
}

TEST_P(CraftedStoreTest, DepthsMustCountFromTheRoot) {
  tree().nodes[1].depth = 7;
  ExpectRefused("node 1: depth 7 where 1 was expected");
}

TEST_P(CraftedStoreTest, LeafDigestsMustBeOnePerLeaf) {
  image_.objects().leaf_digest.push_back(0);
  ExpectRefused(std::to_string(tree().leaves.size() + 1) + " leaf id digests for " +
                std::to_string(tree().leaves.size()) + " leaves");
}

TEST_P(CraftedStoreTest, LeafDigestsNotAddingUpToEveryObjectAreRefused) {
  image_.objects().leaf_digest[3] += 1;
  ExpectRefused("the leaves' id digests do not add up to the store's 300 objects");
}

TEST_P(CraftedStoreTest, LeafCountsNotAddingUpToEveryObjectAreRefused) {
  // One object dropped from the store's count: the leaves account for one more.
  image_.contents.objects.count = 299;
  SetRecordsOf(299);
  ExpectRefused("the leaves hold 300 objects but the store has 299");
}

TEST_P(CraftedStoreTest, DigestsSwappedBetweenLeavesAreRefusedAtTheirLeafRead) {
  // The sum still agrees, so open accepts it; each leaf's entries then disagree with its digest.
  std::swap(image_.objects().leaf_digest[0], image_.objects().leaf_digest[1]);
  ExpectRefused("page " + std::to_string(tree().leaves[0].first_page) +
                " (leaf 0): its objects are not the ones the object table puts in it");
}

TEST_P(CraftedStoreTest, RecordNamingNoLeafIsRefusedAtItsRead) {
  image_.object_leaf[5] = static_cast<uint32_t>(tree().leaves.size());
  SetRecordsOf(300);
  ExpectRefused("object 5: in leaf " + std::to_string(tree().leaves.size()) + " of " +
                std::to_string(tree().leaves.size()));
}

TEST_P(CraftedStoreTest, SplitTreeCycleIsRefused) {
  for (TreeNode& n : tree().nodes)
    if (!n.is_leaf() && n.split_root != kNoIndex) {
      tree().split_nodes[n.split_root].child[1] = n.split_root;  // PointSides would loop forever
      break;
    }
  ExpectRefused("reached twice (a cycle or a shared split node)");
}

TEST_P(CraftedStoreTest, SharedSplitNodeIsRefused) {
  std::vector<uint32_t> roots;
  for (const TreeNode& n : tree().nodes)
    if (!n.is_leaf() && n.split_root != kNoIndex) roots.push_back(n.split_root);
  ASSERT_GE(roots.size(), 2u);
  tree().split_nodes[roots[1]].child[0] = tree().split_nodes[roots[0]].child[0];
  ExpectRefused("reached twice (a cycle or a shared split node)");
}

TEST_P(CraftedStoreTest, SplitNodeLeftOverIsRefused) {
  tree().split_nodes.push_back(SplitNode{});
  ExpectRefused("not in any node's SplitTree");
}

TEST_P(CraftedStoreTest, DeepSplitTreeChainIsRefused) {
  // A 10,000-deep SplitTree under the root: each inner node's upper child is a cell, its lower the next.
  std::vector<SplitNode>& s = tree().split_nodes;
  const uint32_t old_root = tree().nodes[0].split_root;
  const uint32_t first = static_cast<uint32_t>(s.size());
  for (uint32_t i = 0; i < 10000; ++i) {
    SplitNode inner;
    inner.axis = 0;
    inner.cut = static_cast<float>(-1.0 * i);
    inner.child[0] = i + 1 < 10000 ? first + 2 * (i + 1) : old_root;
    inner.child[1] = first + 2 * i + 1;
    SplitNode cell;
    cell.label = CellLabel::kBoth;
    s.push_back(inner);
    s.push_back(cell);
  }
  tree().nodes[0].split_root = first;
  ExpectRefused("SplitTree deeper than 64 levels");
}

TEST_P(CraftedStoreTest, DeepNodeChainIsRefused) {
  // A chain of 10,000 internal nodes, each with one leaf child, over 10,001 leaves of one object and one
  // 512-byte page each: everything else about it is consistent.
  const uint32_t chain = 10000;
  std::mt19937 g(3);
  std::vector<SceneObject> objects(chain + 1);
  for (uint32_t i = 0; i <= chain; ++i) {
    objects[i].id = i;
    objects[i].mesh = testing::RandomMesh(g, 20, 5);  // ~350 bytes, incompressible: one per page
  }
  BuildParams params;
  params.block_size = 512;
  params.blocks_per_page = 1;
  auto img = testing::MakeTestImage(objects, params);
  ASSERT_TRUE(img.ok()) << img.status().ToString();
  image_ = std::move(img).value();
  MKTree& t = tree();
  ASSERT_EQ(t.leaves.size(), chain + 1);
  t.nodes.clear();
  t.split_nodes.clear();
  for (uint32_t i = 0; i < chain; ++i) {
    TreeNode inner;
    inner.axis = 0;
    inner.depth = static_cast<uint8_t>(std::min<uint32_t>(i, 255));  // saturating, as the builder does
    inner.child[0] = 2 * i + 1;
    inner.child[1] = 2 * i + 2;
    TreeNode leaf;
    leaf.depth = static_cast<uint8_t>(std::min<uint32_t>(i + 1, 255));
    leaf.leaf = i;
    t.leaves[i].node = 2 * i + 1;
    t.nodes.push_back(inner);
    t.nodes.push_back(leaf);
  }
  TreeNode last;
  last.depth = 255;
  last.leaf = chain;
  t.leaves[chain].node = 2 * chain;
  t.nodes.push_back(last);
  testing::FlattenBoxes(&image_);
  ExpectRefused("tree deeper than 256 levels");
}

TEST_P(CraftedStoreTest, ChildBoxOutsideItsParentIsRefused) {
  const uint32_t p = testing::NodeWithTwoLeaves(tree());
  const uint32_t c = tree().nodes[p].child[0];
  tree().nodes[c].box.max[2] = tree().nodes[p].box.max[2] + 1;
  tree().leaves[tree().nodes[c].leaf].box = tree().nodes[c].box;
  ExpectRefused("node " + std::to_string(p) + ": a child's box is not within the node's box");
}

TEST_P(CraftedStoreTest, LeafBoxDifferentFromItsNodesIsRefused) {
  tree().leaves[3].box.min[0] -= 1;
  ExpectRefused("leaf 3: box differs from its node's");
}

TEST_P(CraftedStoreTest, OverlapPlanesInconsistentWithTheChildrenAreRefused) {
  tree().nodes[0].a -= 1;  // a query left of the true plane would skip the right child
  ExpectRefused("node 0: overlap planes a, b disagree");
}

TEST_P(CraftedStoreTest, NanBoxIsRefused) {
  tree().nodes[0].box.min[1] = std::nanf("");
  ExpectRefused("box is not a number");
}

TEST_P(CraftedStoreTest, LeafPagesOutOfOrderOrOverlappingAreRefused) {
  tree().leaves[4].first_page = tree().leaves[3].first_page;
  ExpectRefused("leaf 4: pages overlap the previous leaf's");
}

TEST_P(CraftedStoreTest, LeafPageCountMustMatchItsPayload) {
  const uint32_t l = testing::LeafWithObjects(tree(), 2);
  tree().leaves[l].page_count = 2;
  ExpectRefused("leaf " + std::to_string(l) + ": 2 pages for");
}

// The leaf record's payload size, resealed within the same page count, must be the page's (hostile
// campaign: crafted-013 and crafted-051 answered from such stores).
TEST_P(CraftedStoreTest, LeafPayloadSizeMustMatchItsPage) {
  const uint32_t l = testing::LeafWithObjects(tree(), 2);
  tree().leaves[l].payload_bytes += 8;
  ExpectRefused("holds a payload of " + std::to_string(tree().leaves[l].payload_bytes - 8) +
                " bytes but the tree says");
}

TEST_P(CraftedStoreTest, LeafFilterOfTheWrongSizeIsRefused) {
  tree().leaf_filter.assign(12, 0);
  ExpectRefused("leaf filter holds 12 bytes");
}

TEST_P(CraftedStoreTest, PageDuplicatingAnIdIsRefusedAtItsRead) {
  const uint32_t l = testing::LeafWithObjects(tree(), 3);
  uint32_t dup = 0;
  EditLeafPage(l, [&](std::vector<uint8_t>& page, const std::vector<size_t>& at) {
    dup = IdAt(page, at[0]);
    SetIdAt(page, at[1], dup);  // the second object answered as the first, the second lost
  });
  ExpectRefused("object " + std::to_string(dup) + " appears twice");
}

TEST_P(CraftedStoreTest, PageCarryingAnotherLeafsObjectIsRefusedAtItsRead) {
  const uint32_t l = testing::LeafWithObjects(tree(), 2);
  uint32_t other = 0;
  while (image_.object_leaf[other] == l) ++other;
  EditLeafPage(
      l, [&](std::vector<uint8_t>& page, const std::vector<size_t>& at) { SetIdAt(page, at[1], other); });
  ExpectRefused("(leaf " + std::to_string(l) + "): its objects are not the ones the object table puts in it");
}

TEST_P(CraftedStoreTest, PageWithAnIdOutOfRangeIsRefusedAtItsRead) {
  const uint32_t l = testing::LeafWithObjects(tree(), 2);
  EditLeafPage(
      l, [&](std::vector<uint8_t>& page, const std::vector<size_t>& at) { SetIdAt(page, at[0], 1u << 30); });
  ExpectRefused("object 1073741824 out of range");
}

TEST_P(CraftedStoreTest, PageWithAnEntryOutsideTheLeafBoxIsRefusedAtItsRead) {
  const uint32_t l = testing::LeafWithObjects(tree(), 2);
  EditLeafPage(l, [&](std::vector<uint8_t>& page, const std::vector<size_t>& at) {
    storage_internal::Put<float>(page.data() + at[0] + 4 + 12, 1e30f);  // max x
  });
  ExpectRefused("lies outside the leaf's box");
}

TEST_P(CraftedStoreTest, PageHoldingFewerEntriesThanItsLeafIsRefusedAtItsRead) {
  // The last entry dropped from the page, its leaf header and the tree's payload size rewritten to match:
  // the page is well formed, and only the tree's count says an object is missing.
  const uint32_t l = testing::LeafWithObjects(tree(), 2);
  EditLeafPage(l, [&](std::vector<uint8_t>& page, const std::vector<size_t>& at) {
    uint8_t* payload = page.data() + kPageHeaderBytes;
    const uint32_t count = storage_internal::Get<uint32_t>(payload);
    const uint64_t cut = at.back() - kPageHeaderBytes;
    std::fill(page.begin() + static_cast<std::ptrdiff_t>(at.back()), page.end(), 0);
    storage_internal::Put<uint32_t>(payload, count - 1);
    storage_internal::Put<uint64_t>(payload + 8, cut);
    storage_internal::Put<uint32_t>(page.data() + 20, static_cast<uint32_t>(cut));  // page payload bytes
    tree().leaves[l].payload_bytes = cut;
  });
  ExpectRefused("holds " + std::to_string(tree().leaves[l].object_count - 1) + " objects but the tree says");
}

INSTANTIATE_TEST_SUITE_P(Backends, CraftedStoreTest, ::testing::Values(Backend::kPagedFile, Backend::kHdf5),
                         [](const ::testing::TestParamInfo<Backend>& p) {
                           return std::string(BackendName(p.param));
                         });

// The validator on its own, on trees built in RAM.
TEST(CraftedStructureTest, EmptyTreeMustHoldNothing) {
  MKTree t;
  ObjectTable objects;
  EXPECT_TRUE(ValidateStructure(t, objects, 0, "s").ok());
  objects.count = 1;
  EXPECT_EQ(ValidateStructure(t, objects, 0, "s").code(), Status::Code::kCorruption);
  objects.count = 0;
  objects.leaf_digest.push_back(0);
  EXPECT_EQ(ValidateStructure(t, objects, 0, "s").code(), Status::Code::kCorruption);
}

// Every key the builder writes passes, overlap counts included; Commit refuses what Open would.
TEST(CraftedStatsTest, TheBuildersStatisticsPassAndCommitRefusesOthers) {
  auto img = testing::MakeTestImage(300, 7);
  ASSERT_TRUE(img.ok());
  const MKTree& t = img->tree();
  const std::vector<uint32_t> overlap(t.nodes.size(), 2);
  const std::string stats = ComputeTreeStats(t, 300, overlap).ToJson();
  ASSERT_NE(stats.find("mean_overlap_objects"), std::string::npos);
  EXPECT_TRUE(ValidateStatsJson(stats).ok()) << ValidateStatsJson(stats).ToString();
  EXPECT_TRUE(ValidateStatsJson(img->contents.stats_json).ok());

  testing::TempDir dir;
  const std::string path = dir.file("bad_stats.mkt");
  const std::vector<SceneObject> objects = testing::MakeObjects(40, 2);
  auto w = StoreWriter::Create(path, StoreOptions{});
  ASSERT_TRUE(w.ok());
  testing::BuiltStore built;
  ASSERT_TRUE(testing::BuildTestStore(objects, {}, {}, &(*w)->pages(), &built).ok());
  for (const auto& o : objects) ASSERT_TRUE((*w)->AppendObject(o.id, built.object_leaf[o.id], o.name).ok());
  Status st = (*w)->Commit(built.tree, "{\"objects\": 40, \"note\": \"hi\"}");
  EXPECT_EQ(st.code(), Status::Code::kInvalidArgument) << st.ToString();
  EXPECT_NE(st.message().find("build statistics"), std::string::npos) << st.message();
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace mktree
