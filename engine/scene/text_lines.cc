#include "engine/scene/text_lines.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>

namespace mktree {

namespace {
constexpr size_t kBlockBytes = 1 << 20;
}  // namespace

Result<std::unique_ptr<TextLines>> TextLines::Open(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return Status::IOError(path + ": cannot open: " + std::strerror(errno));
  return std::unique_ptr<TextLines>(new TextLines(f, path));
}

TextLines::~TextLines() { std::fclose(file_); }

bool TextLines::Fill() {
  if (eof_ || !status_.ok()) return false;
  buf_.resize(kBlockBytes);
  end_ = std::fread(buf_.data(), 1, buf_.size(), file_);
  at_ = 0;
  if (end_ < buf_.size()) {
    if (std::ferror(file_)) {
      status_ = Status::IOError(path_ + ": read failed");
      return false;
    }
    eof_ = true;
  }
  return end_ > 0;
}

bool TextLines::Next(std::string_view* line) {
  line_.clear();
  bool any = false;
  while (true) {
    if (at_ == end_ && !Fill()) {
      if (!status_.ok() || !any) return false;
      break;  // the last line has no line end
    }
    if (skip_lf_) {
      skip_lf_ = false;
      if (buf_[at_] == '\n') {
        ++at_;
        continue;
      }
    }
    any = true;
    // The run of ordinary bytes up to the next special one, appended at once.
    size_t stop = at_;
    while (stop < end_ && buf_[stop] != '\n' && buf_[stop] != '\r' && buf_[stop] != '\0' &&
           buf_[stop] != '\f')
      ++stop;
    if (line_.size() + (stop - at_) > kMaxLineBytes) {
      ++line_no_;
      status_ = Status::Corruption(Where() + "line longer than " + std::to_string(kMaxLineBytes) + " bytes");
      return false;
    }
    line_.append(buf_.data() + at_, stop - at_);
    at_ = stop;
    if (at_ == end_) continue;
    const char c = buf_[at_++];
    if (c == '\r') skip_lf_ = true;
    if (c == '\n' || c == '\r') break;
    ++line_no_;
    status_ = Status::Corruption(Where() + (c == '\0' ? "NUL byte" : "form feed byte") + " in a text file");
    return false;
  }
  ++line_no_;
  *line = line_;
  return true;
}

std::vector<std::string_view> SplitTokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  SplitTokens(line, &tokens);
  return tokens;
}

void SplitTokens(std::string_view line, std::vector<std::string_view>* out) {
  std::vector<std::string_view>& tokens = *out;
  tokens.clear();
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) tokens.push_back(line.substr(i, j - i));
    i = j;
  }
}

std::string QuotedToken(std::string_view token) {
  std::string q;
  q.reserve(std::min<size_t>(token.size(), 40) + 5);
  q += '\'';
  q.append(token.substr(0, 40));
  if (token.size() > 40) q += "...";
  q += '\'';
  return q;
}

bool ParseDecimal(std::string_view t, double* value) {
  size_t i = 0;
  if (i < t.size() && (t[i] == '+' || t[i] == '-')) ++i;
  size_t digits = 0;
  while (i < t.size() && t[i] >= '0' && t[i] <= '9') ++i, ++digits;
  if (i < t.size() && t[i] == '.') {
    ++i;
    while (i < t.size() && t[i] >= '0' && t[i] <= '9') ++i, ++digits;
  }
  if (digits == 0) return false;
  if (i < t.size() && (t[i] == 'e' || t[i] == 'E')) {
    ++i;
    if (i < t.size() && (t[i] == '+' || t[i] == '-')) ++i;
    size_t exp_digits = 0;
    while (i < t.size() && t[i] >= '0' && t[i] <= '9') ++i, ++exp_digits;
    if (exp_digits == 0) return false;
  }
  if (i != t.size()) return false;
  if (t[0] == '+') t.remove_prefix(1);  // from_chars takes no '+'
  // Out of range (1e999, 1e-999) is a value for the caller's finiteness check, as strtod gives it.
  auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), *value);
  if (ec == std::errc::result_out_of_range) {
    const std::string s(t);
    *value = std::strtod(s.c_str(), nullptr);
  }
  return end == t.data() + t.size();
}

bool ParseCount(std::string_view t, uint32_t* value) {
  if (t.empty() || t[0] < '0' || t[0] > '9') return false;
  auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), *value);
  return ec == std::errc() && end == t.data() + t.size();
}

}  // namespace mktree
