// Bytes of any kind (object names, attributes, file names) as the contents of a JSON string, and as one
// line of text: the CLI prints names that may hold NUL, newlines, tabs or invalid UTF-8.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

#include "mktree/database.h"

namespace mktree::tools {

// The length of the valid UTF-8 sequence at s[i] (shortest form, no surrogates, at most U+10FFFF), or 0.
inline size_t Utf8SequenceAt(std::string_view s, size_t i) {
  const auto b = [&](size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = b(i);
  size_t n = 0;
  uint32_t cp = 0;
  if (c < 0x80) return 1;
  if (c >= 0xc2 && c <= 0xdf) {
    n = 2;
    cp = c & 0x1f;
  } else if (c >= 0xe0 && c <= 0xef) {
    n = 3;
    cp = c & 0x0f;
  } else if (c >= 0xf0 && c <= 0xf4) {
    n = 4;
    cp = c & 0x07;
  } else {
    return 0;
  }
  if (i + n > s.size()) return 0;
  for (size_t k = 1; k < n; ++k) {
    if ((b(i + k) & 0xc0) != 0x80) return 0;
    cp = (cp << 6) | (b(i + k) & 0x3f);
  }
  if ((n == 3 && (cp < 0x800 || (cp >= 0xd800 && cp <= 0xdfff))) ||
      (n == 4 && (cp < 0x10000 || cp > 0x10ffff)))
    return 0;
  return n;
}

// JSON string contents: quote and backslash escaped, control characters (newline, tab, NUL, ...) as
// \u00XX, and each byte that is not part of valid UTF-8 as U+FFFD (JSON text must be UTF-8; the replacement
// is lossy only for such bytes).
inline std::string JsonText(std::string_view s) {
  std::string out;
  out.reserve(s.size() + 2);
  for (size_t i = 0; i < s.size();) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += static_cast<char>(c);
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(c));
      out += buf;
    } else if (c >= 0x80) {
      const size_t n = Utf8SequenceAt(s, i);
      if (n == 0) {
        out += "\xef\xbf\xbd";
        ++i;
      } else {
        out.append(s.substr(i, n));
        i += n;
      }
      continue;
    } else {
      out += static_cast<char>(c);
    }
    ++i;
  }
  return out;
}

// One line of text: the same escapes as JsonText, so that a name never breaks a line or a column (a tab
// shows as \u0009, a newline as \u000a).
inline std::string LineText(std::string_view s) { return JsonText(s); }

// A second handle on `store` for --names, with a small cache of its own: reading names then leaves the
// main handle's cache and statistics as they are without --names.
inline Result<std::unique_ptr<Database>> OpenNamesHandle(const std::string& store, OpenOptions options) {
  options.cache_pages = 64;
  return Database::Open(store, options);
}

}  // namespace mktree::tools
