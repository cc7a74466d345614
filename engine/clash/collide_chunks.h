// Collide's reads and narrow phase (docs/clash.md §3, collide): the leaves the broad phase kept are read
// once each, in leaf order, on the calling thread; the objects whose float32 boxes grown by C meet the
// query object's box are its candidates, tested on all threads in chunks while their leaves stay pinned.
// While one chunk is tested the calling thread hands the chunk before it to the visitor and reads the next
// chunk's leaves (the same leaves, once each, in the same order: the same page counts and visitor calls).
// Thread safety: one thread calls Run.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "engine/clash/clash_engine.h"
#include "engine/clash/clash_reads.h"
#include "engine/clash/pair_emitter.h"
#include "engine/clash/part_numbering.h"
#include "engine/clash/work_pool.h"
#include "engine/geometry/mesh_separation.h"
#include "mktree/clash.h"

namespace mktree::clash {

class CollideChunks {
 public:
  // `part`: the one part (ClashPart) collided with, whose hidden objects are no candidates and whose
  // pairs and exclusions carry global ids; `leaves`: its leaves to read; `object`: the query object's
  // shape in the store's frame, `object_box` its bounds. All must outlive this; `s` gets the read seconds
  // and, once Run succeeds, the candidate counts and the I/O counts.
  CollideChunks(const PartNumbering& part, const std::vector<uint32_t>& leaves, const ClashShape& object,
                const Box3d& object_box, const ClashOptions& o, ClashStats* s);

  // Tests every candidate, handing its pairs to `emit` in leaf order, then candidate order. The first
  // error stops it (a chunk's read error after its pairs before it are handed on).
  Status Run(WorkPool& pool, PairEmitter emit);

 private:
  struct Candidate {
    size_t pin;  // index into the chunk's pins
    uint32_t pos;
  };
  struct Chunk;

  Status Fill(Chunk& c);
  Status Test(const ObjectEntryView& e, PairWork* w) const;
  Status CheckReportedOnce(std::vector<PairWork>& w, size_t count);

  const PartNumbering& part_;
  const LeafSource& st_;
  const std::vector<uint32_t>& leaves_;
  const ClashShape& object_;
  const Box3d object_box_;
  const Vec3d origin_;  // the store frame's
  const ClashOptions& o_;
  ClashStats* s_;
  size_t next_leaf_ = 0;
  uint64_t candidates_ = 0, excluded_ = 0;
  std::vector<uint64_t> reported_;  // one bit an object: ids reported
  IoCount io_;
  std::vector<uint64_t> seen_;
};

}  // namespace mktree::clash
