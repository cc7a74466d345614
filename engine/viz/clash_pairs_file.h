// The pairs file of `mktree render --clashes` and `mktree export --clashes`: the JSON lines `mktree clash`
// prints (docs/clash.md §4), one pair a line,
//   {"a": i, "b": j, "class": "hard"|"touch"|"clearance", "distance": s, ...}
// with object ids a < b of the store. Only "a", "b" and "class" are read; other keys are skipped (their
// values must still be valid JSON). A line that is a JSON object without "a", "b" and "class" (the
// `--summary` line) and a blank line are skipped. Anything else is an error naming the file and line:
// a line that is not one JSON object, an id that is not an integer or not an object of the store,
// a >= b, a class other than the three, a key given twice, a pair line missing one of the three keys.
//
// The file is streamed (it may hold millions of pairs): what is kept is one byte per object of the store,
// its worst class, plus counts, and the one pair `focus` asks for.
//
// Thread safety: ReadClashPairs is a pure function of its arguments and the file.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mktree/status.h"

namespace mktree {

// A pair's class as the file gives it, in order of severity (a larger value is a worse class), and
// kNone for objects in no pair. Not mktree::ClashClass (include/mktree/clash.h): that one has no kNone,
// and one name for two types in one program would break the one-definition rule.
enum class ClashMark : uint8_t { kNone = 0, kClearance = 1, kTouch = 2, kHard = 3 };
inline constexpr int kClashMarks = 4;  // ClashMark values, usable as array indices
// "none", "clearance", "touch", "hard".
const char* ClashMarkName(ClashMark c);

struct MarkedPair {
  uint64_t a = 0, b = 0;
  ClashMark cls = ClashMark::kNone;
  uint64_t line = 0;  // its line in the file (from 1)
};

struct ClashMarks {
  std::vector<uint8_t> worst;                   // per object id: its worst ClashMark over its pairs
  std::array<uint64_t, kClashMarks> pairs{};    // pair lines per class (index kNone: 0)
  std::array<uint64_t, kClashMarks> objects{};  // objects per worst class (kNone: objects in no pair)
  uint64_t other_lines = 0;                     // JSON objects without a pair (the summary line)
  std::optional<MarkedPair> focus;              // the pair ReadClashPairs' `focus` asked for

  ClashMark Of(uint64_t id) const { return static_cast<ClashMark>(worst[id]); }
  uint64_t pair_count() const { return pairs[1] + pairs[2] + pairs[3]; }
};

// Reads the pairs file at `path` for a store of `object_count` objects. `focus` > 0 asks for the
// focus-th pair line of the file (counting from 1; InvalidArgument naming the file if it has fewer).
// Errors name the file (and the line, for what is wrong with a line); IOError if it cannot be read.
Result<ClashMarks> ReadClashPairs(const std::string& path, uint64_t object_count, uint64_t focus = 0);

}  // namespace mktree
