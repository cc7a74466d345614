// A clash test's rules (mktree/clash_tests.h, ClashRules) made ready to judge pairs of objects from their
// records: which rule, if any, removes a pair. Thread safety: immutable once made.
#pragma once

#include <set>
#include <string>
#include <utility>
#include <vector>

#include "mktree/clash_tests.h"
#include "mktree/database.h"

namespace mktree::coordination {

// Whether the object is a spatial element that is not a solid: attribute ifc_spatial "true", or an
// ifc_type of IfcSpace, IfcOpeningElement, IfcSite, IfcBuilding, IfcBuildingStorey, IfcSpatialZone, ...
bool IsSpatialContainer(const ObjectRecord& object);

class ClashRuleSet {
 public:
  explicit ClashRuleSet(const ClashTest& test);

  // The rules in force, in the order they are asked (ClashTestSummary::excluded_by_rule lists them all).
  const std::vector<std::string>& names() const { return names_; }
  // The index in names() of the first rule that removes the pair, or -1. `stable_a`, `stable_b`: the
  // objects' stable identities; `key`: the pair's clash key.
  int Excluding(const ObjectRecord& a, const ObjectRecord& b, const std::string& stable_a,
                const std::string& stable_b, const std::string& key) const;

 private:
  enum class Rule { kSpatial, kHosted, kAggregate, kGroup, kAttribute, kApproved };
  bool Removes(Rule rule, const ObjectRecord& a, const ObjectRecord& b, const std::string& stable_a,
               const std::string& stable_b, const std::string& key) const;

  ClashRules rules_;
  std::vector<Rule> order_;
  std::vector<std::string> names_;
  std::set<std::string> approved_keys_;
  std::set<std::pair<std::string, std::string>> approved_pairs_;  // each pair sorted
};

}  // namespace mktree::coordination
