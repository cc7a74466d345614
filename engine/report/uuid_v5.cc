#include "engine/report/uuid_v5.h"

#include "engine/report/sha1.h"

namespace mktree {

std::string UuidV5(std::string_view name_space, std::string_view name) {
  auto nibble = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  std::string input;
  int hi = -1;
  for (char c : name_space) {
    const int v = nibble(c);
    if (v < 0) continue;
    if (hi < 0) {
      hi = v;
    } else {
      input.push_back(static_cast<char>(hi << 4 | v));
      hi = -1;
    }
  }
  input.append(name);
  std::array<uint8_t, 20> h = Sha1(input);
  h[6] = static_cast<uint8_t>((h[6] & 0x0f) | 0x50);
  h[8] = static_cast<uint8_t>((h[8] & 0x3f) | 0x80);
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (int i = 0; i < 16; ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out.push_back('-');
    out.push_back(kHex[h[i] >> 4]);
    out.push_back(kHex[h[i] & 15]);
  }
  return out;
}

}  // namespace mktree
