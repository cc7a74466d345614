// One warm-path check shared by the query tests: Database::Run (the windowed scan) and VisitUntil (leaf by
// leaf) on two databases of the same store must give the same ids and every QueryStats field alike.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "mktree/database.h"

namespace mktree::testing {

inline void ExpectRunMatchesVisitUntil(const Database& windowed, const Database& single, const Query& q,
                                       const std::vector<ObjectId>& expected, const std::string& where) {
  SCOPED_TRACE(where);
  QueryResult r;
  ASSERT_TRUE(windowed.Run(q, &r).ok());
  ASSERT_EQ(r.hits, expected);
  std::vector<ObjectId> one;
  QueryStats s;
  auto complete = single.VisitUntil(
      q,
      [&](ObjectId id) {
        one.push_back(id);
        return true;
      },
      &s);
  ASSERT_TRUE(complete.ok() && *complete);
  std::sort(one.begin(), one.end());
  ASSERT_EQ(one, expected);
  const QueryStats& w = r.stats;
  EXPECT_EQ(w.pages_read, s.pages_read);
  EXPECT_EQ(w.pages_touched, s.pages_touched);
  EXPECT_EQ(w.cache_hits, s.cache_hits);
  EXPECT_EQ(w.bytes_read, s.bytes_read);
  EXPECT_EQ(w.leaves_visited, s.leaves_visited);
  EXPECT_EQ(w.leaves_filtered, s.leaves_filtered);
  EXPECT_EQ(w.leaves_with_hits, s.leaves_with_hits);
  EXPECT_EQ(w.candidates_tested, s.candidates_tested);
  EXPECT_EQ(w.internal_nodes_visited, s.internal_nodes_visited);
  EXPECT_EQ(w.split_nodes_visited, s.split_nodes_visited);
  EXPECT_EQ(w.hits, s.hits);
}

}  // namespace mktree::testing
