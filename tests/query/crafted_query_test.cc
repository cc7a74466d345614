// The public API on crafted stores (tests/store_format/crafted_store.h) and under memory limits: a tampered
// store gives a Corruption naming the file (at Database::Open or at the query that reads the bad leaf),
// never a hang, a duplicated or missing id; RunBatch keeps the error's code and message; and an exception
// (such as std::bad_alloc under RLIMIT_AS) never crosses the API. Crafted* suites run under a short
// timeout.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "mktree/database.h"
#include "store_format/crafted_store.h"
#include "tool_runner.h"

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
  QueryResult r;
  ASSERT_TRUE((*db)->Run(Query::Box(Everything(image_)), &r).ok());
  ASSERT_EQ(r.hits.size(), 300u);
  for (ObjectId i = 0; i < 300; ++i) EXPECT_EQ(r.hits[i], i);
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

// An entry whose geometry does not decode fails the exact query with an error naming the store (the
// hostile campaign's crafted-030 to 032 said only "object N: ...").
// An object's leaf is in its record: a record naming another leaf (an index the tree has) makes that
// object's geometry a Corruption, never another object's mesh; the other objects and the queries are
// unaffected.
TEST_F(CraftedQueryTest, RecordNamingAnotherLeafIsCorruptionAtTheObjectsGeometry) {
  const uint32_t moved = 17;
  const uint32_t own = image_.object_leaf[moved];
  image_.object_leaf[moved] = own == 0 ? 1 : 0;
  ASSERT_TRUE(testing::SetObjectRecords(&image_, testing::MakeObjects(300, 11)).ok());
  auto db = WriteAndOpen();
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  Status st = (*db)->ObjectGeometry(moved).status();
  ExpectCorruptionNamingTheFile(st);
  EXPECT_NE(st.message().find("object 17: its record puts it in leaf " + std::to_string(own == 0 ? 1 : 0) +
                              ", which does not hold it"),
            std::string::npos)
      << st.message();
  EXPECT_TRUE((*db)->ObjectGeometry(moved + 1).ok());
  QueryResult r;
  ASSERT_TRUE((*db)->Run(Query::Box(Everything(image_)), &r).ok());
  EXPECT_EQ(r.hits.size(), 300u);
}

// The documented limit of the leaf id digests: a crafted collision. Ids `twice` and `gone` have equal
// ObjectIdHash sums (found by lattice reduction, scripts/hostile.py mut_digest_collision); each position
// of a `gone` object holds a copy of a `twice` object instead, and the leaves' digests are recomputed.
// Counts and digests add up and every leaf passes its check, so the store opens; a query that meets both
// copies of an id, and a clash (the copies meet), are a Corruption, never an answer with the id twice or
// an object paired with itself (the `gone` ids cannot be seen).
Status WriteDigestCollision(StoreImage* image, const std::string& path, ObjectId* first_twice) {
  const std::vector<ObjectId> twice = {36, 65, 68, 72, 105, 111, 136, 150, 154, 198, 279};
  const std::vector<ObjectId> gone = {156, 162, 196, 210, 240, 242, 0, 6, 82, 128, 144};
  uint64_t sum_twice = 0, sum_gone = 0;
  for (size_t k = 0; k < twice.size(); ++k)
    sum_twice += ObjectIdHash(twice[k]), sum_gone += ObjectIdHash(gone[k]);
  if (sum_twice != sum_gone) return Status::Internal("not a collision");
  const std::vector<SceneObject> objects = testing::MakeObjects(300, 11);
  std::vector<SceneObject> crafted = objects;
  for (size_t k = 0; k < twice.size(); ++k) crafted[gone[k]] = objects[twice[k]];
  MemoryPageStore pages(image->mem_page());
  testing::BuiltStore built;
  MKTREE_RETURN_IF_ERROR(
      testing::BuildTestStore(crafted, image->contents.codec, image->contents.params, &pages, &built));
  for (size_t k = 0; k < twice.size(); ++k)
    if (built.object_leaf[twice[k]] == built.object_leaf[gone[k]]) return Status::Internal("same leaf");
  for (uint64_t& d : built.objects.leaf_digest) d = 0;
  for (size_t i = 0; i < crafted.size(); ++i)
    built.objects.leaf_digest[built.object_leaf[i]] += ObjectIdHash(crafted[i].id);
  image->contents.tree = std::move(built.tree);
  image->contents.objects = built.objects;
  image->contents.stats_json.clear();
  image->object_leaf = built.object_leaf;
  image->pages.resize(pages.page_count());
  for (uint64_t i = 0; i < image->pages.size(); ++i)
    image->pages[i].assign(pages.mutable_page(i), pages.mutable_page(i) + image->mem_page());
  MKTREE_RETURN_IF_ERROR(testing::SetObjectRecords(image, objects));
  *first_twice = twice[0];
  return testing::WriteStoreImage(*image, path, Backend::kPagedFile);
}

TEST_F(CraftedQueryTest, AnIdInTwoLeavesByADigestCollisionIsCorruptionNotTwoHits) {
  ObjectId twice = 0;
  ASSERT_TRUE(WriteDigestCollision(&image_, path_, &twice).ok());
  auto db = Database::Open(path_);
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  const std::string what = " is in two leaves";
  for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
    QueryResult r;
    const Status st = (*db)->Run(Query::Box(Everything(image_), mode), &r);
    ExpectCorruptionNamingTheFile(st);
    EXPECT_NE(st.message().find(what), std::string::npos) << st.message();
    std::vector<QueryResult> results;
    ExpectCorruptionNamingTheFile((*db)->RunBatch({Query::Box(Everything(image_), mode)}, 2, &results));
  }
  std::vector<ClashPair> pairs;
  const Status st = (*db)->SelfClash(
      ClashOptions(), [&](const ClashPair& p) { pairs.push_back(p); }, nullptr);
  ExpectCorruptionNamingTheFile(st);
  EXPECT_NE(st.message().find(" is in two leaves"), std::string::npos) << st.message();
  for (const ClashPair& p : pairs) EXPECT_LT(p.a, p.b);

  // A box around the whole scene meets every object: each id once, or the Corruption.
  const Box3d all = Everything(image_);
  Mesh box;
  for (int v = 0; v < 8; ++v)
    for (int i = 0; i < 3; ++i) box.vertices.push_back((v >> i) & 1 ? all.max[i] : all.min[i]);
  box.triangles = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                   2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
  pairs.clear();
  const Status collide = (*db)->Collide(
      box, std::nullopt, ClashOptions(), [&](const ClashPair& p) { pairs.push_back(p); }, nullptr);
  ExpectCorruptionNamingTheFile(collide);
  EXPECT_NE(collide.message().find(" is in two leaves"), std::string::npos) << collide.message();
  std::vector<ObjectId> ids;
  for (const ClashPair& p : pairs) ids.push_back(p.a);
  std::sort(ids.begin(), ids.end());
  EXPECT_EQ(std::adjacent_find(ids.begin(), ids.end()), ids.end());
}

// The same store through every path that streams or counts ids instead of sorting them, each on a fresh
// Database: the leaf read second of two holding one id is refused where it is read (LeafClaims), so no
// visitor, span, count or batch sees an id twice. A count would otherwise say 300, the right number,
// for 289 distinct ids.
TEST_F(CraftedQueryTest, AnIdInTwoLeavesIsCorruptionOnEveryStreamingAndCountingPath) {
  ObjectId twice = 0;
  ASSERT_TRUE(WriteDigestCollision(&image_, path_, &twice).ok());
  const Box3d all = Everything(image_);
  std::vector<ObjectId> seen;  // what the call visited before it failed: no id twice
  auto expect_twice = [&](const Status& st, const std::string& path_name) {
    SCOPED_TRACE(path_name);
    ExpectCorruptionNamingTheFile(st);
    EXPECT_NE(st.message().find(" is in two leaves"), std::string::npos) << st.message();
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(std::adjacent_find(seen.begin(), seen.end()), seen.end()) << "an id visited twice";
    seen.clear();
  };
  auto fresh = [&] {
    auto db = Database::Open(path_);
    EXPECT_TRUE(db.ok()) << db.status().ToString();
    return std::move(db).value();
  };
  for (QueryMode mode : {QueryMode::kAabb, QueryMode::kExact}) {
    const Query q = Query::Box(all, mode);
    expect_twice(fresh()
                     ->VisitUntil(
                         q, [&](ObjectId id) { return seen.push_back(id), true; }, nullptr)
                     .status(),
                 "VisitUntil");
    Query limited = q;
    limited.limit = 1000;
    expect_twice(fresh()
                     ->VisitUntil(
                         limited, [&](ObjectId id) { return seen.push_back(id), true; }, nullptr)
                     .status(),
                 "VisitUntil under a limit");
    expect_twice(fresh()->Visit(
                     q, [&](ObjectId id) { seen.push_back(id); }, nullptr),
                 "Visit");
    expect_twice(
        fresh()->VisitSpans(
            q, [&](std::span<const ObjectId> ids) { seen.insert(seen.end(), ids.begin(), ids.end()); },
            nullptr),
        "VisitSpans");
    QueryResult r;
    expect_twice(fresh()->Run(limited, &r), "Run under a limit");
    for (bool cold : {false, true}) {
      BatchOptions o;
      o.threads = 2;
      o.ids = false;
      o.cold = cold;
      uint64_t delivered = 0;
      expect_twice(fresh()->RunBatchStreamed({q, q, q}, o,
                                             [&](uint64_t, const QueryResult&) {
                                               ++delivered;
                                               return Status::Ok();
                                             }),
                   cold ? "count-only batch, cold" : "count-only batch");
      EXPECT_EQ(delivered, 0u);
    }
  }
  // Any stops at its first answer, which a duplicate cannot make wrong; once the second copy's leaf was
  // read, every read of that leaf is refused.
  auto db = fresh();
  auto any = db->Any(Query::Box(all), nullptr);
  ASSERT_TRUE(any.ok()) << any.status().ToString();
  EXPECT_TRUE(*any);
  expect_twice(db->VisitSpans(
                   Query::Box(all), [](std::span<const ObjectId>) {}, nullptr),
               "VisitSpans");
  expect_twice(db->VisitSpans(
                   Query::Box(all), [](std::span<const ObjectId>) {}, nullptr),
               "VisitSpans again");
  db->ClearCache();
  expect_twice(db->VisitSpans(
                   Query::Box(all), [](std::span<const ObjectId>) {}, nullptr),
               "VisitSpans after ClearCache");
  // Each object's geometry reads the leaf its record names: reading them all reads every leaf.
  db = fresh();
  int refused = 0;
  for (ObjectId id = 0; id < 300; ++id) {
    Status st = db->ObjectGeometry(id).status();
    if (st.ok()) continue;
    ++refused;
    ExpectCorruptionNamingTheFile(st);
  }
  EXPECT_GT(refused, 0);
}

// The command line on the same store: every command that reads the leaves fails with one error line
// naming the store, and leaves no output file behind.
TEST_F(CraftedQueryTest, AnIdInTwoLeavesFailsEveryCommandThatReadsTheLeaves) {
  ObjectId twice = 0;
  ASSERT_TRUE(WriteDigestCollision(&image_, path_, &twice).ok());
  const Box3d all = Everything(image_);
  char box[256];
  std::snprintf(box, sizeof box, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", all.min[0], all.min[1], all.min[2],
                all.max[0], all.max[1], all.max[2]);
  {
    std::ofstream q(dir_.file("q.txt"));
    q.precision(17);
    for (int k = 0; k < 4; ++k)
      q << "box " << all.min[0] << " " << all.min[1] << " " << all.min[2] << " " << all.max[0] << " "
        << all.max[1] << " " << all.max[2] << "\n";
    std::ofstream obj(dir_.file("all.obj"));
    obj.precision(17);
    obj << "o all\n";
    for (int v = 0; v < 8; ++v)
      obj << "v " << ((v & 1) ? all.max[0] : all.min[0]) << " " << ((v & 2) ? all.max[1] : all.min[1]) << " "
          << ((v & 4) ? all.max[2] : all.min[2]) << "\n";
    obj << "f 1 3 4\nf 1 4 2\nf 5 6 8\nf 5 8 7\nf 1 2 6\nf 1 6 5\n"
        << "f 3 7 8\nf 3 8 4\nf 1 5 7\nf 1 7 3\nf 2 4 8\nf 2 8 6\n";
  }
  const std::string s = " " + path_;
  const std::vector<std::string> commands = {
      "query" + s + " --box " + box,
      "query" + s + " --box " + box + " --count",
      "query" + s + " --box " + box + " --summary",
      "query" + s + " --box " + box + " --exact --count",
      "query" + s + " --queries " + dir_.file("q.txt") + " --count --threads 2",
      "query" + s + " --queries " + dir_.file("q.txt") + " --count --cold --threads 2",
      "query" + s + " --queries " + dir_.file("q.txt") + " --limit 1000",
      "clash" + s + " --threads 1",
      "collide" + s + " --object " + dir_.file("all.obj") + " --threads 1",
      "export" + s + " --level 1 -o " + dir_.file("out.ply") + " -q",
      "export" + s + " --level 1 --boxes -o " + dir_.file("out.glb") + " -q",
      "render" + s + " --level 1 -o " + dir_.file("out.png") + " -q",
  };
  for (const std::string& c : commands) {
    SCOPED_TRACE(c);
    const testing::ToolRun r = testing::RunMktree(c, dir_.path());
    EXPECT_EQ(r.code, 1) << r.out.substr(0, 300);
    EXPECT_EQ(r.err.rfind("error: ", 0), 0u) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << r.err;
    EXPECT_NE(r.err.find(path_), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(" is in two leaves"), std::string::npos) << r.err;
    for (const char* out : {"out.ply", "out.glb", "out.png"})
      EXPECT_FALSE(std::filesystem::exists(dir_.file(out))) << out;
  }
  // --any stops at the first leaf with an answer: right whatever the other leaves hold.
  const testing::ToolRun r = testing::RunMktree("query" + s + " --box " + box + " --any", dir_.path());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("\"any\": true"), std::string::npos) << r.out;
}

TEST_F(CraftedQueryTest, GeometryThatDoesNotDecodeIsCorruptionNamingTheStore) {
  auto img = testing::MakeTestImage(testing::MakeObjects(300, 11), {}, Codec::kNone);
  ASSERT_TRUE(img.ok()) << img.status().ToString();
  image_ = std::move(img).value();
  const uint32_t l = testing::LeafWithObjects(image_.tree(), 1);
  std::vector<uint8_t>& page = image_.pages[image_.tree().leaves[l].first_page];
  const size_t at = testing::EntryOffsets(page)[0];
  auto e = ParseObjectEntry(page.data() + at, page.size() - at);
  ASSERT_TRUE(e.ok());
  ASSERT_GT(e->triangle_count, 0u);
  // The entry's last triangle index, past its vertices.
  storage_internal::Put<uint32_t>(page.data() + at + e->entry_bytes() - 4, e->vertex_count + 1000);
  testing::ResealPage(&page);
  auto db = WriteAndOpen();
  ASSERT_TRUE(db.ok()) << db.status().ToString();
  QueryResult r;
  Status st = (*db)->Run(Query::Box(Everything(image_), QueryMode::kExact), &r);
  ExpectCorruptionNamingTheFile(st);
  EXPECT_NE(st.message().find("triangle index out of range"), std::string::npos) << st.message();
}

TEST_F(CraftedQueryTest, TamperedPagesAreCorruptionAtTheQueryNotAnAnswer) {
  const uint32_t l = testing::LeafWithObjects(image_.tree(), 3);
  std::vector<uint8_t>& page = image_.pages[image_.tree().leaves[l].first_page];
  const std::vector<size_t> at = testing::EntryOffsets(page);
  storage_internal::Put<uint32_t>(page.data() + at[1], storage_internal::Get<uint32_t>(page.data() + at[0]));
  testing::ResealPage(&page);
  auto db = WriteAndOpen();
  ASSERT_TRUE(db.ok()) << db.status().ToString();  // the page is only read by a query
  QueryResult r;
  ExpectCorruptionNamingTheFile((*db)->Run(Query::Box(Everything(image_)), &r));
  ExpectCorruptionNamingTheFile((*db)->Run(Query::Box(Everything(image_), QueryMode::kExact), &r));

  // RunBatch returns the first failing query's own Status (in query order, whatever the threads do), its
  // message prefixed with the query's index: here a Corruption at 5, and an InvalidArgument at 9.
  std::vector<Query> queries(12, Query::Point({-1e6, -1e6, -1e6}));  // outside: read nothing
  queries[5] = Query::Box(Everything(image_));
  queries[9] = Query::Point({std::nan(""), 0, 0});
  QueryResult alone;
  const Status corrupt = (*db)->Run(queries[5], &alone);
  const Status invalid = (*db)->Run(queries[9], &alone);
  ASSERT_EQ(invalid.code(), Status::Code::kInvalidArgument);
  std::vector<QueryResult> results;
  for (unsigned threads : {1u, 3u, 12u}) {
    Status st = (*db)->RunBatch(queries, threads, &results);
    ExpectCorruptionNamingTheFile(st);
    EXPECT_EQ(st.message(), "query 5: " + corrupt.message());
  }
  std::swap(queries[5], queries[9]);
  for (unsigned threads : {1u, 3u, 12u}) {
    Status st = (*db)->RunBatch(queries, threads, &results);
    EXPECT_EQ(st.code(), Status::Code::kInvalidArgument);
    EXPECT_EQ(st.message(), "query 5: " + invalid.message());
  }
}

// VmSize of this process, in bytes (0 if unknown).
uint64_t VmSizeBytes() {
  std::ifstream f("/proc/self/status");
  std::string line;
  while (std::getline(f, line))
    if (line.rfind("VmSize:", 0) == 0) return std::stoull(line.substr(7)) * 1024;
  return 0;
}

// Runs `body` in a forked child whose address space may grow only `headroom` bytes beyond its size at
// the fork; returns the child's exit code, or -1 if it did not exit normally (an abort, a crash).
int RunUnderMemoryLimit(uint64_t headroom, const std::function<int()>& body) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const uint64_t size = VmSizeBytes();
    if (size == 0) ::_exit(90);
    const rlimit lim{size + headroom, size + headroom};
    if (::setrlimit(RLIMIT_AS, &lim) != 0) ::_exit(91);
    ::_exit(body());
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CraftedMemoryLimitTest, OpenAndQueriesUnderAMemoryLimitReturnAStatus) {
  testing::TempDir dir;
  const std::string path = dir.file("big_sources.mkt");
  {
    auto img = testing::MakeTestImage(16, 5);
    ASSERT_TRUE(img.ok());
    // 16 sources of 2 MiB each: opening needs twice 32 MiB (the section, then the table). (Names are no
    // longer read at open: they live in the record pages.)
    for (uint64_t i = 1; i < 16; ++i)
      img->objects().sources.push_back(std::string(2 << 20, static_cast<char>('a' + i % 26)));
    ASSERT_TRUE(testing::WriteStoreImage(*img, path, Backend::kPagedFile).ok());
  }
  // Enough to run (checked below), far from enough to open.
  const uint64_t headroom = 8 << 20;
  EXPECT_EQ(RunUnderMemoryLimit(headroom, [] { return 0; }), 0);
  const int open = RunUnderMemoryLimit(headroom, [&] {
    auto db = Database::Open(path);
    if (db.ok()) return 2;
    const Status& st = db.status();
    return st.message().find(path) != std::string::npos &&
                   st.message().find("out of memory") != std::string::npos
               ? 0
               : 3;
  });
  EXPECT_EQ(open, 0) << "0: a Status naming the file and the cause; 2: opened; 3: another error; -1: aborted";

  // A batch whose threads cannot all start still answers (or fails cleanly), never aborts.
  auto img = testing::MakeTestImage(300, 12);
  ASSERT_TRUE(img.ok());
  const std::string small = dir.file("small.mkt");
  ASSERT_TRUE(testing::WriteStoreImage(*img, small, Backend::kPagedFile).ok());
  auto db = Database::Open(small);
  ASSERT_TRUE(db.ok());
  std::vector<Query> queries(64, Query::Box(Everything(*img)));
  const int batch = RunUnderMemoryLimit(4 << 20, [&] {
    std::vector<QueryResult> results;
    Status st = (*db)->RunBatch(queries, 16, &results);
    if (!st.ok()) return st.code() == Status::Code::kInternal ? 4 : 3;
    for (const QueryResult& r : results)
      if (r.hits.size() != 300) return 5;
    return 0;
  });
  EXPECT_TRUE(batch == 0 || batch == 4) << batch;
}

}  // namespace
}  // namespace mktree
