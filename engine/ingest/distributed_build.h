// The sharded build (docs/shards.md) spread over ranks, as steps that need no MPI: the ranks talk through
// a RankExchange (engine/shard/rank_exchange.h), which tools/mpi implements over MPI and a test over
// threads. Every rank runs BuildShardedOnRanks with the same options:
// 1. PartitionScene: each rank reads a disjoint part of the scene (tanker:N: the id range
//    [ceil(N r / R), ceil(N (r+1) / R)); one .mks: the records starting in bytes [floor(B r / R),
//    floor(B (r+1) / R)) of its body, found by resync, the parts checked to chain and numbered after an
//    exclusive sum of their counts; any other input: rank 0 reads it all and the exchange scatters it).
// 2. ChooseTopLevelsOnRanks: each rank samples its part; the samples merge up a binary tree to rank 0,
//    which chooses the top levels and broadcasts them with the scene's frame and the build id.
// 3. ExchangeObjects: each rank routes its objects (TopLevels::ShardOf) to the rank of their shard
//    (RankOfShard) in bounded all-to-all rounds; the receiver spills them per (shard, sender).
// 4. BuildRankShards: each rank builds its shards, under staging names, from the senders' streams in rank
//    order, which is global id order (the parts are increasing id ranges); its own objects are read again
//    rather than spilled.
// 5. CommitShards: every rank puts its shards in place, then rank 0 writes the manifest. A failed rank
//    makes every rank remove its staged files, and no manifest is written.
// Rank 0 holds the build's lock (ShardBuildLock) throughout and first removes what killed builds left.
// Thread-safety: one call a rank; the ranks' calls run concurrently and meet in the exchange's collectives.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "engine/generator/tanker_spec.h"
#include "engine/ingest/shard_build.h"
#include "engine/ingest/store_builder.h"
#include "engine/shard/manifest.h"
#include "engine/shard/rank_exchange.h"

namespace mktree {

// Bytes a rank sends in one exchange round at most (and so receives: each sender sends a rank at most
// round_bytes / R, plus one object), whatever the scene's size and R; the receiver spills them.
inline constexpr uint64_t kExchangeRoundBytes = uint64_t{32} << 20;

// The rank of shard s of K on R ranks: shards in blocks, floor(s R / K), so that neighbouring shards are on
// one rank and an input whose nearby ids are nearby in space (a model exported deck by deck, the tanker)
// moves few objects in the build's exchange. The query batch uses the same rank, where the build wrote it.
inline int RankOfShard(uint32_t shard, uint32_t shards, int ranks) {
  return static_cast<int>(uint64_t{shard} * static_cast<uint64_t>(ranks) / shards);
}

// "<manifest>.shard-S.mkt.from-R.new": the objects of shard S that rank R sent, as its owner spilled them.
std::string ExchangeSpillPath(const std::string& manifest_path, uint32_t shard, int sender);

struct DistributedBuildOptions {
  std::vector<std::string> inputs;  // scene files or "tanker:N[:SEED]"
  std::string manifest_path;
  uint32_t shards = 0;  // 1 to 65536
  IngestOptions ingest;
  uint64_t round_bytes = kExchangeRoundBytes;
  // This rank's errors, its inputs' warnings, and rank 0's notes on how the scene was read, as they come.
  std::function<void(const std::string&)> error, warning, note;
  // Called on the rank at "exchanged" (its spills received) and "staged" (after each of its shards is built
  // under its staging names): tests kill a rank at the first.
  std::function<void(const char* point)> checkpoint;
};

// How the ranks read the scene.
enum class PartMode { kIdRanges, kByteRanges, kRankZero };
// "disjoint id ranges", "disjoint byte ranges", "read by rank 0".
const char* PartModeName(PartMode mode);

struct DistributedBuildReport {
  Manifest manifest;  // whole on rank 0; the shards' entries are missing on the others
  PartMode mode = PartMode::kRankZero;
  // Over every rank:
  uint64_t moved_objects = 0, moved_bytes = 0, rounds = 0;
  double scan_seconds = 0, exchange_seconds = 0, shard_seconds = 0;  // the slowest rank's
};

// On failure every rank returns an error: its own first error (already given to options.error), or
// Internal("another rank failed").
Result<DistributedBuildReport> BuildShardedOnRanks(const DistributedBuildOptions& options,
                                                   RankExchange* exchange);

// The steps. A step returns false when the build stops, on every rank alike.

// This rank's errors: each given to the report callback as it comes; AllOk is every rank's verdict.
class RankErrors {
 public:
  RankErrors(RankExchange* exchange, std::function<void(const std::string&)> report)
      : exchange_(exchange), report_(std::move(report)) {}
  // Records (and reports) a failure; returns false.
  bool Fail(const Status& status);
  bool ok() const { return first_.ok(); }
  // Collective: whether no rank failed.
  bool AllOk() { return exchange_->Min(ok() ? 1 : 0) == 1; }
  // This rank's first error, or Internal("another rank failed").
  Status Failure() const;

 private:
  RankExchange* exchange_;
  std::function<void(const std::string&)> report_;
  Status first_;
};

// One input of the build.
struct SceneInput {
  bool tanker = false;  // read by id range
  bool mks = false;     // read by byte range
  std::string path;
  TankerSpec spec;
  SceneOpener opener;
};
// A scene reader's scratch file goes to `spill_dir`; a malformed tanker spec is an InvalidArgument.
Result<SceneInput> SceneInputFor(const std::string& input, const std::string& spill_dir);

// This rank's part of the scene.
struct RankPart {
  PartMode mode = PartMode::kRankZero;
  std::function<std::unique_ptr<SceneSource>()> open;  // each call reads the part from its start
};

// What every step of one rank's build shares.
struct RankBuild {
  RankBuild(const DistributedBuildOptions& o, RankExchange* x)
      : options(o), exchange(x), errors(x, o.error) {}
  const DistributedBuildOptions& options;
  RankExchange* exchange;
  RankErrors errors;
  std::vector<SceneInput> inputs;
  RankPart part;
  Manifest manifest;
  std::vector<uint32_t> own;  // this rank's shards
  DistributedBuildReport report;
};

bool PartitionScene(RankBuild* b);
bool ChooseTopLevelsOnRanks(RankBuild* b);
// Rank 0's sample merged with every rank's (the others' are left empty), up a binary tree (rank r + step
// into rank r), each step one sample of at most kShardSampleSize items: rank 0's memory does not grow with R.
void MergeSamplesToRankZero(ShardSample* sample, RankExchange* exchange);
bool ExchangeObjects(RankBuild* b);
bool BuildRankShards(RankBuild* b);
bool CommitShards(RankBuild* b);
// Removes every file this rank may have staged: its shards' staging files and the spills it received.
void DiscardRankFiles(const RankBuild& b);

}  // namespace mktree
