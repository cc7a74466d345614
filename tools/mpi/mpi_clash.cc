// mktree-mpi clash: the self-clash of a sharded store (docs/shards.md, "Clash on MPI ranks"), each rank
// finding the pairs of its shard group.
//   mpirun -n R mktree-mpi clash MANIFEST [--clearance C] [--touch-tolerance T] [--max-pairs N] [--no-touch]
//                                [--exclude-group SEP] [--threads N] [--cache-pages N] [--summary] [--names]
//                                [--revision R]
// Rank r owns the shards the build wrote there (RankOfShard) and, of a store that has taken changes, some
// of the revision's delta stores (tools/mpi/mpi_parts.h; the parts are the shards, then the deltas). A
// pair of objects in parts i <= j is found by the owner of i alone: the pairs inside its parts and, for
// j > i, the pairs between i and j, where j is a delta or a shard whose root box grown by C meets i's
// (j's store opened read-only on r too, checked as the Database checks it; every rank opens every delta).
// Objects a part no longer answers for (removed, or replaced in a later part) are hidden. Each rank
// runs one RunMultiClash over the parts it opened, limited to those part pairs, and sorts its pairs by
// (a, b) in bounded RAM (runs of at most 4 MiB to unnamed temporary files, merged by a heap). When every
// rank has finished without error, rank 0 merges the ranks' sorted streams (each sent in bounded messages
// as rank 0 needs them) and prints them in (a, b) order, the same bytes for any R and K; the cap keeps the
// first N of that order. The lines are `mktree clash`'s on the one-process Database, sorted by (a, b).
#include <fcntl.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <queue>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/clash/pair_rules.h"
#include "storage/file_util.h"
#include "tools/clash_lines.h"
#include "tools/cli_numbers.h"
#include "tools/mpi/mpi_cli.h"
#include "tools/mpi/mpi_parts.h"
#include "tools/mpi/mpi_util.h"

namespace mktree {
namespace {

static_assert(std::is_trivially_copyable_v<ClashPair> && std::is_trivially_copyable_v<ClashStats>);

// Pairs from a rank to rank 0: data messages, then one empty end message, or a failure message (its text).
constexpr int kPairsTag = 7;
constexpr int kEndTag = 8;
constexpr int kFailTag = 9;
// Rank 0 holds one message from each other rank: about 16 MiB over them, at most 1 MiB a message.
constexpr size_t kRank0MessageBudget = size_t{16} << 20;
constexpr size_t kMaxMessageBytes = size_t{1} << 20;
constexpr size_t kMinMessageBytes = size_t{64} << 10;
// The external sort: runs of at most 4 MiB of pairs (the RAM it adds to the clash's); a merge reads at most
// 64 runs at once, 64 KiB each.
constexpr size_t kRunBytes = size_t{4} << 20;
constexpr size_t kFanIn = 64;
constexpr size_t kReadPairs = (size_t{64} << 10) / sizeof(ClashPair);

struct ClashArgs {
  std::string manifest;
  ClashOptions o;
  uint64_t cache_pages = 4096;  // over the manifest's shards, as `mktree clash`
  bool summary = false;
  bool names = false;
  std::optional<uint64_t> revision;
};

constexpr char kUsage[] =
    "usage: mktree-mpi clash MANIFEST [--clearance C] [--touch-tolerance T] [--max-pairs N] "
    "[--no-touch] [--exclude-group SEP] [--threads N] [--cache-pages N] [--summary] [--names] "
    "[--revision R]";

// A distance option: a finite number >= 0.
bool DistanceOption(const std::string& flag, const std::string& text, double* out, int rank) {
  if (text.empty()) return true;
  const auto d = tools::ParseReal(text);
  if (!d || !std::isfinite(*d) || *d < 0)
    return UsageError(rank, flag + " must be a finite number >= 0"), false;
  *out = *d;
  return true;
}

// A count option from 0 to most.
bool CountOf(const std::string& flag, const std::string& text, uint64_t most, uint64_t* out, int rank) {
  if (text.empty()) return true;
  const auto n = CountOption(text, most);
  if (!n) return UsageError(rank, flag + " must be 0 to " + std::to_string(most)), false;
  *out = *n;
  return true;
}

// -1 to go on, else the exit status.
int ParseClash(int argc, char** argv, int rank, ClashArgs* a) {
  CLI::App app{"mktree-mpi clash: the self-clash of a sharded store, each rank its shard group", "clash"};
  std::vector<std::string> manifests;
  std::string clearance, touch, max_pairs, threads, cache_pages, exclude, revision;
  app.add_option("manifest", manifests, "The sharded store's manifest");
  app.add_option("--clearance", clearance, "Clearance C: pairs closer than C are reported");
  app.add_option("--touch-tolerance", touch, "Touch tolerance T: meeting pairs with depth <= T are touches");
  app.add_option("--max-pairs", max_pairs, "Report at most N pairs (the rest are counted)");
  app.add_option("--threads", threads, "Each rank's clash threads (0: one per core)");
  app.add_option("--cache-pages", cache_pages, "Page cache, in pages, over the shards");
  app.add_option("--exclude-group", exclude, "Skip pairs whose names agree up to this separator");
  bool no_touch = false;
  app.add_flag("--no-touch", no_touch, "Count touch pairs without printing them");
  app.add_flag("--summary", a->summary, "A last line with counts and statistics");
  app.add_flag("--names", a->names, "Each pair's object names as name_a, name_b");
  app.add_option("--revision", revision, "Answer this kept revision (default: the newest)");
  if (const int code = ParseMpiCommandLine(&app, argc, argv, rank); code >= 0) return code;
  a->o.threads = 1;  // as `mktree-mpi query`: ranks on one machine share its cores
  uint64_t n = a->o.threads;
  if (!DistanceOption("--clearance", clearance, &a->o.clearance, rank) ||
      !DistanceOption("--touch-tolerance", touch, &a->o.touch_tolerance, rank) ||
      !CountOf("--max-pairs", max_pairs, std::numeric_limits<uint64_t>::max(), &a->o.max_pairs, rank) ||
      !CountOf("--threads", threads, 65536, &n, rank) ||
      !CountOf("--cache-pages", cache_pages, std::numeric_limits<uint64_t>::max(), &a->cache_pages, rank))
    return 2;
  if (!revision.empty()) {
    uint64_t r = 0;
    if (!CountOf("--revision", revision, std::numeric_limits<uint64_t>::max(), &r, rank)) return 2;
    a->revision = r;
  }
  a->o.threads = static_cast<unsigned>(n);
  if (app.count("--exclude-group")) {
    if (exclude.empty()) return UsageError(rank, "--exclude-group needs a separator");
    a->o.exclude_group_separator = exclude;
  }
  if (no_touch) a->o.report_touch = false;
  if (manifests.size() > 1) return UsageError(rank, "one manifest only: " + manifests[1]);
  if (manifests.empty()) return UsageError(rank, kUsage);
  a->manifest = manifests[0];
  return -1;
}

uint64_t PeakRss() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<uint64_t>(u.ru_maxrss) * 1024;
}

// The run size: kRunBytes, or for tests (several runs and merge levels on a small scene)
// MKTREE_MPI_TEST_SORT_RUN_BYTES.
Result<size_t> RunPairs() {
  const char* env = std::getenv("MKTREE_MPI_TEST_SORT_RUN_BYTES");
  if (!env) return kRunBytes / sizeof(ClashPair);
  const std::string v = env;
  uint64_t n = 0;
  auto [end, ec] = std::from_chars(v.data(), v.data() + v.size(), n);
  if (v.empty() || ec != std::errc() || end != v.data() + v.size() || n < sizeof(ClashPair) || n > kRunBytes)
    return Status::InvalidArgument("MKTREE_MPI_TEST_SORT_RUN_BYTES must be " +
                                   std::to_string(sizeof(ClashPair)) + " to " + std::to_string(kRunBytes));
  return static_cast<size_t>(n / sizeof(ClashPair));
}

uint64_t PairKey(const ClashPair& p) { return uint64_t{p.a} << 32 | p.b; }
bool PairLess(const ClashPair& x, const ClashPair& y) { return PairKey(x) < PairKey(y); }

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;

// An unnamed file in $TMPDIR (default /tmp): std::tmpfile ignores TMPDIR, and a large self-clash's pairs
// (about 104 bytes each) belong on the disk the user chose. No name, so a killed rank leaves nothing.
Result<File> TempFile() {
  MKTREE_ASSIGN_OR_RETURN(
      storage_internal::UnnamedFile file,
      storage_internal::OpenUnnamedFile("", "mktree-pairs", "a temporary file for the pairs"));
  std::FILE* f = ::fdopen(file.fd, "w+b");
  if (!f) {
    const std::string why = std::strerror(errno);
    ::close(file.fd);
    return Status::IOError(file.where + ": cannot open a temporary file for the pairs: " + why);
  }
  return File(f);
}

Status WritePairs(std::FILE* f, const ClashPair* p, size_t n) {
  if (n && std::fwrite(p, sizeof *p, n, f) != n)
    return Status::IOError(std::string("cannot write a temporary pair file: ") + std::strerror(errno));
  return Status::Ok();
}

// One sorted run: a temporary file of `pairs` pairs, read back kReadPairs at a time; or (no file) the pairs
// held in `buffer`.
struct Run {
  File file;
  uint64_t pairs = 0;
  std::vector<ClashPair> buffer;
  size_t at = 0;

  Result<bool> Next(ClashPair* p) {
    if (at == buffer.size()) {
      if (!file || pairs == 0) return false;
      const size_t want = static_cast<size_t>(std::min<uint64_t>(pairs, kReadPairs));
      buffer.resize(want);
      if (std::fread(buffer.data(), sizeof(ClashPair), want, file.get()) != want)
        return Status::IOError(std::string("cannot read a temporary pair file back: ") +
                               (std::ferror(file.get()) ? std::strerror(errno) : "shorter than written"));
      pairs -= want;
      at = 0;
    }
    *p = buffer[at++];
    return true;
  }
};

// Finishes a run file written to its end: flushed and rewound for reading.
Status Rewind(Run* r) {
  if (std::fflush(r->file.get()) != 0 || std::ferror(r->file.get()) ||
      std::fseek(r->file.get(), 0, SEEK_SET) != 0)
    return Status::IOError(std::string("cannot write a temporary pair file: ") + std::strerror(errno));
  return Status::Ok();
}

// The k-way merge of sorted sources (each with Result<bool> Next(Item*)) by (a, b): a heap of each
// source's head. Keys are unique over the sources (each pair is found once); ties would go by source.
template <typename Source, typename Item>
class Merge {
 public:
  explicit Merge(std::vector<Source*> sources) : sources_(std::move(sources)), heads_(sources_.size()) {}

  Status Start() {
    for (size_t i = 0; i < sources_.size(); ++i) MKTREE_RETURN_IF_ERROR(Pull(i));
    return Status::Ok();
  }
  Result<bool> Next(Item* out) {
    if (heap_.empty()) return false;
    const size_t i = heap_.top().second;
    heap_.pop();
    *out = std::move(heads_[i]);
    MKTREE_RETURN_IF_ERROR(Pull(i));
    return true;
  }

 private:
  static const ClashPair& PairOf(const ClashPair& p) { return p; }
  template <typename T>
  static const ClashPair& PairOf(const T& t) {
    return t.pair;
  }
  Status Pull(size_t i) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, sources_[i]->Next(&heads_[i]));
    if (more) heap_.emplace(PairKey(PairOf(heads_[i])), i);
    return Status::Ok();
  }

  std::vector<Source*> sources_;
  std::vector<Item> heads_;
  using Entry = std::pair<uint64_t, size_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> heap_;
};

// Merges runs into one new run file.
Result<Run> MergeToFile(std::vector<Run>* runs) {
  std::vector<Run*> sources;
  for (Run& r : *runs) sources.push_back(&r);
  Merge<Run, ClashPair> merge(sources);
  MKTREE_RETURN_IF_ERROR(merge.Start());
  Run out;
  MKTREE_ASSIGN_OR_RETURN(out.file, TempFile());
  std::vector<ClashPair> chunk;
  chunk.reserve(kReadPairs);
  for (ClashPair p;;) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, merge.Next(&p));
    if (more) chunk.push_back(p);
    if (chunk.size() == kReadPairs || (!more && !chunk.empty())) {
      MKTREE_RETURN_IF_ERROR(WritePairs(out.file.get(), chunk.data(), chunk.size()));
      out.pairs += chunk.size();
      chunk.clear();
    }
    if (!more) break;
  }
  MKTREE_RETURN_IF_ERROR(Rewind(&out));
  runs->clear();
  return out;
}

// A rank's pairs sorted by (a, b) in bounded RAM: Add collects a run of at most run_pairs, sorts it and
// writes it to a temporary file; kFanIn files of one level merge into one of the next (so at most about
// kFanIn files a level are open, and each pair is rewritten log_kFanIn(runs) times). Finish sorts the last
// run, kept in RAM, and merges levels until at most kFanIn files are left for Next's merge.
class PairSorter {
 public:
  explicit PairSorter(size_t run_pairs) : run_pairs_(run_pairs) {}

  Status Add(const ClashPair& p) {
    if (run_.empty()) run_.reserve(run_pairs_);  // address space only: pages count as they fill
    run_.push_back(p);
    if (run_.size() < run_pairs_) return Status::Ok();
    std::sort(run_.begin(), run_.end(), PairLess);
    Run r;
    MKTREE_ASSIGN_OR_RETURN(r.file, TempFile());
    MKTREE_RETURN_IF_ERROR(WritePairs(r.file.get(), run_.data(), run_.size()));
    r.pairs = run_.size();
    MKTREE_RETURN_IF_ERROR(Rewind(&r));
    run_.clear();
    return AddFile(0, std::move(r));
  }

  Status Finish() {
    std::sort(run_.begin(), run_.end(), PairLess);
    auto files = [&] {
      size_t n = 0;
      for (const auto& l : levels_) n += l.size();
      return n;
    };
    for (size_t l = 0; files() > kFanIn; ++l) {
      if (levels_[l].empty()) continue;
      if (levels_[l].size() == 1) {  // merging one run would only copy it: it moves up as it is
        Run alone = std::move(levels_[l][0]);
        levels_[l].clear();
        MKTREE_RETURN_IF_ERROR(AddFile(l + 1, std::move(alone)));
        continue;
      }
      MKTREE_ASSIGN_OR_RETURN(Run merged, MergeToFile(&levels_[l]));
      MKTREE_RETURN_IF_ERROR(AddFile(l + 1, std::move(merged)));
    }
    std::vector<Run*> sources;
    for (auto& l : levels_)
      for (Run& r : l) sources.push_back(&r);
    last_.buffer = std::move(run_);
    sources.push_back(&last_);
    merge_ = std::make_unique<Merge<Run, ClashPair>>(std::move(sources));
    return merge_->Start();
  }

  Result<bool> Next(ClashPair* p) { return merge_->Next(p); }

 private:
  Status AddFile(size_t level, Run r) {
    if (levels_.size() <= level) levels_.resize(level + 1);
    levels_[level].push_back(std::move(r));
    if (levels_[level].size() < kFanIn) return Status::Ok();
    MKTREE_ASSIGN_OR_RETURN(Run merged, MergeToFile(&levels_[level]));
    return AddFile(level + 1, std::move(merged));
  }

  size_t run_pairs_;
  std::vector<ClashPair> run_;
  std::vector<std::vector<Run>> levels_;
  Run last_;
  std::unique_ptr<Merge<Run, ClashPair>> merge_;
};

// A pair with its objects' names (empty without --names).
struct NamedPair {
  ClashPair pair;
  std::string name_a, name_b;
};

// A rank's sorted pairs with their names. Names are looked up by the rank that found the pair, on the
// parts it has open: both objects' parts are among them (the pair is inside one of its parts or between
// its part and one it opened), so no rank opens more parts for names, and rank 0 does not look up every
// name alone. A part's ObjectName is what the one-process Database gives.
class LocalStream {
 public:
  LocalStream(PairSorter* sorter, const std::vector<RankStore>* parts, bool names)
      : sorter_(sorter), parts_(parts), names_(names) {}

  Result<bool> Next(NamedPair* out) {
    MKTREE_ASSIGN_OR_RETURN(const bool more, sorter_->Next(&out->pair));
    if (!more || !names_) return more;
    MKTREE_ASSIGN_OR_RETURN(out->name_a, NameOf(out->pair.a));
    MKTREE_ASSIGN_OR_RETURN(out->name_b, NameOf(out->pair.b));
    return true;
  }

 private:
  Result<std::string> NameOf(ObjectId id) const {
    for (const RankStore& p : *parts_)
      if (auto local = LocalIdOf(p.ids, id); local && !p.Hidden(*local)) return p.db->ObjectName(*local);
    return Status::Internal("object " + std::to_string(id) + " is live in no part open on this rank");
  }

  PairSorter* sorter_;
  const std::vector<RankStore>* parts_;
  bool names_;
};

void PutName(std::vector<uint8_t>* b, const std::string& s) {
  Put<uint32_t>(b, static_cast<uint32_t>(s.size()));
  b->insert(b->end(), s.begin(), s.end());
}

// Rank 0's view of another rank's sorted pairs: one message at a time, received when the merge needs the
// next pair of that rank.
class RemoteStream {
 public:
  RemoteStream(int rank, bool names) : rank_(rank), names_(names) {}

  Result<bool> Next(NamedPair* out) {
    while (at_ == bytes_.size()) {
      if (done_) return false;
      const int tag = Receive();
      if (tag == kEndTag) return false;
      if (tag == kFailTag)
        return Status::IOError("rank " + std::to_string(rank_) + ": " +
                               std::string(bytes_.begin(), bytes_.end()));
    }
    if (!Take(&out->pair, sizeof out->pair) ||
        (names_ && (!TakeName(&out->name_a) || !TakeName(&out->name_b))))
      return Status::Internal("rank " + std::to_string(rank_) + " sent a malformed pair message");
    return true;
  }
  // Receives (and drops) the rest, so that the rank's blocking sends end.
  void Drain() {
    while (!done_) Receive();
  }

 private:
  int Receive() {
    MPI_Status status;
    MPI_Probe(rank_, MPI_ANY_TAG, MPI_COMM_WORLD, &status);
    int n = 0;
    MPI_Get_count(&status, MPI_BYTE, &n);
    bytes_.resize(static_cast<size_t>(n));
    MPI_Recv(bytes_.data(), n, MPI_BYTE, rank_, status.MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    at_ = 0;
    if (status.MPI_TAG != kPairsTag) done_ = true;
    return status.MPI_TAG;
  }
  bool Take(void* out, size_t n) {
    if (bytes_.size() - at_ < n) return false;
    std::memcpy(out, bytes_.data() + at_, n);
    at_ += n;
    return true;
  }
  bool TakeName(std::string* s) {
    uint32_t n = 0;
    if (!Take(&n, sizeof n) || bytes_.size() - at_ < n) return false;
    s->assign(reinterpret_cast<const char*>(bytes_.data() + at_), n);
    at_ += n;
    return true;
  }

  int rank_;
  bool names_;
  std::vector<uint8_t> bytes_;
  size_t at_ = 0;
  bool done_ = false;
};

// A rank other than 0: its sorted pairs (with names) to rank 0 in messages of about message_bytes, then
// the end message; on an error, the failure message instead (and false).
bool SendPairs(LocalStream* stream, bool names, size_t message_bytes, int rank) {
  std::vector<uint8_t> message;
  message.reserve(message_bytes + sizeof(ClashPair));
  NamedPair p;
  for (;;) {
    auto more = stream->Next(&p);
    if (!more.ok()) {
      const std::string& text = more.status().message();
      std::fprintf(stderr, "error: rank %d: %s\n", rank, text.c_str());
      MPI_Send(text.data(), static_cast<int>(text.size()), MPI_BYTE, 0, kFailTag, MPI_COMM_WORLD);
      return false;
    }
    if (*more) {
      Put(&message, p.pair);
      if (names) {
        PutName(&message, p.name_a);
        PutName(&message, p.name_b);
      }
    }
    if (!message.empty() && (message.size() >= message_bytes || !*more)) {
      MPI_Send(message.data(), static_cast<int>(message.size()), MPI_BYTE, 0, kPairsTag, MPI_COMM_WORLD);
      message.clear();
    }
    if (!*more) break;
  }
  MPI_Send(message.data(), 0, MPI_BYTE, 0, kEndTag, MPI_COMM_WORLD);
  return true;
}

// Rank 0's side of the merge: rank 0's own stream and one RemoteStream a rank, behind one heap.
class RankSource {
 public:
  explicit RankSource(LocalStream* local) : local_(local) {}
  explicit RankSource(RemoteStream* remote) : remote_(remote) {}
  Result<bool> Next(NamedPair* out) { return local_ ? local_->Next(out) : remote_->Next(out); }

 private:
  LocalStream* local_ = nullptr;
  RemoteStream* remote_ = nullptr;
};

bool FailOnRank(int rank, const std::string& message) {
  std::fprintf(stderr, "error: rank %d: %s\n", rank, message.c_str());
  return false;
}

// The parts rank `rank` reads: its own; every delta; and the shards above one of its own whose root box
// grown by C meets it.
std::vector<uint8_t> PartsToOpen(const RankRevision& r, double c, int rank, int ranks) {
  const uint32_t k = r.shard_count();
  std::vector<uint8_t> open(r.part_count(), 0);
  for (uint32_t i = 0; i < open.size(); ++i) {
    if (i >= k) open[i] = 1;
    if (i >= k || r.OwnerOf(i, ranks) != rank) continue;
    open[i] = 1;
    for (uint32_t j = i + 1; j < k; ++j)
      if (clash::GrownMeet(clash::ToBox3d(r.base.shards[i].box), clash::ToBox3d(r.base.shards[j].box), c))
        open[j] = 1;
  }
  return open;
}

// This rank's pairs into the sorter (finished when every pair is in) and its statistics; false after an
// error, printed.
bool ClashOnRank(const ClashArgs& a, const RankRevision& r, const std::vector<RankStore>& parts, int rank,
                 int ranks, PairSorter* sorter, ClashStats* stats) {
  auto fail = [rank](const std::string& message) { return FailOnRank(rank, message); };
  bool ok = true;
  std::vector<ClashPart> clash_parts;
  for (const RankStore& p : parts) clash_parts.push_back(p.AsClashPart());
  ClashOptions o = a.o;
  o.max_pairs = std::numeric_limits<uint64_t>::max();  // the cap is rank 0's, over every rank's pairs
  Status sort_status;
  const Status st = RunMultiClash(
      clash_parts, [&](uint32_t i, uint32_t) { return r.OwnerOf(parts[i].index, ranks) == rank; }, o,
      [&](const ClashPair& p) {
        if (sort_status.ok()) sort_status = sorter->Add(p);
      },
      stats);
  if (!st.ok()) ok = fail(st.message());
  if (ok && !sort_status.ok()) ok = fail(sort_status.message());
  // The store's pages are counted by the parts' owners (a part read for its pairs with a lower one is
  // read here too: its reads count, its size does not).
  stats->store_pages = 0;
  for (const RankStore& p : parts)
    if (r.OwnerOf(p.index, ranks) == rank)
      for (const LeafInfo& l : p.db->reader().tree().leaves) stats->store_pages += l.page_count;
  if (ok) {
    const Status fs = sorter->Finish();
    if (!fs.ok()) ok = fail(fs.message());
  }
  return ok;
}

// Every rank's statistics, summed on rank 0.
ClashStats SumOnRankZero(const ClashStats& stats, int rank, int ranks) {
  std::vector<uint8_t> mine(sizeof(ClashStats));
  std::memcpy(mine.data(), &stats, sizeof stats);
  const auto all = Gather(mine, rank, ranks);
  ClashStats total;
  for (const auto& b : all) {
    ClashStats s;
    std::memcpy(&s, b.data(), sizeof s);
    AddClashStats(&total, s);
  }
  return total;
}

// What rank 0 printed of the pairs.
struct Printed {
  uint64_t reported = 0, capped = 0;
  bool write_failed = false;
};

// The ranks' sorted pairs, printed by rank 0; false after an error.
bool MergePairs(const ClashArgs& a, const std::vector<RankStore>& parts, PairSorter* sorter, int rank,
                int ranks, Printed* printed) {
  // Pairs: the ranks' sorted streams merged on rank 0. A rank sends only to rank 0 (blocking) and rank 0
  // receives from the rank whose pair it needs next, so no rank waits on a cycle. Every rank's messages
  // end with an end or failure message, all received by rank 0 (Drain), so an error ends every rank; an
  // error in this phase (a temporary file read back, a name) comes after pairs were printed, and every
  // rank exits 1.
  const size_t message_bytes = std::clamp(kRank0MessageBudget / static_cast<size_t>(std::max(ranks - 1, 1)),
                                          kMinMessageBytes, kMaxMessageBytes);
  LocalStream local(sorter, &parts, a.names);
  uint64_t& reported = printed->reported;
  uint64_t& capped = printed->capped;
  bool& write_failed = printed->write_failed;
  bool ok = true;
  if (rank != 0) {
    ok = SendPairs(&local, a.names, message_bytes, rank);
  } else {
    std::vector<RemoteStream> remotes;
    for (int r = 1; r < ranks; ++r) remotes.emplace_back(r, a.names);
    std::vector<RankSource> sources{RankSource(&local)};
    for (RemoteStream& r : remotes) sources.emplace_back(&r);
    std::vector<RankSource*> heads;
    for (RankSource& s : sources) heads.push_back(&s);
    Merge<RankSource, NamedPair> merge(heads);
    Status st = merge.Start();
    std::string line;
    for (NamedPair p; st.ok();) {
      auto more = merge.Next(&p);
      if (!more.ok()) st = more.status();
      if (!more.ok() || !*more) break;
      if (reported >= a.o.max_pairs) {
        ++capped;
        continue;
      }
      ++reported;
      line = a.names ? tools::PairLine(p.pair, &p.name_a, &p.name_b) : tools::PairLine(p.pair);
      if (!write_failed && std::fwrite(line.data(), 1, line.size(), stdout) != line.size())
        write_failed = true;
    }
    for (RemoteStream& r : remotes) r.Drain();
    if (!st.ok()) ok = FailOnRank(rank, st.message());
  }
  return ok;
}

// Rank 0, when the pairs were merged (merged_ok): the summary line (with the largest rank's peak RSS,
// taken after the sort and the merge) and the flush of the output; false after an error (or !merged_ok).
bool FinishOutput(const ClashArgs& a, ClashStats* total, const Printed& printed, bool merged_ok, int rank,
                  int ranks, std::chrono::steady_clock::time_point start) {
  std::vector<uint8_t> rss(sizeof(uint64_t));
  const uint64_t my_rss = PeakRss();
  std::memcpy(rss.data(), &my_rss, sizeof my_rss);
  const auto all_rss = Gather(rss, rank, ranks);
  bool ok = merged_ok, write_failed = printed.write_failed;
  if (rank == 0) {
    uint64_t peak_rss = 0;
    for (const auto& b : all_rss) {
      uint64_t r = 0;
      std::memcpy(&r, b.data(), sizeof r);
      peak_rss = std::max(peak_rss, r);
    }
    if (ok && a.summary) {
      total->reported_pairs = printed.reported;
      total->capped_pairs = printed.capped;
      total->total_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      const std::string line = tools::SummaryLine(*total, peak_rss);
      if (std::fwrite(line.data(), 1, line.size(), stdout) != line.size()) write_failed = true;
    }
    if (ok && (std::fflush(stdout) != 0 || write_failed))
      ok = FailOnRank(rank, "cannot write the pairs to standard output");
  }
  return ok;
}

}  // namespace

int RunClash(int argc, char** argv, int rank, int ranks) {
  const auto start = std::chrono::steady_clock::now();
  ClashArgs a;
  if (const int code = ParseClash(argc, argv, rank, &a); code >= 0) return code;
  auto fail = [rank](const std::string& message) { return FailOnRank(rank, message); };
  bool ok = true;
  auto r = HoldRankRevision(a.manifest, a.revision, rank);
  if (!r.ok() && !r.status().message().empty()) ok = fail(r.status().message());
  const auto run_pairs = RunPairs();
  if (!run_pairs.ok()) ok = fail(run_pairs.status().message());
  if (!AllOk(ok) || !r.ok()) return 1;
  auto parts = OpenRankStores(*r, PartsToOpen(*r, a.o.clearance, rank, ranks), a.cache_pages);
  if (!parts.ok()) ok = fail(parts.status().message());
  if (!AllOk(ok)) return 1;
  if (const Status live = CheckOwnedLive(*r, *parts, rank, ranks); !live.ok()) {
    if (!live.message().empty()) fail(live.message());
    return 1;
  }
  // Sorted as they come: a run is sorted and written when full, so RAM grows by at most one run on top of
  // the clash's own (measured: sorting a spill after the clash peaked as high, the clash's memory being
  // still held, and wrote every pair once more).
  PairSorter sorter(*run_pairs);
  ClashStats stats;
  if (ok) ok = ClashOnRank(a, *r, *parts, rank, ranks, &sorter, &stats);
  if (!AllOk(ok)) return 1;
  // Statistics: every rank's, summed on rank 0 (peak RSS gathered after the merge, in FinishOutput).
  ClashStats total = SumOnRankZero(stats, rank, ranks);
  Printed printed;
  ok = MergePairs(a, *parts, &sorter, rank, ranks, &printed);
  ok = FinishOutput(a, &total, printed, ok, rank, ranks, start);
  if (!AllOk(ok)) return 1;
  if (rank != 0) return 0;
  std::fprintf(stderr, "clash of %u shards%s over %d ranks: %llu pairs, %llu pages read of %llu\n",
               r->shard_count(), r->DeltaNote().c_str(), ranks,
               static_cast<unsigned long long>(total.hard + total.touch + total.clearance),
               static_cast<unsigned long long>(total.pages_read),
               static_cast<unsigned long long>(total.store_pages));
  return 0;
}

}  // namespace mktree
