// A clash test's selection (mktree/clash_tests.h, Selection) made ready to test objects' records: glob
// patterns, the IFC supertypes a plain ifc_type pattern also stands for. Thread safety: immutable once
// made (any number of threads may ask it).
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "mktree/clash_tests.h"
#include "mktree/database.h"

namespace mktree::coordination {

// Whether `text` matches the glob `pattern` ('*' any run of bytes, '?' one byte); without case when
// `fold_case` (ASCII letters).
bool GlobMatch(std::string_view pattern, std::string_view text, bool fold_case = false);

// The IFC entity names a plain ifc_type pattern also selects: `type` itself and its subtypes in the table
// of docs/clash_workflow.md (IfcWall: IfcWallStandardCase, IfcWallElementedCase, ...), upper case.
std::vector<std::string> IfcTypeAndSubtypes(std::string_view type);

class SelectionMatcher {
 public:
  explicit SelectionMatcher(const Selection& selection);
  // Whether the selection picks the object.
  bool Matches(const ObjectRecord& object) const;
  bool everything() const { return include_.empty() && exclude_.empty(); }

 private:
  struct Key {
    std::string key;
    std::vector<std::string> patterns;  // for ifc_type: upper case, plain supertypes expanded
    bool ifc_type = false;
  };
  static std::vector<Key> Compile(const Selection::Patterns& patterns);
  static bool AllKeysMatch(const std::vector<Key>& keys, const ObjectRecord& object);

  std::vector<Key> include_, exclude_;
};

}  // namespace mktree::coordination
