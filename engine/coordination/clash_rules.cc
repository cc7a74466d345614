#include "engine/coordination/clash_rules.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <string_view>

#include "engine/coordination/clash_keys.h"

namespace mktree::coordination {

namespace {

bool EqualNoCase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::toupper(static_cast<unsigned char>(x)) == std::toupper(static_cast<unsigned char>(y));
         });
}

// Spatial and other non-solid elements of IFC2X3, IFC4 and IFC4X3.
constexpr std::array<std::string_view, 22> kSpatialTypes = {"IfcSpace",
                                                            "IfcOpeningElement",
                                                            "IfcOpeningStandardCase",
                                                            "IfcSite",
                                                            "IfcBuilding",
                                                            "IfcBuildingStorey",
                                                            "IfcSpatialZone",
                                                            "IfcSpatialElement",
                                                            "IfcExternalSpatialElement",
                                                            "IfcSpatialStructureElement",
                                                            "IfcZone",
                                                            "IfcGrid",
                                                            "IfcAnnotation",
                                                            "IfcVirtualElement",
                                                            "IfcFacility",
                                                            "IfcFacilityPart",
                                                            "IfcBridge",
                                                            "IfcBridgePart",
                                                            "IfcRoad",
                                                            "IfcRailway",
                                                            "IfcMarineFacility",
                                                            "IfcVoidingFeature"};

bool SameSource(const ObjectRecord& a, const ObjectRecord& b) { return a.source == b.source; }

// `of` names `other` through attribute `key` (of's value is other's ifc_global_id).
bool Names(const ObjectRecord& of, std::string_view key, const ObjectRecord& other) {
  const std::string_view gid = AttributeValue(other, "ifc_global_id");
  if (gid.empty()) return false;
  for (const ObjectAttribute& at : of.attributes)
    if (at.key == key && at.value == gid) return true;
  return false;
}

// The name's group: up to the first separator; empty when the name has none.
std::string_view GroupOf(std::string_view name, const std::string& sep) {
  const size_t at = name.find(sep);
  return at == std::string_view::npos ? std::string_view() : name.substr(0, at);
}

}  // namespace

bool IsSpatialContainer(const ObjectRecord& o) {
  if (AttributeValue(o, "ifc_spatial") == "true") return true;
  const std::string_view type = AttributeValue(o, "ifc_type");
  if (type.empty()) return false;
  return std::any_of(kSpatialTypes.begin(), kSpatialTypes.end(),
                     [&](std::string_view t) { return EqualNoCase(t, type); });
}

ClashRuleSet::ClashRuleSet(const ClashTest& test) : rules_(test.rules) {
  auto add = [&](Rule r, const char* name) {
    order_.push_back(r);
    names_.emplace_back(name);
  };
  if (!rules_.keep_spatial) add(Rule::kSpatial, "spatial_container");
  if (rules_.hosted_fillings) add(Rule::kHosted, "hosted_filling");
  if (rules_.same_aggregate) add(Rule::kAggregate, "same_aggregate");
  if (!rules_.same_group_separator.empty()) add(Rule::kGroup, "same_group");
  if (!rules_.same_attribute.empty()) add(Rule::kAttribute, "same_attribute");
  if (!rules_.approved_keys.empty() || !rules_.approved_pairs.empty()) add(Rule::kApproved, "approved");
  approved_keys_.insert(rules_.approved_keys.begin(), rules_.approved_keys.end());
  for (auto [x, y] : rules_.approved_pairs) {
    if (y < x) std::swap(x, y);
    approved_pairs_.emplace(std::move(x), std::move(y));
  }
}

bool ClashRuleSet::Removes(Rule rule, const ObjectRecord& a, const ObjectRecord& b, const std::string& sa,
                           const std::string& sb, const std::string& key) const {
  switch (rule) {
    case Rule::kSpatial:
      return IsSpatialContainer(a) || IsSpatialContainer(b);
    case Rule::kHosted:
      return SameSource(a, b) && (Names(a, "ifc_fills", b) || Names(b, "ifc_fills", a) ||
                                  Names(a, "ifc_voids", b) || Names(b, "ifc_voids", a));
    case Rule::kAggregate: {
      if (!SameSource(a, b)) return false;
      const std::string_view ga = AttributeValue(a, "ifc_aggregate"), gb = AttributeValue(b, "ifc_aggregate");
      return (!ga.empty() && ga == gb) || Names(a, "ifc_aggregate", b) || Names(b, "ifc_aggregate", a);
    }
    case Rule::kGroup: {
      const std::string_view ga = GroupOf(a.name, rules_.same_group_separator);
      return !ga.empty() && ga == GroupOf(b.name, rules_.same_group_separator);
    }
    case Rule::kAttribute:
      for (const std::string& k : rules_.same_attribute)
        for (const ObjectAttribute& x : a.attributes)
          if (x.key == k)
            for (const ObjectAttribute& y : b.attributes)
              if (y.key == k && y.value == x.value) return true;
      return false;
    case Rule::kApproved:
      return approved_keys_.count(key) ||
             approved_pairs_.count(sa < sb ? std::pair{sa, sb} : std::pair{sb, sa});
  }
  return false;
}

int ClashRuleSet::Excluding(const ObjectRecord& a, const ObjectRecord& b, const std::string& sa,
                            const std::string& sb, const std::string& key) const {
  for (size_t i = 0; i < order_.size(); ++i)
    if (Removes(order_[i], a, b, sa, sb, key)) return static_cast<int>(i);
  return -1;
}

}  // namespace mktree::coordination
