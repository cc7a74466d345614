// The query file of `mktree query --queries FILE`: one query a line, `point X Y Z`,
// `box X0 Y0 Z0 X1 Y1 Z1`, `nearest X Y Z K [D]` (the K nearest objects, at most D away) or
// `ray OX OY OZ DX DY DZ [L]` (the ray's first hit, at most L along it); `#` starts a comment; blank lines
// are skipped.
#pragma once

#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "mktree/database.h"

namespace mktree::tools {

// One line of a query file: a point or box query, a nearest query or a ray.
struct FileQuery {
  enum class Kind { kQuery, kNearest, kRay };
  Kind kind = Kind::kQuery;
  Query query;
  DistanceQuery nearest;
  RayQuery ray;
};

// Reads a query file one query at a time, holding one line: memory does not grow with the file.
class QueryFileReader {
 public:
  // Refuses what is not a regular readable file, naming it.
  static Result<std::unique_ptr<QueryFileReader>> Open(const std::string& path);
  // The next query into *q and true, or false at the end; errors name the file and line.
  Result<bool> Next(FileQuery* q);
  // The same for files of point and box queries only: a nearest or ray line is an error.
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
// "X,Y,Z" of --nearest with k and the maximum distance; "OX,OY,OZ,DX,DY,DZ" of --ray with its maximum
// length. Errors name the option and what is wrong (k < 1, a negative distance, a zero direction).
Result<DistanceQuery> ParseNearestArg(const std::string& text, uint64_t k, double max_distance);
Result<RayQuery> ParseRayArg(const std::string& text, double max_length, bool all_hits);

}  // namespace mktree::tools
