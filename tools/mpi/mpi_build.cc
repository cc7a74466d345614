// mktree-mpi: the sharded build (docs/shards.md) spread over MPI ranks (CMake option MKTREE_MPI).
//   mpirun -n R mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N]
//                          [--round-bytes B]
// Each rank reads a disjoint part of the scene (tanker:N: the id range [ceil(N r / R), ceil(N (r+1) / R));
// one .mks: the records starting in bytes [floor(B r / R), floor(B (r+1) / R)) of its body, found by resync,
// the parts checked to chain and numbered after MPI_Exscan of their counts; any other input: rank 0 reads
// it all and the exchange scatters it) and samples it; rank 0 merges the
// samples, chooses the top levels and broadcasts them. Each rank then routes its objects (TopLevels::ShardOf)
// to the rank of their shard (shard s on rank floor(s R / K)) in bounded MPI_Alltoallv rounds; the receiver
// spills them per (shard, sender) and builds its shards from the senders' streams in rank order, which is
// global id order (the parts are increasing id ranges); its own objects are read again rather than spilled.
// Rank 0 writes the manifest after every rank has put its shards in place; a failed rank makes every rank
// remove its staged files, and no manifest is written. Rank 0 holds the build's lock (ShardBuildLock)
// throughout and first removes what killed builds of the path left.
#include <mpi.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/shard_build.h"
#include "engine/ingest/store_builder.h"
#include "engine/scene/mkscene_format.h"
#include "engine/scene/scene_source.h"
#include "tools/mpi/mpi_util.h"

namespace mktree {
namespace {

// Bytes a rank sends in one exchange round at most (and so receives: each sender sends a rank at most
// kRoundBytes / R, plus one object), whatever the scene's size and R; the receiver spills them.
constexpr uint64_t kRoundBytes = uint64_t{32} << 20;

struct Args {
  std::vector<std::string> inputs;
  std::string output;
  uint32_t shards = 0;
  std::string backend = "hdf5";
  uint32_t threads = 0;
  uint64_t round_bytes = kRoundBytes;
};

bool ParseU64(const std::string& s, uint64_t* v) {
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *v);
  return !s.empty() && ec == std::errc() && end == s.data() + s.size();
}

bool Parse(int argc, char** argv, Args* a, std::string* err) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](std::string* out) {
      if (i + 1 >= argc) return false;
      *out = argv[++i];
      return true;
    };
    std::string v;
    uint64_t n = 0;
    if (arg == "-o" || arg == "--output") {
      if (!value(&a->output)) return *err = "-o needs a path", false;
    } else if (arg == "--shards") {
      if (!value(&v) || !ParseU64(v, &n) || n == 0 || n > 65536)
        return *err = "--shards must be 1 to 65536", false;
      a->shards = static_cast<uint32_t>(n);
    } else if (arg == "--threads") {
      if (!value(&v) || !ParseU64(v, &n) || n > 65536) return *err = "--threads must be 0 to 65536", false;
      a->threads = static_cast<uint32_t>(n);
    } else if (arg == "--round-bytes") {  // tests: many exchange rounds on a small scene
      if (!value(&v) || !ParseU64(v, &n) || n == 0) return *err = "--round-bytes must be positive", false;
      a->round_bytes = n;
    } else if (arg == "--backend") {
      if (!value(&a->backend) || (a->backend != "hdf5" && a->backend != "pagefile"))
        return *err = "--backend must be hdf5 or pagefile", false;
    } else if (!arg.empty() && arg[0] == '-') {
      return *err = "unknown option " + arg, false;
    } else {
      a->inputs.push_back(arg);
    }
  }
  if (a->inputs.empty() || a->output.empty() || a->shards == 0)
    return *err =
               "usage: mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N] "
               "[--round-bytes B]",
           false;
  return true;
}

// One input: a tanker spec (read by id range), an .mks (by byte range) or another scene file.
struct Input {
  bool tanker = false;
  bool mks = false;
  std::string path;
  uint64_t n = 0, seed = 1;
  SceneOpener opener;
};

// A scene reader's scratch file (OBJ vertices past the reader's budget) goes to `spill_dir`.
Result<Input> InputFor(const std::string& input, const std::string& spill_dir) {
  Input in;
  if (input.rfind("tanker:", 0) == 0) {
    const std::string spec = input.substr(7);
    const size_t colon = spec.find(':');
    if (!ParseU64(spec.substr(0, colon), &in.n) || in.n == 0 || in.n > (uint64_t{1} << 32) ||
        (colon != std::string::npos && !ParseU64(spec.substr(colon + 1), &in.seed)))
      return Status::InvalidArgument(input + ": expected tanker:N or tanker:N:SEED, N from 1 to 2^32");
    in.tanker = true;
    in.opener = [n = in.n, seed = in.seed](ObjectId first) { return MakeTankerSource(n, seed, first); };
  } else {
    in.opener = [input, spill_dir](ObjectId first) { return OpenSceneFile(input, first, spill_dir); };
    in.path = input;
    const std::string ext = std::filesystem::path(input).extension().string();
    in.mks = ext.size() == 4 && std::tolower(static_cast<unsigned char>(ext[1])) == 'm' &&
             std::tolower(static_cast<unsigned char>(ext[2])) == 'k' &&
             std::tolower(static_cast<unsigned char>(ext[3])) == 's';
  }
  return in;
}

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

// Tests (tests/mpi/ranks.sh): MKTREE_MPI_TEST_KILL="RANK:POINT" kills that rank with SIGKILL at that point of
// the build, "exchanged" (the spills received) or "staged" (its first shard built under its staging names).
void KillForTest(int rank, const char* point) {
  const char* k = std::getenv("MKTREE_MPI_TEST_KILL");
  if (k && std::to_string(rank) + ":" + point == k) std::raise(SIGKILL);
}

// Bytes this process has read through read(2) and pread(2) (/proc/self/io rchar), or 0.
uint64_t BytesRead() {
  std::FILE* f = std::fopen("/proc/self/io", "r");
  if (!f) return 0;
  unsigned long long v = 0;
  const bool got = std::fscanf(f, "rchar: %llu", &v) == 1;
  std::fclose(f);
  return got ? v : 0;
}

// The wire and spill encoding of an object: u32 id, name, source, u32 attribute count, (key, value)...,
// u32 vertex count, f64 xyz..., u32 triangle count, u32 abc... (strings: u32 length, bytes). World
// coordinates in float64, so the receiver's store is bit for bit the one a single process builds.
void PutU32(std::vector<uint8_t>* b, uint32_t v) {
  const size_t n = b->size();
  b->resize(n + 4);
  std::memcpy(b->data() + n, &v, 4);
}
void PutBytes(std::vector<uint8_t>* b, const void* p, size_t n) {
  const auto* c = static_cast<const uint8_t*>(p);
  b->insert(b->end(), c, c + n);
}
void PutStr(std::vector<uint8_t>* b, const std::string& s) {
  PutU32(b, static_cast<uint32_t>(s.size()));
  PutBytes(b, s.data(), s.size());
}
void EncodeObject(const SceneObject& o, std::vector<uint8_t>* b) {
  PutU32(b, o.id);
  PutStr(b, o.name);
  PutStr(b, o.source);
  PutU32(b, static_cast<uint32_t>(o.attributes.size()));
  for (const ObjectAttribute& a : o.attributes) {
    PutStr(b, a.key);
    PutStr(b, a.value);
  }
  PutU32(b, static_cast<uint32_t>(o.mesh.vertex_count()));
  PutBytes(b, o.mesh.vertices.data(), 8 * o.mesh.vertices.size());
  PutU32(b, static_cast<uint32_t>(o.mesh.triangle_count()));
  PutBytes(b, o.mesh.triangles.data(), 4 * o.mesh.triangles.size());
}

// Reads back a spill file of EncodeObject records, each preceded by its u32 length.
class SpillSource final : public SceneSource {
 public:
  static Result<std::unique_ptr<SceneSource>> Open(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return Status::IOError(path + ": " + std::strerror(errno));
    return std::unique_ptr<SceneSource>(new SpillSource(path, f));
  }
  ~SpillSource() override { std::fclose(f_); }
  Result<bool> Next(SceneObject* o) override {
    uint32_t n = 0;
    const size_t got = std::fread(&n, 1, 4, f_);
    if (got == 0 && std::feof(f_)) return false;
    buf_.resize(n);
    if (got != 4 || std::fread(buf_.data(), 1, n, f_) != n) return Status::IOError(path_ + ": truncated");
    at_ = 0;
    o->id = U32();
    o->name = Str();
    o->source = Str();
    o->attributes.resize(U32());
    for (ObjectAttribute& a : o->attributes) {
      a.key = Str();
      a.value = Str();
    }
    o->mesh.vertices.resize(3 * size_t{U32()});
    Bytes(o->mesh.vertices.data(), 8 * o->mesh.vertices.size());
    o->mesh.triangles.resize(3 * size_t{U32()});
    Bytes(o->mesh.triangles.data(), 4 * o->mesh.triangles.size());
    if (!ok_ || at_ != buf_.size()) return Status::Internal(path_ + ": a damaged exchange record");
    return true;
  }

 private:
  SpillSource(std::string path, std::FILE* f) : path_(std::move(path)), f_(f) {}
  void Bytes(void* p, size_t n) {
    if (at_ + n > buf_.size()) {
      ok_ = false;
      return;
    }
    std::memcpy(p, buf_.data() + at_, n);
    at_ += n;
  }
  uint32_t U32() {
    uint32_t v = 0;
    Bytes(&v, 4);
    return v;
  }
  std::string Str() {
    std::string s(ok_ ? std::min<size_t>(U32(), buf_.size()) : 0, '\0');
    Bytes(s.data(), s.size());
    return s;
  }
  std::string path_;
  std::FILE* f_;
  std::vector<uint8_t> buf_;
  size_t at_ = 0;
  bool ok_ = true;
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

std::string SpillPath(const std::string& manifest, uint32_t shard, int sender) {
  return ShardStorePath(manifest, shard) + ".from-" + std::to_string(sender) + ".new";
}

using Clock = std::chrono::steady_clock;
double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// The largest of every rank's value, on rank 0.
double MaxOf(double v) {
  double out = 0;
  MPI_Reduce(&v, &out, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
  return out;
}
uint64_t SumOf(uint64_t v) {
  uint64_t out = 0;
  MPI_Allreduce(&v, &out, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
  return out;
}

}  // namespace

int RunBuild(int argc, char** argv, int rank, int ranks) {
  const auto start = Clock::now();
  Args a;
  std::string err;
  if (!Parse(argc, argv, &a, &err)) {
    if (rank == 0) std::fprintf(stderr, "error: %s\n", err.c_str());
    return 2;
  }
  auto fail = [&](const std::string& message) {
    std::fprintf(stderr, "error: rank %d: %s\n", rank, message.c_str());
    return false;
  };
  std::vector<Input> inputs;
  std::vector<SceneOpener> openers;
  bool ok = true;
  for (const std::string& in : a.inputs) {
    auto input = InputFor(in, IngestSpillDir(a.output, ""));
    if (!input.ok()) {
      ok = fail(input.status().message());
    } else {
      openers.push_back(input->opener);
      inputs.push_back(std::move(*input));
    }
  }
  if (std::filesystem::is_directory(a.output)) ok = fail(a.output + ": not a regular file");
  // Rank 0 holds the build's lock to the end, and removes what killed builds of this path left before any
  // rank stages a file (the next collective).
  std::unique_ptr<ShardBuildLock> lock;
  if (rank == 0 && ok) {
    auto l = ShardBuildLock::Acquire(a.output);
    if (!l.ok())
      ok = fail(l.status().message());
    else
      lock = std::move(*l);
    if (ok) RemoveShardLeftovers(a.output);
  }
  if (!AllOk(ok)) return 1;
  IngestOptions opts;
  opts.store.backend = a.backend == "pagefile" ? Backend::kPagedFile : Backend::kHdf5;
  opts.threads = a.threads;
  opts.tuning.threads = static_cast<int>(a.threads);

  // This rank's part: a tanker by id range, one .mks by byte range; anything else is read by rank 0 and
  // scattered by the exchange.
  const bool by_range = inputs.size() == 1 && inputs[0].tanker;
  bool by_bytes = inputs.size() == 1 && inputs[0].mks;
  const uint64_t n = inputs[0].n, seed = inputs[0].seed, r = static_cast<uint64_t>(rank),
                 nr = static_cast<uint64_t>(ranks);
  const uint64_t lo = (n * r + nr - 1) / nr, hi = (n * (r + 1) + nr - 1) / nr;
  MkSceneLayout layout;
  MkScenePart mks;
  uint64_t mks_first = 0;  // the file index (and id) of this rank's first record
  if (by_bytes) {
    const std::string& path = inputs[0].path;
    auto l = ReadMkSceneLayout(path);
    if (!l.ok())
      ok = fail(l.status().message());
    else if (l->objects > uint64_t{kNoIndex})
      ok = fail(path + ": too many objects: ids are 32-bit");
    else
      layout = *l;
    if (!AllOk(ok)) return 1;
    const uint64_t body = layout.body_end - layout.body_begin;
    auto range_begin = [&](uint64_t q) {
      return layout.body_begin + static_cast<uint64_t>(static_cast<unsigned __int128>(body) * q / nr);
    };
    auto p = FindMkScenePart(path, layout, range_begin(r), range_begin(r + 1));
    if (!p.ok())
      ok = fail(p.status().message());
    else
      mks = *p;
    if (!AllOk(ok)) return 1;
    const uint64_t mine[4] = {mks.found ? 1u : 0u, mks.begin, mks.end, mks.objects};
    std::vector<uint64_t> all(4 * static_cast<size_t>(ranks));
    MPI_Allgather(mine, 4, MPI_UINT64_T, all.data(), 4, MPI_UINT64_T, MPI_COMM_WORLD);
    std::vector<MkScenePart> parts(ranks);
    std::vector<uint64_t> begins(ranks);
    for (int q = 0; q < ranks; ++q) {
      parts[q] = {all[4 * q] != 0, all[4 * q + 1], all[4 * q + 2], all[4 * q + 3]};
      begins[q] = range_begin(static_cast<uint64_t>(q));
    }
    // Every rank sees the same parts and decides alike. Parts that do not chain (a damaged file, or a
    // record-like pattern with a matching checksum inside a record) fall back to rank 0's whole read,
    // which reports damage with the object and offset.
    if (Status st = CheckMkSceneParts(path, layout, begins, parts); !st.ok()) {
      if (rank == 0) std::printf("note: %s; rank 0 reads the input whole\n", st.message().c_str());
      by_bytes = false;
    }
    MPI_Exscan(&mks.objects, &mks_first, 1, MPI_UINT64_T, MPI_SUM, MPI_COMM_WORLD);
    if (rank == 0) mks_first = 0;  // MPI_Exscan leaves rank 0's undefined
  }
  auto part = [&]() -> std::unique_ptr<SceneSource> {
    if (by_range) return MakeTankerRangeSource(n, seed, lo, hi);
    if (by_bytes) {
      auto source = OpenMkScenePart(inputs[0].path, layout, mks, mks_first, static_cast<ObjectId>(mks_first));
      if (!source.ok()) return std::make_unique<ErrorSource>(source.status());
      return std::move(*source);
    }
    if (rank == 0) return ChainInputs(openers);
    return std::make_unique<EmptySource>();
  };
  if (!by_range && !by_bytes && rank == 0 && ranks > 1)
    std::printf("note: only tanker:N and one .mks are read in parts; rank 0 reads %s and scatters it\n",
                inputs.size() == 1 ? "the input" : "the inputs");

  // 1. Samples of the ranks' parts, merged on rank 0, which chooses the top levels.
  auto scan = [&] {
    auto source = part();
    return ScanPart(source.get(), opts);
  }();
  if (!scan.ok()) ok = fail(scan.status().message());
  if (!AllOk(ok)) return 1;
  for (const std::string& w : scan->warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  const uint64_t objects = SumOf(scan->objects);
  const double scan_seconds = MaxOf(Since(start));
  // The samples merged up a binary tree (rank r + step into rank r), each step one sample of at most
  // 2^18 items: rank 0's memory for it does not grow with R.
  ShardSample merged = std::move(scan->sample);
  for (int step = 1; step < ranks; step *= 2) {
    if (rank % (2 * step) == step) {
      std::vector<uint8_t> bytes;
      for (const ShardSample::Item& i : merged.Items()) {
        Put(&bytes, i.id);
        for (int k = 0; k < 3; ++k) Put(&bytes, i.box.min[k]);
        for (int k = 0; k < 3; ++k) Put(&bytes, i.box.max[k]);
      }
      const uint64_t n = bytes.size();
      MPI_Send(&n, 1, MPI_UINT64_T, rank - step, 0, MPI_COMM_WORLD);
      MPI_Send(bytes.data(), static_cast<int>(n), MPI_BYTE, rank - step, 1, MPI_COMM_WORLD);
      break;
    }
    if (rank % (2 * step) == 0 && rank + step < ranks) {
      uint64_t n = 0;
      MPI_Recv(&n, 1, MPI_UINT64_T, rank + step, 0, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      std::vector<uint8_t> b(n);
      MPI_Recv(b.data(), static_cast<int>(n), MPI_BYTE, rank + step, 1, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      ShardSample sample;
      for (size_t at = 0; at < b.size();) {
        const ObjectId id = Get<ObjectId>(b, &at);
        Box3d box;
        for (int k = 0; k < 3; ++k) box.min[k] = Get<double>(b, &at);
        for (int k = 0; k < 3; ++k) box.max[k] = Get<double>(b, &at);
        sample.Add(id, box);
      }
      merged.Merge(sample);
    }
  }
  Manifest m;
  std::vector<uint8_t> head;
  if (rank == 0) {
    auto top = objects == 0 ? Result<TopLevels>(Status::InvalidArgument(
                                  a.output + " not built: empty scene, no object with geometry in the input"))
                            : ChooseTopLevels(merged.Items(), a.shards);
    if (!top.ok()) {
      fail(top.status().message());
    } else {
      Put<uint8_t>(&head, 1);
      Put<uint64_t>(&head, objects);
      const Vec3d origin = ChooseStoreOrigin(scan->first);  // rank 0's part starts at object 0
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
    }
    if (head.empty()) Put<uint8_t>(&head, 0);
  }
  Broadcast(&head);
  size_t at = 0;
  if (Get<uint8_t>(head, &at) != 1) return 1;
  m.objects = Get<uint64_t>(head, &at);
  for (int k = 0; k < 3; ++k) m.origin[k] = Get<double>(head, &at);
  m.build_id = Get<uint64_t>(head, &at);
  m.top.shard_count = a.shards;
  while (at < head.size()) {
    TopNode t;
    t.axis = Get<uint8_t>(head, &at);
    t.key = static_cast<ShardKey>(Get<uint8_t>(head, &at));
    t.cut = Get<double>(head, &at);
    t.child[0] = Get<uint32_t>(head, &at);
    t.child[1] = Get<uint32_t>(head, &at);
    t.shard = Get<uint32_t>(head, &at);
    m.top.nodes.push_back(t);
  }
  auto rank_of = [&](uint32_t shard) { return RankOfShard(shard, a.shards, ranks); };
  std::vector<uint32_t> own;
  for (uint32_t s = 0; s < a.shards; ++s)
    if (rank_of(s) == rank) own.push_back(s);

  // Every file this rank may have staged: its shards' and the spills it received.
  auto discard = [&] {
    for (uint32_t s : own) {
      DiscardShard(a.output, s);
      for (int from = 0; from < ranks; ++from) {
        std::error_code ec;
        std::filesystem::remove(SpillPath(a.output, s, from), ec);
      }
    }
  };

  // 2. The exchange: objects for another rank's shards are encoded (with their shard and length) and sent
  // in rounds of at most --round-bytes a sender; the receiver appends them to its (shard, sender) spill.
  const auto exchange_start = Clock::now();
  uint64_t sent_bytes = 0, sent_objects = 0, rounds = 1;
  {
    std::vector<std::FILE*> spills(static_cast<size_t>(a.shards) * ranks, nullptr);
    auto spill = [&](uint32_t s, int from) -> std::FILE*& { return spills[size_t{s} * ranks + from]; };
    std::unique_ptr<SceneSource> source = part();
    std::vector<std::vector<uint8_t>> out(ranks);
    std::vector<uint8_t> record;
    SceneObject obj;
    bool done = false;
    for (;; ++rounds) {
      const size_t cap = std::max<uint64_t>(1, a.round_bytes / static_cast<uint64_t>(ranks));
      bool full = false;
      while (ok && !done && !full) {
        auto more = source->Next(&obj);
        if (!more.ok()) {
          ok = fail(more.status().message());
          break;
        }
        if (!*more) {
          done = true;
          break;
        }
        const uint32_t s = m.top.ShardOf(obj.mesh.Bounds());
        const int to = rank_of(s);
        if (to == rank) continue;  // read again when its shard is built
        record.clear();
        EncodeObject(obj, &record);
        PutU32(&out[to], s);
        PutU32(&out[to], static_cast<uint32_t>(record.size()));
        PutBytes(&out[to], record.data(), record.size());
        full = out[to].size() >= cap;
        sent_bytes += record.size() + 8;
        ++sent_objects;
      }
      int flags[2] = {ok ? 1 : 0, done ? 1 : 0}, all[2] = {0, 0};
      MPI_Allreduce(flags, all, 2, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
      if (!all[0]) break;
      std::vector<int> send_counts(ranks), recv_counts(ranks), send_at(ranks), recv_at(ranks);
      for (int q = 0; q < ranks; ++q) send_counts[q] = static_cast<int>(out[q].size());
      MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
      std::vector<uint8_t> send, recv;
      for (int q = 0; q < ranks; ++q) {
        send_at[q] = static_cast<int>(send.size());
        send.insert(send.end(), out[q].begin(), out[q].end());
        out[q].clear();
      }
      int total = 0;
      for (int q = 0; q < ranks; ++q) recv_at[q] = std::exchange(total, total + recv_counts[q]);
      recv.resize(static_cast<size_t>(total));
      MPI_Alltoallv(send.data(), send_counts.data(), send_at.data(), MPI_BYTE, recv.data(),
                    recv_counts.data(), recv_at.data(), MPI_BYTE, MPI_COMM_WORLD);
      for (int from = 0; from < ranks && ok; ++from) {
        for (size_t p = static_cast<size_t>(recv_at[from]), e = p + static_cast<size_t>(recv_counts[from]);
             p < e && ok;) {
          uint32_t s = 0, len = 0;
          std::memcpy(&s, recv.data() + p, 4);
          std::memcpy(&len, recv.data() + p + 4, 4);
          if (s >= a.shards || rank_of(s) != rank) {
            ok = fail("an exchanged object for shard " + std::to_string(s) + " reached the wrong rank");
            break;
          }
          std::FILE*& f = spill(s, from);
          const std::string path = SpillPath(a.output, s, from);
          if (!f && !(f = std::fopen(path.c_str(), "wb"))) {
            ok = fail(path + ": " + std::strerror(errno));
            break;
          }
          if (std::fwrite(recv.data() + p + 4, 1, size_t{len} + 4, f) != size_t{len} + 4)
            ok = fail(path + ": write failed: " + std::strerror(errno));
          p += size_t{len} + 8;
        }
      }
      if (all[1]) break;
    }
    for (size_t i = 0; i < spills.size(); ++i)
      if (spills[i] && std::fclose(spills[i]) != 0 && ok)
        ok = fail(SpillPath(a.output, static_cast<uint32_t>(i / ranks), static_cast<int>(i % ranks)) +
                  ": write failed: " + std::strerror(errno));
  }
  if (!AllOk(ok)) {
    discard();
    return 1;
  }
  KillForTest(rank, "exchanged");
  const double exchange_seconds = MaxOf(Since(exchange_start));
  const uint64_t all_sent = SumOf(sent_bytes), all_moved = SumOf(sent_objects);

  // 3. This rank's shards, under staging names, each from its senders' streams in rank order.
  const auto build_start = Clock::now();
  std::vector<uint8_t> entries;
  for (uint32_t s : own) {
    std::vector<ShardObjects> streams;
    for (int from = 0; from < ranks; ++from) {
      if (from == rank) {
        streams.push_back(
            [&, s]() -> Result<std::unique_ptr<SceneSource>> { return ShardObjectsOf(part(), m.top, s); });
      } else if (std::filesystem::exists(SpillPath(a.output, s, from))) {
        streams.push_back([path = SpillPath(a.output, s, from)] { return SpillSource::Open(path); });
      }
    }
    IngestReport report;
    auto e = BuildShardFrom(
        [&]() -> Result<std::unique_ptr<SceneSource>> {
          return std::unique_ptr<SceneSource>(std::make_unique<Concat>(streams));
        },
        a.output, m, s, opts, &report);
    for (int from = 0; from < ranks; ++from) {
      std::error_code ec;
      std::filesystem::remove(SpillPath(a.output, s, from), ec);
    }
    if (!e.ok()) {
      ok = fail(e.status().message());
      break;
    }
    for (const std::string& w : report.warnings)
      std::fprintf(stderr, "warning: shard %u: %s\n", s, w.c_str());
    KillForTest(rank, "staged");
    Put(&entries, s);
    for (const ShardFileInfo* f : {&e->store, &e->ids}) {
      PutString(&entries, f->name);
      Put(&entries, f->bytes);
      Put(&entries, f->fingerprint);
    }
    Put(&entries, e->objects);
    for (int k = 0; k < 3; ++k) Put(&entries, e->box.min[k]);
    for (int k = 0; k < 3; ++k) Put(&entries, e->box.max[k]);
  }
  if (!AllOk(ok)) {
    discard();
    return 1;
  }
  const double build_seconds = MaxOf(Since(build_start));
  const auto gathered = Gather(entries, rank, ranks);
  std::vector<uint64_t> reads(ranks);
  const uint64_t my_reads = BytesRead();
  MPI_Gather(&my_reads, 1, MPI_UINT64_T, reads.data(), 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
  if (rank == 0) {
    m.shards.resize(a.shards);
    for (const auto& b : gathered) {
      for (size_t p = 0; p < b.size();) {
        ShardEntry& e = m.shards[Get<uint32_t>(b, &p)];
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
  }

  // 4. Every rank's shards into place, then the manifest on rank 0.
  for (uint32_t s : own)
    if (ok) {
      Status st = PublishShard(a.output, s);
      if (!st.ok()) ok = fail(st.message());
    }
  if (!AllOk(ok)) {
    for (uint32_t s : own) {  // placed or staged: none of this build's files stays
      std::error_code ec;
      std::filesystem::remove(ShardStorePath(a.output, s), ec);
      std::filesystem::remove(ShardIdsPath(a.output, s), ec);
    }
    discard();
    return 1;
  }
  int written = 1;
  if (rank == 0) {
    Status st = WriteManifest(a.output, m);
    if (!st.ok()) {
      written = (fail(st.message()), 0);
    } else {
      std::printf("built %s: %llu objects in %u shards on %d ranks (%s)\n", a.output.c_str(),
                  static_cast<unsigned long long>(m.objects), a.shards, ranks,
                  by_range   ? "disjoint id ranges"
                  : by_bytes ? "disjoint byte ranges"
                             : "read by rank 0");
      std::printf(
          "exchange: %llu objects (%.1f %%) moved, %llu bytes, %.1f bytes an object of the scene, "
          "%.1f a moved object, %llu rounds\n",
          static_cast<unsigned long long>(all_moved),
          100.0 * static_cast<double>(all_moved) / static_cast<double>(m.objects),
          static_cast<unsigned long long>(all_sent),
          static_cast<double>(all_sent) / static_cast<double>(m.objects),
          all_moved ? static_cast<double>(all_sent) / static_cast<double>(all_moved) : 0.0,
          static_cast<unsigned long long>(rounds));
      std::printf("seconds: scan %.2f, exchange %.2f, shards %.2f, total %.2f\n", scan_seconds,
                  exchange_seconds, build_seconds, Since(start));
      std::printf("bytes read per rank (rchar: input, spills, store checks):");
      for (uint64_t b : reads) std::printf(" %llu", static_cast<unsigned long long>(b));
      std::printf("\n");
    }
  }
  MPI_Bcast(&written, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (!written) {
    for (uint32_t s : own) {
      std::error_code ec;
      std::filesystem::remove(ShardStorePath(a.output, s), ec);
      std::filesystem::remove(ShardIdsPath(a.output, s), ec);
    }
  }
  return written ? 0 : 1;
}

}  // namespace mktree
