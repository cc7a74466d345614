#include "engine/clash/narrow_batches.h"

#include <algorithm>
#include <string>
#include <utility>

namespace mktree::clash {

namespace {

// Leaf pairs tested between two hand-overs of found pairs to the visitor.
constexpr size_t kNarrowChunk = 128;

// Tests the candidate pairs of leaves p and q (the same leaf: its pairs i < j): those whose boxes grown by
// C meet, with an object in the focus (and the other in its partner set).
Status TestLeafPair(const std::string& store, const LoadedLeaf& lp, const LoadedLeaf& lq, bool same,
                    const ClashOptions& o, const Exclusions& ex, const Vec3d& origin, PairWork* w) {
  const double c = o.clearance;
  const auto& A = lp.objects;
  const auto& B = lq.objects;
  for (size_t i = 0; i < A.size(); ++i) {
    for (size_t j = same ? i + 1 : 0; j < B.size(); ++j) {
      const bool scoped = (A[i].in_focus && B[j].in_partner) || (A[i].in_partner && B[j].in_focus);
      if (!scoped || !GrownMeet(A[i].box, B[j].box, c)) continue;
      ++w->candidates;
      const LoadedObject* a = &A[i];
      const LoadedObject* b = &B[j];
      if (a->id > b->id) std::swap(a, b);
      // Ids never repeat within a leaf; across two only if their id digests were made to collide.
      if (a->id == b->id)
        return Status::Corruption(store + ": object " + std::to_string(a->id) +
                                  " is in two leaves (their id digests were made to collide)");
      if (ex.Excluded(a->id, b->id)) {
        ++w->excluded;
        continue;
      }
      if (!a->shape || !b->shape)
        return Status::Internal("clash: objects " + std::to_string(a->id) + " and " + std::to_string(b->id) +
                                " are a candidate pair the leaf filter did not admit");
      const double r = a->resolution + b->resolution;
      const Separation sep =
          Separate(*a->shape, *b->shape, NarrowMaxDistance(o, r), &w->narrow, NarrowOptions(o, r));
      ClashPair pair;
      if (Classify(sep, o, r, a->id, b->id, origin, &pair)) w->found.push_back(pair);
    }
  }
  return Status::Ok();
}

}  // namespace

NarrowBatches::NarrowBatches(const PartNumbering& parts, const ClashOptions& o, const Exclusions& ex,
                             const Vec3d& origin, PairEmitter emit)
    : parts_(parts), o_(o), ex_(ex), origin_(origin), emit_(emit) {}

Status NarrowBatches::Test(std::span<const LeafPair> pairs, const ClashWindow& window, WorkPool& pool) {
  const size_t n = pairs.size();
  for (size_t from = 0; from < n; from += kNarrowChunk) {
    const size_t count = std::min(kNarrowChunk, n - from);
    if (work_.size() < count) work_.resize(count);
    errors_.assign(count, Status::Ok());
    pool.For(
        count,
        [&](size_t k) {
          const LeafPair& lp = pairs[from + k];
          work_[k].Clear();
          errors_[k] = TestLeafPair(parts_.path(parts_.part_of(lp.p)), window.leaf(lp.p), window.leaf(lp.q),
                                    lp.p == lp.q, o_, ex_, origin_, &work_[k]);
        },
        [&] { EmitPrevious(); });
    MKTREE_RETURN_IF_ERROR(FirstError(errors_));
    std::swap(work_, previous_);
    previous_count_ = count;
  }
  return Status::Ok();
}

void NarrowBatches::Finish() { EmitPrevious(); }

void NarrowBatches::EmitPrevious() {
  for (size_t k = 0; k < previous_count_; ++k) emit_.Add(previous_[k]);
  previous_count_ = 0;
}

}  // namespace mktree::clash
