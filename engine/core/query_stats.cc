#include "mktree/query_stats.h"

namespace mktree {

QueryStats& QueryStats::operator+=(const QueryStats& o) {
  internal_nodes_visited += o.internal_nodes_visited;
  split_nodes_visited += o.split_nodes_visited;
  leaves_visited += o.leaves_visited;
  leaves_filtered += o.leaves_filtered;
  pages_touched += o.pages_touched;
  pages_read += o.pages_read;
  cache_hits += o.cache_hits;
  bytes_read += o.bytes_read;
  candidates_tested += o.candidates_tested;
  hits += o.hits;
  leaves_with_hits += o.leaves_with_hits;
  return *this;
}

std::string QueryStats::ToJsonMembers() const {
  std::string s;
  auto add = [&](const char* k, uint64_t v) {
    if (!s.empty()) s += ", ";
    s += '"';
    s += k;
    s += "\": ";
    s += std::to_string(v);
  };
  add("pages_read", pages_read);
  add("pages_touched", pages_touched);
  add("cache_hits", cache_hits);
  add("leaves_visited", leaves_visited);
  add("leaves_filtered", leaves_filtered);
  add("internal_nodes_visited", internal_nodes_visited);
  add("split_nodes_visited", split_nodes_visited);
  add("bytes_read", bytes_read);
  add("candidates_tested", candidates_tested);
  add("hit_count", hits);  // "hits" is the id array in query output
  add("leaves_with_hits", leaves_with_hits);
  return s;
}

}  // namespace mktree
