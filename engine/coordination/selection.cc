#include "engine/coordination/selection.h"

#include <algorithm>
#include <array>
#include <cctype>

namespace mktree::coordination {

namespace {

char Fold(char c, bool fold) {
  return fold ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
}

std::string Upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = Fold(c, true);
  return out;
}

// Supertypes and the subtypes a plain pattern naming them selects (IFC2X3 and IFC4 entity names; the
// abstract ones a coordinator uses to say "all walls" or "all flow segments").
struct Family {
  const char* super;
  std::vector<const char*> subs;
};

const std::vector<Family>& Families() {
  static const std::vector<Family> families = {
      {"IfcWall", {"IfcWallStandardCase", "IfcWallElementedCase"}},
      {"IfcSlab", {"IfcSlabStandardCase", "IfcSlabElementedCase"}},
      {"IfcBeam", {"IfcBeamStandardCase"}},
      {"IfcColumn", {"IfcColumnStandardCase"}},
      {"IfcMember", {"IfcMemberStandardCase"}},
      {"IfcPlate", {"IfcPlateStandardCase"}},
      {"IfcDoor", {"IfcDoorStandardCase"}},
      {"IfcWindow", {"IfcWindowStandardCase"}},
      {"IfcOpeningElement", {"IfcOpeningStandardCase"}},
      {"IfcFlowSegment", {"IfcDuctSegment", "IfcPipeSegment", "IfcCableSegment", "IfcCableCarrierSegment"}},
      {"IfcFlowFitting",
       {"IfcDuctFitting", "IfcPipeFitting", "IfcCableFitting", "IfcCableCarrierFitting", "IfcJunctionBox"}},
      {"IfcFlowTerminal",
       {"IfcAirTerminal", "IfcSanitaryTerminal", "IfcLightFixture", "IfcOutlet", "IfcFireSuppressionTerminal",
        "IfcWasteTerminal", "IfcStackTerminal", "IfcSpaceHeater", "IfcLamp"}},
      {"IfcFlowController", {"IfcValve", "IfcDamper", "IfcFlowMeter", "IfcSwitchingDevice"}},
      {"IfcFlowMovingDevice", {"IfcPump", "IfcFan", "IfcCompressor"}},
      {"IfcBuildingElement",
       {"IfcWall",
        "IfcWallStandardCase",
        "IfcWallElementedCase",
        "IfcSlab",
        "IfcSlabStandardCase",
        "IfcSlabElementedCase",
        "IfcBeam",
        "IfcBeamStandardCase",
        "IfcColumn",
        "IfcColumnStandardCase",
        "IfcMember",
        "IfcMemberStandardCase",
        "IfcPlate",
        "IfcPlateStandardCase",
        "IfcDoor",
        "IfcDoorStandardCase",
        "IfcWindow",
        "IfcWindowStandardCase",
        "IfcRoof",
        "IfcStair",
        "IfcStairFlight",
        "IfcRamp",
        "IfcRampFlight",
        "IfcRailing",
        "IfcCovering",
        "IfcCurtainWall",
        "IfcFooting",
        "IfcPile",
        "IfcBuildingElementProxy",
        "IfcChimney",
        "IfcShadingDevice"}},
  };
  return families;
}

}  // namespace

bool GlobMatch(std::string_view p, std::string_view t, bool fold) {
  // Iterative matching with one backtrack point (the last '*'): linear in practice, never exponential.
  size_t pi = 0, ti = 0, star = std::string_view::npos, mark = 0;
  while (ti < t.size()) {
    if (pi < p.size() && (p[pi] == '?' || (p[pi] != '*' && Fold(p[pi], fold) == Fold(t[ti], fold)))) {
      ++pi;
      ++ti;
    } else if (pi < p.size() && p[pi] == '*') {
      star = pi++;
      mark = ti;
    } else if (star != std::string_view::npos) {
      pi = star + 1;
      ti = ++mark;
    } else {
      return false;
    }
  }
  while (pi < p.size() && p[pi] == '*') ++pi;
  return pi == p.size();
}

std::vector<std::string> IfcTypeAndSubtypes(std::string_view type) {
  std::vector<std::string> out{Upper(type)};
  for (const Family& f : Families())
    if (Upper(f.super) == out[0])
      for (const char* sub : f.subs) out.push_back(Upper(sub));
  return out;
}

SelectionMatcher::SelectionMatcher(const Selection& s)
    : include_(Compile(s.include)), exclude_(Compile(s.exclude)) {}

std::vector<SelectionMatcher::Key> SelectionMatcher::Compile(const Selection::Patterns& patterns) {
  std::vector<Key> keys;
  for (const auto& [key, globs] : patterns) {
    Key k;
    k.key = key;
    k.ifc_type = key == "ifc_type";
    for (const std::string& g : globs) {
      if (!k.ifc_type) {
        k.patterns.push_back(g);
      } else if (g.find_first_of("*?") != std::string::npos) {
        k.patterns.push_back(Upper(g));
      } else {
        for (std::string& t : IfcTypeAndSubtypes(g)) k.patterns.push_back(std::move(t));
      }
    }
    keys.push_back(std::move(k));
  }
  return keys;
}

bool SelectionMatcher::AllKeysMatch(const std::vector<Key>& keys, const ObjectRecord& o) {
  for (const Key& k : keys) {
    auto any = [&](std::string_view value) {
      return std::any_of(k.patterns.begin(), k.patterns.end(),
                         [&](const std::string& p) { return GlobMatch(p, value, k.ifc_type); });
    };
    bool hit = false;
    if (k.key == "name") {
      hit = any(o.name);
    } else if (k.key == "source") {
      hit = any(o.source);
    } else {
      for (const ObjectAttribute& a : o.attributes)
        if (a.key == k.key && any(a.value)) {
          hit = true;
          break;
        }
    }
    if (!hit) return false;
  }
  return true;
}

bool SelectionMatcher::Matches(const ObjectRecord& o) const {
  if (!AllKeysMatch(include_, o)) return false;
  return exclude_.empty() || !AllKeysMatch(exclude_, o);
}

}  // namespace mktree::coordination
