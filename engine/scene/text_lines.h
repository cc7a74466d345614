// Reads a text file line by line for the input checks (assimp_input_checks.h), with the line structure
// assimp's text importers see: "\n", "\r\n" and a lone "\r" each end a line. A NUL or form feed byte is
// an error (assimp stops a file at a NUL, and ends some tokens but not lines at a form feed), and so is a
// line longer than kMaxLineBytes (a bound on the memory of the check).
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "mktree/status.h"

namespace mktree {

class TextLines {
 public:
  static constexpr size_t kMaxLineBytes = 1 << 20;

  // Opens `path` (which must be a regular file: see OpenAssimpFile).
  static Result<std::unique_ptr<TextLines>> Open(const std::string& path);
  ~TextLines();

  // The next line without its end, or false at the end of the file or on an error (then status() says
  // which, naming the file and line).
  bool Next(std::string_view* line);
  Status status() const { return status_; }
  // 1-based number of the line Next returned last.
  uint64_t line_no() const { return line_no_; }
  // "path:line: " for messages about the line Next returned last.
  std::string Where() const { return path_ + ":" + std::to_string(line_no_) + ": "; }
  const std::string& path() const { return path_; }

 private:
  TextLines(std::FILE* file, std::string path) : file_(file), path_(std::move(path)) {}
  bool Fill();  // reads the next block into buf_; false at the end or on an error

  std::FILE* file_;
  std::string path_;
  std::vector<char> buf_;
  size_t at_ = 0, end_ = 0;
  bool eof_ = false;
  bool skip_lf_ = false;  // the last line ended with '\r': a '\n' right after it belongs to it
  std::string line_;
  uint64_t line_no_ = 0;
  Status status_;
};

// Whitespace-separated tokens of a line (spaces and tabs).
std::vector<std::string_view> SplitTokens(std::string_view line);
void SplitTokens(std::string_view line, std::vector<std::string_view>* tokens);  // reuses *tokens

// A decimal number as assimp's fast_atoreal reads it in full: [+-] then digits with an optional '.' and
// fraction (or '.' and digits), then an optional exponent. False for anything else (nan, inf, hex, junk).
bool ParseDecimal(std::string_view token, double* value);
// 'token' for an error message, cut to 40 bytes so that a garbage line cannot flood the message.
std::string QuotedToken(std::string_view token);

// Decimal digits only, at most 2^32 - 1 (assimp's strtoul10 reads "-1" as 0 and wraps past 2^32).
bool ParseCount(std::string_view token, uint32_t* value);

}  // namespace mktree
