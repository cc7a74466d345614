// mktree-mpi: the sharded build (docs/shards.md) spread over MPI ranks (CMake option MKTREE_MPI).
//   mpirun -n R mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N]
// Each rank samples the objects of its part of the scene (ids i with i % R == rank); rank 0 gathers the
// samples, chooses the top levels and broadcasts them; shard s is built by rank s % R; rank 0 gathers the
// shards' entries and writes the manifest after every rank has put its shards in place. A failed rank
// makes every rank remove its staged shards, and no manifest is written.
// Not yet distributed: each rank reads the whole input (keeping its part and its shards' objects) instead
// of reading a disjoint part and exchanging objects by shard (docs/shards.md, "For the MPI build").
#include <mpi.h>

#include <charconv>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "engine/generator/tanker_generator.h"
#include "engine/ingest/shard_build.h"
#include "engine/scene/scene_source.h"

namespace mktree {
namespace {

struct Args {
  std::vector<std::string> inputs;
  std::string output;
  uint32_t shards = 0;
  std::string backend = "hdf5";
  uint32_t threads = 0;
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
    return *err = "usage: mktree-mpi SCENE... -o MANIFEST --shards K [--backend hdf5|pagefile] [--threads N]",
           false;
  return true;
}

Result<SceneOpener> OpenerFor(const std::string& input) {
  if (input.rfind("tanker:", 0) == 0) {
    const std::string spec = input.substr(7);
    const size_t colon = spec.find(':');
    uint64_t n = 0, seed = 1;
    if (!ParseU64(spec.substr(0, colon), &n) || n == 0 ||
        (colon != std::string::npos && !ParseU64(spec.substr(colon + 1), &seed)))
      return Status::InvalidArgument(input + ": expected tanker:N or tanker:N:SEED");
    return SceneOpener([n, seed](ObjectId first) { return MakeTankerSource(n, seed, first); });
  }
  return SceneOpener([input](ObjectId first) { return OpenSceneFile(input, first); });
}

// Bytes from one rank to all (root's vector, resized on the others).
void Broadcast(std::vector<uint8_t>* bytes) {
  uint64_t n = bytes->size();
  MPI_Bcast(&n, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
  bytes->resize(n);
  MPI_Bcast(bytes->data(), static_cast<int>(n), MPI_BYTE, 0, MPI_COMM_WORLD);
}

// Every rank's bytes, on rank 0, one vector per rank.
std::vector<std::vector<uint8_t>> Gather(const std::vector<uint8_t>& mine, int rank, int ranks) {
  const int n = static_cast<int>(mine.size());
  std::vector<int> sizes(ranks), offsets(ranks);
  MPI_Gather(&n, 1, MPI_INT, sizes.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  std::vector<uint8_t> all;
  if (rank == 0) {
    int at = 0;
    for (int r = 0; r < ranks; ++r) offsets[r] = std::exchange(at, at + sizes[r]);
    all.resize(at);
  }
  MPI_Gatherv(mine.data(), n, MPI_BYTE, all.data(), sizes.data(), offsets.data(), MPI_BYTE, 0,
              MPI_COMM_WORLD);
  std::vector<std::vector<uint8_t>> out;
  if (rank == 0)
    for (int r = 0; r < ranks; ++r)
      out.emplace_back(all.begin() + offsets[r], all.begin() + offsets[r] + sizes[r]);
  return out;
}

template <typename T>
void Put(std::vector<uint8_t>* b, const T& v) {
  const size_t n = b->size();
  b->resize(n + sizeof(T));
  std::memcpy(b->data() + n, &v, sizeof(T));
}
template <typename T>
T Get(const std::vector<uint8_t>& b, size_t* at) {
  T v;
  std::memcpy(&v, b.data() + *at, sizeof(T));
  *at += sizeof(T);
  return v;
}
void PutString(std::vector<uint8_t>* b, const std::string& s) {
  Put<uint64_t>(b, s.size());
  b->insert(b->end(), s.begin(), s.end());
}
std::string GetString(const std::vector<uint8_t>& b, size_t* at) {
  const uint64_t n = Get<uint64_t>(b, at);
  std::string s(reinterpret_cast<const char*>(b.data() + *at), n);
  *at += n;
  return s;
}

// Whether every rank's `ok` holds.
bool AllOk(bool ok) {
  int mine = ok ? 1 : 0, all = 0;
  MPI_Allreduce(&mine, &all, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  return all == 1;
}

int Run(int argc, char** argv, int rank, int ranks) {
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
  std::vector<SceneOpener> inputs;
  bool ok = true;
  for (const std::string& in : a.inputs) {
    auto opener = OpenerFor(in);
    if (!opener.ok())
      ok = fail(opener.status().message());
    else
      inputs.push_back(*opener);
  }
  if (!AllOk(ok)) return 1;
  IngestOptions opts;
  opts.store.backend = a.backend == "pagefile" ? Backend::kPagedFile : Backend::kHdf5;
  opts.threads = a.threads;
  opts.tuning.threads = static_cast<int>(a.threads);

  // 1. Samples of the ranks' parts, merged on rank 0, which chooses the top levels.
  auto scan = ScanForShards(
      inputs, [&](ObjectId id) { return static_cast<int>(id % static_cast<uint32_t>(ranks)) == rank; }, opts);
  if (!scan.ok()) ok = fail(scan.status().message());
  if (!AllOk(ok)) return 1;
  std::vector<uint8_t> mine;
  for (const ShardSample::Item& i : scan->sample.Items()) {
    Put(&mine, i.id);
    for (int k = 0; k < 3; ++k) Put(&mine, i.box.min[k]);
    for (int k = 0; k < 3; ++k) Put(&mine, i.box.max[k]);
  }
  const auto samples = Gather(mine, rank, ranks);
  Manifest m;
  std::vector<uint8_t> head;
  if (rank == 0) {
    ShardSample merged;
    for (const auto& b : samples) {
      ShardSample part;
      for (size_t at = 0; at < b.size();) {
        const ObjectId id = Get<ObjectId>(b, &at);
        Box3d box;
        for (int k = 0; k < 3; ++k) box.min[k] = Get<double>(b, &at);
        for (int k = 0; k < 3; ++k) box.max[k] = Get<double>(b, &at);
        part.Add(id, box);
      }
      merged.Merge(part);
    }
    auto top = ChooseTopLevels(merged.Items(), a.shards);
    if (!top.ok()) {
      fail(top.status().message());
    } else {
      Put<uint8_t>(&head, 1);
      Put<uint64_t>(&head, scan->objects);
      const Vec3d origin = ChooseStoreOrigin(scan->first);
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

  // 2. This rank's shards, under staging names.
  std::vector<uint8_t> entries;
  std::vector<uint32_t> built;
  for (uint32_t s = static_cast<uint32_t>(rank); s < a.shards && ok; s += static_cast<uint32_t>(ranks)) {
    IngestReport report;
    auto e = BuildShard(inputs, a.output, m, s, opts, &report);
    if (!e.ok()) {
      ok = fail(e.status().message());
      break;
    }
    built.push_back(s);
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
  auto discard = [&] {
    for (uint32_t s : built) DiscardShard(a.output, s);
  };
  if (!AllOk(ok)) {
    discard();
    return 1;
  }
  const auto gathered = Gather(entries, rank, ranks);
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

  // 3. Every rank's shards into place, then the manifest on rank 0.
  for (uint32_t s : built)
    if (ok) {
      Status st = PublishShard(a.output, s);
      if (!st.ok()) ok = fail(st.message());
    }
  if (!AllOk(ok)) {
    discard();
    return 1;
  }
  int written = 1;
  if (rank == 0) {
    Status st = WriteManifest(a.output, m);
    if (!st.ok())
      written = (fail(st.message()), 0);
    else
      std::printf("built %s: %llu objects in %u shards on %d ranks\n", a.output.c_str(),
                  static_cast<unsigned long long>(m.objects), a.shards, ranks);
  }
  MPI_Bcast(&written, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return written ? 0 : 1;
}

}  // namespace
}  // namespace mktree

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  const int rc = mktree::Run(argc, argv, rank, ranks);
  MPI_Finalize();
  return rc;
}
