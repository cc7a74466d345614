// The distributed sharded build's steps (engine/ingest/distributed_build.h) on R = 1..4 ranks simulated by
// threads of one process (an in-process RankExchange), as tests/mpi/ranks.sh runs them over MPI: the top
// levels and shard sizes of the single-process sharded build, the same shard stores byte for byte, every
// answer of the unsharded store; a tanker read by id ranges, an .mks by byte ranges (many exchange
// rounds), several inputs read by rank 0; a failed build on every rank, with no file left.
#include "engine/ingest/distributed_build.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <random>
#include <thread>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/exchange_record.h"
#include "engine/ingest/shard_build.h"
#include "engine/scene/mkscene_format.h"
#include "engine/shard/manifest.h"
#include "mktree/build.h"
#include "mktree/database.h"
#include "test_dirs.h"

namespace mktree {
namespace {

using testing::TempDir;

// What the ranks of one process share: a barrier, one slot a rank for the collectives, mailboxes.
class Hub {
 public:
  explicit Hub(int ranks) : ranks_(ranks), bytes_(ranks), matrix_(size_t(ranks) * ranks), values_(ranks) {}

  // Every rank's `put` (writing its slots), then every rank's `take` (reading them), then the next.
  template <typename Put, typename Take>
  void Collective(const Put& put, const Take& take) {
    put();
    Wait();
    take();
    Wait();
  }
  void Post(int from, int to, std::vector<uint8_t> bytes) {
    std::lock_guard lock(mail_mu_);
    mail_[{from, to}].push_back(std::move(bytes));
    mail_cv_.notify_all();
  }
  std::vector<uint8_t> Take(int from, int to) {
    std::unique_lock lock(mail_mu_);
    auto& box = mail_[{from, to}];
    mail_cv_.wait(lock, [&] { return !box.empty(); });
    std::vector<uint8_t> b = std::move(box.front());
    box.pop_front();
    return b;
  }

  const int ranks_;
  std::vector<std::vector<uint8_t>> bytes_;   // by rank
  std::vector<std::vector<uint8_t>> matrix_;  // [from * R + to]
  std::vector<std::vector<uint64_t>> values_;
  std::vector<double> reals_ = std::vector<double>(size_t(ranks_));

 private:
  void Wait() {
    std::unique_lock lock(mu_);
    const uint64_t generation = generation_;
    if (++waiting_ == ranks_) {
      waiting_ = 0;
      ++generation_;
      cv_.notify_all();
    } else {
      cv_.wait(lock, [&] { return generation_ != generation; });
    }
  }
  std::mutex mu_;
  std::condition_variable cv_;
  int waiting_ = 0;
  uint64_t generation_ = 0;
  std::mutex mail_mu_;
  std::condition_variable mail_cv_;
  std::map<std::pair<int, int>, std::deque<std::vector<uint8_t>>> mail_;
};

class ThreadExchange final : public RankExchange {
 public:
  ThreadExchange(Hub* hub, int rank) : hub_(*hub), rank_(rank) {}
  int rank() const override { return rank_; }
  int ranks() const override { return hub_.ranks_; }
  std::vector<std::vector<uint8_t>> AllToAll(const std::vector<std::vector<uint8_t>>& send) override {
    std::vector<std::vector<uint8_t>> in(ranks());
    hub_.Collective(
        [&] {
          for (int q = 0; q < ranks(); ++q) hub_.matrix_[size_t(rank_) * ranks() + q] = send[q];
        },
        [&] {
          for (int q = 0; q < ranks(); ++q) in[q] = hub_.matrix_[size_t(q) * ranks() + rank_];
        });
    return in;
  }
  std::vector<std::vector<uint8_t>> Gather(const std::vector<uint8_t>& mine) override {
    std::vector<std::vector<uint8_t>> all;
    hub_.Collective([&] { hub_.bytes_[rank_] = mine; },
                    [&] {
                      if (rank_ == 0) all = hub_.bytes_;
                    });
    return all;
  }
  void Broadcast(std::vector<uint8_t>* bytes) override {
    hub_.Collective(
        [&] {
          if (rank_ == 0) hub_.bytes_[0] = *bytes;
        },
        [&] {
          if (rank_ != 0) *bytes = hub_.bytes_[0];
        });
  }
  std::vector<uint64_t> AllGather(const std::vector<uint64_t>& mine) override {
    std::vector<uint64_t> all;
    hub_.Collective([&] { hub_.values_[rank_] = mine; },
                    [&] {
                      for (const auto& v : hub_.values_) all.insert(all.end(), v.begin(), v.end());
                    });
    return all;
  }
  uint64_t ExclusiveSum(uint64_t value) override {
    const std::vector<uint64_t> all = AllGather({value});
    uint64_t sum = 0;
    for (int q = 0; q < rank_; ++q) sum += all[q];
    return sum;
  }
  uint64_t Sum(uint64_t value) override {
    uint64_t sum = 0;
    for (uint64_t v : AllGather({value})) sum += v;
    return sum;
  }
  uint64_t Min(uint64_t value) override {
    const std::vector<uint64_t> all = AllGather({value});
    return *std::min_element(all.begin(), all.end());
  }
  double Max(double value) override {
    double max = 0;
    hub_.Collective([&] { hub_.reals_[rank_] = value; },
                    [&] { max = *std::max_element(hub_.reals_.begin(), hub_.reals_.end()); });
    return max;
  }
  void Send(int to, const std::vector<uint8_t>& bytes) override { hub_.Post(rank_, to, bytes); }
  std::vector<uint8_t> Receive(int from) override { return hub_.Take(from, rank_); }

 private:
  Hub& hub_;
  int rank_;
};

struct RankOutcome {
  Status status;
  DistributedBuildReport report;
  std::vector<std::string> errors, notes;
};

// The build on `ranks` threads, each its own rank.
std::vector<RankOutcome> BuildOnRanks(int ranks, const std::vector<std::string>& inputs,
                                      const std::string& manifest, uint32_t shards, uint64_t round_bytes) {
  Hub hub(ranks);
  std::vector<RankOutcome> out(ranks);
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) {
    threads.emplace_back([&, r] {
      ThreadExchange x(&hub, r);
      DistributedBuildOptions o;
      o.inputs = inputs;
      o.manifest_path = manifest;
      o.shards = shards;
      o.ingest.store.backend = Backend::kPagedFile;
      o.ingest.threads = 1;
      o.ingest.tuning.threads = 1;
      o.round_bytes = round_bytes;
      o.error = [&out, r](const std::string& m) { out[r].errors.push_back(m); };
      o.note = [&out, r](const std::string& m) { out[r].notes.push_back(m); };
      auto report = BuildShardedOnRanks(o, &x);
      out[r].status = report.status();
      if (report.ok()) out[r].report = std::move(*report);
    });
  }
  for (auto& t : threads) t.join();
  return out;
}

std::string Bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

std::vector<std::string> FilesIn(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// Every query's ids on the store at `path`.
std::vector<std::vector<ObjectId>> Answers(const std::string& path, const Box3d& bounds) {
  auto db = Database::Open(path);
  EXPECT_TRUE(db.ok()) << db.status().message();
  if (!db.ok()) return {};
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<std::vector<ObjectId>> answers;
  for (int i = 0; i < 300; ++i) {
    Box3d b;
    const double side = 0.5 + unit(rng) * 20;
    for (int a = 0; a < 3; ++a) {
      b.min[a] = bounds.min[a] + unit(rng) * (bounds.max[a] - bounds.min[a]);
      b.max[a] = b.min[a] + side;
    }
    const Query q =
        i % 2 ? Query::Box(b, QueryMode::kExact) : Query::Point(Vec3d{b.min[0], b.min[1], b.min[2]});
    std::vector<ObjectId> ids;
    EXPECT_TRUE((*db)
                    ->Visit(
                        q, [&](ObjectId id) { ids.push_back(id); }, nullptr)
                    .ok());
    std::sort(ids.begin(), ids.end());
    answers.push_back(std::move(ids));
  }
  return answers;
}

class DistributedBuild : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(BuildFromFiles({kScene}, dir_.file("plain.mkt"), Options(0)).ok());
    auto db = Database::Open(dir_.file("plain.mkt"));
    ASSERT_TRUE(db.ok());
    bounds_ = (*db)->bounds();
    plain_answers_ = Answers(dir_.file("plain.mkt"), bounds_);
  }

  static BuildOptions Options(uint32_t shards) {
    BuildOptions o;
    o.backend = BuildOptions::Backend::kPagedFile;
    o.threads = 1;
    o.shards = shards;
    return o;
  }

  // The single-process sharded build of `inputs` (built once).
  const std::string& Reference(const std::vector<std::string>& inputs) {
    std::string& path = references_[inputs[0]];
    if (path.empty()) {
      path = dir_.file("one" + std::to_string(references_.size()) + ".mkts");
      const auto built = BuildFromFiles(inputs, path, Options(kShards));
      EXPECT_TRUE(built.ok()) << built.status().message();
    }
    return path;
  }

  // The manifest built on `ranks` ranks into its own folder: every shard store byte for byte the
  // single-process build's, the same top levels and shard sizes, the unsharded store's answers.
  void ExpectTheSingleProcessBuild(int ranks, const std::vector<std::string>& inputs, PartMode mode,
                                   uint64_t round_bytes = kExchangeRoundBytes) {
    SCOPED_TRACE("ranks " + std::to_string(ranks) + ", " + inputs[0]);
    TempDir out("mktree_distributed");
    const std::string manifest = out.file("mpi.mkts");
    const std::vector<RankOutcome> ranks_out = BuildOnRanks(ranks, inputs, manifest, kShards, round_bytes);
    for (const RankOutcome& r : ranks_out) ASSERT_TRUE(r.status.ok()) << r.status.message();
    const DistributedBuildReport& report = ranks_out[0].report;
    EXPECT_EQ(report.mode, mode);
    EXPECT_EQ(report.manifest.objects, kObjects);
    if (ranks > 1 && mode == PartMode::kByteRanges) {
      EXPECT_GT(report.rounds, 3u);
    }
    const std::string& reference = Reference(inputs);
    auto one = ReadManifest(reference);
    ASSERT_TRUE(one.ok()) << one.status().message();
    auto m = ReadManifest(manifest);
    ASSERT_TRUE(m.ok()) << m.status().message();
    ASSERT_EQ(m->shards.size(), one->shards.size());
    ASSERT_EQ(m->top.nodes.size(), one->top.nodes.size());
    for (size_t n = 0; n < one->top.nodes.size(); ++n) EXPECT_EQ(m->top.nodes[n].cut, one->top.nodes[n].cut);
    EXPECT_EQ(m->origin.x, one->origin.x);
    for (uint32_t s = 0; s < kShards; ++s) {
      EXPECT_EQ(m->shards[s].objects, one->shards[s].objects) << "shard " << s;
      EXPECT_TRUE(Bytes(ShardStorePath(manifest, s)) == Bytes(ShardStorePath(reference, s))) << "shard " << s;
    }
    EXPECT_EQ(Answers(manifest, bounds_), plain_answers_);
    // Nothing but the manifest and its shards: no spill, no staging file, no lock.
    EXPECT_EQ(FilesIn(out).size(), 1u + 2 * kShards);
  }

  static constexpr uint32_t kShards = 5;
  static constexpr uint64_t kObjects = 3000;
  static constexpr char kScene[] = "tanker:3000:4";
  TempDir dir_{"mktree_distributed"};
  std::map<std::string, std::string> references_;  // first input -> its single-process sharded build
  Box3d bounds_;
  std::vector<std::vector<ObjectId>> plain_answers_;
};

TEST_F(DistributedBuild, TankerByIdRangesIsTheSingleProcessBuild) {
  for (int ranks = 1; ranks <= 4; ++ranks) ExpectTheSingleProcessBuild(ranks, {kScene}, PartMode::kIdRanges);
}

TEST_F(DistributedBuild, MksByByteRangesIsTheSingleProcessBuild) {
  const std::string mks = dir_.file("scene.mks");
  {
    auto w = MkSceneWriter::Create(mks);
    ASSERT_TRUE(w.ok());
    auto source = MakeTankerSource(kObjects, 4);
    for (SceneObject o; *source->Next(&o);) ASSERT_TRUE((*w)->Write(o).ok());
    ASSERT_TRUE((*w)->Finish().ok());
  }
  // Small rounds: many of them, the receivers' streams still in id order.
  for (int ranks = 1; ranks <= 4; ++ranks)
    ExpectTheSingleProcessBuild(ranks, {mks}, PartMode::kByteRanges, 64 << 10);
}

TEST_F(DistributedBuild, SeveralInputsAreReadByRankZeroAndScattered) {
  // The scene in two parts: ids continue from the first input into the second.
  const std::string a = dir_.file("a.mks"), b = dir_.file("b.mks");
  {
    auto wa = MkSceneWriter::Create(a), wb = MkSceneWriter::Create(b);
    ASSERT_TRUE(wa.ok() && wb.ok());
    auto source = MakeTankerSource(kObjects, 4);
    for (SceneObject o; *source->Next(&o);) ASSERT_TRUE((o.id < 1000 ? *wa : *wb)->Write(o).ok());
    ASSERT_TRUE((*wa)->Finish().ok() && (*wb)->Finish().ok());
  }
  for (int ranks = 1; ranks <= 3; ++ranks) ExpectTheSingleProcessBuild(ranks, {a, b}, PartMode::kRankZero);
}

TEST(DistributedBuildErrors, TooManyShardsFailsEveryRankAndLeavesNothing) {
  TempDir out("mktree_distributed");
  for (int ranks = 1; ranks <= 4; ++ranks) {
    const std::vector<RankOutcome> r = BuildOnRanks(ranks, {"tanker:3:1"}, out.file("bad.mkts"), 5, 1 << 20);
    ASSERT_FALSE(r[0].status.ok());
    EXPECT_NE(r[0].status.message().find("cannot make 5 shards"), std::string::npos) << r[0].status.message();
    ASSERT_EQ(r[0].errors.size(), 1u);
    for (int q = 1; q < ranks; ++q) {
      EXPECT_FALSE(r[q].status.ok());
      EXPECT_TRUE(r[q].errors.empty());
    }
    EXPECT_TRUE(FilesIn(out).empty());
  }
}

TEST(DistributedBuildErrors, AMalformedTankerSpecIsEveryRanksError) {
  TempDir out("mktree_distributed");
  const std::vector<RankOutcome> r = BuildOnRanks(2, {"tanker:0"}, out.file("bad.mkts"), 2, 1 << 20);
  for (const RankOutcome& o : r) {
    ASSERT_EQ(o.errors.size(), 1u);
    EXPECT_EQ(o.errors[0], "tanker:0: expected tanker:N or tanker:N:SEED, N from 1 to 2^32");
  }
  EXPECT_TRUE(FilesIn(out).empty());
}

TEST(ExchangeRecord, SpillReadsBackEveryObjectAsEncoded) {
  TempDir out("mktree_distributed");
  const std::string path = out.file("spill");
  std::vector<SceneObject> objects;
  auto source = MakeTankerSource(200, 9);
  for (SceneObject o; *source->Next(&o);) objects.push_back(o);
  objects[3].attributes = {{"deck", "2"}, {"", "empty key"}};
  {
    std::ofstream f(path, std::ios::binary);
    for (const SceneObject& o : objects) {
      std::vector<uint8_t> record;
      EncodeExchangeRecord(o, &record);
      const uint32_t n = static_cast<uint32_t>(record.size());
      f.write(reinterpret_cast<const char*>(&n), 4);
      f.write(reinterpret_cast<const char*>(record.data()), n);
    }
  }
  auto spill = OpenExchangeSpill(path);
  ASSERT_TRUE(spill.ok());
  size_t i = 0;
  for (SceneObject o; *(*spill)->Next(&o); ++i) {
    ASSERT_LT(i, objects.size());
    EXPECT_EQ(o.id, objects[i].id);
    EXPECT_EQ(o.name, objects[i].name);
    EXPECT_EQ(o.source, objects[i].source);
    ASSERT_EQ(o.attributes.size(), objects[i].attributes.size());
    for (size_t a = 0; a < o.attributes.size(); ++a)
      EXPECT_EQ(o.attributes[a].value, objects[i].attributes[a].value);
    EXPECT_EQ(o.mesh.vertices, objects[i].mesh.vertices);
    EXPECT_EQ(o.mesh.triangles, objects[i].mesh.triangles);
  }
  EXPECT_EQ(i, objects.size());
}

}  // namespace
}  // namespace mktree
