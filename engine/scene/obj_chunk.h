// The parallel half of the OBJ reader (obj_reader.h): one chunk of the file, cut at a line start, parsed on
// its own into numbers and a list of operations. What needs the lines before the chunk (the vertex count
// for relative and range-checked indices, the line number, the `g` rule, the object being built) is left to
// the reader, which applies the chunks' operations in file order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "mktree/status.h"

namespace mktree {

enum class ObjOpKind : uint8_t {
  kVertices,   // `count` vertices from consecutive lines `line`, `line` + 1, ... (xyz in ObjChunk::vertices)
  kTexcoords,  // `count` vt lines
  kNormals,    // `count` vn lines
  kFace,       // `count` vertices in ObjChunk::refs from arg: v (stride 1) or v, vt, vn (stride 3)
  kObject,     // `o`: name = names[arg, arg + count)
  kGroup,      // `g`: the rest of the line, names[arg, arg + count)
  kMaterial,   // `usemtl`: names[arg, arg + count)
  kError,      // the chunk's error (ObjChunk::error_*), at `line`
};

struct ObjOp {
  ObjOpKind kind;
  uint8_t stride = 1;  // kFace: references per vertex
  uint32_t count = 0;
  uint64_t line = 0;  // 1-based within the chunk: the record's first line
  uint64_t arg = 0;
  // kFace only: with an error, the references are resolved up to refs[arg + stop] (excluded), then the
  // chunk's error is reported.
  uint64_t stop = kNoStop;
  static constexpr uint64_t kNoStop = ~uint64_t{0};
};

struct ObjChunk {
  // Input: bytes [begin, end) of the file; at_eof when end is the end of the file.
  size_t begin = 0, end = 0;
  bool at_eof = false;

  // Output of ParseObjChunk.
  uint64_t lines = 0;            // lines the chunk holds (when it has no error)
  std::vector<double> vertices;  // x, y, z of each `v`
  std::vector<int64_t> refs;     // OBJ indices of the face vertices (see kFace; 0 = absent)
  std::vector<ObjOp> ops;
  std::string names;
  // The first error: parsing stops there. A face's error waits for the range checks before it.
  bool has_error = false;
  bool error_unsupported = false;   // free-form geometry (else malformed input)
  bool error_unterminated = false;  // in the last line, which has no newline
  uint64_t error_line = 0;
  std::string error_what;

  void Reset(size_t b, size_t e, bool eof);
};

// Parses `data[chunk->begin, chunk->end)`; `chunk->begin` is a line start and `chunk->end` follows a line
// end that does not continue the line (or is the end of the file).
void ParseObjChunk(const char* data, ObjChunk* chunk);

// Where a chunk that starts at `begin` and wants about `target` bytes ends: just after the first line end
// at or past begin + target whose line is not continued by a trailing backslash, or `size`.
size_t ObjChunkEnd(const char* data, size_t size, size_t begin, size_t target);

// A coordinate as the reader takes it: a decimal or "inf"/"nan" number with an optional leading '+',
// correctly rounded. Overflow is an error, underflow written with a negative exponent reads as 0; NaN,
// infinities and magnitudes above kMaxCoordinate are errors. On error, *why says what was wrong.
bool ParseObjCoordinate(const char* b, const char* e, double* out, std::string* why);

}  // namespace mktree
