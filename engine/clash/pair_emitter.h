// The hand-over of found pairs to the caller's visitor, in plan order: what one unit of narrow work (a
// leaf pair, a collide candidate) found, and the emitter that counts it into ClashStats and applies the
// cap and the unreported touches. Thread safety: a PairWork is filled by one worker; the emitter runs on
// the calling thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/geometry/mesh_separation.h"
#include "mktree/clash.h"

namespace mktree::clash {

// What the tests of one leaf pair (or one collide candidate) found.
struct PairWork {
  std::vector<ClashPair> found;
  uint64_t candidates = 0, excluded = 0;
  NarrowStats narrow;
  // Empties it for the next unit, keeping little memory.
  void Clear();
};

// Hands pairs to the visitor in order: the cap, unreported touches and the class counts.
struct PairEmitter {
  const ClashOptions& o;
  const ClashVisitor& visit;
  ClashStats& s;
  void Add(const PairWork& w);
};

}  // namespace mktree::clash
