// The query file of `mktree query --queries FILE`: one query a line, `point X Y Z` or
// `box X0 Y0 Z0 X1 Y1 Z1`; `#` starts a comment; blank lines are skipped.
#pragma once

#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "mktree/database.h"

namespace mktree::tools {

// Reads a query file one query at a time, holding one line: memory does not grow with the file.
class QueryFileReader {
 public:
  // Refuses what is not a regular readable file, naming it.
  static Result<std::unique_ptr<QueryFileReader>> Open(const std::string& path);
  // The next query into *q and true, or false at the end; errors name the file and line.
  Result<bool> Next(Query* q);

 private:
  explicit QueryFileReader(const std::string& path) : path_(path), in_(path) {}
  std::string path_;
  std::ifstream in_;
  std::string line_;
  std::vector<double> numbers_;
  uint64_t line_no_ = 0;
};

// Parses the whole file; errors name the file and line.
Result<std::vector<Query>> ReadQueryFile(const std::string& path);
// Parses "X,Y,Z" (point) or "X0,Y0,Z0,X1,Y1,Z1" (box) as given on the command line.
Result<Query> ParsePointArg(const std::string& text);
Result<Query> ParseBoxArg(const std::string& text);

}  // namespace mktree::tools
