// `mktree build --shards`, and `query`/`info` on a manifest (docs/cli.md).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "engine/shard/manifest.h"
#include "test_dirs.h"
#include "tool_runner.h"

namespace mktree {
namespace {

using testing::RunMktree;
using testing::TempDir;

std::string Hits(const std::string& jsonl) {  // the "hits" arrays, one a line
  std::string out;
  size_t at = 0;
  while ((at = jsonl.find("\"hits\": [", at)) != std::string::npos) {
    const size_t end = jsonl.find(']', at);
    out += jsonl.substr(at, end - at + 1) + "\n";
    at = end;
  }
  return out;
}

TEST(ShardCli, BuildQueryAndInfo) {
  TempDir dir("mktree_shard_cli");
  const std::string d = dir.path().string();
  ASSERT_EQ(RunMktree("build tanker:8000:2 -o " + d + "/plain.mkt -q", dir).code, 0);
  auto built = RunMktree("build tanker:8000:2 -o " + d + "/s.mkts --shards 3 --backend pagefile", dir);
  ASSERT_EQ(built.code, 0) << built.err;
  EXPECT_NE(built.out.find("built " + d + "/s.mkts: 8000 objects"), std::string::npos) << built.out;
  ASSERT_EQ(
      RunMktree("generate queries " + d + "/plain.mkt --count 100 --seed 2 -o " + d + "/q.txt", dir).code, 0);
  for (const std::string mode : {"", " --exact"}) {
    auto a = RunMktree("query " + d + "/plain.mkt --queries " + d + "/q.txt --cold" + mode, dir);
    auto b = RunMktree("query " + d + "/s.mkts --queries " + d + "/q.txt --cold" + mode, dir);
    ASSERT_EQ(a.code, 0);
    ASSERT_EQ(b.code, 0) << b.err;
    EXPECT_EQ(Hits(a.out), Hits(b.out));
    EXPECT_EQ(std::count(b.out.begin(), b.out.end(), '\n'), 400);
  }
  auto info = RunMktree("info " + d + "/s.mkts --json", dir);
  ASSERT_EQ(info.code, 0) << info.err;
  EXPECT_NE(info.out.find("\"objects\": 8000, \"revision\": 0, \"base_objects\": 8000,"), std::string::npos)
      << info.out;
  EXPECT_NE(info.out.find("\"removed_ids\": 0, \"shards\": 3,"), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("\"top_levels\": [{\"axis\""), std::string::npos) << info.out;
  auto object = RunMktree("info " + d + "/s.mkts --object 77", dir);
  auto plain_object = RunMktree("info " + d + "/plain.mkt --object 77", dir);
  ASSERT_EQ(object.code, 0) << object.err;
  EXPECT_EQ(object.out, plain_object.out);
  // A shard alone is a store.
  EXPECT_EQ(RunMktree("info " + ShardStorePath(d + "/s.mkts", 2), dir).code, 0);
  // A missing shard: one error line naming it.
  std::filesystem::remove(ShardStorePath(d + "/s.mkts", 1));
  auto missing = RunMktree("query " + d + "/s.mkts --point 1,1,1", dir);
  EXPECT_NE(missing.code, 0);
  EXPECT_EQ(missing.err.rfind("error: ", 0), 0u) << missing.err;
  EXPECT_NE(missing.err.find("s.mkts.shard-1.mkt"), std::string::npos) << missing.err;
  EXPECT_EQ(std::count(missing.err.begin(), missing.err.end(), '\n'), 1);
}

// The pair lines without the --summary line, sorted (a sharded store gives them in another order), and
// the summary's pair counts.
std::string SortedPairs(const std::string& out) {
  std::vector<std::string> lines;
  std::istringstream in(out);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("{\"a\"", 0) == 0) lines.push_back(line);
  std::sort(lines.begin(), lines.end());
  std::string all;
  for (const auto& l : lines) all += l + "\n";
  return all;
}
std::string Counts(const std::string& out) {
  const size_t at = out.find("{\"pairs\"");
  return at == std::string::npos ? "" : out.substr(at, out.find(", \"pages_read\"", at) - at);
}

TEST(ShardCli, ClashAndCollideOnAManifest) {
  TempDir dir("mktree_shard_cli");
  const std::string d = dir.path().string();
  ASSERT_EQ(RunMktree("build tanker:6000:3 -o " + d + "/plain.mkt -q", dir).code, 0);
  ASSERT_EQ(RunMktree("build tanker:6000:3 -o " + d + "/s.mkts --shards 3 -q", dir).code, 0);
  {
    std::ofstream obj(d + "/probe.obj");
    obj << "v 0 -4 0\nv 30 -4 0\nv 30 4 0\nv 0 4 0\nv 0 -4 8\nv 30 -4 8\nv 30 4 8\nv 0 4 8\n"
           "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\n"
           "f 4 1 5\nf 4 5 8\n";
  }
  for (const std::string& args :
       {std::string("clash %s --summary --clearance 0.01 --names"),
        std::string("clash %s --summary --threads 2 --max-pairs 50"),
        "collide %s --object " + d + "/probe.obj --translate 90,0,2 --rotate-deg 0,0,20 --summary"}) {
    SCOPED_TRACE(args);
    auto with = [&](const std::string& store) {
      std::string a = args;
      a.replace(a.find("%s"), 2, store);
      return a;
    };
    auto plain = RunMktree(with(d + "/plain.mkt"), dir);
    auto sharded = RunMktree(with(d + "/s.mkts"), dir);
    ASSERT_EQ(plain.code, 0) << plain.err;
    ASSERT_EQ(sharded.code, 0) << sharded.err;
    EXPECT_GT(std::count(plain.out.begin(), plain.out.end(), '\n'), 10);
    if (args.find("max-pairs") == std::string::npos) {
      EXPECT_EQ(SortedPairs(sharded.out), SortedPairs(plain.out));
    }
    EXPECT_EQ(Counts(sharded.out), Counts(plain.out));
    EXPECT_NE(Counts(sharded.out), "");
  }
}

TEST(ShardCli, BadShardCountsAreRefused) {
  TempDir dir("mktree_shard_cli");
  const std::string d = dir.path().string();
  auto big = RunMktree("build tanker:100 -o " + d + "/s.mkts --shards 70000 -q", dir);
  EXPECT_NE(big.code, 0);
  EXPECT_NE(big.err.find("--shards"), std::string::npos) << big.err;
  auto few = RunMktree("build tanker:3 -o " + d + "/s.mkts --shards 4 -q", dir);
  EXPECT_NE(few.code, 0);
  EXPECT_NE(few.err.find("cannot make 4 shards"), std::string::npos) << few.err;
  EXPECT_TRUE(std::filesystem::is_empty(dir.path()));
}

}  // namespace
}  // namespace mktree
