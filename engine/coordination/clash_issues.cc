#include "mktree/clash_issues.h"

namespace mktree {

const char* ClashClassName(ClashClass c) {
  switch (c) {
    case ClashClass::kHard:
      return "hard";
    case ClashClass::kTouch:
      return "touch";
    case ClashClass::kClearance:
      return "clearance";
  }
  return "hard";
}

const char* ClashStatusName(ClashStatus s) {
  switch (s) {
    case ClashStatus::kNone:
      return "";
    case ClashStatus::kNew:
      return "new";
    case ClashStatus::kActive:
      return "active";
    case ClashStatus::kResolved:
      return "resolved";
  }
  return "";
}

}  // namespace mktree
