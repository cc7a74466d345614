// The query file of `mktree query --queries FILE`: one query a line, `point X Y Z` or
// `box X0 Y0 Z0 X1 Y1 Z1`; `#` starts a comment; blank lines are skipped.
#pragma once

#include <string>
#include <vector>

#include "mktree/database.h"

namespace mktree::tools {

// Parses the whole file; errors name the file and line.
Result<std::vector<Query>> ReadQueryFile(const std::string& path);
// Parses "X,Y,Z" (point) or "X0,Y0,Z0,X1,Y1,Z1" (box) as given on the command line.
Result<Query> ParsePointArg(const std::string& text);
Result<Query> ParseBoxArg(const std::string& text);

}  // namespace mktree::tools
