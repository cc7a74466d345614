// The parallel half of the OBJ reader (obj_reader.h): one chunk of the file, cut at a line start, parsed on
// its own into numbers and a list of operations. What needs the lines before the chunk (the vertex count
// for relative and range-checked indices, the line number, the `g` rule, the object being built) is left to
// the reader, which applies the chunks' operations in file order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "mktree/status.h"

namespace mktree {

// Splits off the next token of an OBJ line, separated by blanks (space, tab, CR, FF, VT); empty when none
// is left.
std::string_view ObjNextToken(std::string_view* s);

enum class ObjOpKind : uint8_t {
  kVertices,   // `count` vertices on lines `line`, `line` + 1, ... (xyz in ObjChunk::vertices)
  kTexcoords,  // `count` vt lines
  kNormals,    // `count` vn lines
  kFaces,      // `count` faces on lines `line`, `line` + 1, ..., each of `corners` vertices
  kFaceError,  // one face: its references up to ObjChunk::error_stop are checked, then the chunk's error
  kObject,     // `o`: the name is the next `count` bytes of ObjChunk::names
  kGroup,      // `g`: the rest of the line, the next `count` bytes of names
  kMaterial,   // `usemtl`: the next `count` bytes of names
  kError,      // the chunk's error (ObjChunk::error_*), at `line`
};

// Operations are applied in order; each takes its vertices, references and name bytes from where the
// previous one left off.
struct ObjOp {
  ObjOpKind kind;
  uint8_t stride = 1;  // faces: references per vertex, v (1) or v, vt, vn (3)
  uint32_t count = 0;
  uint32_t corners = 0;  // faces: vertices per face
  uint64_t line = 0;     // 1-based within the chunk: the (first) record's first line
};

struct ObjChunk {
  // Input: bytes [begin, end) of the file.
  size_t begin = 0, end = 0;

  // Output of ParseObjChunk.
  uint64_t lines = 0;              // lines the chunk holds (when it has no error)
  uint64_t unterminated_line = 0;  // the record the file ends in without a newline, or 0
  std::vector<double> vertices;    // x, y, z of each `v`
  std::vector<int64_t> refs;       // OBJ indices of the face vertices (see ObjOp::stride; 0 = absent)
  std::vector<ObjOp> ops;
  std::string names;
  // The first error: parsing stops there. A face's error waits for the range checks before it.
  bool has_error = false;
  bool error_unsupported = false;   // free-form geometry (else malformed input)
  bool error_unterminated = false;  // in the last line, which has no newline
  uint64_t error_line = 0;
  uint64_t error_stop = 0;  // kFaceError: the references checked before the error
  std::string error_what;

  void Reset(size_t b, size_t e);
};

// Parses the chunk's bytes, `bytes[0, chunk->end - chunk->begin)`; `chunk->begin` is a line start and
// `chunk->end` follows a line end that does not continue the line (or is the end of the file).
void ParseObjChunk(const char* bytes, ObjChunk* chunk);

// Chunk boundaries: just after the first line end at or past `data + from` whose line is not continued by
// a trailing backslash; SIZE_MAX when `data[from, size)` holds none. Looks back up to two bytes before a
// line end (data[from - 2] when from >= 2), so a boundary depends only on the file, not on the chunking.
size_t ObjLineBoundary(const char* data, size_t size, size_t from);

// A coordinate as the reader takes it: a decimal or "inf"/"nan" number with an optional leading '+',
// correctly rounded. Overflow is an error, underflow written with a negative exponent reads as 0; NaN,
// infinities and magnitudes above kMaxCoordinate are errors. On error, *why says what was wrong.
bool ParseObjCoordinate(const char* b, const char* e, double* out, std::string* why);

}  // namespace mktree
