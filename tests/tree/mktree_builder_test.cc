#include "engine/tree/mktree_builder.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <unordered_map>

#include "tree/tree_test_util.h"

namespace mktree {
namespace {

using testing::CheckTree;
using testing::kAllPolicies;
using testing::MakeScene;
using testing::SceneKind;
using testing::WithPolicy;

BuildObject Rec(ObjectId id, Box3f box, uint32_t bytes = 1000) {
  BuildObject r;
  r.id = id;
  r.box = box;
  r.encoded_bytes = bytes;
  return r;
}

Box3f B(float x0, float y0, float z0, float x1, float y1, float z1) {
  Box3f b;
  b.min = {x0, y0, z0};
  b.max = {x1, y1, z1};
  return b;
}

TEST(BuildMKTree, EmptyInputGivesEmptyTree) {
  auto r = BuildMKTree({}, BuildParams());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->tree.empty());
  EXPECT_TRUE(r->tree.leaves.empty());
  EXPECT_TRUE(r->leaf_objects.empty());
  ASSERT_EQ(r->leaf_offsets.size(), 1u);
  EXPECT_EQ(r->stats.height, 0u);
  std::vector<uint32_t> leaves;
  r->tree.RoutePoint(Vec3d{0, 0, 0}, &leaves, nullptr);
  Box3d q;
  q.min = {-1, -1, -1};
  q.max = {1, 1, 1};
  r->tree.RouteBox(q, &leaves, nullptr);
  EXPECT_TRUE(leaves.empty());
}

TEST(BuildMKTree, SingleObjectIsOneLeaf) {
  std::vector<BuildObject> recs{Rec(7, B(0, 0, 0, 1, 1, 1))};
  auto r = BuildMKTree(recs, BuildParams());
  ASSERT_TRUE(r.ok());
  ASSERT_EQ(r->tree.nodes.size(), 1u);
  ASSERT_EQ(r->tree.leaves.size(), 1u);
  EXPECT_EQ(r->leaf_objects, std::vector<ObjectId>{7});
  EXPECT_EQ(r->tree.leaves[0].payload_bytes, LeafPayloadBytes(1000));
  EXPECT_EQ(r->stats.height, 1u);
  CheckTree(recs, *r, BuildParams());
}

TEST(BuildMKTree, RejectsBadInputNamingTheObject) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  struct Case {
    std::vector<BuildObject> recs;
    std::string needle;
  } cases[] = {
      {{Rec(0, B(0, 0, 0, 1, 1, 1)), Rec(41, B(0, nan, 0, 1, 1, 1))}, "object 41"},
      {{Rec(0, B(0, 0, 0, 1, 1, 1)), Rec(42, B(0, 0, 0, inf, 1, 1))}, "object 42"},
      {{Rec(0, B(0, 0, 0, 1, 1, 1)), Rec(43, B(0, 0, 2, 1, 1, 1))}, "object 43"},
      {{Rec(5, B(0, 0, 0, 1, 1, 1)), Rec(5, B(0, 0, 0, 1, 1, 1))}, "object 5"},
      {{Rec(4000000000u, B(0, 0, 0, 1, 1, 1)), Rec(4000000000u, B(0, 0, 0, 1, 1, 1))}, "object 4000000000"},
  };
  for (const Case& c : cases) {
    auto r = BuildMKTree(c.recs, BuildParams());
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument);
    EXPECT_NE(r.status().message().find(c.needle), std::string::npos) << r.status().message();
  }
}

// Large enough for the checks to run on two halves: the error still names the first bad object in input
// order, wherever the halves split.
TEST(BuildMKTree, RejectsTheFirstBadObjectOfALargeInput) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const uint32_t n = 200000;
  std::vector<BuildObject> good;
  for (uint32_t i = 0; i < n; ++i)
    good.push_back(Rec(i, B(i % 97, i % 89, i % 83, i % 97 + 1, i % 89 + 1, i % 83 + 1)));
  BuildTuning two;
  two.threads = 2;
  const float inf = std::numeric_limits<float>::infinity();
  struct Case {
    std::vector<std::pair<uint32_t, Box3f>> bad;  // (position, bad box)
    uint32_t first;
  } cases[] = {
      {{{150000, B(0, 0, nan, 1, 1, 1)}}, 150000},                               // second half only
      {{{170000, B(0, 2, 0, 1, 1, 1)}, {30000, B(0, 0, 0, inf, 1, 1)}}, 30000},  // both halves
      {{{99999, B(0, 0, 0, 1, 1, nan)}, {100000, B(0, 0, 3, 1, 1, 1)}}, 99999},  // either side of the middle
  };
  for (const Case& c : cases) {
    std::vector<BuildObject> recs = good;
    for (const auto& [at, box] : c.bad) recs[at].box = box;
    auto r = BuildMKTree(recs, BuildParams(), two);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.status().message().find("object " + std::to_string(c.first) + ":"), std::string::npos)
        << r.status().message();
  }
  std::vector<BuildObject> dup = good;
  dup[180000].id = 20000;  // the duplicate is found at the later of the two
  auto r = BuildMKTree(dup, BuildParams(), two);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("object 20000: duplicate"), std::string::npos) << r.status().message();
  // Two duplicated ids: the one named is the one whose second use comes first in input order (position
  // 6000), not the first met in the builder's own (spatial) order of the objects, where it is id 10.
  dup = good;
  dup[150000].id = 10;
  dup[6000].id = 5999;
  r = BuildMKTree(dup, BuildParams(), two);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("object 5999: duplicate"), std::string::npos) << r.status().message();
}

TEST(BuildMKTree, RejectsBadParams) {
  std::vector<BuildObject> recs{Rec(0, B(0, 0, 0, 1, 1, 1))};
  for (double bad_r : {-0.1, 0.5, 0.7, std::nan("")}) {
    BuildParams p;
    p.balance_r = bad_r;
    auto r = BuildMKTree(recs, p);
    EXPECT_FALSE(r.ok()) << bad_r;
    EXPECT_EQ(r.status().code(), Status::Code::kInvalidArgument);
  }
  BuildParams tiny;
  tiny.block_size = 16;
  tiny.blocks_per_page = 3;  // 48 bytes = page header + leaf header: no room for anything
  EXPECT_FALSE(BuildMKTree(recs, tiny).ok());
  tiny.blocks_per_page = 0;
  EXPECT_FALSE(BuildMKTree(recs, tiny).ok());
}

// Structure, planes, groups and the SplitTree invariant on every kind of scene, both thread counts, every
// split policy (and the SOA without the fill-aware ranking).
TEST(BuildMKTree, StructureOnAllSceneKinds) {
  for (SceneKind kind :
       {SceneKind::kUniform, SceneKind::kClustered, SceneKind::kIdentical, SceneKind::kPlates,
        SceneKind::kHuge, SceneKind::kOversized, SceneKind::kShip, SceneKind::kGrid}) {
    for (size_t n : {2u, 9u, 100u, 3000u}) {
      for (int threads : {1, 2}) {
        for (int variant = 0; variant < 3; ++variant) {
          BuildTuning tune = WithPolicy(variant == 2 ? SplitPolicy::kSoa : kAllPolicies[variant]);
          tune.fill_aware = variant != 2;
          tune.threads = threads;
          SCOPED_TRACE(std::string(testing::Name(kind)) + " n=" + std::to_string(n) +
                       " threads=" + std::to_string(threads) + " policy=" + testing::Name(tune.split_policy) +
                       (tune.fill_aware ? "" : " plain"));
          auto recs = MakeScene(kind, n, 17 + n);
          BuildParams p;
          auto r = BuildMKTree(recs, p, tune);
          ASSERT_TRUE(r.ok()) << r.status().ToString();
          CheckTree(recs, *r, p);
        }
      }
    }
  }
}

TEST(BuildMKTree, StructureWithExtremeParams) {
  for (double ratio : {0.0, 0.49}) {
    for (uint32_t budget : {0u, 1u, 3u, 64u, 1000u}) {
      for (SceneKind kind : {SceneKind::kUniform, SceneKind::kShip, SceneKind::kGrid}) {
        for (SplitPolicy policy : kAllPolicies) {
          SCOPED_TRACE(std::string(testing::Name(kind)) + " r=" + std::to_string(ratio) +
                       " budget=" + std::to_string(budget) + " policy=" + testing::Name(policy));
          auto recs = MakeScene(kind, 2000, 5);
          BuildParams p;
          p.balance_r = ratio;
          p.split_tree_node_budget = budget;
          p.block_size = 1024;  // smaller pages: deeper trees
          auto r = BuildMKTree(recs, p, WithPolicy(policy));
          ASSERT_TRUE(r.ok()) << r.status().ToString();
          CheckTree(recs, *r, p);
        }
      }
    }
  }
}

TEST(BuildMKTree, OversizedObjectsGetTheirOwnMultiPageLeaf) {
  for (SplitPolicy policy : kAllPolicies) {
    SCOPED_TRACE(testing::Name(policy));
    BuildParams p;
    auto recs = MakeScene(SceneKind::kOversized, 500, 3, p.mem_page());
    auto r = BuildMKTree(recs, p, WithPolicy(policy));
    ASSERT_TRUE(r.ok());
    CheckTree(recs, *r, p);
    uint64_t multi = 0;
    for (const LeafInfo& lf : r->tree.leaves) {
      if (lf.page_count > 1) {
        ++multi;
        EXPECT_EQ(lf.object_count, 1u);
      }
    }
    EXPECT_GT(multi, 0u);
    EXPECT_EQ(multi, r->stats.multi_page_leaves);
  }
}

void ExpectSameTree(const BuildResult& r1, const BuildResult& r2) {
  EXPECT_EQ(r1.leaf_objects, r2.leaf_objects);
  EXPECT_EQ(r1.leaf_offsets, r2.leaf_offsets);
  ASSERT_EQ(r1.tree.nodes.size(), r2.tree.nodes.size());
  ASSERT_EQ(r1.tree.split_nodes.size(), r2.tree.split_nodes.size());
  ASSERT_EQ(r1.tree.leaves.size(), r2.tree.leaves.size());
  for (size_t i = 0; i < r1.tree.nodes.size(); ++i) {
    const TreeNode &x = r1.tree.nodes[i], &y = r2.tree.nodes[i];
    ASSERT_TRUE(x.box == y.box && x.a == y.a && x.b == y.b && x.child[0] == y.child[0] &&
                x.child[1] == y.child[1] && x.leaf == y.leaf && x.split_root == y.split_root &&
                x.axis == y.axis && x.depth == y.depth)
        << "node " << i;
  }
  for (size_t i = 0; i < r1.tree.split_nodes.size(); ++i) {
    const SplitNode &x = r1.tree.split_nodes[i], &y = r2.tree.split_nodes[i];
    ASSERT_TRUE(x.cut == y.cut && x.child[0] == y.child[0] && x.child[1] == y.child[1] && x.axis == y.axis &&
                x.label == y.label)
        << "split node " << i;
  }
  for (size_t i = 0; i < r1.tree.leaves.size(); ++i) {
    const LeafInfo &x = r1.tree.leaves[i], &y = r2.tree.leaves[i];
    ASSERT_TRUE(x.box == y.box && x.node == y.node && x.object_count == y.object_count &&
                x.payload_bytes == y.payload_bytes && x.first_page == y.first_page &&
                x.page_count == y.page_count)
        << "leaf " << i;
  }
  EXPECT_EQ(r1.stats.overlap_objects, r2.stats.overlap_objects);
}

// The multi-thread build (task queue, fragments stitched in DFS order, a root that shares its sweeps and
// partitions with a second thread) gives exactly the 1-thread tree: default task size, and tiny tasks
// (many fragments, 2-4 threads) on smaller pages. (LargeInputs... covers a root that does not share.)
TEST(BuildMKTree, SingleThreadAndTwoThreadsBuildTheSameTree) {
  for (SplitPolicy policy : kAllPolicies) {
    for (SceneKind kind : {SceneKind::kShip, SceneKind::kClustered, SceneKind::kOversized}) {
      for (uint32_t task : {0u, 64u}) {
        SCOPED_TRACE(std::string(testing::Name(policy)) + " " + testing::Name(kind) + " task " +
                     std::to_string(task));
        auto recs = MakeScene(kind, 20000, 11);
        BuildParams p;
        if (task > 0) p.block_size = 1024;
        BuildTuning one = WithPolicy(policy);
        one.threads = 1;
        auto r1 = BuildMKTree(recs, p, one);
        ASSERT_TRUE(r1.ok());
        for (int threads : {2, 3, 4}) {
          if (task == 0 && threads > 2) continue;
          SCOPED_TRACE("threads " + std::to_string(threads));
          BuildTuning many = one;
          many.threads = threads;
          many.parallel_task_objects = task;
          many.cooperative_root_objects = 1;
          auto r2 = BuildMKTree(recs, p, many);
          ASSERT_TRUE(r2.ok());
          ExpectSameTree(*r1, *r2);
          CheckTree(recs, *r2, p);
        }
      }
    }
  }
}

// From 65536 objects on, the records are laid out on two threads as well: still the 1-thread tree.
TEST(BuildMKTree, LargeInputsBuildTheSameTreeOnTwoThreads) {
  auto recs = MakeScene(SceneKind::kShip, 70000, 5);
  BuildTuning one;
  one.threads = 1;
  BuildTuning two;
  two.threads = 2;
  auto r1 = BuildMKTree(recs, BuildParams(), one);
  auto r2 = BuildMKTree(recs, BuildParams(), two);
  ASSERT_TRUE(r1.ok());
  ASSERT_TRUE(r2.ok());
  ExpectSameTree(*r1, *r2);
  CheckTree(recs, *r2, BuildParams());
}

// From 262144 objects on, the lists are mapped on their own and the builder gives back their pages over
// positions whose leaves are built (DoneRanges), while other nodes are still being split: the tree must
// not change, on one thread and on several whose small tasks report leaves out of order.
TEST(BuildMKTree, ListPagesGivenBackDuringTheBuildKeepTheTree) {
  auto recs = MakeScene(SceneKind::kShip, 300000, 9);
  BuildTuning one;
  one.threads = 1;
  auto r1 = BuildMKTree(recs, BuildParams(), one);
  ASSERT_TRUE(r1.ok());
  CheckTree(recs, *r1, BuildParams());
  for (uint32_t task : {0u, 5000u}) {
    SCOPED_TRACE("task " + std::to_string(task));
    BuildTuning two;
    two.threads = 2;
    two.parallel_task_objects = task;
    auto r2 = BuildMKTree(recs, BuildParams(), two);
    ASSERT_TRUE(r2.ok());
    ExpectSameTree(*r1, *r2);
  }
}

// The names in a directory (the spill files must be gone however the build ends).
std::vector<std::string> DirEntries(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    names.push_back(e.path().filename().string());
  return names;
}

// A fresh empty directory for one test's spill files.
std::filesystem::path FreshSpillDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("mktree_builder_test_" + name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

// Out-of-core top levels (BuildTuning::ram_node_objects): with tiny budgets nearly every node, leaves
// included, keeps its lists in the spill file and loads them a list at a time; the tree must be the one
// built in RAM, on one thread and on several (a cooperative root, tiny tasks), and the file must be gone.
TEST(BuildMKTree, OutOfCoreTopLevelsBuildTheSameTree) {
  const std::filesystem::path dir = FreshSpillDir("same");
  for (SplitPolicy policy : kAllPolicies) {
    for (SceneKind kind : {SceneKind::kShip, SceneKind::kClustered, SceneKind::kOversized}) {
      auto recs = MakeScene(kind, 6000, 13);
      BuildParams p;
      p.block_size = 2048;
      BuildTuning in_ram = WithPolicy(policy);
      in_ram.threads = 1;
      auto r1 = BuildMKTree(recs, p, in_ram);
      ASSERT_TRUE(r1.ok());
      for (uint32_t budget : {1u, 5u, 300u, 3000u}) {
        for (int threads : {1, 2}) {
          SCOPED_TRACE(std::string(testing::Name(policy)) + " " + testing::Name(kind) + " budget " +
                       std::to_string(budget) + " threads " + std::to_string(threads));
          BuildTuning spilled = in_ram;
          spilled.ram_node_objects = budget;
          spilled.spill_dir = dir.string();
          spilled.threads = threads;
          spilled.parallel_task_objects = threads > 1 ? 64 : 0;
          spilled.cooperative_root_objects = 1;
          auto r2 = BuildMKTree(recs, p, spilled);
          ASSERT_TRUE(r2.ok()) << r2.status().ToString();
          ExpectSameTree(*r1, *r2);
          EXPECT_TRUE(DirEntries(dir).empty());
        }
      }
    }
  }
  // Identical boxes at +0 and -0 (random_tunings found it): a leaf's box from its objects and the one
  // from the lists' ends differ in the sign of a zero, and a spilled leaf must take the one RAM takes.
  std::vector<BuildObject> zeros(3000);
  std::mt19937_64 rng(5);
  for (size_t i = 0; i < zeros.size(); ++i) {
    zeros[i].id = static_cast<ObjectId>(i);
    zeros[i].encoded_bytes = static_cast<uint32_t>(64 + rng() % 3000);
    for (int a = 0; a < 3; ++a) zeros[i].box.min[a] = zeros[i].box.max[a] = rng() % 2 ? 0.0f : -0.0f;
  }
  BuildTuning in_ram;
  in_ram.threads = 1;
  auto z1 = BuildMKTree(zeros, BuildParams(), in_ram);
  ASSERT_TRUE(z1.ok());
  for (uint32_t budget : {1u, 3u, 40u}) {
    BuildTuning spilled = in_ram;
    spilled.ram_node_objects = budget;
    spilled.spill_dir = dir.string();
    auto z2 = BuildMKTree(zeros, BuildParams(), spilled);
    ASSERT_TRUE(z2.ok());
    ExpectSameTree(*z1, *z2);
  }
  std::filesystem::remove_all(dir);
}

// Lists of 262144 objects and more are mapped: a spilled node's pages are given back (not zeroed) between
// its sweeps, next to ranges whose pages DoneRanges gives back. Still the in-RAM tree.
TEST(BuildMKTree, OutOfCoreLargeListsBuildTheSameTree) {
  auto recs = MakeScene(SceneKind::kShip, 300000, 9);
  BuildTuning in_ram;
  in_ram.threads = 1;
  in_ram.ram_node_objects = kNoIndex;
  auto r1 = BuildMKTree(recs, BuildParams(), in_ram);
  ASSERT_TRUE(r1.ok());
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    BuildTuning spilled;
    spilled.threads = threads;
    spilled.ram_node_objects = 20000;
    auto r2 = BuildMKTree(recs, BuildParams(), spilled);
    ASSERT_TRUE(r2.ok()) << r2.status().ToString();
    ExpectSameTree(*r1, *r2);
  }
}

// Builds `recs` on one and two threads with files limited to `limit` bytes: each build must fail with an
// I/O error naming `dir` and leave nothing in it.
void ExpectSpillFailsUnderFileLimit(const std::vector<BuildObject>& recs, BuildTuning tuning,
                                    const std::filesystem::path& dir, rlim_t limit_bytes) {
  struct sigaction ignore {
  }, old{};
  ignore.sa_handler = SIG_IGN;
  ASSERT_EQ(sigaction(SIGXFSZ, &ignore, &old), 0);
  rlimit limit{}, saved{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &saved), 0);
  limit = saved;
  limit.rlim_cur = limit_bytes;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
  for (int threads : {1, 2}) {
    SCOPED_TRACE("threads " + std::to_string(threads));
    tuning.threads = threads;
    auto r = BuildMKTree(recs, BuildParams(), tuning);
    EXPECT_FALSE(r.ok());
    if (!r.ok()) {
      EXPECT_EQ(r.status().code(), Status::Code::kIOError);
      EXPECT_NE(r.status().message().find(dir.string()), std::string::npos) << r.status().ToString();
    }
  }
  setrlimit(RLIMIT_FSIZE, &saved);
  sigaction(SIGXFSZ, &old, nullptr);
  EXPECT_TRUE(DirEntries(dir).empty());
  std::filesystem::remove_all(dir);
}

// A spill file that cannot be written (here: past the file size limit) fails the build with an I/O error
// naming it, on one thread and on two, and leaves nothing behind; so does a spill directory that is not.
TEST(BuildMKTree, SpillFailuresAreErrorsAndLeaveNothing) {
  const std::filesystem::path dir = FreshSpillDir("fail");
  auto recs = MakeScene(SceneKind::kShip, 20000, 3);
  BuildTuning tuning;
  tuning.ram_node_objects = 100;
  tuning.spill_dir = (dir / "missing").string();
  auto missing = BuildMKTree(recs, BuildParams(), tuning);
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), Status::Code::kIOError);
  EXPECT_NE(missing.status().message().find((dir / "missing").string()), std::string::npos)
      << missing.status().ToString();

  tuning.spill_dir = dir.string();
  tuning.cooperative_root_objects = 1;
  ExpectSpillFailsUnderFileLimit(recs, tuning, dir, 64 * 1024);  // the lists take 6 x 20000 x 4 = 480 kB
}

// A spill write that fails inside the node tasks, on a worker thread with two threads, fails the build
// the same way. The limit lets the lists and the ids in; list 0's first built chunk, written by whichever
// worker builds its last leaf (DoneRanges), is the first write past it.
TEST(BuildMKTree, SpillFailureInANodeTaskIsAnError) {
  const std::filesystem::path dir = FreshSpillDir("task");
  const size_t n = 300000;  // lists of 262144 objects and more are mapped: DoneRanges works on them
  auto recs = MakeScene(SceneKind::kShip, n, 9);
  BuildTuning tuning;
  tuning.ram_node_objects = 20000;
  tuning.spill_dir = dir.string();
  ExpectSpillFailsUnderFileLimit(recs, tuning, dir, 7 * n * sizeof(uint32_t));  // six lists and the ids
}

// Degenerate inputs that would make a quadratic step explode: they must complete quickly (no timing
// assertion: the test time limit is the guard) and still be correct.
TEST(BuildMKTree, DegenerateLargeInputsBuildFast) {
  const size_t n = 200000;
  for (SplitPolicy policy : kAllPolicies) {
    SCOPED_TRACE(testing::Name(policy));
    {
      auto recs = MakeScene(SceneKind::kIdentical, n, 1);
      auto r = BuildMKTree(recs, BuildParams(), WithPolicy(policy));
      ASSERT_TRUE(r.ok());
      EXPECT_EQ(r->leaf_objects.size(), n);
      EXPECT_LT(r->stats.height, 64u);
    }
    {
      // All objects cross the plane x = 0.
      std::mt19937_64 rng(3);
      std::uniform_real_distribution<float> u(0, 100);
      std::vector<BuildObject> recs(n);
      for (size_t i = 0; i < n; ++i) {
        const float y = u(rng), z = u(rng);
        recs[i] =
            Rec(static_cast<ObjectId>(i), B(-u(rng) - 0.1f, y, z, u(rng) + 0.1f, y + 0.3f, z + 0.3f), 1500);
      }
      auto r = BuildMKTree(recs, BuildParams(), WithPolicy(policy));
      ASSERT_TRUE(r.ok());
      EXPECT_EQ(r->leaf_objects.size(), n);
      EXPECT_LT(r->stats.height, 64u);
    }
    {
      // r = 0 on a uniform scene invites peeling one object per level; the depth guard bounds it.
      auto recs = MakeScene(SceneKind::kUniform, 50000, 2);
      BuildParams p;
      p.balance_r = 0;
      auto r = BuildMKTree(recs, p, WithPolicy(policy));
      ASSERT_TRUE(r.ok());
      EXPECT_LE(r->stats.height, 255u);
    }
  }
}

TEST(BuildMKTree, PageFillNearTheLeavesIsHigh) {
  auto recs = MakeScene(SceneKind::kShip, 50000, 9);
  BuildTuning plain = WithPolicy(SplitPolicy::kSoa);
  plain.fill_aware = false;
  auto fill = BuildMKTree(recs, BuildParams(), WithPolicy(SplitPolicy::kSoa));
  auto soa = BuildMKTree(recs, BuildParams(), plain);
  auto compact = BuildMKTree(recs, BuildParams(), WithPolicy(SplitPolicy::kCompact));
  ASSERT_TRUE(fill.ok() && soa.ok() && compact.ok());
  EXPECT_GT(fill->stats.mean_page_fill, soa->stats.mean_page_fill);
  EXPECT_LT(fill->stats.leaves, soa->stats.leaves);
  // The compact policy keeps the fill-aware ranking near the leaves.
  EXPECT_GT(compact->stats.mean_page_fill, soa->stats.mean_page_fill);
  EXPECT_GT(compact->stats.mean_page_fill, 0.95 * fill->stats.mean_page_fill);
}

// kCompact splits a node only along an axis whose objects spread at least compact_axis_ratio x the longest
// spread (spread: the mean of the spreads of min_w and max_w), or along the longest.
TEST(BuildMKTree, CompactPolicySplitsOnlyAlongWideAxes) {
  for (SceneKind kind : {SceneKind::kShip, SceneKind::kPlates, SceneKind::kUniform}) {
    SCOPED_TRACE(testing::Name(kind));
    auto recs = MakeScene(kind, 20000, 4);
    BuildTuning tune = WithPolicy(SplitPolicy::kCompact);
    auto r = BuildMKTree(recs, BuildParams(), tune);
    ASSERT_TRUE(r.ok());
    std::unordered_map<ObjectId, size_t> by_id;
    for (size_t i = 0; i < recs.size(); ++i) by_id[recs[i].id] = i;
    const testing::NodeRanges nr = testing::ComputeRanges(*r);
    uint64_t checked = 0;
    for (uint32_t i = 0; i < r->tree.nodes.size(); ++i) {
      const TreeNode& n = r->tree.nodes[i];
      if (n.is_leaf()) continue;
      float lo_min[3], hi_min[3], lo_max[3], hi_max[3];
      for (int w = 0; w < 3; ++w) {
        lo_min[w] = lo_max[w] = std::numeric_limits<float>::infinity();
        hi_min[w] = hi_max[w] = -std::numeric_limits<float>::infinity();
      }
      for (uint64_t k = nr.begin[i]; k < nr.end[i]; ++k) {
        const Box3f& bx = recs[by_id.at(r->leaf_objects[k])].box;
        for (int w = 0; w < 3; ++w) {
          lo_min[w] = std::min(lo_min[w], bx.min[w]);
          hi_min[w] = std::max(hi_min[w], bx.min[w]);
          lo_max[w] = std::min(lo_max[w], bx.max[w]);
          hi_max[w] = std::max(hi_max[w], bx.max[w]);
        }
      }
      double spread[3], longest = 0;
      for (int w = 0; w < 3; ++w) {
        spread[w] = 0.5 * ((double{hi_min[w]} - lo_min[w]) + (double{hi_max[w]} - lo_max[w]));
        longest = std::max(longest, spread[w]);
      }
      EXPECT_TRUE(spread[n.axis] == longest || spread[n.axis] >= tune.compact_axis_ratio * longest)
          << "node " << i << " split along axis " << int{n.axis} << " spread " << spread[n.axis] << " of "
          << longest;
      ++checked;
    }
    EXPECT_GT(checked, 100u);
  }
}

// What the compact policy is for: on a ship-like scene of long pipes and plates, random boxes meet fewer
// leaves holding an answer than with the SOA (the leaves a query reads once the leaf filter has spoken),
// at a page fill within a few percent.
TEST(BuildMKTree, CompactPolicyBoxesMeetFewerLeaves) {
  auto recs = MakeScene(SceneKind::kShip, 60000, 21);
  auto soa = BuildMKTree(recs, BuildParams(), WithPolicy(SplitPolicy::kSoa));
  auto compact = BuildMKTree(recs, BuildParams(), WithPolicy(SplitPolicy::kCompact));
  ASSERT_TRUE(soa.ok() && compact.ok());
  std::unordered_map<ObjectId, size_t> by_id;
  for (size_t i = 0; i < recs.size(); ++i) by_id[recs[i].id] = i;
  auto leaves_met = [&](const BuildResult& r, double side) {
    std::vector<uint32_t> leaf_of(recs.size());
    for (uint32_t l = 0; l < r.tree.leaves.size(); ++l)
      for (uint64_t k = r.leaf_offsets[l]; k < r.leaf_offsets[l + 1]; ++k)
        leaf_of[by_id.at(r.leaf_objects[k])] = l;
    std::mt19937_64 rng(77);
    std::uniform_real_distribution<double> u(0, 100);
    std::vector<uint32_t> seen(r.tree.leaves.size(), 0);
    uint64_t met = 0;
    for (uint32_t q = 1; q <= 300; ++q) {
      Box3f box;
      for (int a = 0; a < 3; ++a) {
        const double c = u(rng);
        box.min[a] = static_cast<float>(c - side / 2);
        box.max[a] = static_cast<float>(c + side / 2);
      }
      for (size_t i = 0; i < recs.size(); ++i) {
        if (recs[i].box.Intersects(box) && seen[leaf_of[i]] != q) {
          seen[leaf_of[i]] = q;
          ++met;
        }
      }
    }
    return met;
  };
  for (double side : {4.0, 16.0}) {
    const uint64_t s = leaves_met(*soa, side), c = leaves_met(*compact, side);
    EXPECT_LT(c, s) << "box side " << side;
    std::printf("box side %.0f: leaves with an answer, soa %llu, compact %llu\n", side,
                static_cast<unsigned long long>(s), static_cast<unsigned long long>(c));
  }
  EXPECT_GT(compact->stats.mean_page_fill, 0.95 * soa->stats.mean_page_fill);
}

}  // namespace
}  // namespace mktree

namespace mktree {
namespace {

// The root's split is the SOA optimum: no candidate of any of the 6 keys, within the balance range, has a
// smaller overlap set than the root's (which can only shrink when free objects change side).
// 2000 objects: enough cuts that the scan skips blocks of them by their |Sm| bound.
TEST(BuildMKTree, RootSplitMinimisesTheOverlapSetByBruteForce) {
  for (SceneKind kind : {SceneKind::kUniform, SceneKind::kShip, SceneKind::kClustered, SceneKind::kGrid}) {
    for (uint64_t seed = 1; seed <= 3; ++seed) {
      auto recs = MakeScene(kind, seed == 3 ? 2000 : 120, seed);
      BuildParams p;
      p.block_size = 1024;
      BuildTuning plain = WithPolicy(SplitPolicy::kSoa);
      plain.fill_aware = false;
      auto r = BuildMKTree(recs, p, plain);
      ASSERT_TRUE(r.ok());
      const size_t n = recs.size();
      const size_t k_lo = static_cast<size_t>(std::ceil(p.balance_r * n)),
                   k_hi = static_cast<size_t>(std::floor((1 - p.balance_r) * n));
      size_t best = n + 1;
      for (int w = 0; w < 3; ++w) {
        for (int key = 0; key < 2; ++key) {
          std::vector<size_t> order(n);
          for (size_t i = 0; i < n; ++i) order[i] = i;
          std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
            return key == 0 ? recs[x].box.min[w] < recs[y].box.min[w]
                            : recs[x].box.max[w] < recs[y].box.max[w];
          });
          for (size_t k = std::max<size_t>(k_lo, 1); k <= std::min(k_hi, n - 1); ++k) {
            float a = std::numeric_limits<float>::infinity(), b = -a;
            for (size_t i = k; i < n; ++i) a = std::min(a, recs[order[i]].box.min[w]);
            for (size_t i = 0; i < k; ++i) b = std::max(b, recs[order[i]].box.max[w]);
            size_t sm = 0;
            if (a < b)
              for (const auto& rc : recs) sm += rc.box.max[w] > a && rc.box.min[w] < b;
            best = std::min(best, sm);
          }
        }
      }
      const TreeNode& root = r->tree.nodes[0];
      ASSERT_FALSE(root.is_leaf());
      size_t root_sm = 0;
      if (root.a < root.b)
        for (const auto& rc : recs)
          root_sm += rc.box.max[root.axis] > root.a && rc.box.min[root.axis] < root.b;
      EXPECT_LE(root_sm, best) << testing::Name(kind) << " seed " << seed;
      EXPECT_EQ(r->stats.levels[0].overlap_objects, root_sm);
    }
  }
}

}  // namespace
}  // namespace mktree
