// The self-clash's narrow phase (docs/clash.md §3, execution): the candidate object pairs of a batch's
// leaf pairs tested on all threads, a chunk of leaf pairs at a time, while the calling thread hands the
// previous chunk's pairs to the visitor in plan order (formatting and writing millions of pairs is serial
// work). Chunks, not whole batches, so that the pairs found but not yet handed on stay few. The same pairs
// in the same order, and the same counts, for any thread count. Thread safety: one thread calls it.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include "engine/clash/clash_window.h"
#include "engine/clash/leaf_pairs.h"
#include "engine/clash/pair_emitter.h"
#include "engine/clash/pair_rules.h"
#include "engine/clash/part_numbering.h"
#include "engine/clash/work_pool.h"
#include "mktree/clash.h"

namespace mktree::clash {

class NarrowBatches {
 public:
  // `origin`: the store frame's, for the pairs' points. All must outlive this.
  NarrowBatches(const PartNumbering& parts, const ClashOptions& o, const Exclusions& ex, const Vec3d& origin,
                PairEmitter emit);

  // Tests the candidate pairs of `pairs` (their leaves in `window`), handing on the pairs found before
  // them; the last chunk's wait for the next call or Finish. The first error stops it (in plan order).
  Status Test(std::span<const LeafPair> pairs, const ClashWindow& window, WorkPool& pool);
  // Hands on the pairs still held.
  void Finish();

 private:
  void EmitPrevious();

  const PartNumbering& parts_;
  const ClashOptions& o_;
  const Exclusions& ex_;
  const Vec3d origin_;
  PairEmitter emit_;
  std::vector<PairWork> work_, previous_;  // this chunk's results, the last chunk's (not yet handed on)
  size_t previous_count_ = 0;
  std::vector<Status> errors_;
};

}  // namespace mktree::clash
