#include "engine/clash/collide_chunks.h"

#include <algorithm>
#include <string>

#include "engine/clash/pair_rules.h"
#include "engine/clash/stage_clock.h"

namespace mktree::clash {

namespace {

// Candidates are tested in chunks of about this many objects, with at most this many leaves pinned in the
// cache meanwhile (their entries are decoded on the worker threads).
constexpr size_t kCollideChunk = 256;
constexpr size_t kCollidePinnedLeaves = 16;

}  // namespace

// The candidates of some leaves, read in leaf order and pinned until the chunk is tested.
struct CollideChunks::Chunk {
  std::vector<PinnedLeaf> pins = std::vector<PinnedLeaf>(kCollidePinnedLeaves);
  size_t pinned = 0;
  std::vector<Candidate> candidates;
};

CollideChunks::CollideChunks(const PartNumbering& part, const std::vector<uint32_t>& leaves,
                             const ClashShape& object, const Box3d& object_box, const ClashOptions& o,
                             ClashStats* s)
    : part_(part),
      st_(part.store(0)),
      leaves_(leaves),
      object_(object),
      object_box_(object_box),
      origin_(st_.reader().tree().origin),
      o_(o),
      s_(s),
      reported_((st_.reader().object_count() + 63) / 64) {}

Status CollideChunks::Run(WorkPool& pool, PairEmitter emit) {
  Chunk chunks[2];
  // A chunk's pairs go to the visitor while the next chunk is tested (this thread, before it joins the
  // loop), in chunk order. Two sets of results, one a chunk.
  std::vector<PairWork> work[2];
  size_t pending = 0;  // candidates of the chunk before `cur` whose pairs the visitor has not had
  auto emit_pending = [&](const std::vector<PairWork>& w) {
    for (size_t k = 0; k < pending; ++k) emit.Add(w[k]);
    pending = 0;
  };
  std::vector<Status> errors;
  MKTREE_RETURN_IF_ERROR(Fill(chunks[0]));
  size_t cur = 0;
  for (; !chunks[cur].candidates.empty(); cur ^= 1) {
    Chunk& c = chunks[cur];
    std::vector<PairWork>& w = work[cur];
    const StageClock::time_point t = StageClock::now();
    w.resize(std::max(w.size(), c.candidates.size()));
    errors.assign(c.candidates.size(), Status::Ok());
    Status read_status;
    pool.For(
        c.candidates.size(),
        [&](size_t k) {
          w[k].Clear();
          errors[k] = Test(c.pins[c.candidates[k].pin].view.entry(c.candidates[k].pos), &w[k]);
        },
        [&] {
          emit_pending(work[cur ^ 1]);
          read_status = Fill(chunks[cur ^ 1]);
        });
    for (size_t i = 0; i < c.pinned; ++i) c.pins[i].Release();
    c.pinned = 0;
    s_->narrow_seconds += SecondsSince(t);
    MKTREE_RETURN_IF_ERROR(FirstError(errors));
    MKTREE_RETURN_IF_ERROR(CheckReportedOnce(w, c.candidates.size()));
    pending = c.candidates.size();
    c.candidates.clear();
    if (!read_status.ok()) {
      emit_pending(w);
      return read_status;
    }
  }
  emit_pending(work[cur ^ 1]);  // the last chunk's (chunks[cur] came out empty)
  s_->candidate_pairs = candidates_;
  s_->excluded_pairs = excluded_;
  io_.Fill(s_);
  return Status::Ok();
}

// Reads leaves into `c` until it holds kCollideChunk candidates or kCollidePinnedLeaves leaves with
// candidates, or no leaf is left.
Status CollideChunks::Fill(Chunk& c) {
  const StageClock::time_point t = StageClock::now();
  while (next_leaf_ < leaves_.size() && c.candidates.size() < kCollideChunk && c.pinned < c.pins.size()) {
    PinnedLeaf& pin = c.pins[c.pinned];
    MKTREE_RETURN_IF_ERROR(ReadPinned(st_, leaves_[next_leaf_++], &io_, &seen_, &pin));
    const size_t before = c.candidates.size();
    const auto& entries = pin.view.entries();
    for (uint32_t pos = 0; pos < entries.size(); ++pos) {
      const ObjectEntryView& e = entries[pos];
      if (part_.hidden(0, e.id) || !GrownMeet(ToBox3d(e.box), object_box_, o_.clearance)) continue;
      ++candidates_;
      if (o_.exclude && o_.exclude(part_.global_id(0, e.id), kCollideObject)) {
        ++excluded_;
        continue;
      }
      c.candidates.push_back({c.pinned, pos});
    }
    if (c.candidates.size() > before) {
      ++c.pinned;
    } else {
      pin.Release();
    }
  }
  s_->read_seconds += SecondsSince(t);
  return Status::Ok();
}

// Decodes the candidate, builds its shape for its one pair and tests it against the query object.
Status CollideChunks::Test(const ObjectEntryView& e, PairWork* w) const {
  Mesh mesh;
  MKTREE_RETURN_IF_ERROR(DecodeMesh(st_, e, &mesh));
  const ClashShape other(mesh, StoredEdges(e));
  const double r = CoordinateResolution(e.box);
  const Separation sep = Separate(other, object_, NarrowMaxDistance(o_, r), &w->narrow, NarrowOptions(o_, r));
  ClashPair pair;
  if (Classify(sep, o_, r, e.id, kCollideObject, origin_, &pair)) w->found.push_back(pair);
  return Status::Ok();
}

// An id reported twice is in two leaves, which only id digests made to collide let through. The pairs
// found carry local ids until here, then their global ones.
Status CollideChunks::CheckReportedOnce(std::vector<PairWork>& w, size_t count) {
  for (size_t k = 0; k < count; ++k)
    for (ClashPair& p : w[k].found) {
      const uint64_t bit = uint64_t{1} << (p.a & 63);
      if (reported_[p.a >> 6] & bit)
        return Status::Corruption(st_.reader().path() + ": object " + std::to_string(p.a) +
                                  " is in two leaves (their id digests were made to collide)");
      reported_[p.a >> 6] |= bit;
      p.a = part_.global_id(0, p.a);
    }
  return Status::Ok();
}

}  // namespace mktree::clash
