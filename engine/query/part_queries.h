// What the Databases made of several stores share (a sharded store's shards, a revision's parts): the
// query check, the union of bounds, one query run on one store as a batch of one, and the pair cap of a
// collide over several stores. Thread safety: free functions; a PartPairCap belongs to one part's run.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "engine/query/store_database.h"
#include "mktree/clash.h"
#include "mktree/database.h"

namespace mktree {

// Finite coordinates, and min <= max on every axis of a box.
bool FiniteQuery(const Query& q);

Box3d UnionBox(Box3d a, const Box3d& b);

// `q` on `db` as a batch of one on the calling thread (options.cold: on a private empty cache, with
// options.ids), its result handed to `got`.
Status RunOneOnStore(const StoreDatabase& db, const Query& q, const BatchOptions& options,
                     const std::function<void(const QueryResult&)>& got);

// A batch over several stores (Database::RunBatchStreamed): options.threads workers (0: one per core), a
// window of options.window results (0: 4 a thread), results delivered in query order. `one` answers a
// finite query into a result already reset; a non-finite one is InvalidArgument without calling it.
using OneQuery = std::function<Status(const Query& q, QueryResult* r)>;
Status RunQueriesOneByOne(const std::string& path, const QuerySource& source, const BatchOptions& options,
                          const ResultVisitor& deliver, const OneQuery& one);

// The caller's ClashOptions::max_pairs across the parts of one collide: a part's pairs are counted against
// what the parts before it reported (`total`).
class PartPairCap {
 public:
  PartPairCap(const ClashStats& total, uint64_t max_pairs) : total_(total), max_(max_pairs) {}
  // Whether the next pair is handed on (else it is counted as capped).
  bool Take() {
    if (total_.reported_pairs + reported_ >= max_) {
      ++capped_;
      return false;
    }
    ++reported_;
    return true;
  }
  // The part's counts as the caller sees them.
  void Fill(ClashStats* part) const {
    part->reported_pairs = reported_;
    part->capped_pairs = capped_;
  }

 private:
  const ClashStats& total_;
  uint64_t max_;
  uint64_t reported_ = 0, capped_ = 0;
};

}  // namespace mktree
