#include "engine/ingest/distributed_build.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/exchange_record.h"
#include "engine/scene/mkscene_format.h"
#include "engine/shard/rank_message.h"

namespace mktree {

namespace {

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

class EmptySource final : public SceneSource {
 public:
  Result<bool> Next(SceneObject*) override { return false; }
};

// A part that could not be opened: its error at the first Next().
class ErrorSource final : public SceneSource {
 public:
  explicit ErrorSource(Status st) : st_(std::move(st)) {}
  Result<bool> Next(SceneObject*) override { return st_; }

 private:
  Status st_;
};

// Several sources one after the other (the senders' streams, in rank order).
class Concat final : public SceneSource {
 public:
  explicit Concat(std::vector<ShardObjects> parts) : parts_(std::move(parts)) {}
  Result<bool> Next(SceneObject* o) override {
    for (;;) {
      if (!current_) {
        if (next_ == parts_.size()) return false;
        MKTREE_ASSIGN_OR_RETURN(current_, parts_[next_++]());
      }
      MKTREE_ASSIGN_OR_RETURN(const bool more, current_->Next(o));
      if (more) return true;
      current_.reset();
    }
  }

 private:
  std::vector<ShardObjects> parts_;
  size_t next_ = 0;
  std::unique_ptr<SceneSource> current_;
};

bool HasMksExtension(const std::string& input) {
  const std::string ext = std::filesystem::path(input).extension().string();
  return ext.size() == 4 && std::tolower(static_cast<unsigned char>(ext[1])) == 'm' &&
         std::tolower(static_cast<unsigned char>(ext[2])) == 'k' &&
         std::tolower(static_cast<unsigned char>(ext[3])) == 's';
}

void Note(const RankBuild& b, const std::string& text) {
  if (b.options.note) b.options.note(text);
}
void Warn(const RankBuild& b, const std::string& text) {
  if (b.options.warning) b.options.warning(text);
}

// The inputs, the output's check and, on rank 0, the build's lock and what killed builds left: before any
// rank stages a file (the collective that ends this).
bool OpenInputsAndLock(RankBuild* b, std::unique_ptr<ShardBuildLock>* lock) {
  const DistributedBuildOptions& o = b->options;
  for (const std::string& in : o.inputs) {
    auto input = SceneInputFor(in, IngestSpillDir(o.manifest_path, ""));
    if (!input.ok())
      b->errors.Fail(input.status());
    else
      b->inputs.push_back(std::move(*input));
  }
  if (std::filesystem::is_directory(o.manifest_path))
    b->errors.Fail(Status::InvalidArgument(o.manifest_path + ": not a regular file"));
  if (b->exchange->rank() == 0 && b->errors.ok()) {
    auto l = ShardBuildLock::Acquire(o.manifest_path);
    if (!l.ok())
      b->errors.Fail(l.status());
    else
      *lock = std::move(*l);
    if (b->errors.ok()) RemoveShardLeftovers(o.manifest_path);
  }
  return b->errors.AllOk();
}

// One .mks by byte ranges: this rank's part found by resync, every rank's part checked to chain (else
// rank 0 reads the input whole), the part's first id after the exclusive sum of the parts' counts.
bool PartitionMks(RankBuild* b) {
  RankExchange& x = *b->exchange;
  const int rank = x.rank(), ranks = x.ranks();
  const uint64_t nr = static_cast<uint64_t>(ranks);
  const std::string path = b->inputs[0].path;
  MkSceneLayout layout;
  auto l = ReadMkSceneLayout(path);
  if (!l.ok())
    b->errors.Fail(l.status());
  else if (l->objects > uint64_t{kNoIndex})
    b->errors.Fail(Status::InvalidArgument(path + ": too many objects: ids are 32-bit"));
  else
    layout = *l;
  if (!b->errors.AllOk()) return false;
  const uint64_t body = layout.body_end - layout.body_begin;
  auto range_begin = [&](uint64_t q) {
    return layout.body_begin + static_cast<uint64_t>(static_cast<unsigned __int128>(body) * q / nr);
  };
  MkScenePart mks;
  auto p = FindMkScenePart(path, layout, range_begin(static_cast<uint64_t>(rank)),
                           range_begin(static_cast<uint64_t>(rank) + 1));
  if (!p.ok())
    b->errors.Fail(p.status());
  else
    mks = *p;
  if (!b->errors.AllOk()) return false;
  const std::vector<uint64_t> all = x.AllGather({mks.found ? 1u : 0u, mks.begin, mks.end, mks.objects});
  std::vector<MkScenePart> parts(ranks);
  std::vector<uint64_t> begins(ranks);
  for (int q = 0; q < ranks; ++q) {
    parts[q] = {all[4 * q] != 0, all[4 * q + 1], all[4 * q + 2], all[4 * q + 3]};
    begins[q] = range_begin(static_cast<uint64_t>(q));
  }
  // Every rank sees the same parts and decides alike. Parts that do not chain (a damaged file, or a
  // record-like pattern with a matching checksum inside a record) fall back to rank 0's whole read,
  // which reports damage with the object and offset.
  const Status chained = CheckMkSceneParts(path, layout, begins, parts);
  if (!chained.ok() && rank == 0) Note(*b, chained.message() + "; rank 0 reads the input whole");
  const uint64_t first = x.ExclusiveSum(mks.objects);
  if (!chained.ok()) return true;
  b->part.mode = PartMode::kByteRanges;
  b->part.open = [path, layout, mks, first]() -> std::unique_ptr<SceneSource> {
    auto source = OpenMkScenePart(path, layout, mks, first, static_cast<ObjectId>(first));
    if (!source.ok()) return std::make_unique<ErrorSource>(source.status());
    return std::move(*source);
  };
  return true;
}

// Rank 0's top levels, frame, build id and object count, or a failure byte, as broadcast.
std::vector<uint8_t> ManifestHead(RankBuild* b, uint64_t objects, const ShardSample& merged,
                                  const Box3d& first) {
  std::vector<uint8_t> head;
  auto top =
      objects == 0
          ? Result<TopLevels>(Status::InvalidArgument(
                b->options.manifest_path + " not built: empty scene, no object with geometry in the input"))
          : ChooseTopLevels(merged.Items(), b->options.shards);
  if (!top.ok()) {
    b->errors.Fail(top.status());
    Put<uint8_t>(&head, 0);
    return head;
  }
  Put<uint8_t>(&head, 1);
  Put<uint64_t>(&head, objects);
  const Vec3d origin = ChooseStoreOrigin(first);  // rank 0's part starts at object 0
  for (int k = 0; k < 3; ++k) Put<double>(&head, origin[k]);
  Put<uint64_t>(&head, NewBuildId());
  for (const TopNode& t : top->nodes) {
    Put(&head, t.axis);
    Put(&head, static_cast<uint8_t>(t.key));
    Put(&head, t.cut);
    Put(&head, t.child[0]);
    Put(&head, t.child[1]);
    Put(&head, t.shard);
  }
  return head;
}

// The broadcast head into the manifest; false for rank 0's failure byte.
bool ReadManifestHead(const std::vector<uint8_t>& head, uint32_t shards, Manifest* m) {
  size_t at = 0;
  if (Get<uint8_t>(head, &at) != 1) return false;
  m->objects = Get<uint64_t>(head, &at);
  for (int k = 0; k < 3; ++k) m->origin[k] = Get<double>(head, &at);
  m->build_id = Get<uint64_t>(head, &at);
  m->top.shard_count = shards;
  while (at < head.size()) {
    TopNode t;
    t.axis = Get<uint8_t>(head, &at);
    t.key = static_cast<ShardKey>(Get<uint8_t>(head, &at));
    t.cut = Get<double>(head, &at);
    t.child[0] = Get<uint32_t>(head, &at);
    t.child[1] = Get<uint32_t>(head, &at);
    t.shard = Get<uint32_t>(head, &at);
    m->top.nodes.push_back(t);
  }
  return true;
}

// The objects of this rank's part for other ranks' shards, in rounds; received ones appended to their
// (shard, sender) spill. Failures go to b->errors; the rounds end on every rank alike.
void RunExchangeRounds(RankBuild* b) {
  RankExchange& x = *b->exchange;
  const int rank = x.rank(), ranks = x.ranks();
  const uint32_t shards = b->options.shards;
  const std::string& output = b->options.manifest_path;
  DistributedBuildReport& r = b->report;
  std::vector<std::FILE*> spills(static_cast<size_t>(shards) * ranks, nullptr);
  std::unique_ptr<SceneSource> source = b->part.open();
  std::vector<std::vector<uint8_t>> out(ranks);
  std::vector<uint8_t> record;
  SceneObject obj;
  bool done = false;
  uint64_t sent_bytes = 0, sent_objects = 0;
  const size_t cap = std::max<uint64_t>(1, b->options.round_bytes / static_cast<uint64_t>(ranks));
  for (r.rounds = 1;; ++r.rounds) {
    for (bool full = false; b->errors.ok() && !done && !full;) {
      auto more = source->Next(&obj);
      if (!more.ok()) {
        b->errors.Fail(more.status());
        break;
      }
      if (!*more) {
        done = true;
        break;
      }
      const uint32_t s = b->manifest.top.ShardOf(obj.mesh.Bounds());
      const int to = RankOfShard(s, shards, ranks);
      if (to == rank) continue;  // read again when its shard is built
      record.clear();
      EncodeExchangeRecord(obj, &record);
      Put<uint32_t>(&out[to], s);
      Put<uint32_t>(&out[to], static_cast<uint32_t>(record.size()));
      out[to].insert(out[to].end(), record.begin(), record.end());
      full = out[to].size() >= cap;
      sent_bytes += record.size() + 8;
      ++sent_objects;
    }
    const bool all_ok = x.Min(b->errors.ok() ? 1 : 0) == 1, all_done = x.Min(done ? 1 : 0) == 1;
    if (!all_ok) break;
    const std::vector<std::vector<uint8_t>> in = x.AllToAll(out);
    for (auto& o : out) o.clear();
    for (int from = 0; from < ranks && b->errors.ok(); ++from) {
      const std::vector<uint8_t>& got = in[from];
      for (size_t p = 0; p < got.size() && b->errors.ok();) {
        uint32_t s = 0, len = 0;
        std::memcpy(&s, got.data() + p, 4);
        std::memcpy(&len, got.data() + p + 4, 4);
        if (s >= shards || RankOfShard(s, shards, ranks) != rank) {
          b->errors.Fail(Status::Internal("an exchanged object for shard " + std::to_string(s) +
                                          " reached the wrong rank"));
          break;
        }
        std::FILE*& f = spills[size_t{s} * ranks + from];
        const std::string path = ExchangeSpillPath(output, s, from);
        if (!f && !(f = std::fopen(path.c_str(), "wb"))) {
          b->errors.Fail(Status::IOError(path + ": " + std::strerror(errno)));
          break;
        }
        if (std::fwrite(got.data() + p + 4, 1, size_t{len} + 4, f) != size_t{len} + 4)
          b->errors.Fail(Status::IOError(path + ": write failed: " + std::strerror(errno)));
        p += size_t{len} + 8;
      }
    }
    if (all_done) break;
  }
  for (size_t i = 0; i < spills.size(); ++i)
    if (spills[i] && std::fclose(spills[i]) != 0 && b->errors.ok())
      b->errors.Fail(Status::IOError(
          ExchangeSpillPath(output, static_cast<uint32_t>(i / ranks), static_cast<int>(i % ranks)) +
          ": write failed: " + std::strerror(errno)));
  r.moved_bytes = sent_bytes;
  r.moved_objects = sent_objects;
}

void PutEntry(std::vector<uint8_t>* entries, uint32_t s, const ShardEntry& e) {
  Put(entries, s);
  for (const ShardFileInfo* f : {&e.store, &e.ids}) {
    PutString(entries, f->name);
    Put(entries, f->bytes);
    Put(entries, f->fingerprint);
  }
  Put(entries, e.objects);
  for (int k = 0; k < 3; ++k) Put(entries, e.box.min[k]);
  for (int k = 0; k < 3; ++k) Put(entries, e.box.max[k]);
}

void GetEntries(const std::vector<uint8_t>& b, std::vector<ShardEntry>* shards) {
  for (size_t p = 0; p < b.size();) {
    ShardEntry& e = (*shards)[Get<uint32_t>(b, &p)];
    for (ShardFileInfo* f : {&e.store, &e.ids}) {
      f->name = GetString(b, &p);
      f->bytes = Get<uint64_t>(b, &p);
      f->fingerprint = Get<uint64_t>(b, &p);
    }
    e.objects = Get<uint64_t>(b, &p);
    for (int k = 0; k < 3; ++k) e.box.min[k] = Get<float>(b, &p);
    for (int k = 0; k < 3; ++k) e.box.max[k] = Get<float>(b, &p);
  }
}

void RemovePlacedShards(const RankBuild& b) {
  for (uint32_t s : b.own) {
    std::error_code ec;
    std::filesystem::remove(ShardStorePath(b.options.manifest_path, s), ec);
    std::filesystem::remove(ShardIdsPath(b.options.manifest_path, s), ec);
  }
}

}  // namespace

std::string ExchangeSpillPath(const std::string& manifest_path, uint32_t shard, int sender) {
  return ShardStorePath(manifest_path, shard) + ".from-" + std::to_string(sender) + ".new";
}

const char* PartModeName(PartMode mode) {
  switch (mode) {
    case PartMode::kIdRanges:
      return "disjoint id ranges";
    case PartMode::kByteRanges:
      return "disjoint byte ranges";
    case PartMode::kRankZero:
      break;
  }
  return "read by rank 0";
}

bool RankErrors::Fail(const Status& status) {
  if (report_) report_(status.message());
  if (first_.ok()) first_ = status.ok() ? Status::Internal("failed") : status;
  return false;
}

Status RankErrors::Failure() const { return ok() ? Status::Internal("another rank failed") : first_; }

Result<SceneInput> SceneInputFor(const std::string& input, const std::string& spill_dir) {
  SceneInput in;
  if (IsTankerSpec(input)) {
    const std::optional<TankerSpec> spec = ParseTankerSpec(input);
    if (!spec)
      return Status::InvalidArgument(input + ": expected tanker:N or tanker:N:SEED, N from 1 to 2^32");
    in.tanker = true;
    in.spec = *spec;
    in.opener = [spec = *spec](ObjectId first) { return MakeTankerSource(spec.objects, spec.seed, first); };
  } else {
    in.opener = [input, spill_dir](ObjectId first) { return OpenSceneFile(input, first, spill_dir); };
    in.path = input;
    in.mks = HasMksExtension(input);
  }
  return in;
}

bool PartitionScene(RankBuild* b) {
  RankExchange& x = *b->exchange;
  const int rank = x.rank(), ranks = x.ranks();
  if (b->inputs.size() == 1 && b->inputs[0].tanker) {
    const uint64_t n = b->inputs[0].spec.objects, seed = b->inputs[0].spec.seed;
    const uint64_t r = static_cast<uint64_t>(rank), nr = static_cast<uint64_t>(ranks);
    const uint64_t lo = (n * r + nr - 1) / nr, hi = (n * (r + 1) + nr - 1) / nr;
    b->part.mode = PartMode::kIdRanges;
    b->part.open = [n, seed, lo, hi] { return MakeTankerRangeSource(n, seed, lo, hi); };
    return true;
  }
  if (b->inputs.size() == 1 && b->inputs[0].mks) {
    if (!PartitionMks(b)) return false;
    if (b->part.mode == PartMode::kByteRanges) return true;
  }
  b->part.mode = PartMode::kRankZero;
  if (rank == 0) {
    std::vector<SceneOpener> openers;
    for (const SceneInput& in : b->inputs) openers.push_back(in.opener);
    b->part.open = [openers] { return ChainInputs(openers); };
  } else {
    b->part.open = [] { return std::unique_ptr<SceneSource>(std::make_unique<EmptySource>()); };
  }
  if (rank == 0 && ranks > 1)
    Note(*b, std::string("only tanker:N and one .mks are read in parts; rank 0 reads ") +
                 (b->inputs.size() == 1 ? "the input" : "the inputs") + " and scatters it");
  return true;
}

void MergeSamplesToRankZero(ShardSample* merged, RankExchange* x) {
  const int rank = x->rank(), ranks = x->ranks();
  for (int step = 1; step < ranks; step *= 2) {
    if (rank % (2 * step) == step) {
      std::vector<uint8_t> bytes;
      for (const ShardSample::Item& i : merged->Items()) {
        Put(&bytes, i.id);
        for (int k = 0; k < 3; ++k) Put(&bytes, i.box.min[k]);
        for (int k = 0; k < 3; ++k) Put(&bytes, i.box.max[k]);
      }
      x->Send(rank - step, bytes);
      *merged = ShardSample();
      return;
    }
    if (rank % (2 * step) == 0 && rank + step < ranks) {
      const std::vector<uint8_t> b = x->Receive(rank + step);
      ShardSample sample;
      for (size_t at = 0; at < b.size();) {
        const ObjectId id = Get<ObjectId>(b, &at);
        Box3d box;
        for (int k = 0; k < 3; ++k) box.min[k] = Get<double>(b, &at);
        for (int k = 0; k < 3; ++k) box.max[k] = Get<double>(b, &at);
        sample.Add(id, box);
      }
      merged->Merge(sample);
    }
  }
}

bool ChooseTopLevelsOnRanks(RankBuild* b) {
  RankExchange& x = *b->exchange;
  const auto start = Clock::now();
  auto scan = [&] {
    auto source = b->part.open();
    return ScanPart(source.get(), b->options.ingest);
  }();
  if (!scan.ok()) b->errors.Fail(scan.status());
  if (!b->errors.AllOk()) return false;
  for (const std::string& w : scan->warnings) Warn(*b, w);
  const uint64_t objects = x.Sum(scan->objects);
  b->report.scan_seconds = x.Max(Since(start));
  MergeSamplesToRankZero(&scan->sample, &x);
  std::vector<uint8_t> head;
  if (x.rank() == 0) head = ManifestHead(b, objects, scan->sample, scan->first);
  x.Broadcast(&head);
  if (!ReadManifestHead(head, b->options.shards, &b->manifest)) return false;
  for (uint32_t s = 0; s < b->options.shards; ++s)
    if (RankOfShard(s, b->options.shards, x.ranks()) == x.rank()) b->own.push_back(s);
  return true;
}

void DiscardRankFiles(const RankBuild& b) {
  for (uint32_t s : b.own) {
    DiscardShard(b.options.manifest_path, s);
    for (int from = 0; from < b.exchange->ranks(); ++from) {
      std::error_code ec;
      std::filesystem::remove(ExchangeSpillPath(b.options.manifest_path, s, from), ec);
    }
  }
}

bool ExchangeObjects(RankBuild* b) {
  const auto start = Clock::now();
  RunExchangeRounds(b);
  if (!b->errors.AllOk()) {
    DiscardRankFiles(*b);
    return false;
  }
  if (b->options.checkpoint) b->options.checkpoint("exchanged");
  RankExchange& x = *b->exchange;
  b->report.exchange_seconds = x.Max(Since(start));
  b->report.moved_bytes = x.Sum(b->report.moved_bytes);
  b->report.moved_objects = x.Sum(b->report.moved_objects);
  return true;
}

// Shard s's objects on this rank, its own and those the other ranks sent, in increasing id.
ShardObjects ShardObjectsOnRank(RankBuild* b, uint32_t s) {
  const int rank = b->exchange->rank(), ranks = b->exchange->ranks();
  const std::string& output = b->options.manifest_path;
  std::vector<ShardObjects> streams;
  for (int from = 0; from < ranks; ++from) {
    if (from == rank) {
      streams.push_back([b, s]() -> Result<std::unique_ptr<SceneSource>> {
        return ShardObjectsOf(b->part.open(), b->manifest.top, s);
      });
    } else if (std::filesystem::exists(ExchangeSpillPath(output, s, from))) {
      streams.push_back([path = ExchangeSpillPath(output, s, from)] { return OpenExchangeSpill(path); });
    }
  }
  return [streams]() -> Result<std::unique_ptr<SceneSource>> {
    return std::unique_ptr<SceneSource>(std::make_unique<Concat>(streams));
  };
}

// Collective: the dictionary every shard encodes with, as the single-process build gives it
// (TrainShardDictionary): rank 0, which owns shard 0, trains it and sends it to every rank. Byte 0 says
// whether rank 0 succeeded, byte 1 whether there is a dictionary; its bytes follow.
bool ShareShardDictionary(RankBuild* b, IngestOptions* ingest) {
  RankExchange& x = *b->exchange;
  std::vector<uint8_t> message{0, 0};
  if (x.rank() == 0 && b->errors.ok()) {
    auto trained = TrainShardDictionary(ShardObjectsOnRank(b, 0), b->manifest, b->options.ingest);
    if (!trained.ok()) {
      b->errors.Fail(trained.status());
    } else {
      message[0] = 1;
      if (*trained) {
        message[1] = 1;
        message.insert(message.end(), (*trained)->bytes().begin(), (*trained)->bytes().end());
      }
      ingest->dictionary = *trained;
    }
  }
  x.Broadcast(&message);
  if (message[0] != 1) {
    if (x.rank() != 0) b->errors.Fail(Status::Internal("rank 0 could not train the shards' dictionary"));
    return false;
  }
  if (x.rank() != 0) {
    std::shared_ptr<const CodecDictionary> dictionary;
    if (message[1] == 1) {
      auto loaded = CodecDictionary::Load(std::vector<uint8_t>(message.begin() + 2, message.end()),
                                          ingest->store.codec.zstd_level);
      if (!loaded.ok()) {
        b->errors.Fail(loaded.status());
        return false;
      }
      dictionary = *loaded;
    }
    ingest->dictionary = dictionary;
  }
  return true;
}

bool BuildRankShards(RankBuild* b) {
  RankExchange& x = *b->exchange;
  const int rank = x.rank(), ranks = x.ranks();
  const std::string& output = b->options.manifest_path;
  const Manifest& m = b->manifest;
  const auto start = Clock::now();
  IngestOptions ingest = b->options.ingest;
  const bool shared = ingest.dictionary.has_value() || ShareShardDictionary(b, &ingest);
  if (!b->errors.AllOk() || !shared) {
    DiscardRankFiles(*b);
    return false;
  }
  std::vector<uint8_t> entries;
  for (uint32_t s : b->own) {
    IngestReport report;
    auto e = BuildShardFrom(ShardObjectsOnRank(b, s), output, m, s, ingest, &report);
    for (int from = 0; from < ranks; ++from) {
      std::error_code ec;
      std::filesystem::remove(ExchangeSpillPath(output, s, from), ec);
    }
    if (!e.ok()) {
      b->errors.Fail(e.status());
      break;
    }
    for (const std::string& w : report.warnings) Warn(*b, "shard " + std::to_string(s) + ": " + w);
    if (b->options.checkpoint) b->options.checkpoint("staged");
    PutEntry(&entries, s, *e);
  }
  if (!b->errors.AllOk()) {
    DiscardRankFiles(*b);
    return false;
  }
  b->report.shard_seconds = x.Max(Since(start));
  const std::vector<std::vector<uint8_t>> gathered = x.Gather(entries);
  if (rank == 0) {
    b->manifest.shards.resize(b->options.shards);
    for (const auto& g : gathered) GetEntries(g, &b->manifest.shards);
  }
  return true;
}

bool CommitShards(RankBuild* b) {
  for (uint32_t s : b->own)
    if (b->errors.ok()) {
      Status st = PublishShard(b->options.manifest_path, s);
      if (!st.ok()) b->errors.Fail(st);
    }
  if (!b->errors.AllOk()) {  // placed or staged: none of this build's files stays
    RemovePlacedShards(*b);
    DiscardRankFiles(*b);
    return false;
  }
  std::vector<uint8_t> written{1};
  if (b->exchange->rank() == 0) {
    Status st = WriteManifest(b->options.manifest_path, b->manifest);
    if (!st.ok()) written[0] = (b->errors.Fail(st), 0);
  }
  b->exchange->Broadcast(&written);
  if (written[0] != 1) RemovePlacedShards(*b);
  return written[0] == 1;
}

Result<DistributedBuildReport> BuildShardedOnRanks(const DistributedBuildOptions& options,
                                                   RankExchange* exchange) {
  RankBuild b(options, exchange);
  std::unique_ptr<ShardBuildLock> lock;  // rank 0's, to the end
  if (!OpenInputsAndLock(&b, &lock) || !PartitionScene(&b) || !ChooseTopLevelsOnRanks(&b) ||
      !ExchangeObjects(&b) || !BuildRankShards(&b) || !CommitShards(&b))
    return b.errors.Failure();
  b.report.manifest = std::move(b.manifest);
  b.report.mode = b.part.mode;
  return std::move(b.report);
}

}  // namespace mktree
