// Per-query I/O accounting: a plain struct of counters (docs/design.md §8.3).
// Invariants: pages_read <= pages_touched; cache_hits + pages_read == pages_touched;
// with a cold cache pages_read == pages_touched; hits == size of the answer.
#pragma once

#include <cstdint>
#include <string>

namespace mktree {

struct QueryStats {
  uint64_t internal_nodes_visited = 0;
  uint64_t split_nodes_visited = 0;
  uint64_t leaves_visited = 0;   // leaves read (routed to and let through by the leaf filter)
  uint64_t leaves_filtered = 0;  // leaves routed to but skipped: no object box there (leaf filter)
  uint64_t pages_touched = 0;    // page lookups in the cache
  uint64_t pages_read = 0;       // cache misses = disk accesses
  uint64_t cache_hits = 0;
  uint64_t bytes_read = 0;         // bytes read from the store (misses only)
  uint64_t candidates_tested = 0;  // objects whose AABB (and geometry in exact mode) was tested
  uint64_t hits = 0;
  uint64_t leaves_with_hits = 0;  // leaves visited that held at least one answer

  void Reset() { *this = QueryStats(); }
  QueryStats& operator+=(const QueryStats& o);
  // "internal_nodes_visited": 3, ... as JSON members without braces.
  std::string ToJsonMembers() const;
};

}  // namespace mktree
